// A tensor-mass record's two end forces, shared by the edge layout's record passes
// (`tensor_edges.wgsl`, `tensor_accumulate_fixed.wgsl`, `tensor_accumulate_float.wgsl`), which
// declare `p`, `cur`, `second_in` and `blocks`; prepended after `tensor_products.wgsl`.

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
