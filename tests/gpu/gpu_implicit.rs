//! The implicit step on the device (linearised backward Euler, block-Jacobi conjugate
//! gradients gathered over the connectivity table and the valence buckets, or on the edge
//! layout a spring pass and a gather): each pass equals its CPU twin on random inputs, the
//! whole step equals the twin stepper and follows the float64 reference engine, and it goes on
//! through cut-like patches exactly as an engine rebuilt on the changed model.

use crate::{common, models};
use lancet::engine::gpu::implicit::SolvePass;
use lancet::engine::gpu::GpuEngine;
use lancet::engine::reference::ReferenceEngine;
use lancet::engine::{Engine, GpuOptions, Integrator, SimConfig};
use lancet::layout::edges::{Accumulation, EdgeLayout};
use lancet::layout::{LayoutKind, PackedLayout, Slot};
use lancet::model::{stable_time_step, PackedModel};
use lancet::physics::SolverSettings;
use lancet::twin::implicit_solve::{self as twin, status, Scalars, SolveVectors};
use lancet::Error;
use models::{fresh, random_diff, random_model, random_state, Rng};
use rstest::rstest;

type Raw = (Vec<[f32; 4]>, Vec<[f32; 4]>);

fn implicit(dt: f64) -> SimConfig {
    SimConfig {
        integrator: Integrator::BackwardEuler,
        ..SimConfig::new(dt)
    }
}

/// Ten times the explicit stable bound: a step no explicit integrator survives.
fn stiff_dt(model: &PackedModel) -> f64 {
    10.0 * stable_time_step(model).dt
}

/// Each node's slots in the order the device walks them.
fn rows(engine: &GpuEngine) -> Vec<Vec<Slot>> {
    twin::rows(engine.layout()).expect("every layout has rows")
}

/// The edge layout of `engine`, if it runs one.
fn edges(engine: &GpuEngine) -> Option<&EdgeLayout> {
    match engine.layout() {
        PackedLayout::Edges(e) => Some(e),
        _ => None,
    }
}

/// `steps` twin steps from `raw`, with the iterations of each solve.
fn twin_steps(engine: &GpuEngine, raw: Raw, steps: usize) -> (Raw, Vec<u32>) {
    let p = engine.solve_params().unwrap();
    let (rows, inv_mass) = (rows(engine), engine.inv_mass().to_vec());
    let (mut cur, mut vel) = raw;
    let mut iterations = Vec::new();
    for _ in 0..steps {
        let (next, v, s) = match edges(engine) {
            Some(e) => twin::implicit_step_edges_cpu(&p, e, &inv_mass, &cur, &vel),
            None => twin::implicit_step_cpu(&p, &rows, &inv_mass, &cur, &vel),
        };
        (cur, vel) = (next, v);
        iterations.push(s.iterations);
    }
    ((cur, vel), iterations)
}

fn engine(model: &PackedModel, config: SimConfig, kind: LayoutKind) -> GpuEngine {
    GpuEngine::with_context(common::gpu().unwrap(), model, config, kind).unwrap()
}

/// Random vec4s with magnitudes about `scale`.
fn random_vecs(rng: &mut Rng, n: usize, scale: f64) -> Vec<[f32; 4]> {
    (0..n)
        .map(|_| {
            [0, 1, 2, 3].map(|c| {
                if c == 3 {
                    0.0
                } else {
                    ((rng.next() - 0.5) * scale) as f32
                }
            })
        })
        .collect()
}

