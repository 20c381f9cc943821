//! Linearised backward Euler with matrix-free preconditioned conjugate gradients, in float64:
//! the implicit integrator (Sørensen and Mosegaard's §3.1, after Baraff and Witkin) on the
//! [`TimeIntegrator`] seam.
//!
//! One step solves (Baraff and Witkin)
//!
//! ```text
//! ((1 + h alpha) M - h D - h^2 K) dv = h (F(x, v) + h K v),   v+ = v + dv,   x+ = x + h v+
//! ```
//!
//! where `F` is the force model's force plus gravity and the mass damping `-alpha M v`, `K` and
//! `D` the force model's stiffness and damping derivatives at `x` (only as products: nothing is
//! assembled), and fixed nodes are held by projecting their rows and columns out of the system.
//! More Newton iterations ([`SolverSettings::newton_iterations`]) solve the nonlinear backward
//! Euler equations `M (v+ - v) = h F(x + h v+, v+)` further, each with the same solver
//! linearised at the latest iterate.
//!
//! The solver is conjugate gradients preconditioned by the inverse 3x3 diagonal blocks of the
//! system (block Jacobi), started from the last step's velocity change
//! ([`SolverSettings::warm_start`]), stopping at a relative residual or an iteration cap. With
//! [`Linearization::Definite`] (the default) the system is symmetric positive definite for any
//! `h`, which conjugate gradients need.
//!
//! Nodes a tool holds ([`NodeConstraint`], set by [`TimeIntegrator::set_contact_constraints`])
//! are filtered as Baraff and Witkin filter them: their normal velocity change is prescribed so
//! that they end the step on the tool's plane, the solve runs on the rest, and the force the tool
//! put on each is read from the residual the filter removed (see
//! [`super::contact_constraint`]).

use super::contact_constraint::{project_out, NodeConstraint};
use super::force_model::{dot, ForceModel, Linearization, Mat3, Vec3};
use super::time_integrator::{NodeState, Nodes, TimeIntegrator};
use nalgebra::Matrix3;

/// How the implicit step solves its system: a scene's `solver: (tolerance: 1e-5,
/// max_iterations: 100)`; every field may be left out for its default.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SolverSettings {
    /// Stop when the residual's norm is below this fraction of the right-hand side's.
    pub tolerance: f64,
    /// Stop after this many conjugate-gradient iterations whatever the residual (counted in
    /// [`SolverStats::capped`]).
    pub max_iterations: u32,
    /// Newton iterations per step: 1 (or 0, taken as 1) is Baraff and Witkin's linearised step.
    pub newton_iterations: u32,
    /// The stiffness matrix the system is built on.
    pub linearization: Linearization,
    /// Start each step's first solve from the last step's velocity change instead of zero
    /// (a cut's new nodes start from zero), on the reference and fast engines; the GPU engine
    /// starts from zero. The solution is the same to the tolerance; the residual starts
    /// smaller wherever the motion changes slowly from step to step.
    pub warm_start: bool,
    /// What conjugate gradients are preconditioned with.
    pub preconditioner: Preconditioner,
}

/// The conjugate gradients' preconditioner. All but [`Preconditioner::Factored`] are
/// matrix-free and need nothing but the system's own blocks, so that a cut's patched rows need
/// no refactorisation; the factored one keeps a factor of an earlier step's system and goes on
/// with it through cuts, refactoring only when it has gone stale.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Preconditioner {
    /// The best each engine has: [`Preconditioner::SymmetricGaussSeidel`] on the fast engine,
    /// [`Preconditioner::BlockJacobi`] on the reference and GPU engines.
    #[default]
    Auto,
    /// The inverse 3x3 diagonal blocks.
    BlockJacobi,
    /// One symmetric Gauss-Seidel sweep (forward then backward over the nodes) within each
    /// block of the fast engine's parallel passes, the blocks' couplings left out: symmetric
    /// positive definite like the system, and the same bits on any number of threads. Only the
    /// fast engine has it: the others refuse it.
    SymmetricGaussSeidel,
    /// A sparse Cholesky factor `L L^T` of the system as it was at some step (factorised in
    /// float64, supernodal, after an approximate-minimum-degree ordering), applied by two
    /// triangular solves that stream the factor in float32 (half the bytes; the solves are
    /// bound by them) on up to two threads: on stiff tissue at small strains the system
    /// changes little from step to step,
    /// so a factor of an earlier step's system is nearly its inverse and conjugate gradients
    /// converge in a few iterations (one or two with a fresh factor). The factor is taken at
    /// the first step and again at the next step after a solve needs more than a few
    /// iterations (6 on the fast engine). A cut does not refactor: the nodes the factor
    /// covers keep it, the cut's new nodes get their inverse diagonal blocks (block Jacobi),
    /// which together are still symmetric positive definite, and the refresh follows when the
    /// iterations grow. It needs the system positive definite ([`Linearization::Definite`],
    /// the default); where a factorisation fails the solve falls back to block Jacobi. Only
    /// the fast engine has it: the others refuse it.
    Factored,
    /// [`Preconditioner::Factored`] with triangular solves in float64 (twice the bytes a
    /// solve streams): for comparison, or for systems too ill-conditioned for a float32 copy
    /// of the factor to precondition.
    FactoredDouble,
}

