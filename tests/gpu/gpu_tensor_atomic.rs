//! The finite elements on the edge layout's atomic variants: the tensor-mass record pass that
//! adds both end forces to the accumulators (fixed point, float atomics) equals its CPU twin
//! (`twin::tensor_atomic`) on a jittered box with random masses and a random state, bit for bit
//! in fixed point on lavapipe and within float32 rounding of the motion for float atomics
//! (whose order of adds varies); the atomic engines follow the gather variant and the float64
//! reference; the fixed point is sized for the tensors and reports saturation; a cut engine
//! steps as a rebuilt one does; corotational runs on the atomic variants as on the gather.

use crate::common;
use crate::gpu_tensor_mass::{config, jittered_box, random_state};
use lancet::engine::gpu::GpuEngine;
use lancet::engine::{Engine, ForceModelKind, GpuOptions, Integrator, SimConfig};
use lancet::layout::edges::Accumulation;
use lancet::layout::tensor_blocks::TensorBlocks;
use lancet::layout::{LayoutKind, PackedLayout};
use lancet::model::PackedModel;
use lancet::Error;
use rstest::rstest;

/// The edge layout with `accumulation`.
fn edges(accumulation: Accumulation) -> GpuOptions {
    GpuOptions {
        layout: LayoutKind::Edges,
        accumulation,
    }
}

/// The engine, or `None` (with a message) for float atomics on a device without them, after
/// checking that the refusal names the feature.
fn engine(model: &PackedModel, config: SimConfig, accumulation: Accumulation) -> Option<GpuEngine> {
    let ctx = common::gpu()?;
    let has = ctx
        .device
        .features()
        .contains(wgpu::Features::SHADER_FLOAT32_ATOMIC);
    match GpuEngine::with_context(ctx, model, config, edges(accumulation)) {
        Ok(e) => Some(e),
        Err(Error::Unsupported(m)) if accumulation == Accumulation::AtomicFloat && !has => {
            assert!(m.contains("SHADER_FLOAT32_ATOMIC"), "{m}");
            eprintln!("skipped: {m}");
            None
        }
        Err(e) => panic!("{accumulation:?}: {e}"),
    }
}

/// Each atomic variant's tensor-mass step equals its CPU twin after 1 and after 20 steps,
/// damped under Verlet (damping blocks, velocity differences) and undamped under symplectic
/// Euler: fixed point bit for bit where the device rounds like the CPU (integer sums do not
/// depend on the order of the adds), float atomics within a few float32 ulps of the motion per
/// step (the twin adds in one order, the device in any). No end force saturated.
#[rstest]
fn tensor_mass_atomic_passes_equal_their_cpu_twin(
    #[values(Accumulation::AtomicFixed, Accumulation::AtomicFloat)] accumulation: Accumulation,
    #[values((Integrator::Verlet, true), (Integrator::SymplecticEuler, false))] scheme: (
        Integrator,
        bool,
    ),
) {
    let (integrator, damped) = scheme;
    let model = jittered_box(7, damped);
    let Some(mut gpu) = engine(&model, config(&model, integrator, 0.5), accumulation) else {
        return;
    };
    let (x, v) = random_state(&model, 11);
    gpu.set_state(&x, &v);
    let start = gpu.raw_state().unwrap();
    let blocks: TensorBlocks = gpu.tensor_mass().expect("tensor-mass").blocks().clone();
    assert_eq!(blocks.damped, damped);
    let PackedLayout::Edges(layout) = gpu.layout().clone() else {
        panic!("the edge layout")
    };
    let fp = gpu.fixed_point();
    let p = gpu.step_params();
    let mut twin = start.clone();
    for steps in [1usize, 19] {
        twin = lancet::twin::steps(&p, twin, steps, |p, u, s| {
            blocks.step_atomic_cpu(accumulation, p, &layout, &fp, u, s)
        });
        gpu.step(steps as u32);
        let got = gpu.raw_state().unwrap();
        let what = format!("{accumulation:?} {integrator:?} damped={damped}");
        if accumulation == Accumulation::AtomicFixed {
            common::assert_twin(&got.0, &twin.0, &start.0, steps, &what);
            common::assert_twin(&got.1, &twin.1, &start.1, steps, &what);
        } else {
            let d = common::relative_difference(&got.0, &twin.0, &start.0);
            assert!(d <= 1e-5 * steps as f64, "{what}: {d:e} of the motion");
        }
    }
    assert!(twin.0 != start.0, "the state moved");
    assert!(!gpu.fixed_point_overflowed().unwrap());
}