/// Random solver vectors and scalars of a running solve (positive `rz`, `b_norm`).
fn random_vectors(rng: &mut Rng, n: usize, groups: usize) -> SolveVectors {
    let minv = (0..n)
        .map(|_| {
            let d = random_vecs(rng, 2, 1.0);
            // A symmetric block near 50 times the identity (an inverse mass of 20 g).
            [
                [50.0 + d[0][0], d[0][1], d[0][2], 50.0 + d[1][0]],
                [d[1][1], 50.0 + d[1][2], 0.0, 0.0],
            ]
        })
        .collect();
    SolveVectors {
        y: random_vecs(rng, n, 1e-2),
        r: random_vecs(rng, n, 1e-4),
        z: random_vecs(rng, n, 1e-2),
        p: random_vecs(rng, n, 1e-2),
        ap: random_vecs(rng, n, 1e-4),
        minv,
        scalars: Scalars {
            rz: (1e-6 * (1.0 + rng.next())) as f32,
            pap: 0.0,
            step: (0.5 + rng.next()) as f32,
            beta: (0.1 + 0.5 * rng.next()) as f32,
            b_norm: (1e-4 * (1.0 + rng.next())) as f32,
            residual: 1.0,
            status: status::RUNNING,
            iterations: 3,
        },
        partials: (0..groups)
            .map(|_| [(1e-8 * rng.next()) as f32, (1e-8 * rng.next()) as f32])
            .collect(),
    }
}

/// Bit for bit where the device rounds like the CPU, else within 1e-5 of the largest
/// magnitude.
#[track_caller]
fn assert_same(got: &[[f32; 4]], want: &[[f32; 4]], what: &str) {
    let zeros = vec![[0.0f32; 4]; want.len()];
    common::assert_twin(got, want, &zeros, 1, what);
}

#[track_caller]
fn assert_same_scalars(got: &Scalars, want: &Scalars, what: &str) {
    let f = |s: &Scalars| [s.rz, s.pap, s.step, s.beta, s.b_norm, s.residual];
    assert_eq!(
        (got.status, got.iterations),
        (want.status, want.iterations),
        "{what}: status"
    );
    if common::rounds_like_cpu() {
        assert_eq!(
            f(got).map(f32::to_bits),
            f(want).map(f32::to_bits),
            "{what}: {got:?} != {want:?}"
        );
    } else {
        for (g, w) in f(got).iter().zip(f(want)) {
            assert!(
                (g - w).abs() <= 1e-5 * w.abs(),
                "{what}: {got:?} != {want:?}"
            );
        }
    }
}

fn assert_same_vectors(got: &SolveVectors, want: &SolveVectors, what: &str) {
    let flat = |m: &[[[f32; 4]; 2]]| m.iter().flatten().copied().collect::<Vec<_>>();
    for (name, g, w) in [
        ("y", &got.y, &want.y),
        ("r", &got.r, &want.r),
        ("z", &got.z, &want.z),
        ("p", &got.p, &want.p),
        ("A p", &got.ap, &want.ap),
    ] {
        assert_same(g, w, &format!("{what}: {name}"));
    }
    assert_same(
        &flat(&got.minv),
        &flat(&want.minv),
        &format!("{what}: inverse diagonal"),
    );
    let pairs = |v: &[[f32; 2]]| v.iter().map(|p| [p[0], p[1], 0.0, 0.0]).collect::<Vec<_>>();
    assert_same(
        &pairs(&got.partials),
        &pairs(&want.partials),
        &format!("{what}: partial sums"),
    );
    assert_same_scalars(&got.scalars, &want.scalars, what);
}

