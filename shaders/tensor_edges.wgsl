// Tensor-mass on the edge layout, pass 1: one invocation per record (a, b) computes both end
// forces from its blocks (`lancet::layout::tensor_blocks`, the record's own index): on a,
// -(K_ab du + C_ab dv), stored at 2 r; on b, K_ab^T du + C_ab^T dv (K_ba = K_ab^T), at 2 r + 1;
// du = u_b - u_a. Unlike a spring's, the two are not opposite. Prepended with common.wgsl and
// edge_spring.wgsl (for the record), tensor_products.wgsl and tensor_block.wgsl; the twin is `twin::tensor_mass`
// (`TensorBlocks::record_forces_cpu`).

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> springs: array<EdgeSpring>;
@group(0) @binding(2) var<storage, read> second_in: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> cur: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> forces: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> blocks: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * p.row;
    if (s >= p.springs) {
        return;
    }
    let sp = springs[s];
    let f = end_forces(s, sp);
    forces[2u * s] = vec4<f32>(f.a, 0.0);
    forces[2u * s + 1u] = vec4<f32>(f.b, 0.0);
}
