//! Backward Euler on the fast float32 engine: it follows the float64 reference implicit
//! engine far above the explicit bound, gives the same bits on one thread and on two, and
//! allocates nothing of its own per step.
//!
//! Tolerance against the reference: both solve each step's system to a relative residual of
//! 1e-7, so what is left is float32 rounding: about 6e-8 of each value per operation, summed
//! over ~14 springs per node and amplified by the system's conditioning (the product and the
//! force are differences of nearly equal spring terms at 20-50 times the explicit bound). Over
//! a few steps that stays far below 1e-4 of the motion; a wrong term of the system (a missing
//! damping block, gravity, a sign) is of the order of the motion itself.

use crate::models::{random_model, random_state, Rng};
use lancet::engine::Integrator;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{stable_time_step, FixedSelector, SpringDamping};
use lancet::physics::SolverSettings;
use lancet::report::bench::relative_l2;
use lancet::{EngineKind, Material, ModelConfig, PackedModel, SimConfig, Simulation, SpringModel};
use rstest::rstest;

fn implicit_config(dt: f64) -> SimConfig {
    let mut config = SimConfig::new(dt);
    config.integrator = Integrator::BackwardEuler;
    config.solver = SolverSettings {
        tolerance: 1e-7,
        max_iterations: 500,
        ..SolverSettings::default()
    };
    config
}

/// Positions and the solver's statistics after `steps` implicit steps from `state`.
fn run(
    model: &PackedModel,
    kind: EngineKind,
    config: SimConfig,
    state: &(Vec<[f64; 3]>, Vec<[f64; 3]>),
    steps: u64,
) -> (Vec<[f64; 3]>, lancet::physics::SolverStats) {
    let mut sim = Simulation::new(model.clone(), kind, config).unwrap();
    sim.set_state(&state.0, &state.1).unwrap();
    sim.run(steps).unwrap();
    (sim.positions(), sim.solver_stats().unwrap())
}

#[rstest]
fn fast_backward_euler_follows_the_reference_far_above_the_bound(
    #[values(1, 2, 3)] seed: u64,
    #[values(20.0, 50.0)] times_bound: f64,
) {
    // Random per-spring stiffness, damping and masses, gravity, mass damping, a fixed base and
    // two springless nodes, from a random loaded state.
    let model = random_model(seed, true);
    let dt = times_bound * stable_time_step(&model).dt;
    let state = random_state(&model, seed + 10);
    let mut config = implicit_config(dt);
    // The reference's preconditioner, so that the iterations compare.
    config.solver.preconditioner = lancet::physics::Preconditioner::BlockJacobi;
    let (reference, ref_stats) = run(&model, EngineKind::Reference, config, &state, 4);
    let (fast, stats) = run(&model, EngineKind::Fast, config, &state, 4);
    assert_eq!(stats.solves, 4);
    assert_eq!(stats.capped, 0, "{stats:?}");
    assert!(stats.last_residual <= 1e-7, "{stats:?}");
    // The same system: about as many iterations to the same tolerance.
    let (a, b) = (stats.iterations as f64, ref_stats.iterations as f64);
    assert!(
        (a - b).abs() <= 0.2 * b + 4.0,
        "{stats:?} against {ref_stats:?}"
    );
    let e = relative_l2(&model.rest, &fast, &reference);
    assert!(
        e < 1e-4,
        "seed {seed}, {times_bound}x the bound: {e:.2e} off the reference"
    );
    // And the motion is real: the state moved well beyond that tolerance.
    let moved = relative_l2(&model.rest, &state.0, &reference);
    assert!(moved > 1e-2, "{moved:.2e}");
}

