//! The fast CPU engine's read ahead (`Engine::prefetch_near`): given a box before a step, it
//! finds the nodes in it after the step, and a `nodes_near` for a box inside it is the list a
//! scan of its own gives, bit for bit. It is never served once the state has changed (a step,
//! a correction, `set_state`, a patch) or for a box it does not hold.

use crate::{models, read_ahead};
use lancet::engine::fast::FastEngine;
use lancet::engine::{Engine, SimConfig};
use lancet::model::PackedModel;
use models::{boxes_near, random_diff, random_model, random_state, Rng};
use read_ahead::{holds_the_box, reads_ahead_as_on_its_own};

/// Something done to an engine between its step and a read.
type Change = Box<dyn Fn(&mut FastEngine)>;

fn engine(model: &PackedModel) -> FastEngine {
    let mut engine = FastEngine::new(model, SimConfig::new(2e-5));
    let (x, v) = random_state(model, 3);
    engine.set_state(&x, &v);
    engine
}

#[test]
fn a_read_ahead_gives_the_nodes_in_the_box_as_a_scan_of_its_own_does() {
    let model = random_model(11, false);
    reads_ahead_as_on_its_own(&mut engine(&model), model, 4);
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
        holds_the_box(&engine, asked, &got);
    }
}
