//! Float32 and small steps. Far below the stable bound a step moves a displacement by a few
//! float32 ulps: Verlet kept as two plainly rounded displacements lost most of its velocity to
//! their rounded difference, and any engine that rounds `u + step` plainly stalls short of
//! equilibrium. The float32 engines keep Verlet's step `u - u_prev` instead of the previous
//! displacement, and every float32 engine (the fast one and every GPU pass) carries what
//! rounding `u + step` loses to the next step (`physics::Compensation`, in the spare `w`
//! lanes), so every float32 engine and GPU layout follows float64 down to 1/64 of the bound,
//! and in a stiffness contrast whose soft part runs far below its own bound.

use lancet::engine::{EngineKind, Integrator, SimConfig, Simulation, FLOAT32_NODE_FRACTION};
use lancet::layout::edges::Accumulation;
use lancet::layout::LayoutKind;
use lancet::mesh::generate::beam;
use lancet::model::{
    stable_time_step, FixedSelector, Material, ModelConfig, PackedModel, SpringDamping,
};
use lancet::report::accuracy::{model_accuracy, AccuracyOptions, AccuracyReport};
use lancet::SpringModel;

/// The default scene's beam, coarser: 50 mm, E = 50 kPa, clamped at x = 0, under gravity,
/// with mass-proportional damping and (when `damping` is not zero) damping along every spring.
fn hanging_beam(damping: f64) -> PackedModel {
    let mesh = beam(0.05, 0.02, 0.02, 10, 4).unwrap();
    let mut material = Material::elastic(50e3, 0.25, 1000.0);
    if damping > 0.0 {
        material.damping = SpringDamping::Absolute(damping);
    }
    let mut config = ModelConfig::new(material);
    config.gravity = [0.0, 0.0, -9.81];
    config.mass_damping = 60.0;
    config.fixed.push(FixedSelector::Plane {
        point: [0.0; 3],
        normal: [1.0, 0.0, 0.0],
        tolerance: 1e-9,
    });
    SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap()
}

/// Spring damping of the loaded, damped scene, N s/m: a few percent of critical for one spring
/// and its node (`2 sqrt(k m)` is about 0.3 N s/m here), enough that the damped kernels matter.
const SPRING_DAMPING: f64 = 0.01;

/// The tolerance of issue 27: within twice float64's error against the converged reference,
/// or 1e-6 relative, whichever is larger.
fn tolerance(float64_error: f64) -> f64 {
    (2.0 * float64_error).max(1e-6)
}

/// Every float32 row of `report` against the float64 row at the same fraction of the bound:
/// the worst error over the sample times and, with `each_time`, the error at every sample time.
/// Returns the number of float32 rows checked.
fn assert_float32_follows_float64(report: &AccuracyReport, what: &str, each_time: bool) -> usize {
    let mut checked = 0;
    for f64_row in report
        .rows
        .iter()
        .filter(|r| r.series == "cpu-reference-f64")
    {
        let e64 = f64_row.worst_relative_l2();
        assert!(e64.is_finite(), "{what}: float64 at {}", f64_row.fraction);
        for row in report
            .rows
            .iter()
            .filter(|r| r.series != "cpu-reference-f64" && r.fraction == f64_row.fraction)
        {
            let e32 = row.worst_relative_l2();
            assert!(
                e32 <= tolerance(e64),
                "{what}, {} at {:.4} of the bound: float32 error {e32:.3e}, float64 {e64:.3e} \
                 (tolerance {:.3e})",
                row.series,
                f64_row.fraction,
                tolerance(e64)
            );
            for (s32, s64) in row.errors.iter().zip(&f64_row.errors).filter(|_| each_time) {
                assert_eq!(s32.time, s64.time);
                assert!(
                    s32.relative_l2 <= tolerance(s64.relative_l2),
                    "{what}, {} at {:.4} of the bound, {} s: float32 error {:.3e}, float64 \
                     {:.3e} (tolerance {:.3e})",
                    row.series,
                    f64_row.fraction,
                    s32.time,
                    s32.relative_l2,
                    s64.relative_l2,
                    tolerance(s64.relative_l2)
                );
            }
            checked += 1;
        }
    }
    checked
}