/// A damped box of 3,003 nodes (three blocks of the engine's parallel passes), random spring
/// stiffnesses, fixed at z = 0, under gravity.
fn large_box() -> PackedModel {
    let mesh = BoxGrid::cube_cells([20, 12, 10], 0.005).build().unwrap();
    let material = Material::elastic(1e5, 0.3, 1000.0)
        .with_damping(SpringDamping::StiffnessProportional(1e-4));
    let mut config = ModelConfig::new(material);
    config.gravity = [0.5, 0.0, -9.81];
    config.mass_damping = 2.0;
    config.fixed.push(FixedSelector::Plane {
        point: [0.0; 3],
        normal: [0.0, 0.0, 1.0],
        tolerance: 1e-9,
    });
    let mut model = SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let mut rng = Rng(77);
    for s in model.springs_mut().iter_mut() {
        let f = 0.5 + rng.next();
        s.stiffness *= f;
        s.damping *= f;
    }
    model
}

#[test]
fn one_thread_and_two_give_the_same_bits() {
    same_bits_on_one_thread_and_two(lancet::physics::Preconditioner::Auto);
}

/// The factored preconditioner's triangular solves run two subtrees of the elimination tree
/// on two threads and add their updates to the rows above in a fixed order: the same bits as
/// on one thread.
#[cfg(feature = "factor")]
#[test]
fn the_factored_solves_give_the_same_bits_on_one_thread_and_two() {
    same_bits_on_one_thread_and_two(lancet::physics::Preconditioner::Factored);
}

fn same_bits_on_one_thread_and_two(preconditioner: lancet::physics::Preconditioner) {
    let model = large_box();
    assert!(model.node_count() > 2048);
    let mut config = implicit_config(30.0 * stable_time_step(&model).dt);
    config.solver.preconditioner = preconditioner;
    let state = random_state(&model, 5);
    let on = |threads: usize| {
        lancet::engine::fast::on_threads(threads, || {
            let mut sim = Simulation::new(model.clone(), EngineKind::Fast, config).unwrap();
            sim.set_state(&state.0, &state.1).unwrap();
            sim.run(3).unwrap();
            (
                sim.positions(),
                sim.velocities(),
                sim.solver_stats().unwrap(),
            )
        })
        .unwrap()
    };
    let (one, two) = (on(1), on(2));
    assert!(one.2.iterations >= 3, "{:?}", one.2);
    // Everything but the factorisations' wall time.
    let counts = |s: lancet::physics::SolverStats| lancet::physics::SolverStats {
        factor_seconds: 0.0,
        ..s
    };
    assert_eq!(counts(one.2), counts(two.2));
    let bits =
        |x: &[[f64; 3]]| -> Vec<[u64; 3]> { x.iter().map(|p| p.map(f64::to_bits)).collect() };
    assert!(
        bits(&one.0) == bits(&two.0),
        "positions differ between 1 and 2 threads"
    );
    assert!(
        bits(&one.1) == bits(&two.1),
        "velocities differ between 1 and 2 threads"
    );
}

#[test]
fn the_gpu_edge_layout_s_atomic_variants_refuse_backward_euler_and_auto_runs_it_where_it_can() {
    let model = random_model(4, true);
    let config = implicit_config(1e-3);
    // The fixed-point variant cannot hold the conjugate gradients' shrinking products (the
    // float-atomic one runs backward Euler): refused (or no adapter at all: refused either
    // way, never stepped explicitly in its place).
    let atomic = lancet::GpuOptions {
        accumulation: lancet::layout::edges::Accumulation::AtomicFixed,
        ..lancet::GpuOptions::from(lancet::layout::LayoutKind::Edges)
    };
    match Simulation::with_gpu(model.clone(), EngineKind::Gpu, config, atomic) {
        Err(lancet::Error::Unsupported(_)) | Err(lancet::Error::Gpu(_)) => {}
        Err(e) => panic!("atomic edges: {e}"),
        Ok(sim) => panic!("{} accepted backward Euler", sim.engine_name()),
    }
    // Auto: the GPU's connectivity layout where there is an adapter, else the fast engine.
    let mut sim = Simulation::new(model, EngineKind::Auto, config).unwrap();
    assert!(matches!(sim.kind(), EngineKind::Fast | EngineKind::Gpu));
    sim.run(2).unwrap();
    assert_eq!(sim.solver_stats().unwrap().solves, 2);
}

