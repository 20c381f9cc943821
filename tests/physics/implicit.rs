//! The implicit integrator (linearised backward Euler with conjugate gradients) on the
//! reference and fast engines, far above the explicit stable bound: it settles a hanging beam to the
//! explicit engines' static equilibrium, and stiff undamped springs lose energy step after
//! step instead of blowing up.

use lancet::engine::reference::ReferenceEngine;
use lancet::engine::{Engine, Integrator};
use lancet::model::stable_time_step;
use lancet::physics::{BackwardEuler, Explicit, SolverSettings};
use lancet::{EngineKind, PackedModel, SimConfig, Simulation};

use super::physics_beam::{cantilever_damped as cantilever, tip_sag};

fn implicit(model: &PackedModel, dt: f64) -> ReferenceEngine {
    ReferenceEngine::with_integrator(
        model,
        dt,
        Box::new(BackwardEuler::new(SolverSettings::default())),
    )
}

/// Kinetic, elastic and gravitational energy, J.
fn total_energy(model: &PackedModel, engine: &dyn Engine) -> f64 {
    let (x, v) = engine.state();
    model.kinetic_energy(&v) + model.elastic_energy(&x) + model.gravity_energy(&x)
}

#[test]
fn the_implicit_step_settles_a_hanging_beam_where_the_explicit_engines_do() {
    let model = cantilever(100.0);
    let bound = stable_time_step(&model).dt;
    // 4 ms: about 30 times the explicit bound.
    let dt = 4e-3;
    assert!(dt > 20.0 * bound, "bound {bound:e} s");
    let mut engine = implicit(&model, dt);
    engine.step((0.5 / dt) as u32);
    let sag = tip_sag(&model, &engine.positions());

    // The explicit fast engine, at 0.9 of its bound, over the same 0.5 s (25 decay times).
    let explicit_dt = 0.9 * bound;
    let mut config = SimConfig::new(explicit_dt);
    config.integrator = Integrator::Verlet;
    let mut sim = Simulation::new(model.clone(), EngineKind::Fast, config).unwrap();
    sim.run((0.5 / explicit_dt) as u64).unwrap();
    let explicit_sag = tip_sag(&model, &sim.positions());
    assert!(explicit_sag < 0.0);
    assert!(
        (sag / explicit_sag - 1.0).abs() < 0.01,
        "implicit sag {sag:e} m, explicit {explicit_sag:e} m"
    );
    // And still: the implicit state is an equilibrium, not a snapshot of a swing.
    let before = sag;
    engine.step(50);
    let after = tip_sag(&model, &engine.positions());
    assert!(
        (after - before).abs() < 1e-4 * before.abs(),
        "{before:e} -> {after:e}"
    );
}

#[test]
fn undamped_stiff_springs_lose_energy_monotonically_at_a_hundred_times_the_bound() {
    let model = cantilever(0.0);
    let dt = 100.0 * stable_time_step(&model).dt;
    let mut engine = implicit(&model, dt);
    let mut energy = total_energy(&model, &engine);
    let start = energy;
    for step in 0..200 {
        engine.step(1);
        let next = total_energy(&model, &engine);
        assert!(next.is_finite(), "step {step}: energy {next}");
        assert!(
            next <= energy + 1e-12 * energy.abs().max(next.abs()),
            "step {step}: energy rose from {energy:e} J to {next:e} J"
        );
        energy = next;
    }
    // It fell under gravity (energy was released and dissipated), and it did not explode.
    assert!(energy < start);
    let x = engine.positions();
    assert!(
        tip_sag(&model, &x).abs() < 0.05,
        "the tip moved by more than half the beam's length"
    );

    // The same step with the explicit scheme blows up: the test is far above the bound.
    let mut explicit =
        ReferenceEngine::with_integrator(&model, dt, Box::new(Explicit::new(Integrator::Verlet)));
    explicit.step(200);
    let e = total_energy(&model, &explicit);
    // (Measured against the energy the implicit run released, the scale of this motion.)
    let blew_up = !e.is_finite() || e.abs() > 1e3 * energy.abs();
    assert!(blew_up, "explicit energy {e:e} J stayed bounded");
}

