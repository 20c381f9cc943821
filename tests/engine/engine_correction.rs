//! Position correction, the contact response's way of moving nodes: every engine reads back
//! exactly the nodes asked for, moves them where told, turns the move into velocity (Verlet
//! by adding the move to its step, symplectic Euler by adding move / dt), leaves fixed nodes
//! alone, and after the correction all engines still agree with the float64 reference.

use crate::{common, models};
use lancet::engine::{EngineKind, Integrator, SimConfig, Simulation};
use lancet::layout::LayoutKind;
use lancet::model::stable_time_step;
use lancet::report::bench::relative_l2;
use models::{random_box, random_state};
use rstest::rstest;

/// Run 10 steps, push five free nodes by 0.2 mm along +x (and one fixed node), 60 more steps.
fn corrected(
    kind: EngineKind,
    layout: LayoutKind,
    integrator: Integrator,
) -> Option<Vec<[f64; 3]>> {
    if kind == EngineKind::Gpu && common::gpu().is_none() {
        return None;
    }
    let model = random_box(91, true);
    let mut config = SimConfig::new(0.5 * stable_time_step(&model).dt);
    config.integrator = integrator;
    let mut sim = Simulation::with_gpu(model.clone(), kind, config, layout.into()).unwrap();
    let (x, v) = random_state(&model, 91);
    sim.set_state(&x, &v).unwrap();
    sim.run(10).unwrap();
    let free: Vec<u32> = (0..model.node_count() as u32)
        .filter(|&i| !model.fixed[i as usize])
        .step_by(7)
        .take(5)
        .collect();
    let fixed = (0..model.node_count() as u32)
        .find(|&i| model.fixed[i as usize])
        .unwrap();
    let mut nodes = free.clone();
    nodes.push(fixed);
    let (all_x, all_v) = (sim.positions(), sim.velocities());
    let got = sim.node_positions(&nodes).unwrap();
    for (k, &i) in nodes.iter().enumerate() {
        assert_eq!(
            got[k], all_x[i as usize],
            "{kind:?}: node {i} read back differently"
        );
    }
    let dx = 2e-4;
    let target: Vec<[f64; 3]> = got.iter().map(|p| [p[0] + dx, p[1], p[2]]).collect();
    sim.correct_positions(&nodes, &target).unwrap();
    let (after_x, after_v) = (sim.positions(), sim.velocities());
    let dt = config.dt;
    for (k, &i) in free.iter().enumerate() {
        let i = i as usize;
        assert!(
            (after_x[i][0] - target[k][0]).abs() < 1e-9,
            "{kind:?}: node {i} not moved"
        );
        // The move becomes velocity: dx / dt more along x (1e-3 of it for float32 rounding).
        let gained = after_v[i][0] - all_v[i][0];
        assert!(
            (gained - dx / dt).abs() < 1e-3 * dx / dt,
            "{kind:?} {integrator:?}: velocity gained {gained}, expected {}",
            dx / dt
        );
    }
    assert_eq!(
        after_x[fixed as usize], model.rest[fixed as usize],
        "a fixed node moved"
    );
    sim.run(60).unwrap();
    Some(sim.positions())
}

#[rstest]
fn every_engine_corrects_positions_alike(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
) {
    let c = LayoutKind::Connectivity;
    let reference = corrected(EngineKind::Reference, c, integrator).unwrap();
    let rest = random_box(91, true).rest;
    let fast = corrected(EngineKind::Fast, c, integrator).unwrap();
    let e = relative_l2(&rest, &fast, &reference);
    assert!(
        e < 1e-4,
        "fast off the reference by {e:.2e} after a correction"
    );
    for layout in [c, LayoutKind::Valence, LayoutKind::Edges] {
        if let Some(gpu) = corrected(EngineKind::Gpu, layout, integrator) {
            let e = relative_l2(&rest, &gpu, &reference);
            assert!(e < 1e-4, "gpu {layout:?} off the reference by {e:.2e}");
        }
    }
}

#[test]
fn a_correction_of_a_missing_node_is_an_error() {
    let model = random_box(92, false);
    let mut sim = Simulation::new(model.clone(), EngineKind::Fast, SimConfig::new(1e-6)).unwrap();
    let n = model.node_count() as u32;
    let err = sim
        .correct_positions(&[n], &[[0.0; 3]])
        .unwrap_err()
        .to_string();
    assert!(err.contains(&n.to_string()), "{err}");
    assert!(sim.correct_positions(&[0, 1], &[[0.0; 3]]).is_err());
    assert!(sim.node_positions(&[n + 5]).is_err());
}