/// A warm start (from the last step's velocity change) and the symmetric Gauss-Seidel
/// preconditioner solve the same systems as a cold block-Jacobi start: the box sagging under
/// gravity from rest at 30 times the explicit bound, 12 steps solved to 1e-7. The sweep takes
/// fewer iterations by a fifth at least (about half on this box and on the SOFA cylinder: it
/// couples each node to its block's neighbours where block Jacobi sees the node alone).
///
/// A warm start saves a fixed number of iterations (those that bring the residual from the
/// cold start's down to the warm start's), which counts at a loose tolerance: to 1e-4 it takes
/// fewer iterations than the cold start. (To 1e-7 the saving is lost in the total.)
#[test]
fn warm_start_and_gauss_seidel_reach_the_cold_solution_in_fewer_iterations() {
    use lancet::physics::Preconditioner::{BlockJacobi, SymmetricGaussSeidel};
    let model = large_box();
    let dt = 30.0 * stable_time_step(&model).dt;
    let state = (model.rest.clone(), vec![[0.0; 3]; model.node_count()]);
    let with = |tolerance: f64, warm_start: bool, preconditioner| {
        let mut config = implicit_config(dt);
        config.solver.tolerance = tolerance;
        config.solver.warm_start = warm_start;
        config.solver.preconditioner = preconditioner;
        run(&model, EngineKind::Fast, config, &state, 12)
    };
    let (cold, cold_stats) = with(1e-7, false, BlockJacobi);
    let moved = relative_l2(&model.rest, &state.0, &cold);
    assert!(moved > 0.5, "the box sagged: {moved:.2e}");
    for (warm, pre) in [
        (true, BlockJacobi),
        (false, SymmetricGaussSeidel),
        (true, SymmetricGaussSeidel),
    ] {
        let (x, stats) = with(1e-7, warm, pre);
        let e = relative_l2(&model.rest, &x, &cold);
        eprintln!(
            "warm {warm}, {pre:?}: {:.1} iterations a solve against {:.1} cold with block Jacobi, \
             {e:.2e} off its solution",
            stats.mean_iterations(),
            cold_stats.mean_iterations()
        );
        assert_eq!(stats.capped, 0, "{stats:?}");
        assert!(
            e < 1e-5,
            "warm {warm}, {pre:?}: {e:.2e} off the cold solution"
        );
        if pre == SymmetricGaussSeidel {
            assert!(
                (stats.iterations as f64) < 0.8 * cold_stats.iterations as f64,
                "warm {warm}, {pre:?}: {stats:?} against {cold_stats:?}"
            );
        }
    }
    let ((_, loose_cold), (_, loose_warm)) = (
        with(1e-4, false, BlockJacobi),
        with(1e-4, true, BlockJacobi),
    );
    eprintln!(
        "to 1e-4: {:.1} iterations a solve warm, {:.1} cold",
        loose_warm.mean_iterations(),
        loose_cold.mean_iterations()
    );
    assert!(
        loose_warm.iterations < loose_cold.iterations,
        "{loose_warm:?} against {loose_cold:?}"
    );
}

