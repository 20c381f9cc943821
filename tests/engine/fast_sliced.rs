//! The fast engine's sliced spring layout (eight nodes a SIMD vector, rows padded within a
//! slice) gives the float64 reference's step to float32 rounding: on random boxes whose nodes
//! are jittered into slivers and prestressed springs, and after cut-like patches, where only the
//! edited slices are rewritten.
//!
//! One step from a random state is compared node by node against the reference's, relative to
//! the size of the terms that step sums at that node (each spring's elastic and damping force,
//! the velocity carried), so that float32 rounding of a sum of ~14 springs (about 1e-6 of it)
//! passes and a spring lost, doubled or read from the wrong lane (a whole term, 1e-2 and more
//! of the sum) fails, even on a node whose forces nearly cancel.

use crate::models::{random_diff, random_model, random_state, Rng};
use lancet::engine::fast::FastEngine;
use lancet::engine::reference::ReferenceEngine;
use lancet::engine::{Engine, Integrator, SimConfig};
use lancet::model::{stable_time_step, PackedModel};

/// Relative error allowed: float32 sums of ~14 terms round to a few 1e-7 of their sizes.
const TOLERANCE: f64 = 2e-5;

/// [`random_model`] with its nodes moved at random by up to 20% of a cell each way, and a few moved to
/// within a micrometre of a neighbour: slivers, springs a thousand times shorter than others,
/// and rest lengths that no longer match the rest shape (the springs start loaded).
fn sliver_model(seed: u64, damped: bool) -> PackedModel {
    let mut model = random_model(seed, damped);
    let mut rng = Rng(seed.wrapping_mul(31) | 1);
    for r in &mut model.rest {
        for c in r.iter_mut() {
            *c += 0.004 * (rng.next() - 0.5);
        }
    }
    let springs: Vec<[u32; 2]> = model.springs().iter().map(|s| s.nodes).collect();
    for k in 0..6 {
        let [a, b] = springs[(k * 97 + seed as usize * 13) % springs.len()];
        let to = model.rest[b as usize];
        model.rest[a as usize] = [to[0] + 1e-6, to[1] - 1e-6, to[2] + 1e-6];
    }
    model
}

/// Per node, the sum of the sizes of what one step adds to its velocity (each spring's elastic
/// and damping force over the mass, times `h`) plus its velocity: the scale float32 rounding of
/// the step is relative to. Float64, from the model, at state `(x, v)`.
fn term_sizes(model: &PackedModel, x: &[[f64; 3]], v: &[[f64; 3]], h: f64) -> Vec<f64> {
    let norm = |a: [f64; 3]| (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    let mut size: Vec<f64> = v.iter().map(|w| norm(*w) + 1e-12).collect();
    for s in model.springs() {
        let [a, b] = s.nodes.map(|i| i as usize);
        let l = norm([0, 1, 2].map(|c| x[b][c] - x[a][c]));
        let dv = norm([0, 1, 2].map(|c| v[b][c] - v[a][c]));
        let f = s.stiffness * (l - s.rest_length).abs() + s.damping * dv;
        size[a] += h * f / model.mass[a];
        size[b] += h * f / model.mass[b];
    }
    size
}

/// The largest difference between the fast engine's and the reference's state after one step
/// from `(x, v)`, relative to [`term_sizes`]; the node where it is.
fn one_step_error(
    fast: &mut FastEngine,
    model: &PackedModel,
    config: SimConfig,
    x: &[[f64; 3]],
    v: &[[f64; 3]],
) -> (f64, usize) {
    let mut reference = ReferenceEngine::new(model, config);
    reference.set_state(x, v);
    fast.set_state(x, v);
    reference.step(1);
    fast.step(1);
    let size = term_sizes(model, x, v, config.dt);
    let (rv, fv) = (reference.velocities(), fast.velocities());
    let (rx, fx) = (reference.positions(), fast.positions());
    (0..model.node_count())
        .map(|i| {
            let dv = (0..3)
                .map(|c| (rv[i][c] - fv[i][c]).abs())
                .fold(0.0, f64::max);
            // A position moves by h times the new velocity.
            let dx = (0..3)
                .map(|c| (rx[i][c] - fx[i][c]).abs())
                .fold(0.0, f64::max);
            ((dv / size[i]).max(dx / (config.dt * size[i])), i)
        })
        .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a })
}

