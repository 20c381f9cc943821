// Edge layout with fixed-point atomics, pass 2: one invocation per node reads its accumulators
// (force = f32(sum) * inv_scale), clears them for the next step and integrates. Prepended with
// common.wgsl and fixed_point.wgsl; the twin is `twin::integrate_fixed`.

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<uniform> fx: FixedPoint;
@group(0) @binding(2) var<storage, read_write> acc: array<atomic<i32>>;
@group(0) @binding(3) var<storage, read> inv_mass: array<f32>;
@group(0) @binding(4) var<storage, read> second_in: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> cur: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> next: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> second_out: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * p.row;
    if (i >= p.n) {
        return;
    }
    let q = vec3<i32>(
        atomicExchange(&acc[3u * i], 0),
        atomicExchange(&acc[3u * i + 1u], 0),
        atomicExchange(&acc[3u * i + 2u], 0),
    );
    let m_inv = inv_mass[i];
    if (m_inv == 0.0) {
        next[i] = vec4<f32>(0.0);
        second_out[i] = vec4<f32>(0.0);
        return;
    }
    let f = vec3<f32>(q) * fx.inv_scale;
    let ui = cur[i].xyz;
    let vi = velocity(p, ui, second_in[i].xyz);
    let r = integrate(p, cur[i], second_in[i], vi, f, m_inv);
    next[i] = r.u;
    second_out[i] = r.second;
}
