// Edge layout with float atomics, pass 1: one invocation per spring computes its force and
// adds it to its ends' float accumulators (+ at `a`, - at `b`). Needs SHADER_FLOAT32_ATOMIC;
// the order of the adds, hence the rounding of the sums, varies between runs. Prepended with
// common.wgsl and edge_spring.wgsl; the twin is
// `twin::accumulate_float` (`EdgeLayout::accumulate_float_cpu`, one of the possible orders).

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> springs: array<EdgeSpring>;
@group(0) @binding(2) var<storage, read> second_in: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> cur: array<vec4<f32>>;
// Three accumulators per node (x, y, z); the node pass clears them.
@group(0) @binding(4) var<storage, read_write> acc: array<atomic<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * p.row;
    if (s >= p.springs) {
        return;
    }
    let sp = springs[s];
    let f = edge_force(sp);
    atomicAdd(&acc[3u * sp.a], f.x);
    atomicAdd(&acc[3u * sp.a + 1u], f.y);
    atomicAdd(&acc[3u * sp.a + 2u], f.z);
    atomicAdd(&acc[3u * sp.b], -f.x);
    atomicAdd(&acc[3u * sp.b + 1u], -f.y);
    atomicAdd(&acc[3u * sp.b + 2u], -f.z);
}
