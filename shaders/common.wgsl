// Structs shared by every pass. Each has a Rust mirror that names it and asserts its size.

// One spring seen from one of its ends; mirrors `lancet::layout::Slot` (32 bytes).
struct Slot {
    edge: vec3<f32>,   // rest vector from this node to the other, m
    rest: f32,         // rest length, m
    k: f32,            // stiffness, N/m
    c: f32,            // damping along the spring, N s/m
    other: u32,        // the other end; 0xffffffff in padding slots
    pad: u32,          // CONTINUE slots: the row the springs go on in
}

// Per-step constants; mirrors `engine::gpu::StepUniform` (64 bytes).
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
    springs: u32,        // springs (edge layout)
    rescale: f32,        // new h / old h at the last change of time step (time_step.wgsl)
    pad1: u32,
    pad2: u32,
}

const EMPTY: u32 = 0xffffffffu;
// Last slot of a full connectivity row whose node has more springs: `pad` names the row they
// go on in (`Slot::CONTINUE`).
const CONTINUE: u32 = 0xfffffffeu;
const VERLET: u32 = 0u;

// Velocity of node j: the stored step over h for Verlet (second = u - u_prev), the stored
// velocity for symplectic Euler (second = velocity).
fn velocity(p: Params, cur: vec3<f32>, second: vec3<f32>) -> vec3<f32> {
    if (p.integrator == VERLET) {
        return second * p.inv_h;
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

// The next state of a free node from its spring force `f`; twin of `physics::integrate`.
// Verlet keeps the step d = u - u_prev (d+ = d + h^2 a, u+ = u + d+), symplectic Euler the
// velocity, so the step is never recovered from two rounded displacements.
struct Integrated {
    u: vec4<f32>,        // next displacement
    second: vec4<f32>,   // next step (Verlet) or velocity
}

fn integrate(p: Params, ui4: vec4<f32>, second4: vec4<f32>, vi: vec3<f32>, f: vec3<f32>, m_inv: f32) -> Integrated {
    let a = f * m_inv + p.gravity - p.alpha * vi;
    let ui = ui4.xyz;
    if (p.integrator == VERLET) {
        let d = second4.xyz + p.h2 * a;
        return Integrated(vec4<f32>(ui + d, 0.0), vec4<f32>(d, 0.0));
    }
    let v = vi + p.h * a;
    return Integrated(vec4<f32>(ui + p.h * v, 0.0), vec4<f32>(v, 0.0));
}