/// Every pass of the solve, run alone on the device from random vectors and a random state,
/// equals its twin run on the same inputs.
#[rstest]
fn each_solve_pass_equals_its_twin_on_random_inputs(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    if common::gpu().is_none() {
        return;
    }
    let model = random_model(7, true);
    let mut gpu = engine(&model, implicit(stiff_dt(&model)), kind);
    let (x, v) = random_state(&model, 7);
    gpu.set_state(&x, &v);
    let (cur, vel) = gpu.raw_state().unwrap();
    let (rows, inv_mass) = (rows(&gpu), gpu.inv_mass().to_vec());
    let p = gpu.solve_params().unwrap();
    let n = cur.len();
    assert!(
        n > 64,
        "more than one workgroup: the second reduction level adds partials"
    );
    let mut rng = Rng(99);
    for pass in [
        SolvePass::Setup,
        SolvePass::Start,
        SolvePass::Multiply,
        SolvePass::StepLength,
        SolvePass::Update,
        SolvePass::Residual,
        SolvePass::Direction,
        SolvePass::Finish,
    ] {
        let mut input = random_vectors(&mut rng, n, n.div_ceil(64));
        if pass == SolvePass::Finish {
            input.scalars.status = status::CONVERGED;
        }
        gpu.set_solve_vectors(&input).unwrap();
        if pass == SolvePass::Multiply {
            // A no-op on the node-centric layouts.
            gpu.run_solve_pass(SolvePass::SpringMultiply).unwrap();
        }
        gpu.run_solve_pass(pass).unwrap();
        let got = gpu.solve_vectors().unwrap();
        let mut want = input.clone();
        match pass {
            SolvePass::Setup => {
                want = twin::setup_cpu(&p, &rows, &inv_mass, &cur, &vel);
                // Setup leaves the scalars to `start` and `A p` to `multiply`.
                want.scalars = input.scalars;
                want.ap = input.ap.clone();
            }
            SolvePass::Start => twin::start_cpu(&p, &mut want),
            SolvePass::SpringMultiply | SolvePass::SetupRecords => {
                unreachable!("not run alone here")
            }
            SolvePass::Multiply => match edges(&gpu) {
                // The spring pass and the gather, run one after the other on the device too.
                Some(e) => {
                    let values = twin::spring_multiply_cpu(&p, e, &cur, &want, &[]);
                    twin::gather_multiply_cpu(&p, e, &inv_mass, &values, &mut want);
                }
                None => twin::multiply_cpu(&p, &rows, &inv_mass, &cur, &mut want),
            },
            SolvePass::StepLength => twin::step_length_cpu(&mut want),
            SolvePass::Update => twin::update_cpu(&mut want),
            SolvePass::Residual => twin::residual_cpu(&p, &mut want),
            SolvePass::Direction => twin::direction_cpu(&mut want),
            SolvePass::Finish => {
                let (next, v) = twin::finish_cpu(&p, &inv_mass, &cur, &vel, &want).unwrap();
                let (gn, gv) = gpu.finished_state().unwrap();
                assert_same(&gn, &next, "finish: displacements");
                assert_same(&gv, &v, "finish: velocities");
                assert!(
                    next.iter().zip(&cur).any(|(a, b)| a != b),
                    "the state moved"
                );
            }
        }
        assert_same_vectors(&got, &want, &format!("{pass:?}"));
        if pass != SolvePass::Finish {
            assert_ne!(got, input, "{pass:?} changed something");
        }
    }
}

/// Once the solve has ended, every pass leaves the vectors as they are and `finish` writes
/// the step: what lets the host record iterations past convergence.
#[test]
fn passes_do_nothing_once_the_solve_has_ended() {
    if common::gpu().is_none() {
        return;
    }
    let model = random_model(8, true);
    let gpu = engine(&model, implicit(stiff_dt(&model)), LayoutKind::Connectivity);
    let n = gpu.layout().node_slots();
    let mut input = random_vectors(&mut Rng(5), n, n.div_ceil(64));
    input.scalars.status = status::CAPPED;
    gpu.set_solve_vectors(&input).unwrap();
    for pass in [
        SolvePass::Multiply,
        SolvePass::StepLength,
        SolvePass::Update,
        SolvePass::Residual,
        SolvePass::Direction,
    ] {
        gpu.run_solve_pass(pass).unwrap();
    }
    let got = gpu.solve_vectors().unwrap();
    assert_eq!(got.y, input.y);
    assert_eq!(got.p, input.p);
    assert_eq!(got.scalars, input.scalars);
}

