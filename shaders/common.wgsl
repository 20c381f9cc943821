// Structs shared by every pass. Each has a Rust mirror that names it and asserts its size.

// One spring seen from one of its ends; mirrors `lancet::layout::Slot` (32 bytes).
struct Slot {
    edge: vec3<f32>,   // rest vector from this node to the other, m
    rest: f32,         // rest length, m
    k: f32,            // stiffness, N/m
    c: f32,            // damping along the spring, N s/m
    other: u32,        // the other end; 0xffffffff in padding slots
    pad: u32,
}

// Per-step constants; mirrors `engine::gpu::StepUniform` (48 bytes).
struct Params {
    h: f32,
    h2: f32,
    inv_h: f32,
    alpha: f32,          // mass-proportional damping, 1/s
    gravity: vec3<f32>,
    integrator: u32,     // 0 = Verlet on displacements, 1 = symplectic Euler
    n: u32,              // nodes
    width: u32,          // slots per node (connectivity layout)
    damped: u32,         // 1 when any spring has damping
    row: u32,            // invocations per dispatch row (2D dispatch of large meshes)
}

const EMPTY: u32 = 0xffffffffu;
const VERLET: u32 = 0u;

// Velocity of node j: backward difference for Verlet (second = previous displacement),
// stored velocity for symplectic Euler (second = velocity).
fn velocity(p: Params, cur: vec3<f32>, second: vec3<f32>) -> vec3<f32> {
    if (p.integrator == VERLET) {
        return (cur - second) * p.inv_h;
    }
    return second;
}

// Force of one slot on its node, as `layout::connectivity::node_update` computes it.
fn slot_force(p: Params, s: Slot, d: vec3<f32>, dv: vec3<f32>) -> vec3<f32> {
    let l = length(d);
    if (l <= 0.0) {
        return vec3<f32>(0.0);
    }
    let dir = d / l;
    var mag = s.k * (l - s.rest);
    if (p.damped != 0u) {
        mag = mag + s.c * dot(dv, dir);
    }
    return mag * dir;
}
