// Edge layout, pass 1: one invocation per spring computes its force once and stores the force
// on its `a` end (the `b` end gets the opposite). Prepended with common.wgsl.

// Mirrors `lancet::layout::edges::EdgeSpring` (32 bytes).
struct EdgeSpring {
    edge: vec3<f32>,   // rest vector from a to b, m
    rest: f32,
    k: f32,
    c: f32,
    a: u32,
    b: u32,
}

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
    let sp = springs[s];
    let ua = cur[sp.a].xyz;
    let ub = cur[sp.b].xyz;
    var dv = vec3<f32>(0.0);
    if (p.damped != 0u) {
        dv = velocity(p, ub, second_in[sp.b].xyz) - velocity(p, ua, second_in[sp.a].xyz);
    }
    let slot = Slot(sp.edge, sp.rest, sp.k, sp.c, sp.b, 0u);
    forces[s] = vec4<f32>(slot_force(p, slot, sp.edge + (ub - ua), dv), 0.0);
}
