// Divergence check on the device: one invocation per node finds non-finite state (the lowest
// such node wins an atomicMin) and each workgroup sums its nodes' kinetic energy and change of
// gravitational energy, so the host reads back a few bytes per 64 nodes instead of the state.
// Prepended with common.wgsl; the twin is `twin::health::health_cpu`.

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> inv_mass: array<f32>;
@group(0) @binding(2) var<storage, read> second_in: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> cur: array<vec4<f32>>;
// Per workgroup: (kinetic energy, gravitational energy change, 0, 0), J.
@group(0) @binding(4) var<storage, read_write> partials: array<vec4<f32>>;
// Lowest layout index with non-finite state; 0xffffffff when none (set by the host).
@group(0) @binding(5) var<storage, read_write> first_bad: atomic<u32>;

var<workgroup> kinetic: array<f32, 64>;
var<workgroup> gravity: array<f32, 64>;

// Infinity or NaN: all exponent bits set (a comparison `x != x` may be folded away).
fn finite3(v: vec3<f32>) -> bool {
    let e = bitcast<vec3<u32>>(v) & vec3<u32>(0x7f800000u);
    return all(e != vec3<u32>(0x7f800000u));
}

@compute @workgroup_size(64)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let i = gid.x + gid.y * p.row;
    var k = 0.0;
    var g = 0.0;
    if (i < p.n) {
        let u = cur[i].xyz;
        let s = second_in[i].xyz;
        if (!finite3(u) || !finite3(s)) {
            atomicMin(&first_bad, i);
        } else if (inv_mass[i] > 0.0) {
            let m = 1.0 / inv_mass[i];
            let v = velocity(p, u, s);
            k = 0.5 * m * dot(v, v);
            g = -m * dot(p.gravity, u);
        }
    }
    kinetic[lid] = k;
    gravity[lid] = g;
    workgroupBarrier();
    for (var stride = 32u; stride > 0u; stride = stride / 2u) {
        if (lid < stride) {
            kinetic[lid] = kinetic[lid] + kinetic[lid + stride];
            gravity[lid] = gravity[lid] + gravity[lid + stride];
        }
        workgroupBarrier();
    }
    if (lid == 0u) {
        partials[wid.x + wid.y * groups.x] = vec4<f32>(kinetic[0], gravity[0], 0.0, 0.0);
    }
}