/// A small clamped box scene stepping with backward Euler at 1 ms (far above its explicit
/// bound), with `extra` fields appended.
fn implicit_scene(extra: &str) -> lancet::scene::Scene {
    let text = format!(
        r#"Scene(
    name: "implicit box",
    mesh: Box((size: (0.02, 0.01, 0.01), cells: (4, 2, 2))),
    material: (stiffness: Material(youngs_modulus: 1e5, poisson_ratio: 0.3), mass: Density(1000.0)),
    gravity: (0.0, 0.0, -9.81),
    fixed: [Plane(point: (0.0, 0.0, 0.0), normal: (1.0, 0.0, 0.0), tolerance: 1e-9)],
    dt: Seconds(1e-3),
    steps: 20,
    engine: Reference,
    integrator: BackwardEuler,
    {extra}
)"#
    );
    lancet::scene::Scene::from_ron(&text, std::path::Path::new("implicit.ron")).unwrap()
}

fn run_scene(scene: &lancet::scene::Scene) -> lancet::Result<lancet::scene::RunSummary> {
    let opts = lancet::scene::RunOptions {
        no_output: true,
        ..Default::default()
    };
    lancet::scene::run_scene(
        scene,
        std::path::Path::new("implicit.ron"),
        &opts,
        |_, _| {},
    )
}

#[test]
fn a_scene_runs_backward_euler_above_the_explicit_bound_and_reports_its_solver() {
    let scene = implicit_scene("solver: (tolerance: 1e-7, max_iterations: 200),");
    let summary = run_scene(&scene).unwrap();
    assert!(!summary.refused, "{:?}", summary.message);
    assert!(summary.dt > 4.0 * summary.dt_bound, "{summary:?}");
    assert_eq!(summary.steps, 20);
    let solver = summary.solver.expect("backward Euler reports its solver");
    assert_eq!(solver.solves, 20);
    assert_eq!(solver.tolerance, 1e-7);
    assert_eq!(solver.capped, 0, "{solver:?}");
    assert!(solver.final_residual <= 1e-7, "{solver:?}");
    assert!(solver.mean_iterations >= 1.0 && solver.max_iterations >= 1);
    assert!(summary.max_displacement > 0.0);
}

#[test]
fn an_iteration_cap_below_what_the_tolerance_needs_is_counted() {
    let scene = implicit_scene("solver: (tolerance: 1e-12, max_iterations: 2),");
    let solver = run_scene(&scene).unwrap().solver.unwrap();
    assert_eq!(solver.max_iterations, 2, "{solver:?}");
    assert_eq!(solver.capped, solver.solves, "{solver:?}");
    assert!(solver.final_residual > 1e-12);
}

#[test]
fn explicit_schemes_report_no_solver_and_unknown_solver_fields_are_refused() {
    let scene = implicit_scene("");
    let mut explicit = scene.clone();
    explicit.integrator = Integrator::SymplecticEuler;
    explicit.dt = lancet::scene::TimeStep::BoundFraction(0.5);
    assert!(run_scene(&explicit).unwrap().solver.is_none());
    let bad = r#"Scene(name: "x", mesh: Box((size: (0.02, 0.01, 0.01), cells: (2, 1, 1))),
           material: (stiffness: Material(youngs_modulus: 1e5, poisson_ratio: 0.3), mass: Density(1000.0)),
           steps: 1, integrator: BackwardEuler, solver: (tolerence: 1e-5))"#;
    let err = lancet::scene::Scene::from_ron(bad, std::path::Path::new("bad.ron")).unwrap_err();
    assert!(err.to_string().contains("tolerence"), "{err}");
}

