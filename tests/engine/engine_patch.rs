//! A model change applied to a running simulation (what a cut does between steps): every
//! engine carries on from the same state, the engines agree with the float64 reference
//! afterwards, copies of split nodes start where their originals are, and a change that makes
//! the time step unstable is refused with nothing changed. A change of time step is a
//! parameter: it writes the step parameters alone and goes on as a run built at the new step.

use crate::{common, models};
use lancet::engine::{EngineKind, Integrator, SimConfig, Simulation};
use lancet::layout::LayoutKind;
use lancet::model::{stable_time_step, AddedNode, ModelDiff, PackedSpring, StateBlend};
use lancet::report::bench::relative_l2;
use lancet::Error;
use models::{random_diff, random_model, random_state};
use rstest::rstest;

/// Run 40 steps, apply two random changes with 60 steps after each, and return the positions.
fn cut_run(kind: EngineKind, layout: LayoutKind) -> (Vec<[f64; 3]>, Vec<[f64; 3]>, Simulation) {
    let model = random_model(51, true);
    let config = SimConfig::new(0.4 * stable_time_step(&model).dt);
    let mut sim = Simulation::with_gpu(model.clone(), kind, config, layout.into()).unwrap();
    let (x, v) = random_state(&model, 51);
    sim.set_state(&x, &v).unwrap();
    sim.run(40).unwrap();
    for round in 0..2 {
        let before = sim.positions();
        let n = sim.model().node_count();
        let diff = random_diff(sim.model(), 500 + round);
        sim.apply(&diff).unwrap();
        // Right after the change, before any step: old nodes where they were, copies on their
        // originals (fixed nodes excepted: they sit at rest).
        let after = sim.positions();
        let m = sim.model();
        for i in 0..n {
            if !m.fixed[i] {
                assert!(
                    dist(after[i], before[i]) < 1e-6,
                    "{kind:?}: node {i} jumped"
                );
            }
        }
        // Copies on their originals; nodes put on an edge on the deformed edge, at the same
        // parameter as on the rest edge.
        for (k, a) in diff.added_nodes.iter().enumerate() {
            let src = a.state_from.unwrap() as usize;
            let (with, t) = a.blend.map_or((src, 0.0), |b| (b.with as usize, b.t));
            if !m.fixed[n + k] && !m.fixed[src] && !m.fixed[with] {
                let want =
                    [0, 1, 2].map(|c| before[src][c] + t * (before[with][c] - before[src][c]));
                assert!(dist(after[n + k], want) < 1e-6, "{kind:?}: added node {k}");
            }
        }
        sim.run(60).unwrap();
    }
    let rest = sim.model().rest.clone();
    (sim.positions(), rest, sim)
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>().sqrt()
}

#[test]
fn engines_agree_with_the_reference_across_cuts() {
    let c = LayoutKind::Connectivity;
    let (reference, rest, _) = cut_run(EngineKind::Reference, c);
    let (fast, _, _) = cut_run(EngineKind::Fast, c);
    let e = relative_l2(&rest, &fast, &reference);
    // Float32 against float64 over 160 steps: rounding (about 3e-6 here), not a different
    // model (a node left off its place by a patch gives 1e-3 and more).
    assert!(
        e < 2e-5,
        "fast engine off the reference by {e:.2e} after cuts"
    );
    if common::gpu().is_some() {
        for layout in [c, LayoutKind::Valence, LayoutKind::Edges] {
            let (gpu, _, sim) = cut_run(EngineKind::Gpu, layout);
            let e = relative_l2(&rest, &gpu, &reference);
            assert!(
                e < 2e-5,
                "{} off the reference by {e:.2e}",
                sim.engine_name()
            );
        }
    }
}

