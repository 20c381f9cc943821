// Tensor-mass on the edge layout with fixed-point atomics, pass 1: one invocation per record
// (a, b) computes both end forces (`end_forces`, tensor_block.wgsl: a tensor's two are not
// opposite) and adds each, quantized, to its own end's integer accumulators. The diagonal
// K_aa u_a needs no term of its own: K_aa = -sum K_ab, so each record's force acts on the
// difference u_b - u_a. The node pass is the springs' (`integrate_fixed.wgsl`). Integer
// addition is associative: the sums do not depend on the order of the adds. Prepended with
// common.wgsl, fixed_point.wgsl, edge_spring.wgsl, tensor_products.wgsl and tensor_block.wgsl;
// the twin is `twin::tensor_atomic` (`TensorBlocks::accumulate_fixed_cpu`).

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> springs: array<EdgeSpring>;
@group(0) @binding(2) var<storage, read> second_in: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> cur: array<vec4<f32>>;
// Three accumulators per node (x, y, z); the node pass clears them.
@group(0) @binding(4) var<storage, read_write> acc: array<atomic<i32>>;
@group(0) @binding(5) var<storage, read> blocks: array<vec4<f32>>;
@group(0) @binding(6) var<uniform> fx: FixedPoint;
// Set (never cleared by the device) when an end force saturated.
@group(0) @binding(7) var<storage, read_write> overflow: array<atomic<u32>, 4>;

// Add `f`, quantized as the springs' pass quantizes, to node `i`'s accumulators.
fn add_fixed(i: u32, f: vec3<f32>) {
    let c = quantize(f, fx);
    if (c.saturated) {
        atomicOr(&overflow[0], 1u);
    }
    let qi = c.q;
    atomicAdd(&acc[3u * i], qi.x);
    atomicAdd(&acc[3u * i + 1u], qi.y);
    atomicAdd(&acc[3u * i + 2u], qi.z);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * p.row;
    if (s >= p.springs) {
        return;
    }
    let sp = springs[s];
    let f = end_forces(s, sp);
    add_fixed(sp.a, f.a);
    add_fixed(sp.b, f.b);
}