fn options(engines: Vec<EngineKind>, ladder: Vec<f64>) -> AccuracyOptions {
    AccuracyOptions {
        engines,
        layouts: vec![
            LayoutKind::Connectivity,
            LayoutKind::Valence,
            LayoutKind::Edges,
        ],
        accumulations: vec![
            Accumulation::Gather,
            Accumulation::AtomicFixed,
            Accumulation::AtomicFloat,
        ],
        ladder,
        implicit_ladder: Vec::new(),
        warmup_steps: 0,
        ..AccuracyOptions::default()
    }
}

/// The beam of [`hanging_beam`] in cells of 10 mm (54 nodes, stable bound 0.53 ms), loaded by
/// gravity, with spring damping and mass damping of 114/s (about critical for its first bending
/// mode), so that it settles within a few tenths of a second.
fn settling_beam() -> PackedModel {
    let mesh = beam(0.05, 0.02, 0.02, 5, 2).unwrap();
    let mut material = Material::elastic(50e3, 0.25, 1000.0);
    material.damping = SpringDamping::Absolute(SPRING_DAMPING);
    let mut config = ModelConfig::new(material);
    config.gravity = [0.0, 0.0, -9.81];
    config.mass_damping = 114.0;
    config.fixed.push(FixedSelector::Plane {
        point: [0.0; 3],
        normal: [1.0, 0.0, 0.0],
        tolerance: 1e-9,
    });
    SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap()
}

/// Float32 against float64 once the loaded beam has settled, where float64's error is small
/// (the state it settles to does not depend on the step) and float32's rounding shows: an
/// engine that rounds `u + step` plainly stalls where the step a node's residual force drives
/// (`h f / (m alpha)` against the mass damping) falls below half an ulp of its displacement,
/// and that distance grows as `1 / h`. Measured on lavapipe before the GPU passes carried the
/// rounding (the fast engine already did), Verlet at 0.3 s: relative L2 errors 7.95e-6 (1/16)
/// and 8.99e-5 (1/64) on the GPU (connectivity layout) against 7.1e-7 and 1.8e-7 for float64
/// and 9.8e-7 and 5.5e-7 for the fast engine.
#[test]
fn float32_follows_float64_at_a_sixteenth_and_a_sixty_fourth_of_the_bound_on_every_engine() {
    let model = settling_beam();
    let gpu = crate::common::gpu().is_some();
    let mut engines = vec![EngineKind::Reference, EngineKind::Fast];
    if gpu {
        engines.push(EngineKind::Gpu);
    }
    let ladder = vec![1.0 / 16.0, 1.0 / 64.0];
    for integrator in [Integrator::Verlet, Integrator::SymplecticEuler] {
        // 0.3 s, measured halfway and at the end: float64's error falls from about 1e-5 to
        // about 2e-7 of the sag as the beam settles (36,000 steps at 1/64 of the bound).
        let mut opts = options(engines.clone(), ladder.clone());
        opts.times = vec![0.15, 0.3];
        // Not the edge layout's fixed-point accumulation: its spring forces are quantised to
        // `FixedPoint::resolution` (set from the largest plausible spring force, with headroom
        // against overflow), so the state it settles to is off by what that resolution allows
        // whatever the step (measured on lavapipe, symplectic Euler: 2.3e-5 at 1/16 of the
        // bound, 2.8e-5 at 1/64), which no rounding of the integration can remove.
        opts.accumulations = vec![Accumulation::Gather, Accumulation::AtomicFloat];
        let report =
            model_accuracy("settling beam", &model, integrator, 0.3, &opts, |_| {}).unwrap();
        // The fast engine, and on a GPU every layout (the edge layout gathering and with float
        // atomics) but what the adapter cannot run (float atomics), which the report names;
        // at each sample time, not only at the worst (at 1/16 of the bound float64's worst,
        // halfway, is 40 times its error once settled).
        let expected = if gpu { 5 - report.skipped.len() } else { 1 };
        let checked = assert_float32_follows_float64(&report, &format!("{integrator:?}"), true);
        assert_eq!(checked, expected * ladder.len(), "{:?}", report.skipped);
    }
}

