//! Checks of reads made ahead (`Engine::prefetch_near`) that hold for every engine that reads
//! ahead (the GPU engine in each layout, the fast CPU engine). Included with `#[path]` beside
//! `common/models.rs`.

use lancet::engine::Engine;
use lancet::model::PackedModel;

use super::models::{boxes_near, random_diff, Rng};

/// Nodes found in a box, with their positions.
pub type Found = Vec<(u32, [f64; 3])>;

/// Every node whose position lies in the box is in `got`, each with the position a full
/// readback gives, bit for bit; returns how many the box holds.
pub fn holds_the_box(engine: &dyn Engine, [lo, hi]: [[f64; 3]; 2], got: &Found) -> usize {
    let x = engine.positions();
    for &(i, p) in got {
        assert_eq!(
            p.map(f64::to_bits),
            x[i as usize].map(f64::to_bits),
            "node {i}: not the position a full readback gives (a stale read?)"
        );
    }
    let inside = |p: &[f64; 3]| (0..3).all(|c| p[c] >= lo[c] && p[c] <= hi[c]);
    let want: Vec<u32> = (0..x.len() as u32)
        .filter(|&i| inside(&x[i as usize]))
        .collect();
    for i in &want {
        assert!(
            got.binary_search_by_key(i, |e| e.0).is_ok(),
            "node {i} lies in the box but was not found"
        );
    }
    want.len()
}

/// Over three rounds of eight random boxes, with a cut-like patch of `model` (the engine's
/// model) between rounds: a read for a box inside the one read ahead with the step is served
/// by it, holds the box, and is the list a read of its own gives, bit for bit.
pub fn reads_ahead_as_on_its_own(engine: &mut dyn Engine, mut model: PackedModel, seed: u64) {
    let mut rng = Rng(seed);
    let mut found = 0;
    for round in 0..3 {
        for _ in 0..8 {
            let (inner, outer) = boxes_near(&mut rng, &engine.positions());
            engine.prefetch_near(outer[0], outer[1]);
            engine.step(1);
            let before = engine.near_reads();
            let ahead = engine.nodes_near(inner[0], inner[1]).unwrap();
            assert_eq!(
                engine.near_reads().ahead,
                before.ahead + 1,
                "served by the step"
            );
            // A box inside it: served by the same read.
            let smaller = [inner[0].map(|v| v + 1e-4), inner[1].map(|v| v - 1e-4)];
            let again = engine.nodes_near(smaller[0], smaller[1]).unwrap();
            assert_eq!(engine.near_reads().ahead, before.ahead + 2);
            holds_the_box(engine, smaller, &again);
            // The same box with a read of its own: a step of no steps drops the read ahead
            // and leaves the state as it is.
            engine.step(0);
            let own = engine.nodes_near(inner[0], inner[1]).unwrap();
            assert_eq!(engine.near_reads().direct, before.direct + 1);
            assert_eq!(ahead.len(), own.len(), "the same nodes");
            for (a, b) in ahead.iter().zip(&own) {
                assert_eq!((a.0, a.1.map(f64::to_bits)), (b.0, b.1.map(f64::to_bits)));
            }
            found += holds_the_box(engine, inner, &ahead);
        }
        // A cut-like change (nodes appended, rows moved, holes left) between reads.
        let diff = random_diff(&model, 300 + round);
        let mut next = model.clone();
        next.apply(&diff).unwrap();
        engine.patch(&next, &diff).unwrap();
        model = next;
    }
    assert!(
        found > 100,
        "the boxes held too few nodes to test ({found})"
    );
}