#[test]
fn the_sliced_layout_steps_as_the_reference_on_slivers_and_after_patches() {
    for (seed, damped) in [(3u64, false), (4, true)] {
        let model = sliver_model(seed, damped);
        for integrator in [Integrator::SymplecticEuler, Integrator::Verlet] {
            let mut config = SimConfig::new(0.5 * stable_time_step(&model).dt);
            config.integrator = integrator;
            config.allow_unstable = true;
            let mut fast = FastEngine::new(&model, config);
            let (x, v) = random_state(&model, seed + 10);
            let (e, node) = one_step_error(&mut fast, &model, config, &x, &v);
            assert!(
                e < TOLERANCE,
                "seed {seed} damped {damped} {integrator:?}: node {node} off the reference by \
                 {e:.2e} of its terms"
            );
            // Cut-like patches: rows shrink, grow, appear (new nodes fill the last slice and
            // open new ones); each patched engine against a reference built on the new model.
            let mut patched = model.clone();
            for round in 0..4 {
                let mut diff = random_diff(&patched, seed * 100 + round);
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
                assert!(
                    fast.patch(&patched, &diff).unwrap().is_some(),
                    "patched in place"
                );
                let rebuilt = fast.differences_from_rebuild(&patched).unwrap();
                assert!(rebuilt.is_empty(), "round {round}: {rebuilt:?}");
                let (x, v) = random_state(&patched, seed + round);
                let (e, node) = one_step_error(&mut fast, &patched, config, &x, &v);
                assert!(
                    e < TOLERANCE,
                    "seed {seed} damped {damped} {integrator:?} after patch {round}: node {node} \
                     off the reference by {e:.2e} of its terms"
                );
            }
        }
    }
}

/// Each spring end is stored once, in the sliced layout, and the valence sort keeps the slices'
/// padding small: on the peer benchmark's five-tet grid (a small one) and on a six-tet box,
/// damped, the engine's memory is its node arrays (four 16-byte state buffers, order and rank,
/// inverse mass, fixed flag, row length, slice bounds) plus at most 28 bytes a spring end
/// (24 of spring, 4 of damping) and the padding, which is under a tenth of the spring bytes.
/// A second, row-wise copy of the springs (36 bytes an end) would double the spring bytes.
#[test]
fn each_spring_end_is_stored_once_with_little_padding() {
    use lancet::mesh::generate::{BoxGrid, TetSplit};
    use lancet::report::bench::Preset;
    for split in [TetSplit::Five, TetSplit::Six] {
        let mut grid = BoxGrid::cube_cells([12, 8, 8], Preset::CELL);
        grid.split = split;
        let mesh = grid.build().unwrap();
        let model = Preset::Damped.model(&mesh).unwrap();
        let fast = FastEngine::new(&model, SimConfig::new(Preset::DT));
        let mem = fast.memory().stats;
        let n = model.node_count() as u64;
        let ends = 2 * model.springs().len() as u64;
        let node_bytes = n * (4 * 16 + 8 + 4 + 1 + 4) + n.div_ceil(8) * 8;
        let spring_bytes = mem.total - node_bytes;
        let live = ends * 28;
        assert!(
            spring_bytes >= live && spring_bytes - mem.padding == live,
            "{split:?}: {spring_bytes} B of springs, {} B of padding, {live} B of spring ends",
            mem.padding
        );
        assert!(
            mem.padding * 10 < spring_bytes,
            "{split:?}: padding {} B of {spring_bytes} B of springs",
            mem.padding
        );
    }
}
