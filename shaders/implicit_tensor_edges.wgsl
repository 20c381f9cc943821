// The tensor-mass setup terms and product on the edge layout for `implicit_solve.wgsl`. The
// edge records are bound as the solve's `slots` (`other` reads `a`, `pad` reads `b`), each
// record's block (K_ab, from its `a` end) at its own index (implicit_tensor.wgsl). A node's
// setup walks its incidence row, the block transposed from a `b` end. The product is the edge
// layout's gather variant: `spring_multiply`, one invocation per record, stores the two ends'
// shares, (h^2 K_ab + h C_ab) (p_b - p_a) for `a` at 2 r and its transpose times (p_a - p_b)
// for `b` at 2 r + 1 (a tensor's two shares are not opposite); `multiply` gathers them per
// node in incidence order, as `tensor_gather_edges.wgsl` gathers the explicit forces. The
// twin is `twin::implicit_tensor` (`record_multiply_cpu`, `gather_multiply_cpu`).

const B_END: u32 = 0x80000000u;
// Room a patch left at the end of a row (`lancet::layout::edges::NO_SPRING`).
const NO_SPRING: u32 = 0xffffffffu;

@group(0) @binding(9) var<storage, read> incidence_rows: array<vec2<u32>>;
@group(0) @binding(10) var<storage, read> incidence: array<u32>;
// Two values per record: its `a` end's share, then its `b` end's.
@group(0) @binding(11) var<storage, read_write> spring_values: array<vec4<f32>>;

fn node_terms(i: u32, ui: vec3<f32>, vi: vec3<f32>) -> Terms {
    var terms = no_terms();
    let stride = block_stride();
    let row = incidence_rows[i];
    for (var e = row.x; e < row.y; e = e + 1u) {
        let entry = incidence[e];
        if (entry == NO_SPRING) {
            break;
        }
        let r = entry & ~B_END;
        let t = (entry & B_END) != 0u;
        var j = slots[r].pad;
        if (t) {
            j = slots[r].other;
        }
        tensor_terms(&terms, r * stride, t, cur[j].xyz - ui, vel[j].xyz - vi);
    }
    // The force model's force (implicit_tensor_force.wgsl, implicit_corotational.wgsl).
    terms.f = element_force(i, terms.f);
    return terms;
}

// Per record (a, b), d = p_b - p_a: (h^2 K + h C) d for a, (h^2 K + h C)^T (-d) for b. Dead
// records (both ends on one node) have zero blocks and store zeros.
@compute @workgroup_size(64)
fn spring_multiply(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * q.row;
    if (s >= q.springs || red.s.status != RUNNING) {
        return;
    }
    let sp = slots[s];
    let d = vecs[at(P, sp.pad)].xyz - vecs[at(P, sp.other)].xyz;
    let b = s * block_stride();
    spring_values[2u * s] = vec4<f32>(tensor_product_term(b, false, d), 0.0);
    spring_values[2u * s + 1u] = vec4<f32>(tensor_product_term(b, true, -d), 0.0);
}

// (A w)_i for the direction p, gathered from `spring_multiply` (zero on fixed nodes). Only
// the direction is ever multiplied on this layout: `v` must be P.
fn product(i: u32, v: u32) -> vec3<f32> {
    let m_inv = inv_mass[i];
    if (m_inv == 0.0) {
        return vec3<f32>(0.0);
    }
    let wi = vecs[at(v, i)].xyz;
    var sum = vec3<f32>(0.0);
    let row = incidence_rows[i];
    for (var e = row.x; e < row.y; e = e + 1u) {
        let entry = incidence[e];
        if (entry == NO_SPRING) {
            break;
        }
        let end = select(0u, 1u, (entry & B_END) != 0u);
        sum = sum + spring_values[2u * (entry & ~B_END) + end].xyz;
    }
    let m = (1.0 + q.h * q.alpha) / m_inv;
    return m * wi + sum;
}
