// Edge layout with fixed-point atomics, pass 1: one invocation per spring computes its force
// and adds it, quantized, to its ends' integer accumulators (+ at `a`, - at `b`). Integer
// addition is associative, so the sums do not depend on the order of the adds. Prepended with
// common.wgsl, fixed_point.wgsl and edge_spring.wgsl; the twin is
// `twin::accumulate_fixed` (`EdgeLayout::accumulate_fixed_cpu`).

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> springs: array<EdgeSpring>;
@group(0) @binding(2) var<storage, read> second_in: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> cur: array<vec4<f32>>;
// Three accumulators per node (x, y, z); the node pass clears them.
@group(0) @binding(4) var<storage, read_write> acc: array<atomic<i32>>;
@group(0) @binding(5) var<uniform> fx: FixedPoint;
// Set (never cleared by the device) when a spring force saturated.
@group(0) @binding(6) var<storage, read_write> overflow: array<atomic<u32>, 4>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * p.row;
    if (s >= p.springs) {
        return;
    }
    let sp = springs[s];
    let f = quantize(edge_force(sp), fx);
    if (f.saturated) {
        atomicOr(&overflow[0], 1u);
    }
    let qi = f.q;
    atomicAdd(&acc[3u * sp.a], qi.x);
    atomicAdd(&acc[3u * sp.a + 1u], qi.y);
    atomicAdd(&acc[3u * sp.a + 2u], qi.z);
    atomicSub(&acc[3u * sp.b], qi.x);
    atomicSub(&acc[3u * sp.b + 1u], qi.y);
    atomicSub(&acc[3u * sp.b + 2u], qi.z);
}
