//! The fast CPU engine's read ahead (`Engine::prefetch_near`): given a box before a step, it
//! finds the nodes in it after the step, and a `nodes_near` for a box inside it is the list a
//! scan of its own gives, bit for bit. It is never served once the state has changed (a step,
//! a correction, `set_state`, a patch) or for a box it does not hold.

#[path = "common/models.rs"]
mod models;

use lancet::engine::fast::FastEngine;
use lancet::engine::{Engine, SimConfig};
use lancet::model::PackedModel;
use models::{boxes_near, random_diff, random_model, random_state, Rng};

type Found = Vec<(u32, [f64; 3])>;

/// Something done to an engine between its step and a read.
type Change = Box<dyn Fn(&mut FastEngine)>;

fn engine(model: &PackedModel) -> FastEngine {
    let mut engine = FastEngine::new(model, SimConfig::new(2e-5));
    let (x, v) = random_state(model, 3);
    engine.set_state(&x, &v);
    engine
}

fn bits(found: &Found) -> Vec<(u32, [u64; 3])> {
    found
        .iter()
        .map(|(i, p)| (*i, p.map(f64::to_bits)))
        .collect()
}

/// Every node in the box, from every position, in node order.
fn in_box(engine: &FastEngine, [lo, hi]: [[f64; 3]; 2]) -> Found {
    engine
        .positions()
        .into_iter()
        .enumerate()
        .filter(|(_, p)| (0..3).all(|c| p[c] >= lo[c] && p[c] <= hi[c]))
        .map(|(i, p)| (i as u32, p))
        .collect()
}

#[test]
fn a_read_ahead_gives_the_nodes_in_the_box_as_a_scan_of_its_own_does() {
    let mut model = random_model(11, false);
    let mut engine = engine(&model);
    let mut rng = Rng(4);
    let mut found = 0;
    for round in 0..3 {
        for _ in 0..8 {
            let (inner, outer) = boxes_near(&mut rng, &engine.positions());
            engine.prefetch_near(outer[0], outer[1]);
            engine.step(1);
            let before = engine.near_reads();
            let ahead = engine.nodes_near(inner[0], inner[1]).unwrap();
            assert_eq!(engine.near_reads().ahead, before.ahead + 1, "served ahead");
            assert_eq!(bits(&ahead), bits(&in_box(&engine, inner)));
            // A step of no steps drops the read and leaves the state: a scan of its own.
            engine.step(0);
            let own = engine.nodes_near(inner[0], inner[1]).unwrap();
            assert_eq!(engine.near_reads().direct, before.direct + 1);
            assert_eq!(bits(&ahead), bits(&own));
            found += ahead.len();
        }
        let diff = random_diff(&model, 40 + round);
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

#[test]
fn a_read_ahead_is_not_served_once_the_state_changed_or_for_a_box_it_does_not_hold() {
    let model = random_model(12, false);
    let mut engine = engine(&model);
    let mut rng = Rng(8);
    let x = engine.positions();
    let (inner, outer) = boxes_near(&mut rng, &x);
    let changes: [(&str, Change); 5] = [
        ("a step", Box::new(|e: &mut FastEngine| e.step(1))),
        (
            "a correction",
            Box::new(|e: &mut FastEngine| {
                let p = e.positions();
                let moved: Vec<u32> = (0..p.len() as u32).step_by(3).collect();
                let to: Vec<[f64; 3]> = moved
                    .iter()
                    .map(|&i| p[i as usize].map(|v| v + 1e-3))
                    .collect();
                e.correct_positions(&moved, &to).unwrap();
            }),
        ),
        (
            "set_state",
            Box::new(|e: &mut FastEngine| {
                let (x, v) = random_state(&random_model(12, false), 9);
                e.set_state(&x, &v);
            }),
        ),
        (
            "a patch",
            Box::new(|e: &mut FastEngine| {
                let model = random_model(12, false);
                let diff = random_diff(&model, 77);
                let mut next = model.clone();
                next.apply(&diff).unwrap();
                e.patch(&next, &diff).unwrap();
            }),
        ),
        (
            "nothing, a box it does not hold",
            Box::new(|_: &mut FastEngine| {}),
        ),
    ];
    for (what, change) in changes {
        engine.prefetch_near(outer[0], outer[1]);
        engine.step(1);
        change(&mut engine);
        let before = engine.near_reads();
        let asked = if what.starts_with("nothing") {
            // Wider than the read on one side.
            [outer[0].map(|v| v - 1e-3), inner[1]]
        } else {
            inner
        };
        let got = engine.nodes_near(asked[0], asked[1]).unwrap();
        assert_eq!(
            engine.near_reads().ahead,
            before.ahead,
            "served after {what}"
        );
        assert_eq!(bits(&got), bits(&in_box(&engine, asked)), "after {what}");
    }
}
