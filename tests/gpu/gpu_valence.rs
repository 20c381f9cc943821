//! The valence pass on the GPU over an irregular model (many buckets, a bucket of springless
//! nodes): it equals its CPU twin, and the engine built on it agrees with the float64 reference
//! and with the connectivity layout. `tests/gpu_layouts.rs` runs the same checks on a regular
//! box for every layout.

use crate::{common, models};
use lancet::engine::gpu::{step_params, GpuEngine};
use lancet::engine::{Engine, EngineKind, Integrator, SimConfig, Simulation};
use lancet::layout::valence::ValenceLayout;
use lancet::layout::{LayoutKind, NodeOrder};
use lancet::model::{stable_time_step, PackedModel};
use models::{random_model, random_state};
use rstest::rstest;

/// `|u - u_ref| / |u_ref|` over all nodes, `u` being displacements from `rest`.
fn relative_l2(rest: &[[f64; 3]], x: &[[f64; 3]], x_ref: &[[f64; 3]]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for ((r, a), b) in rest.iter().zip(x).zip(x_ref) {
        for c in 0..3 {
            num += (a[c] - b[c]).powi(2);
            den += (b[c] - r[c]).powi(2);
        }
    }
    (num / den).sqrt()
}

/// Largest displacement component of `x` from `model`'s rest shape.
fn motion(model: &PackedModel, x: &[[f64; 3]]) -> f64 {
    x.iter()
        .zip(&model.rest)
        .flat_map(|(x, r)| (0..3).map(move |c| (x[c] - r[c]).abs()))
        .fold(0.0, f64::max)
}

#[rstest]
fn valence_pass_equals_its_cpu_twin_on_an_irregular_model(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
    #[values(false, true)] damped: bool,
    #[values(1, 50)] steps: u32,
) {
    let Some(ctx) = common::gpu() else { return };
    let model = random_model(21, damped);
    let layout = ValenceLayout::new(&model, &NodeOrder::locality(&model));
    assert!(layout.buckets.len() >= 5 && layout.buckets[0].valence == 0);
    let dt = 0.5 * stable_time_step(&model).dt;
    let config = SimConfig {
        integrator,
        ..SimConfig::new(dt)
    };
    let p = step_params(&model, config);
    let (x0, v0) = random_state(&model, 22);
    let mut engine = GpuEngine::with_context(ctx, &model, config, LayoutKind::Valence).unwrap();
    engine.set_state(&x0, &v0);
    // The twin starts from the state as the engine rounds it on upload.
    let n = model.node_count();
    let (mut u, mut s) = (vec![[0.0f32; 4]; n], vec![[0.0f32; 4]; n]);
    for (new, &old) in layout.order.order.iter().enumerate() {
        let old = old as usize;
        if model.fixed[old] {
            continue;
        }
        for c in 0..3 {
            let d = x0[old][c] - model.rest[old][c];
            u[new][c] = d as f32;
            s[new][c] = match integrator {
                Integrator::Verlet => (v0[old][c] * dt) as f32,
                Integrator::SymplecticEuler | Integrator::BackwardEuler => v0[old][c] as f32,
            };
        }
    }
    let (u, _) = lancet::twin::steps(&p, (u, s), steps as usize, |p, u, s| {
        layout.step_cpu(p, u, s)
    });
    engine.step(steps);
    let gpu = engine.positions();
    let mut cpu = model.rest.clone();
    for (new, &old) in layout.order.order.iter().enumerate() {
        for c in 0..3 {
            cpu[old as usize][c] += u[new][c] as f64;
        }
    }
    let moved = motion(&model, &cpu);
    let worst = gpu
        .iter()
        .zip(&cpu)
        .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
        .fold(0.0, f64::max);
    eprintln!("{integrator:?} damped={damped} steps={steps}: worst {worst:e}, motion {moved:e}");
    assert!(moved > 1e-5, "the inputs must move the nodes ({moved:e})");
    // The same float32 operations in the same order; a device may still fuse a multiply-add
    // or round a square root differently, so allow a few float32 ulps of the motion per step.
    assert!(
        worst <= 1e-5 * moved * steps as f64,
        "gpu and cpu twin differ by {worst:e} (motion {moved:e})"
    );
}

#[rstest]
fn gpu_valence_engine_agrees_with_the_reference_and_the_connectivity_layout(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let Some(_) = common::gpu() else { return };
    let model = random_model(23, true);
    let dt = 0.8 * stable_time_step(&model).dt;
    let config = SimConfig {
        integrator,
        ..SimConfig::new(dt)
    };
    let steps = 200;
    let (x0, v0) = random_state(&model, 24);
    let run = |kind, layout: LayoutKind| {
        let mut sim = Simulation::with_gpu(model.clone(), kind, config, layout.into()).unwrap();
        sim.set_state(&x0, &v0).unwrap();
        sim.run(steps).unwrap();
        sim.positions()
    };
    let valence = run(EngineKind::Gpu, LayoutKind::Valence);
    let reference = run(EngineKind::Reference, LayoutKind::Connectivity);
    let connectivity = run(EngineKind::Gpu, LayoutKind::Connectivity);
    let err = relative_l2(&model.rest, &valence, &reference);
    let between = relative_l2(&model.rest, &valence, &connectivity);
    eprintln!("{integrator:?}: vs reference {err:e}, vs connectivity {between:e}");
    assert!(motion(&model, &reference) > 1e-5);
    // The float32 engines' bar against float64 (tests/engine_agreement.rs).
    assert!(err < 1e-3, "relative L2 against the reference {err:e}");
    // The same arithmetic per spring; the layouts number the nodes differently, so a node's
    // springs are summed in a different order: rounding-level differences only.
    assert!(
        between < 1e-5,
        "valence and connectivity differ by {between:e}"
    );
}

#[test]
fn a_model_without_springs_falls_freely_through_the_valence_pass() {
    let Some(ctx) = common::gpu() else { return };
    // Every node in the valence-0 bucket and no slots at all.
    let mut model = PackedModel::from_springs(
        vec![[0.0; 3], [0.01, 0.0, 0.0], [0.0, 0.02, 0.0]],
        vec![1e-3; 3],
        &[],
    )
    .unwrap();
    model.gravity = [0.5, -1.0, -9.81];
    let layout = ValenceLayout::new(&model, &NodeOrder::locality(&model));
    assert_eq!(layout.buckets.len(), 1);
    assert!(layout.slots.is_empty());
    let dt = 1e-3;
    let mut engine =
        GpuEngine::with_context(ctx, &model, SimConfig::new(dt), LayoutKind::Valence).unwrap();
    let steps = 20;
    engine.step(steps);
    // From rest, Verlet gives u_k = g h^2 k (k + 1) / 2.
    let (k, h2) = (steps as f64, (dt as f32 as f64).powi(2));
    for (x, r) in engine.positions().iter().zip(&model.rest) {
        for (c, g) in model.gravity.iter().enumerate() {
            let want = g * h2 * k * (k + 1.0) / 2.0;
            let got = x[c] - r[c];
            assert!(
                (got - want).abs() <= 1e-5 * want.abs(),
                "axis {c}: {got:e} vs {want:e}"
            );
        }
    }
}
