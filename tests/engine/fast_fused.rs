//! Two explicit steps in one sweep of the nodes (`engine/fast/fused.rs`) give the same bits as
//! two steps one after the other: on 1, 2 and 3 threads, damped and undamped, the springs'
//! constants per end or one material, Verlet and symplectic Euler, from a random state, and
//! after patches: one that only removes and changes springs (the sweep still pairs steps) and
//! a cut-like one that appends nodes joined to far ones.
//!
//! A node's step read from a half-written neighbour, or a state overwritten before a neighbour
//! read it, changes the bits at once; that the pairs were made in one sweep at all is asserted
//! too (a layout whose reach rules the pairing out steps singly, which proves nothing).

use crate::models::{one_material, random_box_of, random_diff, random_state};
use lancet::engine::fast::{on_threads, FastEngine};
use lancet::engine::{Engine, Integrator, SimConfig};
use lancet::model::{stable_time_step, ModelDiff, PackedModel};
use rstest::rstest;

/// A long box (about 1,500 nodes) whose locality order keeps every spring within a short
/// reach of its ends, with random per-spring constants and masses, gravity, mass damping and a
/// fixed end: long enough that two or three threads' ranges each span several reaches.
fn long_box(seed: u64, damped: bool) -> PackedModel {
    random_box_of([40, 5, 5], [1.0, 0.0, 0.0], seed, damped)
}

/// A patch that adds no node: every ninth spring removed and, where the constants are kept
/// per end, every thirteenth of the rest stiffened (as a cut that only separates does).
fn removals(model: &PackedModel, per_end: bool) -> ModelDiff {
    let mut diff = ModelDiff::default();
    for (k, s) in model.springs().iter().enumerate() {
        if k % 9 == 4 {
            diff.removed_springs.push(s.nodes);
        } else if per_end && k % 13 == 6 {
            let mut s = *s;
            s.stiffness *= 1.5;
            diff.changed_springs.push(s);
        }
    }
    diff
}

/// The bits of the state (positions and velocities, model order).
fn bits(e: &FastEngine) -> Vec<u64> {
    let (x, v) = (e.positions(), e.velocities());
    x.iter().chain(&v).flatten().map(|f| f.to_bits()).collect()
}

/// `steps` steps from `(x, v)` on `threads` threads, paired in one sweep where `fused`:
/// the state's bits and the pairs made.
fn run(
    engine: &mut FastEngine,
    threads: usize,
    fused: bool,
    (x, v): &(Vec<[f64; 3]>, Vec<[f64; 3]>),
    steps: u32,
) -> (Vec<u64>, u64) {
    engine.set_fused_steps(fused);
    engine.set_state(x, v);
    let before = engine.fused_step_pairs();
    on_threads(threads, || engine.step(steps)).unwrap();
    (bits(engine), engine.fused_step_pairs() - before)
}

#[rstest]
fn two_steps_in_one_sweep_give_the_bits_of_two_steps(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
    #[values(false, true)] damped: bool,
    #[values(false, true)] one: bool,
    #[values(1, 2, 3)] threads: usize,
) {
    let seed = 90 + threads as u64;
    let model = if one {
        one_material(long_box(seed, damped))
    } else {
        long_box(seed, damped)
    };
    let mut config = SimConfig::new(0.5 * stable_time_step(&model).dt);
    config.integrator = integrator;
    let mut fused = FastEngine::new(&model, config);
    let mut single = FastEngine::new(&model, config);
    assert_eq!(fused.uniform_springs().is_some(), one);
    let state = random_state(&model, seed);
    // An odd count: the last step is made alone.
    let (a, pairs) = run(&mut fused, threads, true, &state, 41);
    let (b, none) = run(&mut single, threads, false, &state, 41);
    assert_eq!(
        (pairs, none),
        (20, 0),
        "steps paired (bandwidth {})",
        fused.bandwidth()
    );
    assert!(a == b, "two steps a sweep differ from one step a sweep");

    // A patch that adds no node keeps the reach: the pairs are still made, and still exact.
    let mut patched = model.clone();
    let diff = removals(&patched, !one);
    patched.apply(&diff).unwrap();
    for e in [&mut fused, &mut single] {
        assert!(
            e.patch(&patched, &diff).unwrap().is_some(),
            "patched in place"
        );
    }
    let state = random_state(&patched, seed + 1);
    let (a, pairs) = run(&mut fused, threads, true, &state, 30);
    let (b, _) = run(&mut single, threads, false, &state, 30);
    assert_eq!(pairs, 15, "steps paired after the patch");
    assert!(
        a == b,
        "after a patch, two steps a sweep differ from one step a sweep"
    );
}

/// A cut-like patch appends nodes joined to nodes far from the end of the order: the reach
/// grows to about the node count, so several threads step one step a sweep (and one thread
/// pairs steps with its second step waiting for the whole first); the bits stay those of
/// single steps either way.
#[rstest]
fn after_a_cut_like_patch_the_bits_are_those_of_single_steps(
    #[values(Integrator::Verlet, Integrator::SymplecticEuler)] integrator: Integrator,
    #[values(false, true)] damped: bool,
    #[values(1, 2)] threads: usize,
) {
    let model = long_box(97, damped);
    let mut config = SimConfig::new(0.5 * stable_time_step(&model).dt);
    config.integrator = integrator;
    let mut fused = FastEngine::new(&model, config);
    let mut single = FastEngine::new(&model, config);
    let mut patched = model.clone();
    for round in 0..2 {
        let mut diff = random_diff(&patched, 970 + round);
        if !damped {
            // Kept undamped: a first damped spring rebuilds the engine instead.
            for s in diff
                .added_springs
                .iter_mut()
                .chain(&mut diff.changed_springs)
            {
                s.damping = 0.0;
            }
        }
        patched.apply(&diff).unwrap();
        for e in [&mut fused, &mut single] {
            assert!(
                e.patch(&patched, &diff).unwrap().is_some(),
                "patched in place"
            );
        }
        let state = random_state(&patched, 97 + round);
        let (a, pairs) = run(&mut fused, threads, true, &state, 24);
        let (b, _) = run(&mut single, threads, false, &state, 24);
        if threads == 1 {
            assert_eq!(pairs, 12, "one thread pairs steps whatever the reach");
        }
        assert!(
            a == b,
            "round {round}: fused steps differ from single steps"
        );
    }
}
