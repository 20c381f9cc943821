//! Backward Euler with the finite elements (tensor-mass, corotational) on the edge layout's
//! float-atomic variant: each record's setup terms (its block from `a`, transposed from `b`)
//! and each iteration's two block products added to their ends' accumulators, no incidence
//! table (`shaders/implicit_atomic_tensor.wgsl`). The device step follows its CPU twin
//! (`twin::implicit_atomic_tensor`, one order of the adds) within the solver's tolerance, the
//! gather variant and the float64 reference within the springs' bar
//! (`gpu_implicit_atomic.rs`), and a cut engine steps as a rebuilt one.

use crate::gpu_implicit_atomic::apart;
use crate::{common, gpu_corotational as corot, gpu_tensor_mass as tensor};
use lancet::engine::gpu::GpuEngine;
use lancet::engine::{
    Engine, EngineKind, ForceModelKind, GpuOptions, Integrator, SimConfig, Simulation,
};
use lancet::layout::edges::Accumulation;
use lancet::layout::tet_table::IDENTITY;
use lancet::layout::{LayoutKind, PackedLayout};
use lancet::model::PackedModel;
use lancet::twin::implicit_atomic_tensor as twin;
use rstest::rstest;

fn options(accumulation: Accumulation) -> GpuOptions {
    GpuOptions {
        layout: LayoutKind::Edges,
        accumulation,
    }
}

/// Whether the device has float atomics (a message where it has none, or no device).
fn float_atomics() -> bool {
    let Some(ctx) = common::gpu() else {
        return false;
    };
    let has = ctx
        .device
        .features()
        .contains(wgpu::Features::SHADER_FLOAT32_ATOMIC);
    if !has {
        eprintln!("skipped: {} has no float atomics", ctx.describe());
    }
    has
}

/// The float-atomic engine, or `None` on a device without float atomics.
fn engine(model: &PackedModel, config: SimConfig) -> Option<GpuEngine> {
    if !float_atomics() {
        return None;
    }
    let ctx = common::gpu()?;
    let options = options(Accumulation::AtomicFloat);
    Some(GpuEngine::with_context(ctx, model, config, options).unwrap())
}

/// `model` with Poisson's ratio 0.4 in every tet: Lame's lambda and mu differ, so a record's
/// block K_ab is not symmetric and reading it untransposed at the `b` end would show (at the
/// test boxes' 0.25, lambda = mu and every block is symmetric).
fn unequal_lame(mut model: PackedModel) -> PackedModel {
    use lancet::model::Stiffness;
    for tet in &mut model.tets {
        if let Stiffness::Material { poisson_ratio, .. } = &mut tet.material.stiffness {
            *poisson_ratio = 0.4;
        }
    }
    model
}

fn edges(gpu: &GpuEngine) -> lancet::layout::edges::EdgeLayout {
    let PackedLayout::Edges(layout) = gpu.layout().clone() else {
        panic!("the edge layout")
    };
    layout
}

/// The device's positions and velocities after `steps` against the twin's, as a fraction of
/// the twin's motion, within the springs' bar (1e-4: each solve stops at a relative residual
/// of 1e-5 and the device adds in another order); the iteration counts within one a solve.
fn assert_follows(
    gpu: &mut GpuEngine,
    start: &(Vec<[f32; 4]>, Vec<[f32; 4]>),
    want: &(Vec<[f32; 4]>, Vec<[f32; 4]>),
    iterations: &[u32],
    what: &str,
) {
    let steps = iterations.len();
    gpu.step(steps as u32);
    let got = gpu.raw_state().unwrap();
    for (g, w, s) in [(&got.0, &want.0, &start.0), (&got.1, &want.1, &start.1)] {
        let d = common::relative_difference(g, w, s);
        eprintln!("{what}: twin {d:e} of the motion");
        assert!(
            d <= 1e-4,
            "{what}: device and twin differ by {d:e} of the motion"
        );
    }
    let stats = gpu.solver_stats().unwrap();
    assert_eq!(stats.solves, steps as u64, "{what}");
    let sum: u64 = iterations.iter().map(|&i| i as u64).sum();
    assert!(
        stats.iterations.abs_diff(sum) <= steps as u64,
        "{what}: device {} iterations, twin {iterations:?}",
        stats.iterations
    );
    assert_eq!(stats.capped, 0, "{what}");
    assert!(iterations.iter().all(|&i| i > 1), "{what}: {iterations:?}");
    assert!(want.0 != start.0, "{what}: the state moved");
}

/// Four tensor-mass steps at ten times the explicit bound, damped (the damping blocks in the
/// record terms and products) and undamped, follow the twin stepper.
#[rstest]
fn the_atomic_tensor_mass_implicit_step_follows_its_twin(#[values(true, false)] damped: bool) {
    let model = unequal_lame(tensor::jittered_box(17, damped));
    let config = tensor::config(&model, Integrator::BackwardEuler, 10.0);
    let Some(mut gpu) = engine(&model, config) else {
        return;
    };
    let (x, v) = tensor::random_state(&model, 19);
    gpu.set_state(&x, &v);
    let start = gpu.raw_state().unwrap();
    let blocks = gpu.tensor_mass().expect("tensor-mass").blocks().clone();
    let p = gpu.solve_params().expect("an implicit engine");
    assert_eq!(p.damped, damped, "the solve reads the damping blocks");
    let (layout, inv_mass) = (edges(&gpu), gpu.inv_mass().to_vec());
    let mut state = start.clone();
    let mut iterations = Vec::new();
    for _ in 0..4 {
        let (next, vel, s) =
            twin::implicit_step_cpu(&p, &blocks, &layout, &inv_mass, (&state.0, &state.1), None);
        state = (next, vel);
        iterations.push(s.iterations);
    }
    let what = format!("tensor-mass damped={damped}");
    assert_follows(&mut gpu, &start, &state, &iterations, &what);
}