#[test]
fn a_change_that_makes_the_step_unstable_is_refused_and_changes_nothing() {
    let model = random_model(52, false);
    let dt = 0.9 * stable_time_step(&model).dt;
    let mut sim = Simulation::new(model.clone(), EngineKind::Fast, SimConfig::new(dt)).unwrap();
    sim.run(5).unwrap();
    let x = sim.positions();
    let bound = sim.bound().clone();
    // A spring a thousand times stiffer than any other across a free node.
    let s = model
        .springs()
        .iter()
        .find(|s| !model.fixed[s.nodes[0] as usize] && !model.fixed[s.nodes[1] as usize])
        .unwrap();
    let diff = ModelDiff {
        changed_springs: vec![PackedSpring {
            stiffness: s.stiffness * 1e3,
            ..*s
        }],
        ..ModelDiff::default()
    };
    match sim.apply(&diff) {
        Err(Error::UnstableTimeStep { dt: d, bound, .. }) => assert!(d > bound),
        other => panic!("expected the unstable step to be refused, got {other:?}"),
    }
    let unchanged = |sim: &Simulation, what: &str| {
        assert_eq!(sim.model(), &model, "{what}");
        assert_eq!(sim.positions(), x, "{what}");
        assert_eq!(
            sim.bound(),
            &bound,
            "the {what} change moved the stable bound"
        );
    };
    unchanged(&sim, "refused");

    // An invalid diff (a spring that does not exist, next to a valid change) is refused with
    // nothing changed either, bound included.
    let n = model.node_count() as u32;
    let invalid = ModelDiff {
        changed_springs: vec![PackedSpring {
            stiffness: s.stiffness * 0.5,
            ..*s
        }],
        removed_springs: vec![[0, n + 7]],
        ..ModelDiff::default()
    };
    assert!(matches!(sim.apply(&invalid), Err(Error::DiffMismatch(_))));
    unchanged(&sim, "invalid");

    // A node started between two others needs a source, a partner that exists and a weight
    // in [0, 1].
    let free = s.nodes[0];
    for (from, with, t) in [
        (None, free, 0.5),
        (Some(free), n, 0.5),
        (Some(free), 0, 1.5),
    ] {
        let blended = ModelDiff {
            added_nodes: vec![AddedNode {
                key: Default::default(),
                rest: model.rest[free as usize],
                mass: model.mass[free as usize],
                fixed: false,
                state_from: from,
                blend: Some(StateBlend { with, t }),
            }],
            ..ModelDiff::default()
        };
        for at in [None, Some(&x)] {
            let result = match at {
                None => sim.apply(&blended),
                Some(x) => sim.apply_at(&blended, false, x),
            };
            match result {
                // A partner past the model is an index out of range; the rest, a bad blend.
                Err(e @ (Error::Model(_) | Error::NodeOutOfRange { .. })) => {
                    assert!(e.to_string().contains("node"), "{e}")
                }
                other => panic!("a blend from {from:?} with {with} at {t} was taken: {other:?}"),
            }
            unchanged(&sim, "blend");
        }
    }
}

/// Applying a change with the positions a cutter just read takes the same energy reference and
/// steps the same as reading them back from the engine, on every engine; positions of another
/// length, or not finite where the change needs them, are refused and change nothing.
#[test]
fn applying_at_known_positions_equals_reading_them_back() {
    let mut kinds = vec![EngineKind::Reference, EngineKind::Fast];
    if lancet::engine::gpu::GpuContext::new().is_ok()
        || std::env::var("LANCET_REQUIRE_GPU").as_deref() == Ok("1")
    {
        kinds.push(EngineKind::Gpu);
    }
    for kind in kinds {
        let model = random_model(53, true);
        let config = SimConfig::new(0.4 * stable_time_step(&model).dt);
        let start = || {
            let mut sim = Simulation::new(model.clone(), kind, config).unwrap();
            let (x, v) = random_state(&model, 53);
            sim.set_state(&x, &v).unwrap();
            sim.run(20).unwrap();
            sim
        };
        let (mut read, mut given) = (start(), start());
        for round in 0..2 {
            let diff = random_diff(read.model(), 600 + round);
            let reference = read.energy_reference();
            read.apply(&diff).unwrap();
            let x = given.positions();
            let bound = given.bound().clone();
            let err = given.apply_at(&diff, false, &x[1..]).unwrap_err();
            assert!(
                matches!(err, Error::LengthMismatch { given, expected, .. }
                    if given + 1 == expected && expected == x.len()),
                "{kind:?}: {err}"
            );
            assert_eq!(given.bound(), &bound);
            assert_eq!(given.model().node_count(), x.len());
            // A NaN where the change needs a position (what a failed device read gives).
            let mut bad = x.clone();
            bad[diff.removed_springs[0][0] as usize][1] = f64::NAN;
            let err = given.apply_at(&diff, false, &bad).unwrap_err();
            assert!(err.to_string().contains("not finite"), "{kind:?}: {err}");
            assert_eq!(given.bound(), &bound);
            assert_eq!(given.model().node_count(), x.len());
            given.apply_at(&diff, false, &x).unwrap();
            // The change moved the reference (it touched strained springs), the same way.
            assert_ne!(read.energy_reference().0, reference.0, "{kind:?}");
            assert_eq!(
                read.energy_reference(),
                given.energy_reference(),
                "{kind:?}"
            );
            read.run(15).unwrap();
            given.run(15).unwrap();
            assert_eq!(
                read.positions(),
                given.positions(),
                "{kind:?} round {round}"
            );
        }
    }
}