#[test]
fn every_engine_steps_backward_euler_above_the_explicit_bound() {
    let model = cantilever(100.0);
    let mut config = SimConfig::new(1e-3);
    config.integrator = Integrator::BackwardEuler;
    // Every engine takes it, at a step the explicit schemes would refuse (the GPU engine in
    // its connectivity layout when there is an adapter: tests/gpu/gpu_implicit.rs).
    for kind in [EngineKind::Reference, EngineKind::Fast, EngineKind::Auto] {
        let mut sim = Simulation::new(model.clone(), kind, config).unwrap();
        sim.run(5).unwrap();
        assert_eq!(sim.solver_stats().unwrap().solves, 5, "{kind}");
    }
    config.integrator = Integrator::Verlet;
    assert!(matches!(
        Simulation::new(model, EngineKind::Reference, config),
        Err(lancet::Error::UnstableTimeStep { .. })
    ));
}

#[test]
fn the_fast_engine_at_one_millisecond_settles_the_beam_where_the_explicit_engines_do() {
    let model = cantilever(100.0);
    let bound = stable_time_step(&model).dt;
    let dt = 1e-3;
    assert!(dt > 5.0 * bound, "bound {bound:e} s");
    let mut config = SimConfig::new(dt);
    config.integrator = Integrator::BackwardEuler;
    let mut sim = Simulation::new(model.clone(), EngineKind::Fast, config).unwrap();
    sim.run((0.5 / dt) as u64).unwrap();
    let sag = tip_sag(&model, &sim.positions());
    let stats = sim.solver_stats().unwrap();
    assert_eq!(stats.capped, 0, "{stats:?}");

    // The explicit fast engine, at 0.9 of its bound, over the same 0.5 s (25 decay times of
    // the mass damping).
    let explicit_dt = 0.9 * bound;
    let mut config = SimConfig::new(explicit_dt);
    config.integrator = Integrator::Verlet;
    let mut explicit = Simulation::new(model.clone(), EngineKind::Fast, config).unwrap();
    explicit.run((0.5 / explicit_dt) as u64).unwrap();
    let explicit_sag = tip_sag(&model, &explicit.positions());
    assert!(explicit_sag < 0.0);
    assert!(
        (sag / explicit_sag - 1.0).abs() < 0.01,
        "implicit sag {sag:e} m, explicit {explicit_sag:e} m"
    );
}

/// The reference engine's warm start (the last step's velocity change as the first guess)
/// reaches the cold start's solution, in fewer iterations: the damped beam sagging from rest at
/// 4 ms, 40 steps solved to 1e-9. Same states to 1e-7 of the motion (the solves' tolerance sets
/// it). The saving is small here (about 1%: each step's change differs from the last one's by
/// nearly as much as it differs from zero while the beam swings) but it is a saving.
#[test]
fn the_reference_warm_start_reaches_the_cold_solution_in_fewer_iterations() {
    let model = cantilever(100.0);
    let run = |warm_start: bool| {
        let settings = SolverSettings {
            tolerance: 1e-9,
            max_iterations: 1000,
            warm_start,
            ..SolverSettings::default()
        };
        let mut engine =
            ReferenceEngine::with_integrator(&model, 4e-3, Box::new(BackwardEuler::new(settings)));
        engine.step(40);
        (engine.positions(), engine.solver_stats().unwrap())
    };
    let ((cold, cold_stats), (warm, warm_stats)) = (run(false), run(true));
    let e = lancet::report::bench::relative_l2(&model.rest, &warm, &cold);
    eprintln!(
        "{:.1} iterations a solve warm, {:.1} cold; {e:.2e} apart",
        warm_stats.mean_iterations(),
        cold_stats.mean_iterations()
    );
    assert_eq!(warm_stats.capped + cold_stats.capped, 0);
    assert!(e < 1e-7, "{e:.2e} off the cold solution");
    assert!(
        warm_stats.iterations < cold_stats.iterations,
        "{warm_stats:?} against {cold_stats:?}"
    );
}

