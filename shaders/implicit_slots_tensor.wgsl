// The tensor-mass setup terms and product on the node-centric layouts for
// `implicit_solve.wgsl`: a gather over the node's slots (implicit_slots.wgsl's walk), each
// slot's block at its own index (implicit_tensor.wgsl). The twin is
// `twin::implicit_tensor::node_terms` and `twin::implicit_tensor::product`.

fn node_terms(i: u32, ui: vec3<f32>, vi: vec3<f32>) -> Terms {
    var terms = no_terms();
    let stride = block_stride();
    var c = cursor(i);
    loop {
        let k = advance(&c);
        if (k == EMPTY) {
            break;
        }
        let j = slots[k].other;
        tensor_terms(&terms, k * stride, false, cur[j].xyz - ui, vel[j].xyz - vi);
    }
    // The force model's force (implicit_tensor_force.wgsl, implicit_corotational.wgsl).
    terms.f = element_force(i, terms.f);
    return terms;
}

// (A w)_i for the vector `v` of the solver vectors (zero on fixed nodes).
fn product(i: u32, v: u32) -> vec3<f32> {
    let m_inv = inv_mass[i];
    if (m_inv == 0.0) {
        return vec3<f32>(0.0);
    }
    let wi = vecs[at(v, i)].xyz;
    let stride = block_stride();
    var sum = vec3<f32>(0.0);
    var c = cursor(i);
    loop {
        let k = advance(&c);
        if (k == EMPTY) {
            break;
        }
        let j = slots[k].other;
        sum = sum + tensor_product_term(k * stride, false, vecs[at(v, j)].xyz - wi);
    }
    let m = (1.0 + q.h * q.alpha) / m_inv;
    return m * wi + sum;
}
