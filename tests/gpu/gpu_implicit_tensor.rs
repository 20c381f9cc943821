//! Backward Euler with the tensor-mass force model on the GPU layouts: the implicit solve reads
//! the constant tensor-mass blocks in its setup and product (`shaders/implicit_tensor.wgsl`).
//! The step equals its CPU twin (`twin::implicit_tensor`) bit for bit on lavapipe, follows the
//! float64 reference engine's backward Euler step, and goes on through cuts as an engine built
//! afresh from the cut model.

use crate::common;
use crate::gpu_tensor_mass::{config, jittered_box, random_state};
use lancet::engine::gpu::GpuEngine;
use lancet::engine::{Engine, ForceModelKind, Integrator, SimConfig};
use lancet::layout::LayoutKind;
use lancet::twin::implicit_tensor as twin;
use rstest::rstest;

/// Backward Euler at `times` the explicit bound of the tensor-mass model.
fn implicit(model: &lancet::model::PackedModel, times: f64) -> SimConfig {
    config(model, Integrator::BackwardEuler, times)
}

/// Each layout's tensor-mass implicit step equals the twin stepper (state, and iterations per
/// solve where the device rounds as the CPU), damped (the damping blocks in the system) and
/// undamped, at ten times the explicit bound: a step no explicit integrator survives.
#[rstest]
fn the_tensor_mass_implicit_step_equals_its_twin(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
    #[values(true, false)] damped: bool,
) {
    let Some(ctx) = common::gpu() else { return };
    let model = jittered_box(17, damped);
    let mut gpu = GpuEngine::with_context(ctx, &model, implicit(&model, 10.0), kind).unwrap();
    let (x, v) = random_state(&model, 19);
    gpu.set_state(&x, &v);
    let start = gpu.raw_state().unwrap();
    let blocks = gpu
        .tensor_mass()
        .expect("a tensor-mass engine")
        .blocks()
        .clone();
    assert_eq!(blocks.damped, damped);
    let p = gpu.solve_params().expect("an implicit engine");
    assert_eq!(p.damped, damped, "the solve reads the damping blocks");
    let (layout, inv_mass) = (gpu.layout().clone(), gpu.inv_mass().to_vec());
    let (mut cur, mut vel) = start.clone();
    let mut iterations = Vec::new();
    let steps = 4;
    for _ in 0..steps {
        let (next, v, s) = twin::implicit_step_cpu(&p, &blocks, &layout, &inv_mass, &cur, &vel);
        (cur, vel) = (next, v);
        iterations.push(s.iterations);
    }
    gpu.step(steps as u32);
    let got = gpu.raw_state().unwrap();
    let what = format!("{kind:?} damped={damped}");
    common::assert_twin(&got.0, &cur, &start.0, steps, &what);
    common::assert_twin(&got.1, &vel, &start.1, steps, &what);
    let stats = gpu.solver_stats().unwrap();
    assert_eq!(stats.solves, steps as u64);
    if common::rounds_like_cpu() {
        let sum: u64 = iterations.iter().map(|&i| i as u64).sum();
        assert_eq!(stats.iterations, sum, "{what}: {iterations:?}");
    }
    assert!(
        iterations.iter().all(|&i| i > 1),
        "{what}: {iterations:?}: each solve iterated"
    );
    assert!(cur != start.0, "the state moved");
}

/// The GPU's tensor-mass backward Euler in every layout follows the float64 reference engine's
/// (20 steps at ten times the explicit bound, damped, under gravity from a random state)
/// within the solver's tolerance: both solves stop at a relative residual of 1e-5 (the GPU's
/// in float32, from zero; the reference's from the last step's change), and the displacements
/// agree to 1e-5 of their norm (2.7e-6 on lavapipe; leaving the damping blocks out of the
/// product gives 3.3e-5). The reference's springs under the same integrator are far off, so
/// the tensors are what is solved for.
#[rstest]
fn gpu_tensor_mass_backward_euler_follows_the_float64_reference(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] layout: LayoutKind,
) {
    let Some(_) = common::gpu() else { return };
    let model = jittered_box(23, true);
    let config = implicit(&model, 10.0);
    let (x, v) = random_state(&model, 29);
    let (err, apart) = crate::fem_gpu_checks::against_the_reference(
        &model,
        config,
        (&x, &v),
        layout,
        20,
        ForceModelKind::Springs,
    );
    eprintln!("{layout:?}: gpu {err:e}, springs {apart:e}");
    assert!(err < 1e-5, "{layout:?}: relative L2 error {err:e}");
    assert!(
        apart > 100.0 * err.max(1e-6),
        "springs {apart:e}, gpu {err:e}"
    );
}

