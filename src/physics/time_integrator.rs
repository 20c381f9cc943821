//! The integrator seam in float64: how a node state advances one step under a
//! [`ForceModel`], gravity and mass-proportional damping.
//!
//! A [`TimeIntegrator`] owns nothing of the model: it is handed the force model, the nodes'
//! masses and constraints, the step and the state, and keeps only scratch space (and, for an
//! iterative solver, its statistics). The explicit schemes ([`Explicit`]) read the force once
//! per step; an implicit scheme reads it and solves with the force model's Jacobian-vector
//! products ([`ForceModel::add_stiffness_product`], [`ForceModel::add_damping_product`]),
//! which is why the seam hands over the model and not a force vector.
//!
//! The state is positions and velocities for every scheme. Verlet's velocity is its backward
//! difference `(x - x-) / h`, so `x- = x - h v` and position Verlet
//! `x+ = x + (x - x-) + h^2 a` is `x+ = x + h v + h^2 a` with `v+ = (x+ - x) / h`.

use super::backward_euler::{BackwardEuler, SolverSettings, SolverStats};
use super::contact_constraint::NodeConstraint;
use super::force_model::{ForceModel, Vec3};
use super::Integrator;

/// What an integrator needs of the nodes beside the force model.
#[derive(Debug, Clone, Copy)]
pub struct Nodes<'a> {
    /// Lumped masses, kg.
    pub mass: &'a [f64],
    /// Nodes held where they are (their state is never changed).
    pub fixed: &'a [bool],
    /// Gravity, m/s^2.
    pub gravity: Vec3,
    /// Mass-proportional damping, 1/s: a force `-alpha m v` on every node.
    pub mass_damping: f64,
}

impl Nodes<'_> {
    /// The acceleration of free node `i` under force `f` (N) at velocity `v`: `f / m + g -
    /// alpha v`.
    pub fn acceleration(&self, i: usize, f: Vec3, v: Vec3) -> Vec3 {
        let (m, g, alpha) = (self.mass[i], self.gravity, self.mass_damping);
        [0, 1, 2].map(|c| f[c] / m + g[c] - alpha * v[c])
    }
}

/// Positions (m) and velocities (m/s) of every node.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NodeState {
    /// Positions, m.
    pub x: Vec<Vec3>,
    /// Velocities, m/s.
    pub v: Vec<Vec3>,
}

/// A time-integration scheme in float64.
pub trait TimeIntegrator: Send {
    /// The scheme's name, as reports print it.
    fn name(&self) -> &'static str;
    /// Advance `state` by one step of `h` seconds; fixed nodes keep their state.
    fn step(&mut self, forces: &dyn ForceModel, nodes: &Nodes, h: f64, state: &mut NodeState);
    /// What an iterative solver did so far (`None` for a scheme that solves nothing).
    fn solver_stats(&self) -> Option<SolverStats> {
        None
    }
    /// Hold `constraints`' nodes on their planes at the next steps, inside the solve
    /// ([`super::contact_constraint`]); `false` (the default, the explicit schemes) where the
    /// scheme cannot, and the caller must correct positions instead.
    fn set_contact_constraints(&mut self, constraints: &[NodeConstraint]) -> bool {
        let _ = constraints;
        false
    }
    /// The normal force each constraint put on its node in the last step, N, in the order they
    /// were set (empty where none was).
    fn contact_constraint_forces(&self) -> Vec<f64> {
        Vec::new()
    }
}

/// The float64 integrator a run's settings name: [`Explicit`] for Verlet and symplectic
/// Euler, [`BackwardEuler`] with `solver` for backward Euler.
pub fn integrator_for(scheme: Integrator, solver: SolverSettings) -> Box<dyn TimeIntegrator> {
    match scheme {
        Integrator::BackwardEuler => Box::new(BackwardEuler::new(solver)),
        explicit => Box::new(Explicit::new(explicit)),
    }
}

/// The explicit schemes of [`Integrator`] in float64: the force is read once per step at the
/// state at its start.
#[derive(Debug, Clone)]
pub struct Explicit {
    scheme: Integrator,
    force: Vec<Vec3>,
}

impl Explicit {
    /// The float64 form of `scheme`.
    ///
    /// # Panics
    /// If `scheme` is [`Integrator::BackwardEuler`], which is not explicit (build it with
    /// [`integrator_for`]): a programming error, never a user's input.
    pub fn new(scheme: Integrator) -> Self {
        assert!(
            !scheme.is_implicit(),
            "Explicit::new takes an explicit scheme; use integrator_for"
        );
        Explicit {
            scheme,
            force: Vec::new(),
        }
    }
}

impl TimeIntegrator for Explicit {
    fn name(&self) -> &'static str {
        match self.scheme {
            Integrator::Verlet => "verlet",
            Integrator::SymplecticEuler => "symplectic-euler",
            Integrator::BackwardEuler => unreachable!("refused by Explicit::new"),
        }
    }

    fn step(&mut self, forces: &dyn ForceModel, nodes: &Nodes, h: f64, state: &mut NodeState) {
        self.force.clear();
        self.force.resize(state.x.len(), [0.0; 3]);
        forces.add_forces(&state.x, &state.v, &mut self.force);
        for i in 0..state.x.len() {
            if nodes.fixed[i] {
                continue;
            }
            let (x, v) = (state.x[i], state.v[i]);
            let a = nodes.acceleration(i, self.force[i], v);
            match self.scheme {
                Integrator::Verlet => {
                    let next = [0, 1, 2].map(|c| x[c] + h * v[c] + h * h * a[c]);
                    state.v[i] = [0, 1, 2].map(|c| (next[c] - x[c]) / h);
                    state.x[i] = next;
                }
                Integrator::SymplecticEuler | Integrator::BackwardEuler => {
                    let v = [0, 1, 2].map(|c| v[c] + h * a[c]);
                    state.x[i] = [0, 1, 2].map(|c| x[c] + h * v[c]);
                    state.v[i] = v;
                }
            }
        }
    }
}