/// The bytes of each engine's step parameters: the float64 engine's `dt`; the fast engine's
/// h, h², 1/h, gravity and mass damping in float32; the GPU engine's uniform.
fn step_parameter_bytes(kind: EngineKind) -> u64 {
    match kind {
        EngineKind::Reference => 8,
        EngineKind::Fast => 7 * 4,
        _ => std::mem::size_of::<lancet::engine::gpu::StepUniform>() as u64,
    }
}

/// A time step changed mid-run is a parameter of the step. On every engine, layout and
/// integrator, lowering it and then raising it again each writes the engine's step parameters
/// and nothing else (no layout uploaded, no state moved, nothing rebuilt), and the run goes on
/// as a simulation built at the new step from the same positions and velocities does, step for
/// step: bit for bit on the CPU engines, within float32 rounding on the GPU, which moves
/// Verlet's last steps on the device (its pass against its twin:
/// `tests/gpu_patch.rs`). Before this, a change rebuilt the engine and uploaded all of it.
#[rstest]
fn a_time_step_change_writes_only_the_step_parameters_and_goes_on_as_a_fresh_run(
    // The CPU engines have one arrangement each; the layouts are the GPU's.
    #[values(
        (EngineKind::Reference, LayoutKind::Connectivity),
        (EngineKind::Fast, LayoutKind::Connectivity),
        (EngineKind::Gpu, LayoutKind::Connectivity),
        (EngineKind::Gpu, LayoutKind::Valence),
        (EngineKind::Gpu, LayoutKind::Edges)
    )]
    engine: (EngineKind, LayoutKind),
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let (kind, layout) = engine;
    if kind == EngineKind::Gpu && common::gpu().is_none() {
        return;
    }
    let model = random_model(61, true);
    let bound = stable_time_step(&model).dt;
    let mut config = SimConfig::new(0.8 * bound);
    config.integrator = integrator;
    let mut sim = Simulation::with_gpu(model.clone(), kind, config, layout.into()).unwrap();
    let (x, v) = random_state(&model, 61);
    sim.set_state(&x, &v).unwrap();
    sim.run(20).unwrap();
    let what = format!("{} {integrator:?}", sim.engine_name());
    let mut time = 20.0 * config.dt;
    for fraction in [0.3, 0.7] {
        let dt = fraction * bound;
        let (x, v) = (sim.positions(), sim.velocities());
        let cost = sim.set_time_step(dt).unwrap();
        assert_eq!(
            (cost.uploaded_bytes, cost.copied_bytes, cost.buffers_grown),
            (step_parameter_bytes(kind), 0, 0),
            "{what}: {cost:?}"
        );
        assert!(
            !cost.reallocated && cost.state_moves == 0,
            "{what}: {cost:?}"
        );
        assert_eq!(sim.config().dt, dt);
        let fresh_config = SimConfig { dt, ..config };
        let mut fresh =
            Simulation::with_gpu(model.clone(), kind, fresh_config, layout.into()).unwrap();
        fresh.set_state(&x, &v).unwrap();
        let rest = &model.rest;
        for step in 1..=30 {
            sim.run(1).unwrap();
            fresh.run(1).unwrap();
            let (got, want) = (sim.positions(), fresh.positions());
            if kind == EngineKind::Gpu {
                // The rescaled last steps differ from a fresh upload's by float32
                // rounding (a few ulps of the displacement), which the steps carry along.
                let moved = (0..rest.len())
                    .map(|i| dist(want[i], rest[i]))
                    .fold(0.0, f64::max);
                let worst = (0..rest.len())
                    .map(|i| dist(got[i], want[i]))
                    .fold(0.0, f64::max);
                assert!(
                    worst <= 1e-6 * moved,
                    "{what} at {fraction} of the bound, step {step}: {worst:e} m off a fresh \
                     run (displacements up to {moved:e} m)"
                );
            } else {
                assert_eq!(got, want, "{what} at {fraction} of the bound, step {step}");
                assert_eq!(sim.velocities(), fresh.velocities(), "{what}, step {step}");
            }
        }
        // Time is summed over the steps taken at each step size.
        time += 30.0 * dt;
        assert!((sim.time() - time).abs() < 1e-12 * time, "{what}");
    }
}