/// The atomic variants' twins against the gather's on the CPU: the same end forces summed in
/// another order (float) or quantized (fixed point, within its stated resolution, `valence /
/// (2 scale)` N per component of a node's force), so that what the device tests above pin
/// down is the tensor-mass step and not something else.
#[test]
fn atomic_twins_sum_the_gather_s_forces() {
    let Some(mut gpu) = engine(
        &jittered_box(5, true),
        config(&jittered_box(5, true), Integrator::Verlet, 0.5),
        Accumulation::AtomicFixed,
    ) else {
        return;
    };
    let model = jittered_box(5, true);
    let (x, v) = random_state(&model, 3);
    gpu.set_state(&x, &v);
    let (u, s) = gpu.raw_state().unwrap();
    let blocks = gpu.tensor_mass().unwrap().blocks().clone();
    let PackedLayout::Edges(layout) = gpu.layout().clone() else {
        panic!("the edge layout")
    };
    let p = gpu.step_params();
    let fp = gpu.fixed_point();
    let forces = blocks.record_forces_cpu(&p, &layout, &u, &s);
    let gathered = blocks.gather_edges_cpu(&layout, &forces);
    let float = TensorBlocks::accumulate_float_cpu(&layout, &forces);
    let (acc, overflow) = TensorBlocks::accumulate_fixed_cpu(&layout, &fp, &forces);
    assert!(!overflow);
    let fixed = lancet::layout::edges::EdgeLayout::fixed_forces(&fp, &acc);
    let largest = gathered
        .iter()
        .flatten()
        .fold(0.0f32, |m, f| m.max(f.abs()));
    assert!(largest > 0.0, "the state strains the box");
    let resolution = layout.max_valence() as f32 * fp.inv_scale / 2.0;
    for i in 0..gathered.len() {
        for c in 0..3 {
            let g = gathered[i][c];
            assert!(
                (float[i][c] - g).abs() <= 1e-5 * largest,
                "node {i}: float {} gather {g}",
                float[i][c]
            );
            assert!(
                (fixed[i][c] - g).abs() <= resolution + 1e-6 * largest,
                "node {i}: fixed {} gather {g} (resolution {resolution:e})",
                fixed[i][c]
            );
        }
    }
    // The constants were sized for the tensors' end forces: none is within HEADROOM of the
    // saturation level.
    let end = forces.iter().flatten().fold(0.0f32, |m, f| m.max(f.abs()));
    assert!(end * fp.scale < fp.limit, "{end} N saturates");
}

/// A displacement far beyond any plausible strain saturates the fixed-point end forces, and
/// the host reads the flag (the tensors' forces use the springs' overflow policy).
#[test]
fn saturated_tensor_end_forces_set_the_overflow_flag() {
    let model = jittered_box(2, false);
    let Some(mut gpu) = engine(
        &model,
        config(&model, Integrator::SymplecticEuler, 0.5),
        Accumulation::AtomicFixed,
    ) else {
        return;
    };
    let (mut x, v) = random_state(&model, 9);
    gpu.set_state(&x, &v);
    gpu.step(1);
    assert!(!gpu.fixed_point_overflowed().unwrap());
    // Free nodes thrown 1000 times the box's size apart.
    for (i, p) in x.iter_mut().enumerate() {
        if !model.fixed[i] {
            p[0] += if i % 2 == 0 { 10.0 } else { -10.0 };
        }
    }
    gpu.set_state(&x, &v);
    gpu.step(1);
    assert!(gpu.fixed_point_overflowed().unwrap());
}

/// The atomic engines follow the gather engine and the float64 reference engine's tensor-mass
/// run (300 steps at 0.8 of the bound, damped, under gravity from a random state): within the
/// float32 bar the gather meets (`gpu_tensor_mass.rs`), far closer than the springs' run.
#[rstest]
fn atomic_tensor_mass_follows_the_gather_and_the_float64_reference(
    #[values(Accumulation::AtomicFixed, Accumulation::AtomicFloat)] accumulation: Accumulation,
) {
    let model = jittered_box(3, true);
    let config = config(&model, Integrator::Verlet, 0.8);
    if engine(&model, config, accumulation).is_none() {
        return;
    }
    let (x, v) = random_state(&model, 5);
    let (err, apart) = crate::fem_gpu_checks::against_the_reference(
        &model,
        config,
        (&x, &v),
        edges(accumulation),
        300,
        ForceModelKind::Springs,
    );
    assert!(err < 1e-3, "{accumulation:?}: relative L2 error {err:e}");
    assert!(
        apart > 100.0 * err.max(1e-6),
        "springs {apart:e}, gpu {err:e}"
    );
    let run = |options: GpuOptions| {
        let mut g = GpuEngine::new(&model, config, options).unwrap();
        g.set_state(&x, &v);
        g.step(300);
        g.positions()
    };
    let gather = run(LayoutKind::Edges.into());
    let atomic = run(edges(accumulation));
    let between = lancet::report::bench::relative_l2(&model.rest, &atomic, &gather);
    assert!(
        between < 1e-3,
        "{accumulation:?} against gather: {between:e}"
    );
}