/// The same beam with finite elements at 1 ms on the fast engine (tensor-mass and
/// corotational, about 8 times their explicit bound of 0.13 ms) settles where the fast
/// engine's explicit Verlet steps of the same model, at 0.9 of that bound, settle it, within
/// 1% (they agree to about 1e-4), both over 0.3 s (15 times the mass damping's decay time).
/// The static sag depends on the model, not on the integrator: this checks the implicit
/// step's force (its right-hand side) against the explicit one's, and that its solve takes
/// the beam there in that time.
#[rstest::rstest]
fn the_fast_engine_with_finite_elements_settles_the_beam_where_its_explicit_steps_do(
    #[values(
        lancet::physics::ForceModelKind::TensorMass,
        lancet::physics::ForceModelKind::Corotational
    )]
    kind: lancet::physics::ForceModelKind,
) {
    let model = cantilever(100.0);
    let bound = kind.stable_time_step(&model).unwrap().dt;
    let dt = 1e-3;
    let time = 0.3;
    let config = SimConfig {
        integrator: Integrator::BackwardEuler,
        force_model: kind,
        ..SimConfig::new(dt)
    };
    let mut sim = Simulation::new(model.clone(), EngineKind::Fast, config).unwrap();
    sim.run((time / dt) as u64).unwrap();
    let sag = tip_sag(&model, &sim.positions());
    let stats = sim.solver_stats().unwrap();
    assert_eq!(stats.capped, 0, "{stats:?}");

    let explicit_dt = 0.9 * bound;
    let config = SimConfig {
        integrator: Integrator::Verlet,
        force_model: kind,
        ..SimConfig::new(explicit_dt)
    };
    let mut explicit = Simulation::new(model.clone(), EngineKind::Fast, config).unwrap();
    explicit.run((time / explicit_dt) as u64).unwrap();
    let explicit_sag = tip_sag(&model, &explicit.positions());
    eprintln!(
        "{kind}: bound {bound:.2e} s; sag {sag:.4e} m implicit, {explicit_sag:.4e} m explicit; {:.1} iterations a step",
        stats.mean_iterations()
    );
    assert!(explicit_sag < 0.0);
    assert!(
        (sag / explicit_sag - 1.0).abs() < 0.01,
        "{kind}: implicit sag {sag:e} m, explicit {explicit_sag:e} m"
    );
}

/// `solver: (preconditioner: Factored)` parses (and runs on the fast engine when lancet is
/// built with the `factor` feature; without it the run is refused with the feature named), and
/// a misspelled one is refused with the nearest name.
#[test]
fn a_scene_takes_the_factored_preconditioner_and_a_misspelling_names_it() {
    let mut scene = implicit_scene("solver: (preconditioner: Factored)");
    assert_eq!(
        scene.solver.preconditioner,
        lancet::physics::Preconditioner::Factored
    );
    // The reference engine has no factor: refused with what to do.
    let err = run_scene(&scene).unwrap_err().to_string();
    assert!(err.contains("fast engine only"), "{err}");
    scene.engine = EngineKind::Fast;
    if cfg!(feature = "factor") {
        let solver = run_scene(&scene).unwrap().solver.unwrap();
        assert_eq!(solver.capped, 0, "{solver:?}");
        assert!(solver.factorisations >= 1, "{solver:?}");
    } else {
        // Built without the factor: refused with the feature to build with.
        let err = run_scene(&scene).unwrap_err().to_string();
        assert!(err.contains("`factor` feature"), "{err}");
    }
    let bad = r#"Scene(name: "x", mesh: Box((size: (0.02, 0.01, 0.01), cells: (2, 1, 1))),
           material: (stiffness: Material(youngs_modulus: 1e5, poisson_ratio: 0.3), mass: Density(1000.0)),
           steps: 1, integrator: BackwardEuler, solver: (preconditioner: Factord))"#;
    let err = lancet::scene::Scene::from_ron(bad, std::path::Path::new("bad.ron")).unwrap_err();
    let text = format!("{err}");
    assert!(
        text.contains("Factord") && text.contains("did you mean `Factored`"),
        "{text}"
    );
}
