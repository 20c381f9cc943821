//! The integrators: how a node's state advances from the force on it, what state each keeps,
//! and how that state follows a change of time step. Twins of the WGSL `velocity` and
//! `integrate` in `shaders/common.wgsl` and of `shaders/time_step.wgsl`.

use serde::{Deserialize, Serialize};

/// Time integration scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Integrator {
    /// Position Verlet over the two most recent position buffers:
    /// `x+ = x + (x - x-) + h^2 a(x, (x - x-)/h)`.
    #[default]
    Verlet,
    /// Symplectic (semi-implicit) Euler in velocity form: `v+ = v + h a(x, v)`, `x+ = x + h v+`
    /// (what Warp, Newton and Taichi use).
    SymplecticEuler,
    /// Linearised backward Euler solved by matrix-free conjugate gradients
    /// ([`crate::physics::BackwardEuler`], settings in [`crate::engine::SimConfig::solver`]):
    /// stable at any step, so the stable bound does not limit it. Its state is the position and
    /// velocity, as symplectic Euler's. The reference engine runs it; the float32 engines refuse
    /// it until they have it.
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

/// Velocity of a node from its state, as the WGSL `velocity` computes it: backward difference
/// for Verlet (`second` = previous displacement), the stored velocity for symplectic Euler.
pub fn velocity(p: &StepParams, cur: [f32; 4], second: [f32; 4]) -> [f32; 3] {
    if p.integrator == Integrator::Verlet {
        let inv_h = 1.0 / p.h;
        [
            (cur[0] - second[0]) * inv_h,
            (cur[1] - second[1]) * inv_h,
            (cur[2] - second[2]) * inv_h,
        ]
    } else {
        [second[0], second[1], second[2]]
    }
}

/// The next displacement and second state of a free node under spring force `f`, as the WGSL
/// `integrate` computes it.
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
    if p.integrator == Integrator::Verlet {
        let mut next = [0.0f32; 4];
        for c in 0..3 {
            next[c] = ui[c] + (ui[c] - second_i[c]) + (p.h * p.h) * a[c];
        }
        (next, [0.0; 4])
    } else {
        let (mut next, mut v) = ([0.0f32; 4], [0.0f32; 4]);
        for c in 0..3 {
            v[c] = vi[c] + p.h * a[c];
            next[c] = ui[c] + p.h * v[c];
        }
        (next, v)
    }
}

/// Node-state buffers of an integrator: three displacement buffers rotate for Verlet; symplectic
/// Euler uses two displacement and two velocity buffers.
pub fn state_buffers(n: u64, integrator: Integrator) -> Vec<(String, u64)> {
    match integrator {
        Integrator::Verlet => vec![("displacements (3 x vec4)".to_string(), 3 * n * 16)],
        Integrator::SymplecticEuler | Integrator::BackwardEuler => vec![
            ("displacements (2 x vec4)".to_string(), 2 * n * 16),
            ("velocities (2 x vec4)".to_string(), 2 * n * 16),
        ],
    }
}

/// Bytes of node state one step reads and writes (each buffer once).
pub fn state_traffic(n: u64, integrator: Integrator) -> u64 {
    match integrator {
        Integrator::Verlet => 3 * n * 16,
        Integrator::SymplecticEuler | Integrator::BackwardEuler => 4 * n * 16,
    }
}

/// A change of time step from `h` to `h'` (`rescale = h' / h`) for a state that keeps the
/// previous displacement (Verlet): `prev = cur - (cur - prev) * rescale` on x, y, z in
/// float32, in the order `shaders/time_step.wgsl` computes it, so that the backward-difference
/// velocity `(cur - prev) / h` is the same at the new step; `w` is kept. Symplectic Euler keeps
/// the velocity itself and needs nothing.
pub fn rescale_previous(cur: &[[f32; 4]], prev: &mut [[f32; 4]], rescale: f32) {
    for (u, s) in cur.iter().zip(prev.iter_mut()) {
        for c in 0..3 {
            s[c] = u[c] - (u[c] - s[c]) * rescale;
        }
    }
}
