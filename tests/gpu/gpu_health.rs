//! The divergence probe on the device: its per-workgroup energies equal its CPU twin on random
//! state, it finds the first non-finite node, its energies match the float64 ones from the read
//! back state, and a forced unstable GPU run is caught within a bounded number of steps.

use crate::{common, models};
use lancet::engine::gpu::GpuEngine;
use lancet::engine::{DeviceEngine, Engine, EngineKind, SimConfig, Simulation};
use lancet::layout::LayoutKind;
use lancet::model::stable_time_step;
use lancet::twin::health::health_cpu;
use lancet::Error;
use models::{random_model, random_state};
use rstest::rstest;

fn engine(kind: LayoutKind, seed: u64) -> Option<(GpuEngine, lancet::PackedModel)> {
    let ctx = common::gpu()?;
    let model = random_model(seed, true);
    let config = SimConfig::new(0.5 * stable_time_step(&model).dt);
    let mut e = GpuEngine::with_context(ctx, &model, config, kind).unwrap();
    let (x, v) = random_state(&model, seed);
    e.set_state(&x, &v);
    e.step(5);
    Some((e, model))
}

#[rstest]
fn device_probe_equals_its_twin(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    let Some((e, _)) = engine(kind, 61) else {
        return;
    };
    let got = e.health_partials().unwrap();
    let (cur, second) = e.raw_state().unwrap();
    let want = health_cpu(&e.step_params(), e.inv_mass(), &cur, &second);
    assert_eq!(got.first_bad, None);
    assert_eq!(got.partials.len(), want.partials.len());
    for (g, w) in got.partials.iter().zip(&want.partials) {
        for c in 0..2 {
            // The same tree of additions; only fused multiply-adds may differ.
            let tol = 1e-5 * w[c].abs().max(1e-30);
            assert!((g[c] - w[c]).abs() <= tol, "{g:?} vs {w:?}");
        }
    }
}

#[rstest]
fn device_energies_match_the_state_read_back(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    let Some((e, model)) = engine(kind, 62) else {
        return;
    };
    let h = e.health().unwrap();
    let (x, v) = e.state();
    let (k, g) = (model.kinetic_energy(&v), model.gravity_energy(&x));
    assert!(k > 0.0 && g.abs() > 0.0, "a moving, displaced state");
    assert!(
        (h.kinetic - k).abs() < 1e-4 * k,
        "kinetic {} vs {k}",
        h.kinetic
    );
    assert!(
        (h.gravity - g).abs() < 1e-4 * g.abs(),
        "gravity {} vs {g}",
        h.gravity
    );
}

#[rstest]
fn the_first_non_finite_node_is_found(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence)] kind: LayoutKind,
    #[values(f32::NAN, f32::INFINITY, f32::NEG_INFINITY)] bad: f32,
) {
    let Some((mut e, model)) = engine(kind, 63) else {
        return;
    };
    let (mut cur, second) = e.raw_state().unwrap();
    // Two poisoned free nodes: the lower layout index is reported, as a model index.
    let order = e.layout().order().clone();
    let free: Vec<usize> = (0..model.node_count())
        .filter(|&t| !model.fixed[t])
        .map(|t| order.rank[t] as usize)
        .collect();
    let (a, b) = (free[free.len() / 3], free[2 * free.len() / 3]);
    cur[a][1] = bad;
    cur[b][0] = bad;
    e.set_raw_state(&cur, &second).unwrap();
    let h = e.health().unwrap();
    let first = order.order[a.min(b)] as usize;
    assert_eq!(h.non_finite, Some(first));
}

/// As `tests/stability.rs` argues, the box at twice the bound grows about 3x per step and is
/// caught within 60 steps when checked every 10; the device probe must not delay that.
#[rstest]
fn a_forced_unstable_gpu_run_is_caught_by_the_device_probe(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    if common::gpu().is_none() {
        return;
    }
    let model = random_model(64, false);
    let mut config = SimConfig::new(2.0 * stable_time_step(&model).dt);
    config.allow_unstable = true;
    let mut sim =
        Simulation::with_gpu(model.clone(), EngineKind::Gpu, config, kind.into()).unwrap();
    let (x, v) = random_state(&model, 64);
    let tiny: Vec<[f64; 3]> = x
        .iter()
        .zip(&model.rest)
        .map(|(p, r)| [0, 1, 2].map(|c| r[c] + (p[c] - r[c]) * 1e-3))
        .collect();
    sim.set_state(&tiny, &vec![[0.0; 3]; v.len()]).unwrap();
    match sim.run(10_000) {
        Err(Error::Diverged { step, node, .. }) => {
            assert!(step <= 60, "caught only at step {step}");
            assert!(node < model.node_count());
        }
        other => panic!("expected divergence, got {other:?}"),
    }
}