impl Preconditioner {
    /// Whether this is one of the sparse Cholesky factors ([`Preconditioner::Factored`],
    /// [`Preconditioner::FactoredDouble`]).
    pub fn is_factored(self) -> bool {
        matches!(
            self,
            Preconditioner::Factored | Preconditioner::FactoredDouble
        )
    }
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            tolerance: 1e-5,
            max_iterations: 100,
            newton_iterations: 1,
            linearization: Linearization::Definite,
            warm_start: true,
            preconditioner: Preconditioner::Auto,
        }
    }
}

/// What the solver did over the steps taken so far.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SolverStats {
    /// Linear solves (steps times Newton iterations).
    pub solves: u64,
    /// Conjugate-gradient iterations over all solves.
    pub iterations: u64,
    /// The most iterations one solve took.
    pub max_iterations: u32,
    /// Solves that ended above the tolerance: stopped by the iteration cap, or by a direction
    /// of non-positive curvature (possible only with [`Linearization::Exact`] under
    /// compression), where the solve keeps what it reached (nothing, at the first iteration:
    /// the step then moves the nodes at their current velocity).
    pub capped: u64,
    /// Relative residual at the end of the last solve.
    pub last_residual: f64,
    /// Sparse Cholesky factorisations taken for [`Preconditioner::Factored`] (0 with the
    /// other preconditioners).
    pub factorisations: u64,
    /// Wall time those factorisations took, seconds (ordering and symbolic analysis included).
    pub factor_seconds: f64,
    /// Applications of the factor (a forward and a backward triangular solve each) over all
    /// solves: one per iteration that did not converge, and none for a solve that converged
    /// at its start.
    pub factor_solves: u64,
}

impl SolverStats {
    /// Mean conjugate-gradient iterations per solve (0 before the first).
    pub fn mean_iterations(&self) -> f64 {
        if self.solves == 0 {
            0.0
        } else {
            self.iterations as f64 / self.solves as f64
        }
    }
}

/// The backward Euler integrator: its settings and statistics.
#[derive(Debug, Clone, Default)]
pub struct BackwardEuler {
    settings: SolverSettings,
    stats: SolverStats,
    /// The last step's velocity change: the next step's first guess with
    /// [`SolverSettings::warm_start`].
    last_dv: Vec<Vec3>,
    /// The nodes held on tools' planes at the next steps.
    constraints: Vec<NodeConstraint>,
    /// The normal force each constraint put on its node in the last step, N.
    constraint_forces: Vec<f64>,
}

impl BackwardEuler {
    /// An integrator solving with `settings`.
    pub fn new(settings: SolverSettings) -> Self {
        BackwardEuler {
            settings,
            stats: SolverStats::default(),
            last_dv: Vec::new(),
            constraints: Vec::new(),
            constraint_forces: Vec::new(),
        }
    }

    /// What the solver did so far.
    pub fn stats(&self) -> SolverStats {
        self.stats
    }
}

/// The system `A w = (1 + h alpha) M w - h D w - h^2 K w` at positions `x`, with fixed nodes
/// projected out, and its block-Jacobi preconditioner; constrained nodes are filtered by the
/// solve.
struct System<'a> {
    forces: &'a dyn ForceModel,
    nodes: &'a Nodes<'a>,
    x: &'a [Vec3],
    h: f64,
    lin: Linearization,
    /// Inverse diagonal blocks (identity on fixed nodes).
    inverse_diagonal: Vec<Mat3>,
    /// Scratch for `K w` and `D w`, kept across the solver's iterations.
    kw: Vec<Vec3>,
    dw: Vec<Vec3>,
    /// Per node, the normal of the plane it is held on (filtered out of the solve).
    normals: Vec<Option<Vec3>>,
}

