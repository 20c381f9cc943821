// Tensor-mass on the edge layout with float atomics, pass 1: one invocation per record (a, b)
// computes both end forces (`end_forces`, tensor_block.wgsl) and adds each to its own end's
// float accumulators. Needs SHADER_FLOAT32_ATOMIC; the order of the adds, hence the rounding
// of the sums, varies between runs. The node pass is the springs' (`integrate_float.wgsl`).
// Prepended with common.wgsl, edge_spring.wgsl, tensor_products.wgsl and tensor_block.wgsl; the twin is
// `twin::tensor_atomic` (`TensorBlocks::accumulate_float_cpu`, one of the possible orders).

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> springs: array<EdgeSpring>;
@group(0) @binding(2) var<storage, read> second_in: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> cur: array<vec4<f32>>;
// Three accumulators per node (x, y, z); the node pass clears them.
@group(0) @binding(4) var<storage, read_write> acc: array<atomic<f32>>;
@group(0) @binding(5) var<storage, read> blocks: array<vec4<f32>>;

fn add_float(i: u32, f: vec3<f32>) {
    atomicAdd(&acc[3u * i], f.x);
    atomicAdd(&acc[3u * i + 1u], f.y);
    atomicAdd(&acc[3u * i + 2u], f.z);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * p.row;
    if (s >= p.springs) {
        return;
    }
    let sp = springs[s];
    let f = end_forces(s, sp);
    add_float(sp.a, f.a);
    add_float(sp.b, f.b);
}