/// The factored preconditioner (a sparse Cholesky factor of the system, float64) reaches the
/// float64 reference's solution (itself the dense direct solve's: `src/physics/
/// backward_euler_tests.rs`) on random models far above the bound, and in few iterations.
///
/// The bound: the first step's factor is of that very system, so the preconditioned operator
/// is `(L L^T)^-1 A32 = I + (L L^T)^-1 E`, `E` the float32 product's rounding (a few times
/// 6e-8 of each row's terms, amplified by the system's conditioning at 20x the bound, about
/// 1e3 here); each conjugate-gradient iteration divides the error by at least `1 / |(L L^T)^-1
/// E|` (~1e4), so 1e-7 takes two iterations, and three leave room. Block Jacobi needs tens on
/// the same systems. Later steps reuse the factor (the state moves) and stay within the
/// refresh policy's bound or refactor.
#[cfg(feature = "factor")]
#[rstest]
fn the_factored_preconditioner_reaches_the_reference_solution_in_a_few_iterations(
    #[values(1, 2, 3)] seed: u64,
) {
    use lancet::physics::Preconditioner::{BlockJacobi, Factored};
    let model = random_model(seed, true);
    let dt = 20.0 * stable_time_step(&model).dt;
    let state = random_state(&model, seed + 10);
    let mut config = implicit_config(dt);
    config.solver.preconditioner = BlockJacobi;
    let (reference, _) = run(&model, EngineKind::Reference, config, &state, 4);
    let (_, jacobi) = run(&model, EngineKind::Fast, config, &state, 1);
    config.solver.preconditioner = Factored;
    let mut sim = Simulation::new(model.clone(), EngineKind::Fast, config).unwrap();
    sim.set_state(&state.0, &state.1).unwrap();
    sim.run(1).unwrap();
    let first = sim.solver_stats().unwrap();
    eprintln!(
        "seed {seed}: the first solve in {} iterations with a fresh factor, {} with block Jacobi",
        first.iterations, jacobi.iterations
    );
    assert_eq!(first.factorisations, 1, "{first:?}");
    assert!(first.iterations <= 3, "{first:?}");
    assert!(jacobi.iterations > 10, "{jacobi:?}");
    sim.run(3).unwrap();
    let stats = sim.solver_stats().unwrap();
    assert_eq!((stats.solves, stats.capped), (4, 0), "{stats:?}");
    assert!(stats.last_residual <= 1e-7, "{stats:?}");
    // Four steps take fewer iterations together than block Jacobi's first alone: the state
    // moves, but the factor (refreshed past 6 iterations) stays close to the inverse.
    assert!(
        stats.iterations < jacobi.iterations,
        "{stats:?} against {jacobi:?}"
    );
    let e = relative_l2(&model.rest, &sim.positions(), &reference);
    assert!(e < 1e-4, "seed {seed}: {e:.2e} off the reference");
    let moved = relative_l2(&model.rest, &state.0, &reference);
    assert!(moved > 1e-2, "{moved:.2e}");
}

/// The float32 copy of the factor (`Factored`: the triangular solves stream the float64
/// factorisation rounded to float32) preconditions as well as the float64 one
/// (`FactoredDouble`): on random models far above the bound both reach the same steps.
///
/// The bound: both solve every step to a relative residual of 1e-7 with the same float32
/// product, so their steps differ by what two solutions within 1e-7 of the same system can
/// differ by, amplified by its conditioning (about 1e3 at 20x the bound, as above): 1e-4 of the
/// step's velocity change at worst, and less of the motion, which the positions compare. A
/// preconditioner that were not symmetric positive definite (a wrong row, a transposed block)
/// would stall conjugate gradients at the cap instead. The float32 copy's rounding (about
/// 6e-8 of each entry, amplified by the factor's conditioning) is far below the stale
/// factor's own error, so it costs at most one iteration a solve.
///
/// The count: the residual is judged before the factor is applied, so every iteration that
/// did not converge applies it once and the converged one applies nothing: factor solves
/// equal iterations, not iterations plus one a solve.
#[cfg(feature = "factor")]
#[rstest]
fn the_float32_factor_s_steps_equal_the_float64_factor_s(#[values(1, 2, 3)] seed: u64) {
    use lancet::physics::Preconditioner::{Factored, FactoredDouble};
    let model = random_model(seed, true);
    let dt = 20.0 * stable_time_step(&model).dt;
    let state = random_state(&model, seed + 10);
    let mut config = implicit_config(dt);
    config.solver.preconditioner = FactoredDouble;
    let (double, d) = run(&model, EngineKind::Fast, config, &state, 6);
    config.solver.preconditioner = Factored;
    let (single, s) = run(&model, EngineKind::Fast, config, &state, 6);
    eprintln!(
        "seed {seed}: float32 factor {} iterations in {} solves, float64 {}",
        s.iterations, s.solves, d.iterations
    );
    for stats in [&d, &s] {
        assert_eq!((stats.solves, stats.capped), (6, 0), "{stats:?}");
        assert_eq!(stats.factor_solves, stats.iterations, "{stats:?}");
        assert!(stats.last_residual <= 1e-7, "{stats:?}");
    }
    assert!(
        s.iterations <= d.iterations + s.solves,
        "{s:?} against {d:?}"
    );
    let e = relative_l2(&model.rest, &single, &double);
    assert!(
        e < 1e-4,
        "seed {seed}: {e:.2e} off the float64 factor's steps"
    );
    let moved = relative_l2(&model.rest, &state.0, &double);
    assert!(moved > 1e-2, "{moved:.2e}");
}

