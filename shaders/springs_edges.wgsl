// Edge layout, pass 1: one invocation per spring computes its force once and stores the force
// on its `a` end (the `b` end gets the opposite). Prepended with common.wgsl and
// edge_spring.wgsl; the twin is `twin::springs_edges`.

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> springs: array<EdgeSpring>;
@group(0) @binding(2) var<storage, read> second_in: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> cur: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> forces: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let s = gid.x + gid.y * p.row;
    if (s >= p.springs) {
        return;
    }
    forces[s] = vec4<f32>(edge_force(springs[s]), 0.0);
}
