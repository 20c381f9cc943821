//! The integrators: how a node's state advances from the force on it, what state each keeps,
//! and how that state follows a change of time step. Twins of the WGSL `velocity` and
//! `integrate` in `shaders/common.wgsl` and of `shaders/time_step.wgsl`.

use serde::{Deserialize, Serialize};

/// Time integration scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Integrator {
    /// Position Verlet, `x+ = x + (x - x-) + h^2 a(x, (x - x-)/h)`, kept as the displacement
    /// and the last step `d = x - x-`: `d+ = d + h^2 a(x, d/h)`, `x+ = x + d+`.
    #[default]
    Verlet,
    /// Symplectic (semi-implicit) Euler in velocity form: `v+ = v + h a(x, v)`, `x+ = x + h v+`
    /// (what Warp, Newton and Taichi use).
    SymplecticEuler,
    /// Linearised backward Euler solved by matrix-free conjugate gradients
    /// ([`crate::physics::BackwardEuler`], settings in [`crate::engine::SimConfig::solver`]):
    /// stable at any step, so the stable bound does not limit it. Its state is the position and
    /// velocity, as symplectic Euler's. Every engine runs it: the reference engine through this
    /// type, the fast engine and the GPU (connectivity and valence layouts) in their own float32
    /// solvers.
    BackwardEuler,
}

impl Integrator {
    /// Whether the scheme solves a system each step (and so is not limited by the stable bound).
    pub fn is_implicit(self) -> bool {
        self == Integrator::BackwardEuler
    }

    /// Whether the state keeps the velocity (symplectic and backward Euler) rather than the
    /// previous position (Verlet).
    pub fn keeps_velocity(self) -> bool {
        self != Integrator::Verlet
    }
}

/// Constants of one step, as the shaders see them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepParams {
    /// Time step, s.
    pub h: f32,
    /// Gravity, m/s^2.
    pub gravity: [f32; 3],
    /// Mass-proportional damping, 1/s.
    pub alpha: f32,
    /// Integration scheme.
    pub integrator: Integrator,
    /// Whether springs are damped (neighbour velocities are read only then).
    pub damped: bool,
}

/// Velocity of a node from its state, as the WGSL `velocity` computes it: the stored step over
/// `h` for Verlet (`second` = the last step `u - u_prev`), the stored velocity for symplectic
/// Euler.
pub fn velocity(p: &StepParams, cur: [f32; 4], second: [f32; 4]) -> [f32; 3] {
    let _ = cur;
    if p.integrator == Integrator::Verlet {
        let inv_h = 1.0 / p.h;
        [second[0] * inv_h, second[1] * inv_h, second[2] * inv_h]
    } else {
        [second[0], second[1], second[2]]
    }
}

/// The next displacement and second state of a free node under spring force `f`, as the WGSL
/// `integrate` computes it.
///
/// Verlet keeps the step `d = u - u_prev` (`d+ = d + h^2 a`, `u+ = u + d+`) and symplectic
/// Euler the velocity (`v+ = v + h a`, `u+ = u + h v+`): the step is never recovered as the
/// difference of two rounded displacements, which far below the stable bound would round most
/// of it away. What rounding `u + step` still loses is kept and added to the next step
/// ([`Compensation`]), so a displacement creeping by less than its own ulp per step still
/// moves, and a settling node does not stall short of equilibrium.
pub fn integrate(
    p: &StepParams,
    ui: [f32; 4],
    second_i: [f32; 4],
    vi: [f32; 3],
    f: [f32; 3],
    inv_mass: f32,
) -> ([f32; 4], [f32; 4]) {
    let mut a = [0.0f32; 3];
    for c in 0..3 {
        a[c] = f[c] * inv_mass + p.gravity[c] - p.alpha * vi[c];
    }
    let carried = Compensation::decode(ui, second_i);
    let (mut step, mut second) = ([0.0f32; 3], [0.0f32; 4]);
    for c in 0..3 {
        if p.integrator == Integrator::Verlet {
            second[c] = second_i[c] + (p.h * p.h) * a[c];
            step[c] = second[c] + carried[c];
        } else {
            second[c] = vi[c] + p.h * a[c];
            step[c] = p.h * second[c] + carried[c];
        }
    }
    let mut next = [0.0f32; 4];
    let mut lost = [0.0f32; 3];
    for c in 0..3 {
        (next[c], lost[c]) = two_sum(ui[c], step[c]);
    }
    (next[3], second[3]) = Compensation::encode(next, lost);
    (next, second)
}

