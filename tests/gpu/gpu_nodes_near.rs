//! Nodes near a blade, found on the device (`shaders/nodes_near.wgsl`): on random deformed
//! states, in every layout, before and after cut-like patches (appended nodes, valence holes),
//! the device's list holds every node its float64 twin (the same box test on
//! `Engine::positions`) finds, gives each the position a full readback gives bit for bit, and
//! adds only nodes within float32 rounding of the box; an output that is too small grows and
//! the pass runs again, dropping nothing.

use crate::{common, models};
use lancet::cut::reading::float32_box;
use lancet::engine::gpu::GpuEngine;
use lancet::engine::{Engine, SimConfig};
use lancet::layout::{LayoutKind, NodeOrder};
use lancet::mesh::generate::BoxGrid;
use lancet::model::{Material, ModelConfig, PackedModel, SpringModel};
use lancet::twin::nodes_near::nodes_near_cpu;
use models::{random_diff, random_model, random_state, Rng};
use rstest::rstest;

/// Check one box: the device's nodes against the float64 scan of every position.
fn check_box(engine: &mut GpuEngine, lo: [f64; 3], hi: [f64; 3]) -> usize {
    let x = engine.positions();
    let inside =
        |p: &[f64; 3], pad: f64| (0..3).all(|c| p[c] >= lo[c] - pad && p[c] <= hi[c] + pad);
    let got = engine.nodes_near(lo, hi).unwrap();
    assert!(
        got.windows(2).all(|w| w[0].0 < w[1].0),
        "nodes ascending, each once"
    );
    for &(i, p) in &got {
        assert_eq!(
            p.map(f64::to_bits),
            x[i as usize].map(f64::to_bits),
            "node {i}: the position a full readback gives"
        );
        // Only float32 rounding may add a node from outside.
        assert!(
            inside(&p, 1e-5),
            "node {i} at {p:?} is far outside {lo:?}..{hi:?}"
        );
    }
    let want: Vec<u32> = (0..x.len() as u32)
        .filter(|&i| inside(&x[i as usize], 0.0))
        .collect();
    for i in &want {
        assert!(
            got.binary_search_by_key(i, |e| e.0).is_ok(),
            "node {i} at {:?} lies in {lo:?}..{hi:?} but was not found",
            x[*i as usize]
        );
    }
    want.len()
}

/// A random box: a corner near a random node, half-sizes from a millimetre to the whole mesh.
fn random_box(rng: &mut Rng, x: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let p = x[(rng.next() * x.len() as f64) as usize];
    let half = [0, 1, 2].map(|_| 1e-3 * (1.0 + 40.0 * rng.next() * rng.next()));
    let c = p.map(|v| v + (rng.next() - 0.5) * 1e-2);
    (
        [0, 1, 2].map(|k| c[k] - half[k]),
        [0, 1, 2].map(|k| c[k] + half[k]),
    )
}

#[rstest]
fn device_finds_every_node_in_the_box(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    let Some(ctx) = common::gpu() else { return };
    let mut model = random_model(7, false);
    let mut engine = GpuEngine::with_context(ctx, &model, SimConfig::new(2e-5), kind).unwrap();
    let (x, v) = random_state(&model, 7);
    engine.set_state(&x, &v);
    engine.step(3);
    engine.set_surface(&[[0, 1, 2]]).unwrap();
    let mut rng = Rng(99);
    let mut found = 0;
    for round in 0..4 {
        for _ in 0..10 {
            let (lo, hi) = random_box(&mut rng, &engine.positions());
            found += check_box(&mut engine, lo, hi);
        }
        // A cut-like change: nodes appended (copies, nodes on edges), rows moved, holes left.
        let diff = random_diff(&model, 300 + round);
        let mut next: PackedModel = model.clone();
        next.apply(&diff).unwrap();
        engine.patch(&next, &diff).unwrap();
        model = next;
        engine.step(2);
    }
    assert!(
        found > 100,
        "the boxes held too few nodes to test ({found})"
    );
    // The springless nodes far from the box (one at 5 cm) are found when the box holds them.
    let far = model.rest[model.rest.len() - 1];
    assert!(check_box(&mut engine, far.map(|v| v - 1e-3), far.map(|v| v + 1e-3)) >= 1);
}

