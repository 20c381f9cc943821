// Corotational finite elements under backward Euler: the system's blocks, one invocation per
// slot (or edge record) of the layout. After the tet pass (`corotational_tets.wgsl`) has
// written each tet's rotation R for this step, slot s of node i pointing at j gets
//   K'_ij = sum_t R_t K_t,ab R_t^T,   K_ab = V (mu (b_a . b_b) I + mu b_b b_a^T + lambda b_a b_b^T)
// over the tets t holding both nodes (a the corner of i, b that of j; `lancet::layout::tet_pairs`
// lists them per slot, tets ascending), and, where any tet is damped, C'_ij = sum_t beta_t R_t
// K_t,ab R_t^T after it: the layout of `lancet::layout::tensor_blocks`, so that the tensor-mass
// solve (`implicit_tensor.wgsl`) reads the rotated stiffness where it reads the constant one.
// With r_a = R b_a the block is V (mu (b_a . b_b) I + mu r_b r_a^T + lambda r_a r_b^T): no
// 3x3 products. A slot no tet holds gets zero blocks. The rotation's entries are those of
// the tet pass (`rotation_minus_identity`). Every sum of products is a `dot` (see
// corotational_tets.wgsl); the twin is `twin::corotational_implicit::blocks_cpu`.

// Mirrors `engine::gpu::corotational_implicit::BlockUniform` (16 bytes).
struct BlockParams {
    records: u32,   // slots (or edge records) of the layout
    row: u32,       // invocations per dispatch row
    stride: u32,    // vec4 rows per slot: 3 (K'), 6 (K' then C')
    pad: u32,
}

@group(0) @binding(0) var<uniform> bp: BlockParams;
// Per slot, [start, end) in `pairs`.
@group(0) @binding(1) var<storage, read> pair_rows: array<vec2<u32>>;
// Per pair, 16 t + 4 a + b.
@group(0) @binding(2) var<storage, read> pairs: array<u32>;
// Per tet: (b1, V lambda), (b2, 2 V mu), (b3, beta) (`lancet::layout::tet_table`).
@group(0) @binding(3) var<storage, read> shape: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> rotations: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> blocks: array<vec4<f32>>;

// Corner a's shape-function gradient of tet t (corner 0's is minus the others' sum).
fn corner_gradient(t: u32, a: u32) -> vec3<f32> {
    if (a == 0u) {
        return -((shape[3u * t].xyz + shape[3u * t + 1u].xyz) + shape[3u * t + 2u].xyz);
    }
    return shape[3u * t + a - 1u].xyz;
}

// R - I of the unit quaternion q, as the tet pass forms it (`rotation_minus_identity` in
// corotational_tets.wgsl, repeated: the two files are separate modules).
fn rotation_minus_identity(q: vec4<f32>) -> array<vec3<f32>, 3> {
    return array<vec3<f32>, 3>(
        vec3<f32>(
            -2.0 * dot(q.yz, q.yz),
            2.0 * dot(vec2<f32>(q.x, q.w), vec2<f32>(q.y, -q.z)),
            2.0 * dot(vec2<f32>(q.x, q.w), vec2<f32>(q.z, q.y))
        ),
        vec3<f32>(
            2.0 * dot(vec2<f32>(q.x, q.w), vec2<f32>(q.y, q.z)),
            -2.0 * dot(q.xz, q.xz),
            2.0 * dot(vec2<f32>(q.y, q.w), vec2<f32>(q.z, -q.x))
        ),
        vec3<f32>(
            2.0 * dot(vec2<f32>(q.x, q.w), vec2<f32>(q.z, -q.y)),
            2.0 * dot(vec2<f32>(q.y, q.w), vec2<f32>(q.z, q.x)),
            -2.0 * dot(q.xy, q.xy)
        )
    );
}

