//! The tensor-mass force model on the GPU layouts: each layout's passes equal their CPU twin
//! (`twin::tensor_mass`) bit for bit on lavapipe on a jittered box with random masses and a
//! random state; the GPU engine follows the float64 reference engine; a cut engine's blocks
//! and steps equal a rebuilt one's; what has no GPU pass is refused with a reason.

use crate::{common, models};
use lancet::engine::gpu::GpuEngine;
use lancet::engine::{Engine, ForceModelKind, Integrator, SimConfig};
use lancet::layout::edges::Accumulation;
use lancet::layout::tensor_blocks::TensorBlocks;
use lancet::layout::LayoutKind;
use lancet::model::PackedModel;
use lancet::Error;
use models::{random_box, Rng};
use rstest::rstest;

const LAYOUTS: [LayoutKind; 3] = [
    LayoutKind::Connectivity,
    LayoutKind::Valence,
    LayoutKind::Edges,
];

/// [`random_box`] (random masses, gravity, a fixed base; Rayleigh-damped when `damped`) with
/// every free node's rest position moved by up to 8% of a cell: no two tets alike, so every
/// block differs.
pub(crate) fn jittered_box(seed: u64, damped: bool) -> PackedModel {
    let mut model = random_box(seed, damped);
    let mut rng = Rng(seed ^ 0x5151);
    for (r, fixed) in model.rest.iter_mut().zip(&model.fixed) {
        if !fixed {
            for c in r.iter_mut() {
                *c += (rng.next() - 0.5) * 0.16 * 0.01;
            }
        }
    }
    model
}

/// A tensor-mass configuration at `fraction` of the model's stable time step.
pub(crate) fn config(model: &PackedModel, integrator: Integrator, fraction: f64) -> SimConfig {
    let kind = ForceModelKind::TensorMass;
    SimConfig {
        integrator,
        force_model: kind,
        ..SimConfig::new(fraction * kind.stable_time_step(model).unwrap().dt)
    }
}

/// Random displacements (about 5% of a cell) and velocities.
pub(crate) fn random_state(model: &PackedModel, seed: u64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let mut rng = Rng(seed);
    let mut v = |s: f64| [0, 1, 2].map(|_| (rng.next() - 0.5) * s);
    let x = model
        .rest
        .iter()
        .map(|r| {
            let d = v(1e-3);
            [r[0] + d[0], r[1] + d[1], r[2] + d[2]]
        })
        .collect();
    let vel = model.rest.iter().map(|_| v(0.05)).collect();
    (x, vel)
}

/// Each layout's tensor-mass step equals its CPU twin: bit for bit on lavapipe, after 1 and
/// after 20 steps, damped under Verlet (the damping blocks and velocity differences read) and
/// undamped under symplectic Euler.
#[rstest]
fn tensor_mass_passes_equal_their_cpu_twin(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
    #[values((Integrator::Verlet, true), (Integrator::SymplecticEuler, false))] scheme: (
        Integrator,
        bool,
    ),
) {
    let Some(ctx) = common::gpu() else { return };
    let (integrator, damped) = scheme;
    let model = jittered_box(7, damped);
    let mut gpu =
        GpuEngine::with_context(ctx, &model, config(&model, integrator, 0.5), kind).unwrap();
    let (x, v) = random_state(&model, 11);
    gpu.set_state(&x, &v);
    let start = gpu.raw_state().unwrap();
    let tensor = gpu.tensor_mass().expect("a tensor-mass engine");
    assert_eq!(tensor.damped(), damped);
    let blocks: TensorBlocks = tensor.blocks().clone();
    assert!(
        blocks.rows.iter().flatten().any(|&k| k != 0.0),
        "the blocks hold the tensors"
    );
    let layout = gpu.layout().clone();
    let p = gpu.step_params();
    assert_eq!(p.damped, damped);
    let mut twin = start.clone();
    for steps in [1usize, 19] {
        twin = lancet::twin::steps(&p, twin, steps, |p, u, s| blocks.step_cpu(p, &layout, u, s));
        gpu.step(steps as u32);
        let got = gpu.raw_state().unwrap();
        let what = format!("{kind:?} {integrator:?} damped={damped}");
        common::assert_twin(&got.0, &twin.0, &start.0, steps, &what);
        common::assert_twin(&got.1, &twin.1, &start.1, steps, &what);
    }
    // The twin's force is the float64 model's, rounded: the state moved.
    assert!(twin.0 != start.0);
}

/// The GPU engine in every layout follows the float64 reference engine's tensor-mass run (300
/// steps at 0.8 of the bound, damped, under gravity from a random state) within float32
/// rounding: the fast engine's bar (`tests/engine/fast_fem.rs`). The springs' force, which
/// the same engine would compute, is far off: the tensors are what is stepped.
#[rstest]
fn gpu_tensor_mass_follows_the_float64_reference(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] layout: LayoutKind,
) {
    let Some(_) = common::gpu() else { return };
    let model = jittered_box(3, true);
    let config = config(&model, Integrator::Verlet, 0.8);
    let (x, v) = random_state(&model, 5);
    let (err, apart) = crate::fem_gpu_checks::against_the_reference(
        &model,
        config,
        (&x, &v),
        layout,
        300,
        ForceModelKind::Springs,
    );
    assert!(err < 1e-3, "{layout:?}: relative L2 error {err:e}");
    assert!(
        apart > 100.0 * err.max(1e-6),
        "springs {apart:e}, gpu {err:e}"
    );
}

