//! The node order an engine packs its arrays in is internal: the fast CPU engine and the GPU
//! engine in every layout give the same positions (in model order) whatever the order, and a
//! random order is a reproducible permutation.

use crate::{common, models};
use lancet::engine::{EngineKind, GpuOptions, NodeOrdering, SimConfig, Simulation};
use lancet::layout::edges::Accumulation;
use lancet::layout::LayoutKind;
use lancet::model::{stable_time_step, PackedModel};
use lancet::report::bench::relative_l2;
use models::{random_box, random_state};

const ORDERS: [NodeOrdering; 3] = [
    NodeOrdering::Locality,
    NodeOrdering::Identity,
    NodeOrdering::Random(42),
];

/// Only the order in which a node sums its springs' forces changes with the numbering (a node's
/// neighbours are visited in ascending index); float32 rounds that sum differently, by about
/// 1e-7 of a force per step. Over 100 steps of a stable run that stays at rounding level:
/// 1e-5 relative L2 of the displacement is a hundred times the float32 epsilon, and a wrong
/// renumbering (a force applied to the wrong node) gives errors of order 1.
const TOLERANCE: f64 = 1e-5;

/// Positions in model order after 100 steps from a random state.
fn run(model: &PackedModel, kind: EngineKind, config: SimConfig) -> Vec<[f64; 3]> {
    run_on(model, kind, config, GpuOptions::default())
}

/// [`run`] with the GPU engine's layout and accumulation `gpu`.
fn run_on(
    model: &PackedModel,
    kind: EngineKind,
    config: SimConfig,
    gpu: GpuOptions,
) -> Vec<[f64; 3]> {
    let (x, v) = random_state(model, 5);
    let mut sim = Simulation::with_gpu(model.clone(), kind, config, gpu).unwrap();
    sim.set_state(&x, &v).unwrap();
    sim.run(100).unwrap();
    sim.positions()
}

fn config(model: &PackedModel) -> SimConfig {
    SimConfig::new(0.8 * stable_time_step(model).dt)
}

#[test]
fn random_order_is_a_reproducible_permutation_that_depends_on_its_seed() {
    let model = random_box(3, true);
    let n = model.node_count();
    let a = NodeOrdering::Random(7).order(&model);
    let mut seen = vec![false; n];
    for &old in &a.order {
        assert!(!seen[old as usize], "node {old} appears twice");
        seen[old as usize] = true;
    }
    assert!(seen.iter().all(|&s| s));
    for (new, &old) in a.order.iter().enumerate() {
        assert_eq!(a.rank[old as usize] as usize, new);
    }
    assert_eq!(a, NodeOrdering::Random(7).order(&model));
    assert_ne!(a, NodeOrdering::Random(8).order(&model));
    let moved = a
        .order
        .iter()
        .enumerate()
        .filter(|&(i, &o)| i != o as usize)
        .count();
    assert!(moved > n / 2, "only {moved} of {n} nodes moved");
    assert_eq!(
        NodeOrdering::Identity.order(&model).order,
        (0..n as u32).collect::<Vec<_>>()
    );
}

#[test]
fn fast_engine_gives_the_same_positions_in_every_node_order() {
    let model = random_box(11, true);
    let base = run(&model, EngineKind::Fast, config(&model));
    // The state moved: the comparison is not between two copies of the start.
    let (x0, _) = random_state(&model, 5);
    assert!(relative_l2(&model.rest, &x0, &base) > 1e-2);
    for order in &ORDERS[1..] {
        let c = SimConfig {
            node_order: *order,
            ..config(&model)
        };
        let err = relative_l2(&model.rest, &run(&model, EngineKind::Fast, c), &base);
        eprintln!("fast {order}: {err:e}");
        assert!(err < TOLERANCE, "{order} differs from rcm by {err:e}");
    }
}

#[test]
fn gpu_engine_gives_the_same_positions_in_every_node_order_and_layout() {
    let Some(_) = common::gpu() else { return };
    let model = random_box(12, true);
    let base = run(&model, EngineKind::Fast, config(&model));
    let variants = [
        (LayoutKind::Connectivity, Accumulation::Gather),
        (LayoutKind::Valence, Accumulation::Gather),
        (LayoutKind::Edges, Accumulation::Gather),
        (LayoutKind::Edges, Accumulation::AtomicFixed),
    ];
    for (layout, accumulation) in variants {
        for order in ORDERS {
            let c = SimConfig {
                node_order: order,
                ..config(&model)
            };
            let gpu = GpuOptions {
                layout,
                accumulation,
            };
            let err = relative_l2(&model.rest, &run_on(&model, EngineKind::Gpu, c, gpu), &base);
            eprintln!("{layout:?}/{accumulation:?} {order}: {err:e}");
            // Fixed point rounds each force to its quantum (about 1e-5 here, the same in every
            // order since integer sums do not depend on the order of the adds).
            let tol = if accumulation == Accumulation::AtomicFixed {
                1e-4
            } else {
                TOLERANCE
            };
            assert!(
                err < tol,
                "{layout:?}/{accumulation:?} in {order} order differs from the CPU by {err:e}"
            );
        }
    }
}
