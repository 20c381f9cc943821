//! Cuts under the implicit integrator on the fast engine: random blade strokes through a
//! hanging box stepped by backward Euler at 1 ms (far above the explicit bound, which a cut
//! lowers further), with every cut method. After every cut every invariant holds and the
//! patched engine's structures equal a rebuild's; the step is never lowered; and at the end
//! the patched engine steps as an engine built from scratch on the cut model does.

use std::path::Path;

use crate::models::Rng;
use lancet::cut::CutMethod;
use lancet::engine::{EngineKind, Simulation};
use lancet::model::stable_time_step;
use lancet::report::bench::relative_l2;
use lancet::scene::driver::SceneDriver;
use lancet::scene::{RunOptions, Scene};
use lancet::world::World;
use rstest::rstest;

const DT: f64 = 1e-3;

/// A 4 cm box hanging from its y = 0 face, a blade entering from above at a random place and
/// angle and sweeping down and across it over 30 ms; `solver` the scene's solver settings.
fn scene_text(seed: u64, solver: &str) -> String {
    let mut rng = Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    let x0 = 0.005 + 0.03 * rng.next();
    let x1 = 0.005 + 0.03 * rng.next();
    let y0 = 0.01 + 0.025 * rng.next();
    let y1 = 0.01 + 0.025 * rng.next();
    let depth = -0.005 - 0.03 * rng.next();
    format!(
        r#"Scene(
    name: "implicit cuts",
    mesh: Box((cells: (5, 5, 5), size: (0.04, 0.04, 0.04))),
    material: (
        stiffness: Material(youngs_modulus: 1e5, poisson_ratio: 0.3),
        mass: Density(1000.0),
        damping: StiffnessProportional(1e-3),
    ),
    gravity: (0.0, -9.81, 0.0),
    fixed: [Plane(point: (0.0, 0.0, 0.0), normal: (0.0, 1.0, 0.0), tolerance: 1e-9)],
    dt: Seconds({DT}),
    steps: 40,
    engine: Fast,
    integrator: BackwardEuler,
    solver: ({solver}),
    tools: [(
        name: "scalpel",
        shape: Blade(width: 0.1, length: 0.1, thickness: 2e-4),
        trajectory: Keyframes([
            (time: 0.0, translation: ({x0}, {y0}, 0.05)),
            (time: 0.03, translation: ({x1}, {y1}, {depth})),
        ]),
    )],
    cut: Some((methods: [Separate, Remove, Subdivide])),
)"#
    )
}

#[rstest]
fn random_cuts_under_backward_euler_keep_every_invariant_and_the_patched_engine_steps_as_a_rebuilt_one(
    #[values(CutMethod::Separate, CutMethod::Remove, CutMethod::Subdivide)] method: CutMethod,
    #[values(1, 2, 3)] seed: u64,
) {
    let path = Path::new("implicit_cuts.ron");
    let scene = Scene::from_ron(&scene_text(seed, ""), path).unwrap();
    let opts = RunOptions {
        engine: Some(EngineKind::Fast),
        cut_method: Some(method),
        check: true,
        ..RunOptions::default()
    };
    let mut world = World::from_scene(&scene, path, &opts).unwrap();
    assert_eq!(world.sim().config().dt, DT);
    assert!(DT > 10.0 * stable_time_step(world.model()).dt);
    let config = *world.sim().config();
    let mut driver = SceneDriver::new(&scene);
    for _ in 0..scene.steps {
        driver.step(&mut world).unwrap();
    }
    let report = &world.cutting().unwrap().report;
    assert!(
        report.cuts > 0,
        "seed {seed} {method}: the blade cut nothing"
    );
    assert_eq!(report.checks, report.cuts, "seed {seed} {method}");
    assert!(
        report.violations.is_empty(),
        "seed {seed} {method}: {:#?}",
        report.violations
    );
    // A cut lowers the explicit bound, never the implicit step.
    assert_eq!(world.sim().config().dt, DT);
    assert!(report.events.iter().all(|e| e.time_step_bytes == 0));
    let stats = world.sim().solver_stats().unwrap();
    assert_eq!(stats.solves, scene.steps, "seed {seed} {method}");
    assert_eq!(stats.capped, 0, "seed {seed} {method}: {stats:?}");

    // The patched engine against one built from scratch on the cut model, from the same state:
    // float32 rounding in another node order, not another model (a row left stale by a patch
    // moves its nodes by the size of the motion).
    let (x, v) = (world.sim().positions(), world.sim().velocities());
    let mut rebuilt =
        Simulation::new(world.sim().model().clone(), EngineKind::Fast, config).unwrap();
    rebuilt.set_state(&x, &v).unwrap();
    world.sim_mut().run(20).unwrap();
    rebuilt.run(20).unwrap();
    let rest = &world.sim().model().rest;
    let e = relative_l2(rest, &world.sim().positions(), &rebuilt.positions());
    assert!(
        e < 1e-4,
        "seed {seed} {method}: {e:.2e} off a rebuilt engine"
    );
    let moved = relative_l2(rest, &x, &rebuilt.positions());
    assert!(
        moved > 1e-3,
        "seed {seed} {method}: the run was at rest ({moved:.2e})"
    );
}

