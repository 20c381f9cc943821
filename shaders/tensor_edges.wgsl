// Tensor-mass on the edge layout, pass 1: one invocation per record (a, b) computes both end
// forces from its blocks (`lancet::layout::tensor_blocks`, the record's own index): on a,
// -(K_ab du + C_ab dv), stored at 2 r; on b, K_ab^T du + C_ab^T dv (K_ba = K_ab^T), at 2 r + 1;
// du = u_b - u_a. Unlike a spring's, the two are not opposite. Prepended with common.wgsl and
// edge_spring.wgsl (for the record); the twin is `twin::tensor_mass`
// (`TensorBlocks::record_forces_cpu`).

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> springs: array<EdgeSpring>;
@group(0) @binding(2) var<storage, read> second_in: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> cur: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> forces: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> blocks: array<vec4<f32>>;

fn block_stride() -> u32 {
    if (p.damped != 0u) {
        return 6u;
    }
    return 3u;
}

// K du + C dv; twin `TensorBlocks::force_cpu`.
fn tensor_force(b: u32, du: vec3<f32>, dv: vec3<f32>) -> vec3<f32> {
    var f = vec3<f32>(dot(blocks[b].xyz, du), dot(blocks[b + 1u].xyz, du), dot(blocks[b + 2u].xyz, du));
    if (p.damped != 0u) {
        let g = vec3<f32>(dot(blocks[b + 3u].xyz, dv), dot(blocks[b + 4u].xyz, dv), dot(blocks[b + 5u].xyz, dv));
        f = f + g;
    }
    return f;
}

// K^T du + C^T dv, the rows scaled and summed; twin `TensorBlocks::force_t_cpu`.
fn tensor_force_t(b: u32, du: vec3<f32>, dv: vec3<f32>) -> vec3<f32> {
    var f = blocks[b].xyz * du.x + blocks[b + 1u].xyz * du.y + blocks[b + 2u].xyz * du.z;
    if (p.damped != 0u) {
        let g = blocks[b + 3u].xyz * dv.x + blocks[b + 4u].xyz * dv.y + blocks[b + 5u].xyz * dv.z;
        f = f + g;
    }
    return f;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * p.row;
    if (s >= p.springs) {
        return;
    }
    let sp = springs[s];
    let ua = cur[sp.a].xyz;
    let ub = cur[sp.b].xyz;
    var dv = vec3<f32>(0.0);
    if (p.damped != 0u) {
        dv = velocity(p, ub, second_in[sp.b].xyz) - velocity(p, ua, second_in[sp.a].xyz);
    }
    let b = s * block_stride();
    let fa = tensor_force(b, ub - ua, dv);
    forces[2u * s] = vec4<f32>(-fa, 0.0);
    forces[2u * s + 1u] = vec4<f32>(tensor_force_t(b, ub - ua, dv), 0.0);
}