/// A stiff column standing on its clamped base under its own weight, like the SOFA cylinder
/// fixture (E = 1 MPa, 1000 kg/m^3, dt = 1 ms: over 15 times the explicit bound): the
/// factored preconditioner's steps (float32 solves of the factor, refreshed past 6 iterations)
/// equal the default symmetric Gauss-Seidel's, both solved to 1e-7, over 30 steps from rest,
/// in a few iterations a step against tens, with one factor solve per iteration.
///
/// The bound on the agreement is the tolerance's, as in the test above (1e-7 of each step's
/// system amplified by its conditioning, 1e3 to 1e4 here: 1e-3 of a step at worst, and the
/// steps' errors are damped, not summed, over the run); the column (0.1 m) sags by about
/// rho g L^2 / (2 E) = 4.9e-5 m, which the comparison is relative to.
#[cfg(feature = "factor")]
#[test]
fn the_factored_steps_of_a_stiff_column_equal_gauss_seidel_s() {
    use lancet::physics::Preconditioner::{Factored, SymmetricGaussSeidel};
    let mesh = BoxGrid::cube_cells([3, 3, 50], 0.002).build().unwrap();
    let mut config = ModelConfig::new(Material::elastic(1e6, 0.3, 1000.0));
    config.gravity = [0.0, 0.0, -9.81];
    config.mass_damping = 50.0;
    config.fixed.push(FixedSelector::Plane {
        point: [0.0; 3],
        normal: [0.0, 0.0, 1.0],
        tolerance: 1e-9,
    });
    let model = SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let dt = 1e-3;
    let bound = stable_time_step(&model).dt;
    assert!(dt > 15.0 * bound, "dt is {:.1} times the bound", dt / bound);
    let rest = (model.rest.clone(), vec![[0.0; 3]; model.node_count()]);
    let mut sim_config = implicit_config(dt);
    sim_config.solver.preconditioner = SymmetricGaussSeidel;
    let (sgs, g) = run(&model, EngineKind::Fast, sim_config, &rest, 30);
    sim_config.solver.preconditioner = Factored;
    let (factored, f) = run(&model, EngineKind::Fast, sim_config, &rest, 30);
    eprintln!(
        "column: factored {:.1} iterations a solve (max {}, {} factorisations), Gauss-Seidel {:.1}",
        f.mean_iterations(),
        f.max_iterations,
        f.factorisations,
        g.mean_iterations()
    );
    assert_eq!((f.capped, g.capped), (0, 0), "{f:?} {g:?}");
    assert_eq!(f.factor_solves, f.iterations, "{f:?}");
    assert!(
        f.mean_iterations() * 5.0 < g.mean_iterations(),
        "{f:?} {g:?}"
    );
    assert!(
        f.factorisations * 3 < f.solves,
        "refactored at most steps: {f:?}"
    );
    let e = relative_l2(&model.rest, &factored, &sgs);
    assert!(e < 1e-3, "{e:.2e} off Gauss-Seidel's steps");
    let sag = (model.rest.iter().zip(&sgs))
        .map(|(r, x)| r[2] - x[2])
        .fold(0.0, f64::max);
    assert!(sag > 1e-5, "the column did not sag ({sag:.2e} m)");
}