/// Through cuts the factored preconditioner goes on with the factor it took before them: the
/// nodes it covers keep it, the cut's new nodes get block Jacobi, and the step is not
/// refactored for the cut. Conjugate gradients still converge to the same solution as block
/// Jacobi's (both to 1e-8, so the runs agree to float32 rounding over the whole stroke), every
/// invariant holds, and the factorisations stay far fewer than the steps. The same with the
/// factor's solves in float32 (`Factored`) and in float64 (`FactoredDouble`), each applying
/// the factor once per iteration that did not converge.
#[cfg(feature = "factor")]
#[rstest]
fn cuts_under_the_factored_preconditioner_reach_block_jacobi_s_solution(
    #[values(CutMethod::Separate, CutMethod::Remove)] method: CutMethod,
    #[values("Factored", "FactoredDouble")] factor: &str,
) {
    let path = Path::new("implicit_cuts.ron");
    let run = |preconditioner: &str| {
        let solver =
            format!("tolerance: 1e-8, max_iterations: 500, preconditioner: {preconditioner}");
        let scene = Scene::from_ron(&scene_text(1, &solver), path).unwrap();
        let opts = RunOptions {
            engine: Some(EngineKind::Fast),
            cut_method: Some(method),
            check: true,
            ..RunOptions::default()
        };
        let mut world = World::from_scene(&scene, path, &opts).unwrap();
        let mut driver = SceneDriver::new(&scene);
        for _ in 0..scene.steps {
            driver.step(&mut world).unwrap();
        }
        world
    };
    let (factored, jacobi) = (run(factor), run("BlockJacobi"));
    let report = &factored.cutting().unwrap().report;
    assert!(report.cuts > 0, "{method}: the blade cut nothing");
    assert_eq!(report.checks, report.cuts, "{method}");
    assert!(
        report.violations.is_empty(),
        "{method}: {:#?}",
        report.violations
    );
    let (model, other) = (factored.sim().model(), jacobi.sim().model());
    assert_eq!(
        model.node_count(),
        other.node_count(),
        "{method}: the same cuts"
    );
    if method == CutMethod::Separate {
        assert!(model.node_count() > 216, "{method}: the cut added no nodes");
    }
    let stats = factored.sim().solver_stats().unwrap();
    let against = jacobi.sim().solver_stats().unwrap();
    eprintln!(
        "{method}: {:.1} iterations a step factored ({} factorisations, max {}), {:.1} block \
         Jacobi",
        stats.mean_iterations(),
        stats.factorisations,
        stats.max_iterations,
        against.mean_iterations()
    );
    assert_eq!(stats.capped, 0, "{method}: {stats:?}");
    assert_eq!(stats.factor_solves, stats.iterations, "{method}: {stats:?}");
    // Refactored only when a solve went past the refresh bound, not at every step.
    assert!(
        2 * stats.factorisations < stats.solves,
        "{method}: refactored at most steps: {stats:?}"
    );
    let e = relative_l2(
        &model.rest,
        &factored.sim().positions(),
        &jacobi.sim().positions(),
    );
    assert!(e < 1e-5, "{method}: {e:.2e} off block Jacobi's run");
    // The box sagged (about rho g L^2 / E = 1.6e-4 m at this size) and the agreement above is
    // of a real motion.
    let sag = (model.rest.iter().zip(jacobi.sim().positions()))
        .map(|(r, x)| (r[1] - x[1]).abs())
        .fold(0.0, f64::max);
    assert!(sag > 2e-5, "{method}: the run was at rest ({sag:.2e} m)");
}