/// Corotational runs its own element path (per-tet records gathered per node) whatever the
/// edge accumulation: on both atomic variants the engine steps bit for bit as on the gather.
#[rstest]
fn corotational_runs_on_the_atomic_variants_as_on_the_gather(
    #[values(Accumulation::AtomicFixed, Accumulation::AtomicFloat)] accumulation: Accumulation,
) {
    let model = jittered_box(6, true);
    let config = SimConfig {
        force_model: ForceModelKind::Corotational,
        ..config(&model, Integrator::Verlet, 0.5)
    };
    let Some(mut atomic) = engine(&model, config, accumulation) else {
        return;
    };
    let mut gather = engine(&model, config, Accumulation::Gather).unwrap();
    let (x, v) = random_state(&model, 8);
    for e in [&mut atomic, &mut gather] {
        e.set_state(&x, &v);
        e.step(20);
    }
    let (a, g) = (atomic.raw_state().unwrap(), gather.raw_state().unwrap());
    assert!(
        a.0 == g.0 && a.1 == g.1,
        "{accumulation:?} differs from gather"
    );
    assert!(atomic.corotational().is_some());
}

/// Cuts through a tensor-mass model on the atomic variants: after every cut the world's checks
/// against a rebuild find nothing, and the cut engine steps as one built afresh from the cut
/// model (whose fixed point may be sized afresh) to float32 rounding.
#[rstest]
fn a_cut_atomic_tensor_mass_model_equals_a_rebuilt_one(
    #[values(Accumulation::AtomicFixed, Accumulation::AtomicFloat)] accumulation: Accumulation,
    #[values(lancet::cut::CutMethod::Separate, lancet::cut::CutMethod::Subdivide)]
    method: lancet::cut::CutMethod,
) {
    let model = jittered_box(1, false);
    if engine(
        &model,
        config(&model, Integrator::Verlet, 0.5),
        accumulation,
    )
    .is_none()
    {
        return;
    }
    crate::fem_gpu_checks::cut_model_equals_a_rebuilt_one(
        ForceModelKind::TensorMass,
        edges(accumulation),
        method,
        Integrator::Verlet,
    );
}

/// Memory per layout on the atomic variants counts the blocks (one per record, 96 bytes when
/// damped) beside the springs' buffers and accumulators, and a step's bytes add each block
/// read once; no end-force scratch is made (the gather's two forces per record).
#[rstest]
fn atomic_memory_reports_the_tensor_blocks(
    #[values(Accumulation::AtomicFixed, Accumulation::AtomicFloat)] accumulation: Accumulation,
) {
    let model = jittered_box(1, true);
    let tensor_config = config(&model, Integrator::Verlet, 0.5);
    let springs_config = SimConfig {
        force_model: ForceModelKind::Springs,
        ..tensor_config
    };
    let (Some(springs), Some(tensor)) = (
        engine(&model, springs_config, accumulation),
        engine(&model, tensor_config, accumulation),
    ) else {
        return;
    };
    let (ms, mt) = (springs.memory(), tensor.memory());
    let named = |n: &str| mt.stats.buffers.iter().find(|(b, _)| b == n).map(|b| b.1);
    let blocks = named("tensor-mass blocks").expect("the blocks are reported");
    assert!(named("tensor-mass end forces").is_none());
    let records = model.springs().len() as u64;
    assert!(blocks >= records * 96, "{blocks} bytes");
    assert!(mt.stats.total >= ms.stats.total + blocks);
    assert_eq!(mt.bytes_per_step, ms.bytes_per_step + records * 96);
}

/// `lancet bench --force-model tensor-mass --layout edges --accumulation ...` times the atomic
/// rows beside the gather's (none skipped), each within float32 rounding of the float64
/// reference, the atomic rows moving fewer bytes a step than the gather (no end-force scratch
/// written and read back).
#[test]
fn the_bench_times_tensor_mass_on_the_atomic_variants() {
    use lancet::report::bench::{run_bench, BenchMesh, BenchOptions};
    let Some(ctx) = common::gpu() else { return };
    let float = ctx
        .device
        .features()
        .contains(wgpu::Features::SHADER_FLOAT32_ATOMIC);
    let opts = BenchOptions {
        engines: vec![lancet::engine::EngineKind::Gpu],
        layouts: vec![LayoutKind::Edges],
        accumulations: vec![
            Accumulation::Gather,
            Accumulation::AtomicFixed,
            Accumulation::AtomicFloat,
        ],
        steps: 4,
        chunk: 2,
        force_model: ForceModelKind::TensorMass,
        ..BenchOptions::default()
    };
    let bw = lancet::report::bandwidth::stream_triad(1 << 16, 1);
    let report = run_bench(&[BenchMesh::Cube(3)], &opts, &bw, || None).unwrap();
    let names: Vec<_> = report
        .rows
        .iter()
        .map(|r| r.accumulation.clone().unwrap_or_default())
        .collect();
    let want: &[&str] = if float {
        &["gather", "atomic-fixed", "atomic-float"]
    } else {
        &["gather", "atomic-fixed"]
    };
    assert_eq!(names, want, "{:?}", report.skipped);
    for r in &report.rows {
        assert_eq!(r.force_model, "tensor-mass");
        assert!(r.error_vs_reference < 1e-3, "{r:?}");
    }
    let gather = report.rows[0].bytes_per_step;
    assert!(report.rows[1..].iter().all(|r| r.bytes_per_step < gather));
}