impl<'a> System<'a> {
    fn new(
        forces: &'a dyn ForceModel,
        nodes: &'a Nodes<'a>,
        x: &'a [Vec3],
        h: f64,
        lin: Linearization,
        normals: Vec<Option<Vec3>>,
    ) -> Self {
        let n = x.len();
        let (mut k, mut d) = (vec![[[0.0; 3]; 3]; n], vec![[[0.0; 3]; 3]; n]);
        forces.add_diagonal_blocks(x, lin, &mut k, &mut d);
        let inverse_diagonal = (0..n)
            .map(|i| {
                let mut a = Matrix3::zeros();
                for r in 0..3 {
                    for c in 0..3 {
                        a[(r, c)] = -h * d[i][r][c] - h * h * k[i][r][c];
                    }
                    a[(r, r)] += (1.0 + h * nodes.mass_damping) * nodes.mass[i];
                }
                match (nodes.fixed[i], a.try_inverse()) {
                    (false, Some(inv)) => [0, 1, 2].map(|r| [0, 1, 2].map(|c| inv[(r, c)])),
                    // A singular block (a massless node) gets no preconditioning.
                    _ => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                }
            })
            .collect();
        System {
            forces,
            nodes,
            x,
            h,
            lin,
            inverse_diagonal,
            kw: vec![[0.0; 3]; n],
            dw: vec![[0.0; 3]; n],
            normals,
        }
    }

    /// `S w`: each constrained node's normal part removed.
    fn filter(&self, w: &mut [Vec3]) {
        for (w, n) in w.iter_mut().zip(&self.normals) {
            if let Some(n) = n {
                *w = project_out(*w, *n);
            }
        }
    }

    /// `out = A w` on the free nodes, zero on the fixed ones (`w` is zero there).
    fn apply(&mut self, w: &[Vec3], out: &mut [Vec3]) {
        out.iter_mut().for_each(|o| *o = [0.0; 3]);
        let (k, d) = (&mut self.kw, &mut self.dw);
        k.iter_mut().chain(d.iter_mut()).for_each(|v| *v = [0.0; 3]);
        self.forces.add_stiffness_product(self.x, self.lin, w, k);
        self.forces.add_damping_product(self.x, w, d);
        let (k, d) = (&self.kw, &self.dw);
        let (h, alpha) = (self.h, self.nodes.mass_damping);
        for i in 0..w.len() {
            if self.nodes.fixed[i] {
                continue;
            }
            let m = (1.0 + h * alpha) * self.nodes.mass[i];
            out[i] = [0, 1, 2].map(|c| m * w[i][c] - h * d[i][c] - h * h * k[i][c]);
        }
    }

    fn precondition(&self, r: &[Vec3], z: &mut [Vec3]) {
        for ((z, r), m) in z.iter_mut().zip(r).zip(&self.inverse_diagonal) {
            *z = super::force_model::mat_vec(m, *r);
        }
    }

    /// Solve `S A S y = b` by preconditioned conjugate gradients from the guess in `y` (zero on
    /// the fixed nodes; `b` and the guess filtered by the caller), the preconditioner filtered
    /// too; returns the iterations and the final relative residual (to `|b|`, whatever the
    /// guess).
    fn solve(&mut self, b: &[Vec3], y: &mut [Vec3], settings: &SolverSettings) -> (u32, f64) {
        let n = b.len();
        let norm = |v: &[Vec3]| v.iter().map(|a| dot(*a, *a)).sum::<f64>().sqrt();
        let b_norm = norm(b);
        if b_norm == 0.0 {
            y.iter_mut().for_each(|v| *v = [0.0; 3]);
            return (0, 0.0);
        }
        let (mut z, mut ap) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        self.apply(y, &mut ap);
        self.filter(&mut ap);
        let mut r: Vec<Vec3> = (0..n)
            .map(|i| [0, 1, 2].map(|c| b[i][c] - ap[i][c]))
            .collect();
        if norm(&r) <= settings.tolerance * b_norm {
            return (0, norm(&r) / b_norm);
        }
        self.precondition(&r, &mut z);
        self.filter(&mut z);
        let mut p = z.clone();
        let mut rz: f64 = r.iter().zip(&z).map(|(a, b)| dot(*a, *b)).sum();
        let mut residual = 1.0;
        for iteration in 1..=settings.max_iterations {
            self.apply(&p, &mut ap);
            self.filter(&mut ap);
            let pap: f64 = p.iter().zip(&ap).map(|(a, b)| dot(*a, *b)).sum();
            if pap <= 0.0 {
                // Not positive definite along `p` (an exact linearisation under compression):
                // stop with what has been reached rather than step along a bad direction.
                return (iteration, residual);
            }
            let step = rz / pap;
            for i in 0..n {
                for c in 0..3 {
                    y[i][c] += step * p[i][c];
                    r[i][c] -= step * ap[i][c];
                }
            }
            residual = norm(&r) / b_norm;
            if residual <= settings.tolerance {
                return (iteration, residual);
            }
            self.precondition(&r, &mut z);
            self.filter(&mut z);
            let rz_next: f64 = r.iter().zip(&z).map(|(a, b)| dot(*a, *b)).sum();
            let beta = rz_next / rz;
            rz = rz_next;
            for i in 0..n {
                for c in 0..3 {
                    p[i][c] = z[i][c] + beta * p[i][c];
                }
            }
        }
        (settings.max_iterations, residual)
    }
}

