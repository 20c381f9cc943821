// A tensor-mass record's block products, shared by the edge layout's record passes
// (`tensor_edges.wgsl`, `tensor_accumulate_fixed.wgsl`, `tensor_accumulate_float.wgsl`), which
// declare `p`, `cur`, `second_in` and `blocks` (the record's blocks at its own index, `lancet::layout::tensor_blocks`).
// Twins: `TensorBlocks::force_cpu` and `TensorBlocks::force_t_cpu`.

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

// The forces on a record's two ends: on a, -(K_ab du + C_ab dv); on b, K_ab^T du + C_ab^T dv
// (K_ba = K_ab^T), du = u_b - u_a. Unlike a spring's, the two are not opposite. Twin:
// `TensorBlocks::record_forces_cpu`.
struct EndForces {
    a: vec3<f32>,
    b: vec3<f32>,
}

fn end_forces(s: u32, sp: EdgeSpring) -> EndForces {
    let ua = cur[sp.a].xyz;
    let ub = cur[sp.b].xyz;
    var dv = vec3<f32>(0.0);
    if (p.damped != 0u) {
        dv = velocity(p, ub, second_in[sp.b].xyz) - velocity(p, ua, second_in[sp.a].xyz);
    }
    let b = s * block_stride();
    return EndForces(-tensor_force(b, ub - ua, dv), tensor_force_t(b, ub - ua, dv));
}