/// Four corotational steps at ten times the explicit bound, damped, from a state turned by
/// 0.5 rad on a box with slivers, follow the twin stepper (tet pass, block pass, the atomic
/// solve with the gathered corner forces).
#[test]
fn the_atomic_corotational_implicit_step_follows_its_twin() {
    let model = unequal_lame(corot::jittered_box(13, true, 0.25));
    let config = corot::config(&model, Integrator::BackwardEuler, 10.0);
    let Some(mut gpu) = engine(&model, config) else {
        return;
    };
    let (x, v) = corot::random_state(&model, 17, 2e-3, 0.5);
    gpu.set_state(&x, &v);
    let start = gpu.raw_state().unwrap();
    let solve = gpu.solve_params().expect("an implicit engine");
    let p = gpu.step_params();
    assert!(p.damped && solve.damped, "the damped tets reach the solve");
    let table = gpu.corotational().unwrap().table().clone();
    let pairs = gpu.corotational_blocks().unwrap().pairs().clone();
    let (layout, inv_mass) = (edges(&gpu), gpu.inv_mass().to_vec());
    let mut rotations = vec![IDENTITY; table.len()];
    let mut state = start.clone();
    let mut iterations = Vec::new();
    for _ in 0..4 {
        let (next, vel, s) = twin::corotational_step_cpu(
            &p,
            &solve,
            &table,
            &pairs,
            &layout,
            &inv_mass,
            (&state.0, &state.1),
            &mut rotations,
        );
        state = (next, vel);
        iterations.push(s.iterations);
    }
    assert_follows(&mut gpu, &start, &state, &iterations, "corotational");
}

/// Twenty steps at ten times the explicit bound, damped, under gravity, follow the float64
/// reference engine's backward Euler and the gather variant within the springs' bar (2e-4 of
/// the motion, `gpu_implicit_atomic.rs`), for tensor-mass and corotational (from a state
/// turned by 0.6 rad).
#[rstest]
fn the_atomic_fem_implicit_step_follows_the_gather_and_the_float64_reference(
    #[values(ForceModelKind::TensorMass, ForceModelKind::Corotational)] kind: ForceModelKind,
) {
    if !float_atomics() {
        return;
    }
    let (model, config, (x, v)) = match kind {
        ForceModelKind::Corotational => {
            let model = unequal_lame(corot::jittered_box(3, true, 0.08));
            let config = corot::config(&model, Integrator::BackwardEuler, 10.0);
            let state = corot::random_state(&model, 5, 1e-3, 0.6);
            (model, config, state)
        }
        _ => {
            let model = unequal_lame(tensor::jittered_box(23, true));
            let config = tensor::config(&model, Integrator::BackwardEuler, 10.0);
            let state = tensor::random_state(&model, 29);
            (model, config, state)
        }
    };
    let run = |engine: EngineKind, accumulation: Accumulation| {
        let mut sim =
            Simulation::with_gpu(model.clone(), engine, config, options(accumulation)).unwrap();
        sim.set_state(&x, &v).unwrap();
        sim.run(20).unwrap();
        assert!(sim.engine_name().starts_with(match (engine, accumulation) {
            (EngineKind::Gpu, Accumulation::AtomicFloat) => "gpu-edges-atomicfloat",
            (EngineKind::Gpu, _) => "gpu-edges",
            _ => "",
        }));
        sim.positions()
    };
    let got = run(EngineKind::Gpu, Accumulation::AtomicFloat);
    let gather = run(EngineKind::Gpu, Accumulation::Gather);
    let reference = run(EngineKind::Reference, Accumulation::Gather);
    let (error, motion) = apart(&got, &reference, &x);
    assert!(motion > 1e-4, "{kind}: the model moved");
    eprintln!("{kind}: reference {:e} of the motion", error / motion);
    assert!(
        error <= 2e-4 * motion,
        "{kind}: {:e} of the motion",
        error / motion
    );
    let (between, _) = apart(&got, &gather, &x);
    eprintln!("{kind}: gather {:e} of the motion", between / motion);
    assert!(
        between <= 2e-4 * motion,
        "{kind}: gather {:e}",
        between / motion
    );
}

/// Cuts through a tensor-mass and a corotational model under backward Euler on the
/// float-atomic variant, separating and subdividing: the world's checks against a rebuild
/// find nothing after every cut, and the cut engine steps as a rebuilt one does (the
/// accumulators sized for the new node slots, the blocks and records rebound).
#[rstest]
fn a_cut_atomic_fem_implicit_model_equals_a_rebuilt_one(
    #[values(ForceModelKind::TensorMass, ForceModelKind::Corotational)] kind: ForceModelKind,
    #[values(lancet::cut::CutMethod::Separate, lancet::cut::CutMethod::Subdivide)]
    method: lancet::cut::CutMethod,
) {
    if !float_atomics() {
        return;
    }
    crate::fem_gpu_checks::cut_model_equals_a_rebuilt_one(
        kind,
        options(Accumulation::AtomicFloat),
        method,
        Integrator::BackwardEuler,
    );
}