/// The energy a GPU engine reports for its divergence checks is that of the finite elements it
/// steps, as the float64 reference engine's is, not the springs' (which differ by far more than
/// float32 rounding on this state).
#[rstest]
fn a_gpu_engine_weighs_the_energy_of_its_finite_elements(
    #[values(ForceModelKind::TensorMass, ForceModelKind::Corotational)] kind: ForceModelKind,
) {
    use lancet::engine::{EngineKind, Simulation};
    let Some(_) = common::gpu() else { return };
    let model = jittered_box(4, false);
    let (x, v) = random_state(&model, 6);
    let elastic = |engine: EngineKind, kind: ForceModelKind| {
        let config = SimConfig {
            force_model: kind,
            ..config(&model, Integrator::Verlet, 0.5)
        };
        let mut sim =
            Simulation::with_gpu(model.clone(), engine, config, LayoutKind::Valence.into())
                .unwrap();
        sim.set_state(&x, &v).unwrap();
        sim.energy().elastic
    };
    let gpu = elastic(EngineKind::Gpu, kind);
    let reference = elastic(EngineKind::Reference, kind);
    let springs = elastic(EngineKind::Reference, ForceModelKind::Springs);
    // Positions stored in float32 (about 4e-9 m on displacements of 5e-4 m): the energy to
    // a relative 1e-4.
    assert!(
        (gpu - reference).abs() < 1e-4 * reference,
        "{kind:?}: GPU {gpu:e} J, reference {reference:e} J"
    );
    assert!(
        (springs - reference).abs() > 1e-2 * reference,
        "springs {springs:e} J against {reference:e} J: the state does not tell the models apart"
    );
}

/// Memory per layout counts the blocks: a 3x3 block of three vec4 rows per slot in use (six
/// when damped), beside the springs' buffers.
#[test]
fn memory_reports_the_tensor_blocks() {
    let Some(ctx) = common::gpu() else { return };
    let model = jittered_box(1, true);
    for kind in LAYOUTS {
        let springs = GpuEngine::with_context(
            ctx.clone(),
            &model,
            SimConfig {
                force_model: ForceModelKind::Springs,
                ..config(&model, Integrator::Verlet, 0.5)
            },
            kind,
        )
        .unwrap();
        let tensor = GpuEngine::with_context(
            ctx.clone(),
            &model,
            config(&model, Integrator::Verlet, 0.5),
            kind,
        )
        .unwrap();
        let (ms, mt) = (springs.memory(), tensor.memory());
        let blocks = mt
            .stats
            .buffers
            .iter()
            .find(|(n, _)| n == "tensor-mass blocks")
            .map(|b| b.1)
            .expect("the blocks are reported");
        // One block per slot or record: twice the springs on the node-centric layouts (one
        // slot per end), once on the edge layout; 96 bytes each when damped.
        let records = match kind {
            LayoutKind::Edges => model.springs().len() as u64,
            _ => 2 * model.springs().len() as u64,
        };
        assert!(blocks >= records * 96, "{kind:?}: {blocks} bytes");
        assert!(mt.stats.total >= ms.stats.total + blocks, "{kind:?}");
        assert!(
            mt.bytes_per_step >= ms.bytes_per_step + records * 96,
            "{kind:?}: {} vs {}",
            mt.bytes_per_step,
            ms.bytes_per_step
        );
    }
}

/// What has no GPU pass says so and names what runs instead.
#[test]
fn what_the_gpu_does_not_run_is_refused_with_a_reason() {
    let Some(ctx) = common::gpu() else { return };
    let model = jittered_box(1, false);
    let base = config(&model, Integrator::Verlet, 0.5);
    let corot = SimConfig {
        force_model: ForceModelKind::Corotational,
        integrator: Integrator::BackwardEuler,
        ..base
    };
    // The corotational model under backward Euler runs on the GPU (it was refused before the
    // block pass): `gpu_implicit_corotational.rs` checks it.
    let built = GpuEngine::with_context(ctx.clone(), &model, corot, LayoutKind::Connectivity);
    assert!(
        built
            .as_ref()
            .is_ok_and(|g| g.corotational_blocks().is_some()),
        "{:?}",
        built.err()
    );
    let options = lancet::engine::GpuOptions {
        layout: LayoutKind::Edges,
        accumulation: Accumulation::AtomicFixed,
    };
    // The explicit step runs on the atomic variants (`gpu_tensor_atomic.rs` checks it).
    let built = GpuEngine::with_context(ctx.clone(), &model, base, options);
    assert!(built.is_ok(), "{:?}", built.err());
    // Backward Euler runs on the blocks; on the atomic edge variants it is refused as the
    // springs' implicit step is (no incidence table to gather over).
    let implicit = SimConfig {
        integrator: Integrator::BackwardEuler,
        ..base
    };
    let err = GpuEngine::with_context(ctx, &model, implicit, options)
        .err()
        .expect("refused");
    assert!(
        matches!(&err, Error::Unsupported(m) if m.contains("gather")),
        "{err}"
    );
}

/// Cuts through a tensor-mass model on the GPU, in every layout: after every cut the engine's
/// float64 tensors equal a rebuild from the cut mesh to 1e-12 and its blocks (host and device)
/// a fresh assembly beside the patched layout to float32 rounding (the world's checks, through
/// `Engine::differences_from_rebuild`); and the cut engine then steps as a GPU engine built
/// afresh from the cut model does, to float32 rounding.
#[rstest]
fn a_cut_gpu_tensor_mass_model_equals_a_rebuilt_one(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] layout: LayoutKind,
    #[values(lancet::cut::CutMethod::Separate, lancet::cut::CutMethod::Subdivide)]
    method: lancet::cut::CutMethod,
) {
    crate::fem_gpu_checks::cut_model_equals_a_rebuilt_one(
        ForceModelKind::TensorMass,
        layout,
        method,
        Integrator::Verlet,
    );
}