/// The same on the settling beam with springs of one material (its springs' mean stiffness,
/// the same damping, rest lengths its rest edges'), where the fast engine keeps the constants
/// once and takes each rest length from the float32 rest edge vector in the step rather than
/// a stored float32 rest length (`sliced.rs`).
#[test]
fn float32_follows_float64_with_springs_of_one_material_taking_rest_lengths_from_their_edges() {
    let model = crate::models::one_material(settling_beam());
    let fast = lancet::engine::fast::FastEngine::new(&model, SimConfig::new(1e-5));
    assert!(fast.uniform_springs().is_some());
    let ladder = vec![1.0 / 16.0, 1.0 / 64.0];
    for integrator in [Integrator::Verlet, Integrator::SymplecticEuler] {
        let mut opts = options(
            vec![EngineKind::Reference, EngineKind::Fast],
            ladder.clone(),
        );
        opts.times = vec![0.15, 0.3];
        let report =
            model_accuracy("one material", &model, integrator, 0.3, &opts, |_| {}).unwrap();
        let checked = assert_float32_follows_float64(&report, &format!("{integrator:?}"), true);
        assert_eq!(checked, ladder.len());
    }
}

/// The beam with the springs of its clamped half `contrast` times stiffer: the global bound is
/// set there, so the free half runs at about `1 / sqrt(contrast)` of its own bound.
fn stiffness_contrast(contrast: f64) -> PackedModel {
    let base = hanging_beam(0.0);
    let springs: Vec<([u32; 2], f64, f64)> = base
        .springs()
        .iter()
        .map(|s| {
            let stiff = s.nodes.iter().all(|&i| base.rest[i as usize][0] <= 0.025);
            let k = if stiff {
                s.stiffness * contrast
            } else {
                s.stiffness
            };
            (s.nodes, k, s.damping)
        })
        .collect();
    let mut model =
        PackedModel::from_springs(base.rest.clone(), base.mass.clone(), &springs).unwrap();
    model.fixed = base.fixed.clone();
    model.gravity = base.gravity;
    model.mass_damping = base.mass_damping;
    model
}

#[test]
fn a_stiffness_contrast_keeps_float32_on_float64_where_the_soft_part_runs_far_below_its_bound() {
    let model = stiffness_contrast(1e4);
    let bound = stable_time_step(&model);
    // The soft half's own bound is about 100 times the global one (sqrt(10^4)).
    let soft = (0..model.node_count())
        .filter(|&i| model.rest[i][0] > 0.03 && !model.fixed[i])
        .map(|i| bound.per_node[i])
        .fold(f64::INFINITY, f64::min);
    assert!(soft > 50.0 * bound.dt, "{soft} against {}", bound.dt);
    for integrator in [Integrator::Verlet, Integrator::SymplecticEuler] {
        let report = model_accuracy(
            "stiffness contrast",
            &model,
            integrator,
            0.04,
            &options(vec![EngineKind::Reference, EngineKind::Fast], vec![0.9]),
            |_| {},
        )
        .unwrap();
        let checked = assert_float32_follows_float64(&report, &format!("{integrator:?}"), false);
        assert_eq!(checked, 1);
        // Nothing to warn about: float32 does not lose precision there.
        let mut config = SimConfig::new(0.9 * bound.dt);
        config.integrator = integrator;
        let sim = Simulation::new(model.clone(), EngineKind::Fast, config).unwrap();
        assert_eq!(sim.engine_note(), None);
    }
}

