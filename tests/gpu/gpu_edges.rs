//! The edge layout's accumulation variants on the GPU: a step of each (spring pass + node pass)
//! equals its CPU twin on random inputs, the fixed-point variant bitwise and run to run, and the
//! engine in each variant agrees with the float64 reference.

use crate::{common, models};
use lancet::engine::gpu::{step_params, GpuEngine};
use lancet::engine::{Engine, EngineKind, GpuOptions, Integrator, SimConfig, Simulation};
use lancet::layout::edges::{Accumulation, EdgeLayout};
use lancet::layout::{LayoutKind, NodeOrder};
use lancet::model::{stable_time_step, PackedModel};
use lancet::report::bench::relative_l2;
use lancet::Error;
use models::{random_box as random_model, Rng};
use rstest::rstest;

/// Random positions (displacements of about 5% of a cell) and velocities, model order.
fn random_state(model: &PackedModel, seed: u64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let mut rng = Rng(seed);
    let mut x = model.rest.clone();
    let mut v = vec![[0.0; 3]; x.len()];
    for i in 0..x.len() {
        for c in 0..3 {
            x[i][c] += (rng.next() - 0.5) * 1e-3;
            v[i][c] = (rng.next() - 0.5) * 1e-1;
        }
    }
    (x, v)
}

/// The engine for `accumulation`, or `None` (with a message) for float atomics on a device
/// without them, after checking that the refusal is a clear error.
fn engine(model: &PackedModel, config: SimConfig, accumulation: Accumulation) -> Option<GpuEngine> {
    let ctx = common::gpu()?;
    let has_float_atomics = ctx
        .device
        .features()
        .contains(wgpu::Features::SHADER_FLOAT32_ATOMIC);
    let options = GpuOptions {
        layout: LayoutKind::Edges,
        accumulation,
    };
    match GpuEngine::with_context(ctx, model, config, options) {
        Ok(e) => Some(e),
        Err(Error::Unsupported(msg))
            if accumulation == Accumulation::AtomicFloat && !has_float_atomics =>
        {
            assert!(msg.contains("SHADER_FLOAT32_ATOMIC"), "{msg}");
            eprintln!("skipped: {msg}");
            None
        }
        Err(e) => panic!("{accumulation:?}: {e}"),
    }
}

#[rstest]
fn edge_variant_step_equals_its_cpu_twin_on_random_inputs(
    #[values(
        Accumulation::Gather,
        Accumulation::AtomicFixed,
        Accumulation::AtomicFloat
    )]
    accumulation: Accumulation,
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
    #[values(false, true)] damped: bool,
    #[values(1, 50)] steps: u32,
) {
    let model = random_model(7, damped);
    let dt = 0.5 * stable_time_step(&model).dt;
    let config = SimConfig {
        integrator,
        ..SimConfig::new(dt)
    };
    let Some(mut engine) = engine(&model, config, accumulation) else {
        return;
    };
    let layout = EdgeLayout::new(&model, NodeOrder::locality(&model));
    let fp = layout.fixed_point(&model);
    let p = step_params(&model, config);
    let (x, v) = random_state(&model, 11);
    engine.set_state(&x, &v);
    // The twin starts from the float32 state the engine stored (fixed nodes at rest).
    let order = &layout.order;
    let n = model.node_count();
    let (mut u, mut s) = (vec![[0.0f32; 4]; n], vec![[0.0f32; 4]; n]);
    for (new, &old) in order.order.iter().enumerate() {
        let old = old as usize;
        if model.fixed[old] {
            continue;
        }
        for c in 0..3 {
            let d = x[old][c] - model.rest[old][c];
            u[new][c] = d as f32;
            s[new][c] = match integrator {
                Integrator::Verlet => (v[old][c] * dt) as f32,
                Integrator::SymplecticEuler | Integrator::BackwardEuler => v[old][c] as f32,
            };
        }
    }
    let start = u.clone();
    let (u, _) = lancet::twin::steps(&p, (u, s), steps as usize, |p, u, s| {
        layout.step_variant_cpu(accumulation, p, &fp, u, s)
    });
    engine.step(steps);
    let gpu = engine.positions();
    let mut worst = 0.0f64;
    let mut motion = 0.0f64;
    for (new, &old) in order.order.iter().enumerate() {
        let old = old as usize;
        for c in 0..3 {
            let cpu = model.rest[old][c] + u[new][c] as f64;
            worst = worst.max((gpu[old][c] - cpu).abs());
            motion = motion.max((u[new][c] - start[new][c]).abs() as f64);
        }
    }
    eprintln!(
        "{accumulation:?} {integrator:?} damped={damped} steps={steps}: worst {worst:e}, \
         motion {motion:e}"
    );
    assert!(motion > 1e-6, "the inputs must move the nodes ({motion:e})");
    match accumulation {
        // Integer sums do not depend on the order of the atomic adds, and the float32 force
        // and integration arithmetic is the twin's: bitwise equal.
        // (On a device that fuses multiply-adds the forces round differently before they are
        // quantized: the tolerance below then applies.)
        Accumulation::AtomicFixed if common::rounds_like_cpu() => {
            assert_eq!(worst, 0.0, "fixed point differs from its twin")
        }
        // The twin sums in one fixed order; the device's order (gather: the same; float atomics:
        // any) may round differently. A few float32 ulps of the motion per step.
        _ => assert!(
            worst <= 1e-5 * motion * steps as f64,
            "{accumulation:?}: gpu and cpu twin differ by {worst:e} (motion {motion:e})"
        ),
    }
    assert!(!engine.fixed_point_overflowed().unwrap());
}

