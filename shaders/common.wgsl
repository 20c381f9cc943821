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
    one: f32,            // always 1.0: a factor the compiler cannot see through (`two_sum`)
    pad: u32,
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
// velocity, so the step is never recovered from two rounded displacements; what rounding
// u + step loses is kept in the w lanes and added to the next step (`physics::Compensation`).
struct Integrated {
    u: vec4<f32>,        // next displacement, w: packed residuals of x and y
    second: vec4<f32>,   // next step (Verlet) or velocity, w: residual of z
}

// ulp(m) / 4096 for m the largest component of u, as a power of two; 0 where that is not a
// normal float32. Twin of `Compensation::unit`.
fn compensation_unit(u: vec3<f32>) -> f32 {
    let m = max(abs(u.x), max(abs(u.y), abs(u.z)));
    let e = (bitcast<u32>(m) >> 23u) & 0xffu;
    if (e > 35u && e < 255u) {
        return bitcast<f32>((e - 35u) << 23u);
    }
    return 0.0;
}

// The residuals kept with displacement u and second state s; twin of `Compensation::decode`.
fn compensation(u: vec4<f32>, s: vec4<f32>) -> vec3<f32> {
    let unit = compensation_unit(u.xyz);
    if (unit == 0.0) {
        return vec3<f32>(0.0);
    }
    let packed = i32(clamp(u.w, -8388608.0, 8388607.0));
    let qx = ((packed + 2048) & 4095) - 2048;
    let qy = (packed - qx) >> 12u;
    let qz = i32(clamp(s.w, -2047.0, 2047.0));
    return vec3<f32>(f32(qx) * unit, f32(qy) * unit, f32(qz) * unit);
}

// The w lanes (displacement, second state) that keep `lost` with displacement s; twin of
// `Compensation::encode`.
fn compensation_lanes(s: vec3<f32>, lost: vec3<f32>) -> vec2<f32> {
    let unit = compensation_unit(s);
    if (unit == 0.0) {
        return vec2<f32>(0.0);
    }
    let inv = bitcast<f32>((254u << 23u) - bitcast<u32>(unit));
    let q = clamp(round(lost * inv), vec3<f32>(-2047.0), vec3<f32>(2047.0));
    return vec2<f32>(q.x + q.y * 4096.0, q.z);
}

// u + step rounded to float32 and what the rounding lost, exactly (TwoSum; twin of
// `physics::two_sum`). WGSL promises no exact mode, and a compiler that rewrites float
// arithmetic algebraically may fold (u + step) - u to step and the residual to zero (the
// first compensated shaders disagreed with their twins on lavapipe): multiplying the sum and
// s - u by p.one (1.0, but a uniform it cannot know) changes no value and leaves nothing to
// fold. A product by 1.0 is exact, so a
// fused multiply-add made of one rounds the same.
struct Sum {
    s: vec3<f32>,
    lost: vec3<f32>,
}

fn two_sum(p: Params, u: vec3<f32>, step: vec3<f32>) -> Sum {
    let s = (u + step) * p.one;
    let bb = (s - u) * p.one;
    let lost = (u - (s - bb)) + (step - bb);
    return Sum(s, lost);
}

fn integrate(p: Params, ui4: vec4<f32>, second4: vec4<f32>, vi: vec3<f32>, f: vec3<f32>, m_inv: f32) -> Integrated {
    let a = f * m_inv + p.gravity - p.alpha * vi;
    let carried = compensation(ui4, second4);
    var second: vec3<f32>;
    var step: vec3<f32>;
    if (p.integrator == VERLET) {
        second = second4.xyz + p.h2 * a;
        step = second + carried;
    } else {
        second = vi + p.h * a;
        let moved = p.h * second;
        step = moved + carried;
    }
    let r = two_sum(p, ui4.xyz, step);
    let w = compensation_lanes(r.s, r.lost);
    return Integrated(vec4<f32>(r.s, w.x), vec4<f32>(second, w.y));
}
