// The springs' product on the node-centric layouts for `implicit_solve.wgsl`: a gather over the
// node's slots (implicit_slots.wgsl's walk), recomputing each spring's block from the geometry
// (implicit_springs.wgsl). The twin is `twin::implicit_solve::product`.

// (A w)_i for the vector `v` of the solver vectors (zero on fixed nodes).
fn product(i: u32, v: u32) -> vec3<f32> {
    let m_inv = inv_mass[i];
    if (m_inv == 0.0) {
        return vec3<f32>(0.0);
    }
    let ui = cur[i].xyz;
    let wi = vecs[at(v, i)].xyz;
    var sum = vec3<f32>(0.0);
    var c = cursor(i);
    loop {
        let k = advance(&c);
        if (k == EMPTY) {
            break;
        }
        let s = slots[k];
        let g = geometry(s, ui);
        if (g.ok) {
            sum = sum + block_product(s, g, vecs[at(v, s.other)].xyz - wi);
        }
    }
    let m = (1.0 + q.h * q.alpha) / m_inv;
    return m * wi - sum;
}