#[rstest]
fn gpu_edge_engine_agrees_with_the_float64_reference(
    #[values(
        Accumulation::Gather,
        Accumulation::AtomicFixed,
        Accumulation::AtomicFloat
    )]
    accumulation: Accumulation,
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let model = random_model(3, true);
    let dt = 0.8 * stable_time_step(&model).dt;
    let config = SimConfig {
        integrator,
        ..SimConfig::new(dt)
    };
    // Probe for float atomics first (skips with a message without them).
    if engine(&model, config, accumulation).is_none() {
        return;
    }
    let options = GpuOptions {
        layout: LayoutKind::Edges,
        accumulation,
    };
    let mut gpu = Simulation::with_gpu(model.clone(), EngineKind::Gpu, config, options).unwrap();
    let mut reference = Simulation::new(model.clone(), EngineKind::Reference, config).unwrap();
    gpu.run(300).unwrap();
    reference.run(300).unwrap();
    let err = relative_l2(&model.rest, &gpu.positions(), &reference.positions());
    eprintln!("{accumulation:?} {integrator:?}: relative L2 {err:e}");
    // Same bar as the float32 CPU engine (tests/engine_agreement.rs).
    assert!(err < 1e-3, "relative L2 displacement error {err:e}");
    let name = match accumulation {
        Accumulation::Gather => "gpu-edges on".to_string(),
        a => format!("gpu-edges-{a:?}").to_lowercase(),
    };
    assert!(
        gpu.engine_name().starts_with(&name),
        "{}",
        gpu.engine_name()
    );
}

#[test]
fn fixed_point_edge_engine_is_bitwise_deterministic_run_to_run() {
    let model = random_model(9, true);
    let config = SimConfig::new(0.8 * stable_time_step(&model).dt);
    let (x, v) = random_state(&model, 4);
    let run = || {
        let mut e = engine(&model, config, Accumulation::AtomicFixed)?;
        e.set_state(&x, &v);
        e.step(100);
        Some(e.positions())
    };
    let Some(a) = run() else { return };
    let b = run().unwrap();
    assert_eq!(a, b);
}

#[test]
fn fixed_point_overflow_sets_the_flag_the_host_reads() {
    let model = random_model(2, false);
    let config = SimConfig::new(0.5 * stable_time_step(&model).dt);
    let Some(mut e) = engine(&model, config, Accumulation::AtomicFixed) else {
        return;
    };
    e.step(10);
    assert!(!e.fixed_point_overflowed().unwrap(), "ordinary motion fits");
    // Pull one free node a metre away (a hundred cells): its springs exceed the range.
    let i = model.fixed.iter().position(|f| !f).unwrap();
    let mut x = model.rest.clone();
    x[i][0] += 1.0;
    e.set_state(&x, &vec![[0.0; 3]; x.len()]);
    e.step(1);
    assert!(
        e.fixed_point_overflowed().unwrap(),
        "saturation must be reported"
    );
}