// R w, R's rows as the tet pass forms them for its forces (m = R - I).
fn rotate(m: array<vec3<f32>, 3>, w: vec3<f32>) -> vec3<f32> {
    let rr0 = vec3<f32>(m[0].x + 1.0, m[0].y, m[0].z);
    let rr1 = vec3<f32>(m[1].x, m[1].y + 1.0, m[1].z);
    let rr2 = vec3<f32>(m[2].x, m[2].y, m[2].z + 1.0);
    return vec3<f32>(dot(rr0, w), dot(rr1, w), dot(rr2, w));
}

// Row `r` of one tet's rotated block: k . (e_r lane, r_a lane, r_b lane) per column, with
// k = (V mu (b_a . b_b), V mu r_b[r], V lambda r_a[r]).
fn block_row(k: vec3<f32>, r: u32, ra: vec3<f32>, rb: vec3<f32>) -> vec3<f32> {
    let e = vec3<f32>(select(0.0, 1.0, r == 0u), select(0.0, 1.0, r == 1u), select(0.0, 1.0, r == 2u));
    return vec3<f32>(
        dot(k, vec3<f32>(e.x, ra.x, rb.x)),
        dot(k, vec3<f32>(e.y, ra.y, rb.y)),
        dot(k, vec3<f32>(e.z, ra.z, rb.z))
    );
}

// s + beta w, lane by lane (no fused multiply-add).
fn plus_scaled3(s: vec3<f32>, w: vec3<f32>, beta: f32) -> vec3<f32> {
    let c = vec2<f32>(1.0, beta);
    return vec3<f32>(dot(vec2<f32>(s.x, w.x), c), dot(vec2<f32>(s.y, w.y), c), dot(vec2<f32>(s.z, w.z), c));
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let slot = gid.x + gid.y * bp.row;
    if (slot >= bp.records) {
        return;
    }
    var k0 = vec3<f32>(0.0);
    var k1 = vec3<f32>(0.0);
    var k2 = vec3<f32>(0.0);
    var c0 = vec3<f32>(0.0);
    var c1 = vec3<f32>(0.0);
    var c2 = vec3<f32>(0.0);
    let range = pair_rows[slot];
    for (var p = range.x; p < range.y; p = p + 1u) {
        let code = pairs[p];
        let t = code / 16u;
        let a = (code / 4u) % 4u;
        let b = code % 4u;
        let ba = corner_gradient(t, a);
        let bb = corner_gradient(t, b);
        let m = rotation_minus_identity(rotations[t]);
        let ra = rotate(m, ba);
        let rb = rotate(m, bb);
        let lam = shape[3u * t].w;
        let mu = 0.5 * shape[3u * t + 1u].w;
        let beta = shape[3u * t + 2u].w;
        let iso = mu * dot(ba, bb);
        let k_0 = block_row(vec3<f32>(iso, mu * rb.x, lam * ra.x), 0u, ra, rb);
        let k_1 = block_row(vec3<f32>(iso, mu * rb.y, lam * ra.y), 1u, ra, rb);
        let k_2 = block_row(vec3<f32>(iso, mu * rb.z, lam * ra.z), 2u, ra, rb);
        k0 = k0 + k_0;
        k1 = k1 + k_1;
        k2 = k2 + k_2;
        if (bp.stride == 6u) {
            c0 = plus_scaled3(c0, k_0, beta);
            c1 = plus_scaled3(c1, k_1, beta);
            c2 = plus_scaled3(c2, k_2, beta);
        }
    }
    let at = slot * bp.stride;
    blocks[at] = vec4<f32>(k0, 0.0);
    blocks[at + 1u] = vec4<f32>(k1, 0.0);
    blocks[at + 2u] = vec4<f32>(k2, 0.0);
    if (bp.stride == 6u) {
        blocks[at + 3u] = vec4<f32>(c0, 0.0);
        blocks[at + 4u] = vec4<f32>(c1, 0.0);
        blocks[at + 5u] = vec4<f32>(c2, 0.0);
    }
}
