// The tensor-mass part of `implicit_solve.wgsl`: the system's stiffness and damping are the
// constant blocks the explicit tensor passes read (`lancet::layout::tensor_blocks`: per slot or
// edge record the rows of K_ij, then of C_ij = beta K_ij where any tet is damped). The node
// blocks are not stored: a tet's block rows sum to zero, so K_ii = -sum_j K_ij, and with
// f_i = -sum_j K_ij (u_j - u_i) - sum_j C_ij (v_j - v_i) the force's derivatives give
//   (A w)_i = (1 + h alpha) m_i w_i + sum_j (h^2 K_ij + h C_ij) (w_j - w_i),
// the right-hand side's K v term -sum_j K_ij (v_j - v_i), and the diagonal block
// (1 + h alpha) m_i I - sum_j (h^2 K_ij + h C_ij), of which the symmetric part is kept (the
// float64 K_ii is symmetric; the float32 sum of the rows may not be to the last bit). Seen
// from the `b` end of an edge record the block is K_ab^T. The twin is `twin::implicit_tensor`.

// Per slot or record: block_stride() rows.
@group(1) @binding(0) var<storage, read> blocks: array<vec4<f32>>;

fn block_stride() -> u32 {
    if (q.damped != 0u) {
        return 6u;
    }
    return 3u;
}

// The block at row b times w (its transpose times w where `t`).
fn block_mul(b: u32, t: bool, w: vec3<f32>) -> vec3<f32> {
    let r0 = blocks[b].xyz;
    let r1 = blocks[b + 1u].xyz;
    let r2 = blocks[b + 2u].xyz;
    if (t) {
        return r0 * w.x + r1 * w.y + r2 * w.z;
    }
    return vec3<f32>(dot3(r0, w), dot3(r1, w), dot3(r2, w));
}

// The symmetric part of the block at row b: (xx, xy, xz, yy) and (yz, zz); the same for the
// block and its transpose.
fn sym_a(b: u32) -> vec4<f32> {
    let r0 = blocks[b].xyz;
    let r1 = blocks[b + 1u].xyz;
    let r2 = blocks[b + 2u].xyz;
    return vec4<f32>(r0.x, 0.5 * (r0.y + r1.x), 0.5 * (r0.z + r2.x), r1.y);
}

fn sym_b(b: u32) -> vec2<f32> {
    let r1 = blocks[b + 1u].xyz;
    let r2 = blocks[b + 2u].xyz;
    return vec2<f32>(0.5 * (r1.z + r2.y), r2.z);
}

// Add one neighbour's share to node i's setup terms: block row b (transposed where `t`), the
// neighbour's displacement and velocity relative to node i.
fn tensor_terms(terms: ptr<function, Terms>, b: u32, t: bool, du: vec3<f32>, dv: vec3<f32>) {
    (*terms).f = (*terms).f - block_mul(b, t, du);
    (*terms).kv = (*terms).kv - block_mul(b, t, dv);
    let h2 = q.h * q.h;
    var ea = h2 * sym_a(b);
    var eb = h2 * sym_b(b);
    if (q.damped != 0u) {
        (*terms).f = (*terms).f - block_mul(b + 3u, t, dv);
        ea = ea + q.h * sym_a(b + 3u);
        eb = eb + q.h * sym_b(b + 3u);
    }
    (*terms).da = (*terms).da - ea;
    (*terms).db = (*terms).db - eb;
}

// (h^2 K + h C) d of the block at row b (transposed where `t`).
fn tensor_product_term(b: u32, t: bool, d: vec3<f32>) -> vec3<f32> {
    var out = (q.h * q.h) * block_mul(b, t, d);
    if (q.damped != 0u) {
        out = out + q.h * block_mul(b + 3u, t, d);
    }
    return out;
}

fn no_terms() -> Terms {
    return Terms(vec3<f32>(0.0), vec3<f32>(0.0), 0.0, vec4<f32>(0.0), vec2<f32>(0.0));
}