/// The engine's implicit steps equal the twin stepper's (state and iterations per solve), at
/// ten times the explicit bound.
#[rstest]
fn the_implicit_step_equals_its_twin_stepper(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    if common::gpu().is_none() {
        return;
    }
    let model = random_model(11, true);
    let mut gpu = engine(&model, implicit(stiff_dt(&model)), kind);
    let (x, v) = random_state(&model, 11);
    gpu.set_state(&x, &v);
    let start = gpu.raw_state().unwrap();
    let steps = 6;
    let (want, iterations) = twin_steps(&gpu, start.clone(), steps);
    gpu.step(steps as u32);
    let got = gpu.raw_state().unwrap();
    common::assert_twin(&got.0, &want.0, &start.0, steps, "displacements");
    common::assert_twin(&got.1, &want.1, &start.1, steps, "velocities");
    let stats = gpu.solver_stats().unwrap();
    assert_eq!(stats.solves, steps as u64);
    if common::rounds_like_cpu() {
        assert_eq!(
            stats.iterations,
            iterations.iter().map(|&i| i as u64).sum::<u64>()
        );
        assert_eq!(stats.max_iterations, *iterations.iter().max().unwrap());
    }
    assert!(
        iterations.iter().all(|&i| i > 1),
        "{iterations:?}: each solve iterated"
    );
}

/// The float32 device step follows the float64 reference implicit step: positions within
/// 2e-4 of the motion over 20 steps at ten times the explicit bound (each solve stops at a
/// relative residual of 1e-5, in float32), and as many iterations per solve give or take one.
#[rstest]
fn the_implicit_step_follows_the_float64_reference(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    if common::gpu().is_none() {
        return;
    }
    let model = random_model(12, true);
    let config = implicit(stiff_dt(&model));
    let mut gpu = engine(&model, config, kind);
    let mut reference = ReferenceEngine::new(&model, config);
    let (x, v) = random_state(&model, 12);
    gpu.set_state(&x, &v);
    reference.set_state(&x, &v);
    let steps = 20;
    gpu.step(steps);
    reference.step(steps);
    let (got, want) = (gpu.positions(), reference.positions());
    let motion = want
        .iter()
        .zip(&x)
        .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
        .fold(0.0, f64::max);
    let error = got
        .iter()
        .zip(&want)
        .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
        .fold(0.0, f64::max);
    eprintln!(
        "device against reference: {:e} of the motion {motion:e}",
        error / motion
    );
    assert!(motion > 1e-4, "the model moved");
    assert!(error <= 2e-4 * motion, "{:e} of the motion", error / motion);
    let (g, r) = (
        gpu.solver_stats().unwrap(),
        reference.solver_stats().unwrap(),
    );
    eprintln!("iterations: device {g:?}, reference {r:?}");
    assert_eq!(g.solves, r.solves);
    assert!(
        (g.mean_iterations() - r.mean_iterations()).abs() <= 1.0,
        "{g:?} {r:?}"
    );
    assert_eq!(g.capped, 0);
}

/// The edge layout's fixed-point variant (`gpu_implicit_atomic.rs` runs the float one), and
/// more Newton iterations than one, are refused with an error that says what to use instead.
#[test]
fn what_the_device_cannot_solve_yet_is_refused_clearly() {
    if common::gpu().is_none() {
        return;
    }
    let model = random_model(13, false);
    let atomic = GpuOptions {
        accumulation: Accumulation::AtomicFixed,
        ..GpuOptions::from(LayoutKind::Edges)
    };
    let err = GpuEngine::with_context(common::gpu().unwrap(), &model, implicit(1e-3), atomic)
        .err()
        .expect("refused");
    assert!(
        matches!(&err, Error::Unsupported(m) if m.contains("gather")),
        "{err}"
    );
    let mut config = implicit(1e-3);
    config.solver = SolverSettings {
        newton_iterations: 2,
        ..SolverSettings::default()
    };
    let err = GpuEngine::with_context(
        common::gpu().unwrap(),
        &model,
        config,
        LayoutKind::Connectivity,
    )
    .err()
    .expect("refused");
    assert!(
        matches!(&err, Error::Unsupported(m) if m.contains("newton_iterations")),
        "{err}"
    );
}