impl System<'_> {
    /// Solve for the velocity change `y` whose constrained nodes' normal parts are `z` (zero
    /// elsewhere): conjugate gradients on `S A S w = S (b - A z)` from the filtered guess in
    /// `y`, then `y = w + z`. Without constraints, the plain solve.
    fn solve_filtered(
        &mut self,
        b: &[Vec3],
        y: &mut [Vec3],
        z: &[Vec3],
        settings: &SolverSettings,
    ) -> (u32, f64) {
        if self.normals.iter().all(Option::is_none) {
            return self.solve(b, y, settings);
        }
        let mut az = vec![[0.0; 3]; b.len()];
        self.apply(z, &mut az);
        let mut reduced: Vec<Vec3> = b
            .iter()
            .zip(&az)
            .map(|(b, a)| [0, 1, 2].map(|c| b[c] - a[c]))
            .collect();
        self.filter(&mut reduced);
        self.filter(y);
        let result = self.solve(&reduced, y, settings);
        for (y, z) in y.iter_mut().zip(z) {
            *y = [0, 1, 2].map(|c| y[c] + z[c]);
        }
        result
    }

    /// `A y - b`: on a constrained node, the impulse the constraint gave it over the step
    /// (along its normal); on a free node, the solve's residual.
    fn impulse(&mut self, y: &[Vec3], b: &[Vec3]) -> Vec<Vec3> {
        let mut ay = vec![[0.0; 3]; y.len()];
        self.apply(y, &mut ay);
        ay.iter()
            .zip(b)
            .map(|(a, b)| [0, 1, 2].map(|c| a[c] - b[c]))
            .collect()
    }
}

/// The force model's force plus gravity and mass damping at `(x, v)`, zero on fixed nodes.
fn total_force(forces: &dyn ForceModel, nodes: &Nodes, x: &[Vec3], v: &[Vec3]) -> Vec<Vec3> {
    let mut f = vec![[0.0; 3]; x.len()];
    forces.add_forces(x, v, &mut f);
    for i in 0..x.len() {
        f[i] = if nodes.fixed[i] {
            [0.0; 3]
        } else {
            let m = nodes.mass[i];
            [0, 1, 2].map(|c| f[i][c] + m * nodes.gravity[c] - nodes.mass_damping * m * v[i][c])
        };
    }
    f
}