#[test]
fn an_output_too_small_grows_and_drops_nothing() {
    let Some(ctx) = common::gpu() else { return };
    // 19^3 = 6,859 nodes: more than the pass first has room for (2,048 entries, rounded up
    // to a size class: 4,095).
    let mesh = BoxGrid::cube_cells([18, 18, 18], 0.01).build().unwrap();
    let model = SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(5e3, 0.3, 1e3)))
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let mut engine =
        GpuEngine::with_context(ctx, &model, SimConfig::new(1e-5), LayoutKind::Valence).unwrap();
    let (x, v) = random_state(&model, 3);
    engine.set_state(&x, &v);
    engine.set_surface(&[[0, 1, 2]]).unwrap();
    let all = check_box(&mut engine, [-1.0; 3], [1.0; 3]);
    assert_eq!(all, model.rest.len());
    // And again, now with the room the first call made.
    assert_eq!(check_box(&mut engine, [-1.0; 3], [1.0; 3]), all);
}

#[test]
fn without_a_surface_every_position_is_scanned() {
    let Some(ctx) = common::gpu() else { return };
    let model = random_model(11, false);
    let mut engine =
        GpuEngine::with_context(ctx, &model, SimConfig::new(2e-5), LayoutKind::Valence).unwrap();
    let (x, v) = random_state(&model, 11);
    engine.set_state(&x, &v);
    assert!(check_box(&mut engine, [-0.005; 3], [0.025; 3]) >= 27);
}

/// The device's list is exactly its twin's (`twin::nodes_near`, the pass's float32 test on the
/// rest positions and raw displacements in layout order): the same nodes, none more or fewer,
/// at the positions the twin's displacements give, bit for bit; in every layout, before and
/// after a cut-like patch (appended nodes, valence holes).
#[rstest]
fn device_finds_the_nodes_its_twin_finds(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    let Some(ctx) = common::gpu() else { return };
    let mut model = random_model(5, false);
    let mut engine = GpuEngine::with_context(ctx, &model, SimConfig::new(2e-5), kind).unwrap();
    let (x, v) = random_state(&model, 5);
    engine.set_state(&x, &v);
    engine.step(3);
    engine.set_surface(&[[0, 1, 2]]).unwrap();
    let mut rng = Rng(41);
    let mut found = 0;
    for round in 0..2 {
        let rest = engine.rest_f32();
        let (disp, _) = engine.raw_state().unwrap();
        let order = engine.layout().order().order.clone();
        for _ in 0..15 {
            let (lo, hi) = random_box(&mut rng, &engine.positions());
            let (lo32, hi32) = float32_box(lo, hi);
            let mut want: Vec<(u32, [f64; 3])> = nodes_near_cpu(&rest, &disp, lo32, hi32)
                .into_iter()
                .filter(|&(slot, _)| order[slot as usize] != NodeOrder::HOLE)
                .map(|(slot, u)| {
                    let old = order[slot as usize];
                    let r = model.rest[old as usize];
                    (old, [0, 1, 2].map(|c| r[c] + u[c] as f64))
                })
                .collect();
            want.sort_by_key(|e| e.0);
            let got = engine.nodes_near(lo, hi).unwrap();
            let bits = |l: &[(u32, [f64; 3])]| -> Vec<(u32, [u64; 3])> {
                l.iter().map(|&(i, p)| (i, p.map(f64::to_bits))).collect()
            };
            assert_eq!(
                bits(&got),
                bits(&want),
                "{kind:?} round {round}: {lo:?}..{hi:?}"
            );
            found += want.len();
        }
        let diff = random_diff(&model, 500 + round);
        let mut next: PackedModel = model.clone();
        next.apply(&diff).unwrap();
        engine.patch(&next, &diff).unwrap();
        model = next;
        engine.step(2);
    }
    assert!(found > 50, "the boxes held too few nodes to test ({found})");
}