/// Through cut-like random patches the implicit engine goes on: after each, its steps equal an
/// engine's built from scratch on the changed model in the same arrangement (bit for bit: the
/// product reads the same arrays) and the patched layout's twin stepper.
#[rstest]
fn the_implicit_engine_steps_through_patches_like_a_rebuild(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    if common::gpu().is_none() {
        return;
    }
    let mut model = random_model(41, true);
    let config = implicit(stiff_dt(&model));
    let mut gpu = GpuEngine::with_context(
        common::gpu().unwrap(),
        &model,
        config,
        GpuOptions::from(kind),
    )
    .unwrap();
    let (x, v) = random_state(&model, 41);
    gpu.set_state(&x, &v);
    gpu.step(3);
    for round in 0..4 {
        let diff = random_diff(&model, 100 + round);
        let mut next = model.clone();
        next.apply(&diff).unwrap();
        gpu.patch(&next, &diff).unwrap();
        model = next;
        let start = gpu.raw_state().unwrap();
        let (want, _) = twin_steps(&gpu, start.clone(), 5);
        let mut rebuilt = GpuEngine::with_layout(
            common::gpu().unwrap(),
            &model,
            config,
            fresh(&model, gpu.layout()),
            gpu.options().accumulation,
        )
        .unwrap();
        rebuilt.set_raw_state(&start.0, &start.1).unwrap();
        gpu.step(5);
        rebuilt.step(5);
        let (got, other) = (gpu.raw_state().unwrap(), rebuilt.raw_state().unwrap());
        let what = format!("round {round}");
        common::assert_twin(&got.0, &want.0, &start.0, 5, &what);
        common::assert_twin(&got.1, &want.1, &start.1, 5, &what);
        let bits = |r: &Raw| -> Vec<u32> {
            r.0.iter()
                .chain(&r.1)
                .flatten()
                .map(|x| x.to_bits())
                .collect()
        };
        assert_eq!(bits(&got), bits(&other), "{what}: patched != rebuilt");
        assert!(got.0.iter().flatten().all(|x| x.is_finite()));
    }
    assert_eq!(gpu.solver_stats().unwrap().solves, 3 + 4 * 5);
}

/// The edge layout's implicit step (spring pass and gather) follows the connectivity layout's
/// (a gather over each node's slots) from the same state: the same system, summed in another
/// order (incidence rows against connectivity rows), so equal to float32 rounding amplified by
/// the solve: 1e-5 of the motion over 10 steps at ten times the bound, where a wrong sign or a
/// missing spring term is of the order of the motion itself.
#[test]
fn the_edge_layout_steps_like_the_connectivity_layout() {
    if common::gpu().is_none() {
        return;
    }
    let model = random_model(14, true);
    let config = implicit(stiff_dt(&model));
    let (x, v) = random_state(&model, 14);
    let run = |kind: LayoutKind| {
        let mut gpu = engine(&model, config, kind);
        gpu.set_state(&x, &v);
        gpu.step(10);
        (gpu.positions(), gpu.solver_stats().unwrap())
    };
    let ((edge, es), (conn, cs)) = (run(LayoutKind::Edges), run(LayoutKind::Connectivity));
    let max = |a: &[[f64; 3]], b: &[[f64; 3]]| {
        a.iter()
            .zip(b)
            .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs()))
            .fold(0.0, f64::max)
    };
    let (motion, error) = (max(&conn, &x), max(&edge, &conn));
    eprintln!(
        "edges against connectivity: {:e} of the motion {motion:e}",
        error / motion
    );
    assert!(motion > 1e-4, "the model moved");
    assert!(error <= 1e-5 * motion, "{:e} of the motion", error / motion);
    assert_eq!(es.solves, cs.solves);
    assert!(
        (es.mean_iterations() - cs.mean_iterations()).abs() <= 1.0,
        "{es:?} {cs:?}"
    );
}
