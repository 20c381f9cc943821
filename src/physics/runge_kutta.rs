//! The classical fourth-order Runge–Kutta scheme in float64: a reference integrator, not an
//! engine's. Its error falls sixteen times per halving of the step where Verlet's falls four
//! times (two without a start-up correction, or with the backward-difference damping), so a
//! converged reference costs a few force evaluations per stable step instead of a hundred
//! Verlet steps: `lancet report accuracy` uses it for its reference run.
//!
//! It integrates the same equations as every engine, `m x'' = f(x, x') + m g - alpha m x'`,
//! with the damping force at the true velocity, and holds fixed nodes where they are. It is
//! stable up to `h omega = 2.8` on an undamped mode, beyond the explicit schemes' 2.

use super::force_model::{ForceModel, Vec3};
use super::time_integrator::{NodeState, Nodes, TimeIntegrator};

/// Classical RK4 on positions and velocities, with its stages kept between steps (no
/// allocation per step once the first has sized them).
#[derive(Debug, Clone, Default)]
pub struct RungeKutta4 {
    force: Vec<Vec3>,
    /// The stages' accelerations `a1..a4`.
    a: [Vec<Vec3>; 4],
    /// The stages' velocities `v2..v4` (`v1` is the state's).
    v: [Vec<Vec3>; 3],
    /// A stage's positions.
    x: Vec<Vec3>,
}

impl RungeKutta4 {
    /// A new integrator.
    pub fn new() -> Self {
        Self::default()
    }
}

/// Accelerations at `(x, v)` into `out`, zero on fixed nodes; `force` is scratch.
fn accelerations(
    force: &mut Vec<Vec3>,
    forces: &dyn ForceModel,
    nodes: &Nodes,
    x: &[Vec3],
    v: &[Vec3],
    out: &mut [Vec3],
) {
    force.clear();
    force.resize(x.len(), [0.0; 3]);
    forces.add_forces(x, v, force);
    for (i, a) in out.iter_mut().enumerate() {
        *a = if nodes.fixed[i] {
            [0.0; 3]
        } else {
            nodes.acceleration(i, force[i], v[i])
        };
    }
}

/// `out = a + s b`, node by node; fixed nodes keep `a`.
fn offset(out: &mut [Vec3], a: &[Vec3], s: f64, b: &[Vec3], fixed: &[bool]) {
    for (i, o) in out.iter_mut().enumerate() {
        *o = if fixed[i] {
            a[i]
        } else {
            [0, 1, 2].map(|c| a[i][c] + s * b[i][c])
        };
    }
}

impl TimeIntegrator for RungeKutta4 {
    fn name(&self) -> &'static str {
        "runge-kutta-4"
    }

    fn step(&mut self, forces: &dyn ForceModel, nodes: &Nodes, h: f64, state: &mut NodeState) {
        let (fixed, n) = (nodes.fixed, state.x.len());
        let Self { force, a, v, x } = self;
        for buffer in a.iter_mut().chain(v.iter_mut()).chain([&mut *x]) {
            buffer.resize(n, [0.0; 3]);
        }
        let [a1, a2, a3, a4] = a;
        let [v2, v3, v4] = v;
        let (x0, v0) = (&state.x, &state.v);
        accelerations(force, forces, nodes, x0, v0, a1);
        offset(x, x0, h / 2.0, v0, fixed);
        offset(v2, v0, h / 2.0, a1, fixed);
        accelerations(force, forces, nodes, x, v2, a2);
        offset(x, x0, h / 2.0, v2, fixed);
        offset(v3, v0, h / 2.0, a2, fixed);
        accelerations(force, forces, nodes, x, v3, a3);
        offset(x, x0, h, v3, fixed);
        offset(v4, v0, h, a3, fixed);
        accelerations(force, forces, nodes, x, v4, a4);
        for i in (0..n).filter(|&i| !fixed[i]) {
            for c in 0..3 {
                state.x[i][c] +=
                    h / 6.0 * (state.v[i][c] + 2.0 * v2[i][c] + 2.0 * v3[i][c] + v4[i][c]);
                state.v[i][c] += h / 6.0 * (a1[i][c] + 2.0 * a2[i][c] + 2.0 * a3[i][c] + a4[i][c]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::PackedSpring;
    use crate::physics::SpringForces;

    /// A mass on a damped spring to a fixed node along x, released from `u0`: the error of the
    /// displacement at `t = 0.05 s` against the closed-form underdamped solution.
    fn error_at_end(h: f64) -> f64 {
        let (k, c, m, rest, u0) = (400.0, 0.2, 0.01, 0.05, 0.002);
        let springs = [PackedSpring {
            nodes: [0, 1],
            rest_length: rest,
            stiffness: k,
            damping: c,
        }];
        let (mass, fixed) = (vec![m, m], vec![true, false]);
        let nodes = Nodes {
            mass: &mass,
            fixed: &fixed,
            gravity: [0.0; 3],
            mass_damping: 0.0,
        };
        let mut state = NodeState {
            x: vec![[0.0; 3], [rest + u0, 0.0, 0.0]],
            v: vec![[0.0; 3]; 2],
        };
        let mut rk = RungeKutta4::new();
        let t = 0.05;
        let steps = (t / h).round() as usize;
        for _ in 0..steps {
            rk.step(&SpringForces::new(&springs), &nodes, h, &mut state);
        }
        // m u'' + c u' + k u = 0, u(0) = u0, u'(0) = 0.
        let zeta_w = c / (2.0 * m);
        let wd = (k / m - zeta_w * zeta_w).sqrt();
        let exact = u0 * (-zeta_w * t).exp() * ((wd * t).cos() + zeta_w / wd * (wd * t).sin());
        assert_eq!(state.x[0], [0.0; 3]);
        (state.x[1][0] - rest - exact).abs()
    }

    #[test]
    fn the_error_falls_sixteen_times_per_halving_of_the_step() {
        // The explicit bound is 2 / sqrt(k / m) = 0.01 s.
        let (e1, e2, e3) = (error_at_end(1e-3), error_at_end(5e-4), error_at_end(2.5e-4));
        assert!(e1 < 1e-4 * 0.002, "error {e1:e} m at h = 1 ms");
        for (a, b) in [(e1, e2), (e2, e3)] {
            let ratio = a / b;
            assert!(
                (12.0..20.0).contains(&ratio),
                "halving the step cut the error {ratio}x"
            );
        }
    }
}