/// `(s, e)` with `s = fl(a + b)` and `a + b = s + e` exactly (Knuth's TwoSum: additions only,
/// so no contraction into fused multiply-adds can change it). The shaders' `two_sum`
/// multiplies `s` and `s - a` by a uniform 1.0 so that their compiler cannot fold the residual
/// to zero; that changes no value, so this twin leaves it out.
fn two_sum(a: f32, b: f32) -> (f32, f32) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// The part of each displacement component that rounding `u + step` lost, kept in the spare
/// `w` lanes of the two state vectors and added to the next step (compensated summation).
///
/// Three residuals share two lanes, so each is quantised: `|e_c| <= ulp(m) / 2` with `m` the
/// node's largest displacement component, and `e_c` is stored as an integer `q_c` in units of
/// `ulp(m) / 4096` (`|q_c| <= 2047`): `w` of the displacement holds `q_x + 4096 q_y` and `w` of
/// the second state holds `q_z`, integers that a float32 keeps exactly. A displacement is thus
/// carried to about 35 bits (the fast CPU engine and every GPU pass). Every scale is a power
/// of two built from the exponent bits, so the WGSL twin (`compensation` and
/// `compensation_lanes` in `shaders/common.wgsl`) rounds identically; a lane holding
/// anything else (a blended copy after a cut, a state set from outside) decodes to at most
/// half an ulp, and a zero lane to nothing.
pub struct Compensation;

/// Quantisation steps per ulp of the largest component, log2.
const COMP_BITS: u32 = 12;
/// Largest stored `|q|`.
const COMP_MAX: f32 = 2047.0;

impl Compensation {
    /// The power of two `ulp(m) / 2^COMP_BITS` of a node's displacement, or `None` where that
    /// is not a normal float32 (displacements below about 1e-27 m carry nothing).
    fn unit(u: [f32; 4]) -> Option<f32> {
        let m = u[0].abs().max(u[1].abs()).max(u[2].abs());
        // Biased exponent of m; ulp(m) = 2^(e - 127 - 23).
        let e = (m.to_bits() >> 23) & 0xff;
        let shift = 23 + COMP_BITS;
        (e > shift && e < 255).then(|| f32::from_bits((e - shift) << 23))
    }

    /// The three residuals stored with displacement `u` and second state `second`.
    pub fn decode(u: [f32; 4], second: [f32; 4]) -> [f32; 3] {
        let Some(unit) = Self::unit(u) else {
            return [0.0; 3];
        };
        let packed = u[3].clamp(-8_388_608.0, 8_388_607.0) as i32;
        let qx = ((packed + 2048) & 4095) - 2048;
        let qy = (packed - qx) >> COMP_BITS;
        let qz = second[3].clamp(-COMP_MAX, COMP_MAX) as i32;
        [qx as f32 * unit, qy as f32 * unit, qz as f32 * unit]
    }

    /// The `w` lanes (displacement, second state) that keep `lost` with displacement `u`.
    pub fn encode(u: [f32; 4], lost: [f32; 3]) -> (f32, f32) {
        let Some(unit) = Self::unit(u) else {
            return (0.0, 0.0);
        };
        let inv = f32::from_bits((254 << 23) - unit.to_bits());
        let q = lost.map(|e| (e * inv).round_ties_even().clamp(-COMP_MAX, COMP_MAX));
        (q[0] + q[1] * 4096.0, q[2])
    }
}

/// Node-state buffers of an integrator: current and next displacements and current and next
/// second state (Verlet's last step or symplectic Euler's velocity), swapped after each step.
pub fn state_buffers(n: u64, integrator: Integrator) -> Vec<(String, u64)> {
    let second = match integrator {
        Integrator::Verlet => "steps (2 x vec4)",
        Integrator::SymplecticEuler | Integrator::BackwardEuler => "velocities (2 x vec4)",
    };
    vec![
        ("displacements (2 x vec4)".to_string(), 2 * n * 16),
        (second.to_string(), 2 * n * 16),
    ]
}

/// Bytes of node state one step reads and writes (each buffer once).
pub fn state_traffic(n: u64, integrator: Integrator) -> u64 {
    let _ = integrator;
    4 * n * 16
}

/// A change of time step from `h` to `h'` (`rescale = h' / h`) for Verlet, whose state keeps
/// the last step `d = u - u_prev`: `d = d * rescale` on x, y, z in float32, as
/// `shaders/time_step.wgsl` computes it, so that the velocity `d / h` is the same at the new
/// step; `w` (the compensation) is kept. Symplectic Euler keeps the velocity itself and needs
/// nothing.
pub fn rescale_previous(cur: &[[f32; 4]], prev: &mut [[f32; 4]], rescale: f32) {
    let _ = cur;
    for s in prev.iter_mut() {
        for c in s.iter_mut().take(3) {
            *c *= rescale;
        }
    }
}