impl TimeIntegrator for BackwardEuler {
    fn name(&self) -> &'static str {
        "backward-euler"
    }

    fn solver_stats(&self) -> Option<SolverStats> {
        Some(self.stats)
    }

    fn set_contact_constraints(&mut self, constraints: &[NodeConstraint]) -> bool {
        self.constraints = constraints.to_vec();
        self.constraint_forces = vec![0.0; constraints.len()];
        true
    }

    fn contact_constraint_forces(&self) -> Vec<f64> {
        self.constraint_forces.clone()
    }

    fn step(&mut self, forces: &dyn ForceModel, nodes: &Nodes, h: f64, state: &mut NodeState) {
        let n = state.x.len();
        let settings = self.settings;
        let mut dv = vec![[0.0; 3]; n];
        if settings.warm_start {
            // The last step's change where the node was there (a cut appends nodes) and free.
            for (i, (d, last)) in dv.iter_mut().zip(&self.last_dv).enumerate() {
                if !nodes.fixed[i] {
                    *d = *last;
                }
            }
        }
        // Constrained nodes: the plane's normal, and the normal velocity change that puts the
        // node on the plane. A fixed node, an unknown node or a node listed again is skipped.
        let mut normals: Vec<Option<Vec3>> = vec![None; n];
        let mut z = vec![[0.0; 3]; n];
        let mut used = vec![false; self.constraints.len()];
        for (k, c) in self.constraints.iter().enumerate() {
            let i = c.node as usize;
            if i >= n || nodes.fixed[i] || normals[i].is_some() || !c.is_valid() {
                continue;
            }
            normals[i] = Some(c.normal);
            let s = c.velocity_change(state.x[i], state.v[i], h);
            z[i] = c.normal.map(|a| a * s);
            used[k] = true;
        }
        // The first iterate is Baraff and Witkin's: linearised at the start of the step.
        let mut rhs = total_force(forces, nodes, &state.x, &state.v);
        let mut kv = vec![[0.0; 3]; n];
        forces.add_stiffness_product(&state.x, settings.linearization, &state.v, &mut kv);
        for i in (0..n).filter(|&i| !nodes.fixed[i]) {
            rhs[i] = [0, 1, 2].map(|c| h * (rhs[i][c] + h * kv[i][c]));
        }
        let mut system = System::new(
            forces,
            nodes,
            &state.x,
            h,
            settings.linearization,
            normals.clone(),
        );
        self.record(system.solve_filtered(&rhs, &mut dv, &z, &settings));
        let mut impulse = if used.iter().any(|&u| u) {
            system.impulse(&dv, &rhs)
        } else {
            Vec::new()
        };
        // Further Newton iterations on `g(y) = M (y - v) - h F(x + h y, y)`, `y = v + dv`.
        let mut delta = vec![[0.0; 3]; n];
        let no_change = vec![[0.0; 3]; n];
        for _ in 1..settings.newton_iterations.max(1) {
            delta.iter_mut().for_each(|d| *d = [0.0; 3]);
            let y: Vec<Vec3> = (0..n)
                .map(|i| [0, 1, 2].map(|c| state.v[i][c] + dv[i][c]))
                .collect();
            let xk: Vec<Vec3> = (0..n)
                .map(|i| [0, 1, 2].map(|c| state.x[i][c] + h * y[i][c]))
                .collect();
            let f = total_force(forces, nodes, &xk, &y);
            let minus_g: Vec<Vec3> = (0..n)
                .map(|i| {
                    if nodes.fixed[i] {
                        return [0.0; 3];
                    }
                    [0, 1, 2].map(|c| h * f[i][c] - nodes.mass[i] * dv[i][c])
                })
                .collect();
            let mut system = System::new(
                forces,
                nodes,
                &xk,
                h,
                settings.linearization,
                normals.clone(),
            );
            self.record(system.solve_filtered(&minus_g, &mut delta, &no_change, &settings));
            if !impulse.is_empty() {
                // The constraint's impulse is the last linearisation's residual.
                impulse = system.impulse(&delta, &minus_g);
            }
            for i in 0..n {
                for c in 0..3 {
                    dv[i][c] += delta[i][c];
                }
            }
        }
        for (k, c) in self.constraints.iter().enumerate() {
            self.constraint_forces[k] = if used[k] {
                dot(c.normal, impulse[c.node as usize]) / h
            } else {
                0.0
            };
        }
        for i in (0..n).filter(|&i| !nodes.fixed[i]) {
            let v = [0, 1, 2].map(|c| state.v[i][c] + dv[i][c]);
            state.x[i] = [0, 1, 2].map(|c| state.x[i][c] + h * v[c]);
            state.v[i] = v;
        }
        if settings.warm_start {
            self.last_dv = dv;
        }
    }
}

impl BackwardEuler {
    fn record(&mut self, (iterations, residual): (u32, f64)) {
        let s = &mut self.stats;
        s.solves += 1;
        s.iterations += iterations as u64;
        s.max_iterations = s.max_iterations.max(iterations);
        s.last_residual = residual;
        if residual > self.settings.tolerance {
            s.capped += 1;
        }
    }
}

#[cfg(test)]
#[path = "backward_euler_tests.rs"]
mod tests;