/// Cuts through a tensor-mass model under backward Euler on the GPU: the world's checks after
/// every cut, then the cut engine steps as one built afresh from the cut model
/// (`fem_gpu_checks::cut_model_equals_a_rebuilt_one`), the implicit solve rebound to the
/// patched blocks. On the edge layout only, whose solve has the most to follow (the records'
/// blocks, the incidence rows, the per-record product values sized from the records): the
/// blocks' patching in every layout is checked under the explicit integrators
/// (`gpu_tensor_mass.rs`), and an implicit cut costs ten times an explicit one here.
#[test]
fn a_cut_gpu_tensor_mass_implicit_engine_equals_a_rebuilt_one() {
    crate::fem_gpu_checks::cut_model_equals_a_rebuilt_one(
        ForceModelKind::TensorMass,
        LayoutKind::Edges,
        lancet::cut::CutMethod::Subdivide,
        Integrator::BackwardEuler,
    );
}

/// `lancet bench --force-model tensor-mass|corotational --integrator backward-euler` times the fast engine
/// and the GPU layouts, the edge layout's float-atomic variant too where the device has float
/// atomics (with their conjugate-gradient iterations per step, within the solver's tolerance
/// of the float64 reference), and skips, with its reason, the rows that cannot run it: the
/// fixed-point edge variant's.
#[rstest]
fn the_bench_times_finite_elements_under_backward_euler_on_the_gpu_layouts(
    #[values(ForceModelKind::TensorMass, ForceModelKind::Corotational)] model: ForceModelKind,
) {
    use lancet::engine::EngineKind;
    use lancet::layout::edges::Accumulation;
    use lancet::report::bench::{run_bench, BenchMesh, BenchOptions};
    let Some(ctx) = common::gpu() else { return };
    let float = ctx
        .device
        .features()
        .contains(wgpu::Features::SHADER_FLOAT32_ATOMIC);
    let opts = BenchOptions {
        engines: vec![EngineKind::Fast, EngineKind::Gpu],
        layouts: vec![
            LayoutKind::Connectivity,
            LayoutKind::Valence,
            LayoutKind::Edges,
        ],
        accumulations: vec![
            Accumulation::Gather,
            Accumulation::AtomicFloat,
            Accumulation::AtomicFixed,
        ],
        steps: 4,
        chunk: 2,
        integrator: Integrator::BackwardEuler,
        force_model: model,
        ..BenchOptions::default()
    };
    let bw = lancet::report::bandwidth::stream_triad(1 << 16, 1);
    let report = run_bench(&[BenchMesh::Cube(3)], &opts, &bw, || None).unwrap();
    let rows: Vec<_> = report
        .rows
        .iter()
        .map(|r| (r.layout.clone(), r.accumulation.clone()))
        .collect();
    let mut want = vec![
        (None, None),
        (Some("connectivity".to_string()), None),
        (Some("valence".to_string()), None),
        (Some("edges".to_string()), Some("gather".to_string())),
    ];
    if float {
        want.push((Some("edges".to_string()), Some("atomic-float".to_string())));
    }
    assert_eq!(rows, want, "{:?}", report.skipped);
    for r in &report.rows {
        assert_eq!(r.force_model, model.to_string());
        let its = r.cg_iterations_per_step.expect("an implicit row");
        assert!(its >= 1.0, "{r:?}");
        assert!(r.error_vs_reference < 1e-3, "{r:?}");
    }
    assert!(
        report
            .skipped
            .iter()
            .any(|s| s.starts_with("gpu atomic-fixed edge rows skipped")),
        "{:?}",
        report.skipped
    );
}
