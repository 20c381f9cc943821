//! Backward Euler on the edge layout's float-atomic variant (springs): each spring's setup
//! terms and each iteration's products added to their ends' accumulators, no incidence table.
//! The device step follows its CPU twin (`twin::implicit_atomic`, one order of the adds)
//! within the solver's tolerance (float atomics add in any order, so the rounding and at
//! times the iteration count differ), the gather variant and the float64 reference; a cut
//! engine steps as a rebuilt one; the fixed-point variant is refused with the reason.

use crate::{common, models};
use lancet::engine::gpu::GpuEngine;
use lancet::engine::reference::ReferenceEngine;
use lancet::engine::{Engine, ForceModelKind, GpuOptions, Integrator, SimConfig};
use lancet::layout::edges::Accumulation;
use lancet::layout::{LayoutKind, PackedLayout};
use lancet::model::{stable_time_step, PackedModel};
use lancet::twin::implicit_atomic::implicit_step_atomic_cpu;
use lancet::Error;
use models::{random_model, random_state};
use rstest::rstest;

fn implicit(dt: f64) -> SimConfig {
    SimConfig {
        integrator: Integrator::BackwardEuler,
        ..SimConfig::new(dt)
    }
}

fn options(accumulation: Accumulation) -> GpuOptions {
    GpuOptions {
        layout: LayoutKind::Edges,
        accumulation,
    }
}

/// The float-atomic engine, or `None` (with a message) on a device without float atomics.
fn engine(model: &PackedModel, config: SimConfig) -> Option<GpuEngine> {
    let ctx = common::gpu()?;
    if !ctx
        .device
        .features()
        .contains(wgpu::Features::SHADER_FLOAT32_ATOMIC)
    {
        eprintln!("skipped: {} has no float atomics", ctx.describe());
        return None;
    }
    Some(GpuEngine::with_context(ctx, model, config, options(Accumulation::AtomicFloat)).unwrap())
}

/// The largest coordinate difference of `a` and `b`, and of `a` and `start` (also for the
/// finite elements' atomic steps, `gpu_implicit_atomic_fem.rs`).
pub(crate) fn apart(a: &[[f64; 3]], b: &[[f64; 3]], start: &[[f64; 3]]) -> (f64, f64) {
    let most = |p: &[[f64; 3]], q: &[[f64; 3]]| {
        p.iter()
            .zip(q)
            .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs()))
            .fold(0.0, f64::max)
    };
    (most(a, b), most(a, start))
}

/// Six steps at ten times the explicit bound equal the twin's (records in order) within the
/// solver's tolerance of the motion (each solve stops at a relative residual of 1e-5; the
/// device's adds round in another order); every solve iterated.
#[test]
fn the_atomic_implicit_step_follows_its_twin_stepper() {
    let model = random_model(11, true);
    let Some(mut gpu) = engine(&model, implicit(10.0 * stable_time_step(&model).dt)) else {
        return;
    };
    let (x, v) = random_state(&model, 11);
    gpu.set_state(&x, &v);
    let start = gpu.raw_state().unwrap();
    let p = gpu.solve_params().unwrap();
    let inv_mass = gpu.inv_mass().to_vec();
    let PackedLayout::Edges(layout) = gpu.layout().clone() else {
        panic!("the edge layout")
    };
    let steps = 6;
    let (mut cur, mut vel) = start.clone();
    let mut iterations = 0u64;
    for _ in 0..steps {
        let (next, w, s) = implicit_step_atomic_cpu(&p, &layout, &inv_mass, &cur, &vel);
        (cur, vel) = (next, w);
        assert!(s.iterations > 1, "each solve iterated");
        iterations += s.iterations as u64;
    }
    gpu.step(steps);
    let got = gpu.raw_state().unwrap();
    let d = common::relative_difference(&got.0, &cur, &start.0);
    assert!(d <= 1e-4, "device and twin differ by {d:e} of the motion");
    let stats = gpu.solver_stats().unwrap();
    assert_eq!(stats.solves, steps as u64);
    assert!(
        stats.iterations.abs_diff(iterations) <= steps as u64,
        "device {} iterations, twin {iterations}",
        stats.iterations
    );
    assert_eq!(stats.capped, 0);
}

/// Twenty steps at ten times the explicit bound follow the float64 reference (the gather's
/// bar, `gpu_implicit.rs`: 2e-4 of the motion) and the gather variant.
#[test]
fn the_atomic_implicit_step_follows_the_gather_and_the_float64_reference() {
    let model = random_model(12, true);
    let config = implicit(10.0 * stable_time_step(&model).dt);
    let Some(mut gpu) = engine(&model, config) else {
        return;
    };
    let mut gather = GpuEngine::new(&model, config, LayoutKind::Edges).unwrap();
    let mut reference = ReferenceEngine::new(&model, config);
    let (x, v) = random_state(&model, 12);
    gpu.set_state(&x, &v);
    gather.set_state(&x, &v);
    reference.set_state(&x, &v);
    for e in [&mut gpu as &mut dyn Engine, &mut gather, &mut reference] {
        e.step(20);
    }
    let got = gpu.positions();
    let (error, motion) = apart(&got, &reference.positions(), &x);
    assert!(motion > 1e-4, "the model moved");
    assert!(error <= 2e-4 * motion, "{:e} of the motion", error / motion);
    let (between, _) = apart(&got, &gather.positions(), &x);
    assert!(between <= 2e-4 * motion, "gather: {:e}", between / motion);
    assert!(gpu.describe().starts_with("gpu-edges-atomicfloat"));
}

/// Cuts through a spring model under backward Euler on the float-atomic variant: the world's
/// checks against a rebuild find nothing, and the cut engine steps as a rebuilt one does.
#[rstest]
fn a_cut_atomic_implicit_model_equals_a_rebuilt_one(
    #[values(lancet::cut::CutMethod::Separate, lancet::cut::CutMethod::Subdivide)]
    method: lancet::cut::CutMethod,
) {
    let model = random_model(1, false);
    if engine(&model, implicit(1e-3)).is_none() {
        return;
    }
    crate::fem_gpu_checks::cut_model_equals_a_rebuilt_one(
        ForceModelKind::Springs,
        options(Accumulation::AtomicFloat),
        method,
        Integrator::BackwardEuler,
    );
}

/// Backward Euler on the fixed-point accumulation is refused with the reason and what to use,
/// for springs and the finite elements alike; the finite elements run on the float atomics
/// (`gpu_implicit_atomic_fem.rs`).
#[rstest]
fn what_the_atomic_implicit_step_does_not_run_is_refused_clearly(
    #[values(ForceModelKind::Springs, ForceModelKind::TensorMass)] kind: ForceModelKind,
) {
    let Some(ctx) = common::gpu() else { return };
    let model = random_model(13, false);
    let config = SimConfig {
        force_model: kind,
        ..implicit(1e-3)
    };
    let err = GpuEngine::with_context(ctx, &model, config, options(Accumulation::AtomicFixed))
        .err()
        .expect("refused");
    assert!(
        matches!(&err, Error::Unsupported(m) if m.contains("fixed-point") && m.contains("atomic-float")),
        "{err}"
    );
    if let Some(gpu) = engine(&model, config) {
        assert!(
            gpu.describe().starts_with("gpu-edges-atomicfloat"),
            "{kind}"
        );
    }
}