#[test]
fn a_node_far_below_its_own_bound_gets_a_note_though_the_step_is_near_the_global_bound() {
    // A 10^10 contrast: at 0.9 of the global bound the soft half runs at about 1e-5 of its own.
    let model = stiffness_contrast(1e10);
    let bound = stable_time_step(&model);
    let worst = bound
        .per_node
        .iter()
        .filter(|h| h.is_finite())
        .fold(0.0f64, |a, &h| a.max(h));
    assert!(0.9 * bound.dt / worst < FLOAT32_NODE_FRACTION);
    let note = |kind, integrator| {
        let mut config = SimConfig::new(0.9 * bound.dt);
        config.integrator = integrator;
        Simulation::new(model.clone(), kind, config)
            .unwrap()
            .engine_note()
            .map(str::to_string)
    };
    for integrator in [Integrator::Verlet, Integrator::SymplecticEuler] {
        let n = note(EngineKind::Fast, integrator).expect("a note");
        assert!(n.contains("of its own stable bound"), "{n}");
        assert_eq!(note(EngineKind::Reference, integrator), None);
    }
    // The same steps without the contrast: every node near its bound, nothing to say.
    let plain = hanging_beam(0.0);
    let mut config = SimConfig::new(0.9 * stable_time_step(&plain).dt);
    config.integrator = Integrator::Verlet;
    let sim = Simulation::new(plain, EngineKind::Fast, config).unwrap();
    assert_eq!(sim.engine_note(), None);
}

/// Runs `steps` steps of the fast engine on a pool of `threads` threads.
#[cfg(feature = "parallel")]
fn fast_on_threads(
    model: &PackedModel,
    integrator: Integrator,
    threads: usize,
    steps: u64,
) -> Vec<[f64; 3]> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut config = SimConfig::new(0.5 * stable_time_step(model).dt);
        config.integrator = integrator;
        let mut sim = Simulation::new(model.clone(), EngineKind::Fast, config).unwrap();
        sim.run(steps).unwrap();
        let mut state = sim.positions();
        state.extend(sim.velocities());
        state
    })
}

#[cfg(feature = "parallel")]
#[test]
fn the_fast_engine_is_bit_identical_on_one_and_two_threads() {
    // 3,321 nodes: blocks of 1,024 nodes go to both threads.
    // Springs of the elastic material (constants per end) and of one material (kept once).
    let mesh = beam(0.1, 0.02, 0.02, 40, 8).unwrap();
    let materials = [
        Material::elastic(50e3, 0.25, 1000.0),
        Material::springs(500.0, 1e-3),
    ];
    for (damping, mut material) in [0.0, SPRING_DAMPING]
        .into_iter()
        .flat_map(|c| materials.map(move |m| (c, m)))
    {
        if damping > 0.0 {
            material.damping = SpringDamping::Absolute(damping);
        }
        let mut config = ModelConfig::new(material);
        config.gravity = [0.0, 0.0, -9.81];
        config.mass_damping = 60.0;
        config.fixed.push(FixedSelector::Plane {
            point: [0.0; 3],
            normal: [1.0, 0.0, 0.0],
            tolerance: 1e-9,
        });
        let model = SpringModel::build(&mesh, &config)
            .unwrap()
            .pack(&mesh)
            .unwrap();
        assert!(model.node_count() > 2048, "{} nodes", model.node_count());
        for integrator in [Integrator::Verlet, Integrator::SymplecticEuler] {
            let one = fast_on_threads(&model, integrator, 1, 300);
            let two = fast_on_threads(&model, integrator, 2, 300);
            let moved = one.iter().any(|x| x.iter().any(|c| *c != 0.0));
            assert!(moved);
            let differ = one
                .iter()
                .zip(&two)
                .filter(|(a, b)| a.map(f64::to_bits) != b.map(f64::to_bits))
                .count();
            assert_eq!(differ, 0, "damping {damping}, {material:?}, {integrator:?}");
        }
    }
}
