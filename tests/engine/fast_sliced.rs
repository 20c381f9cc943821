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

use crate::models::{one_material, random_diff, random_model, random_state, rest_length, Rng};
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

/// One spring material (one stiffness and damping, each rest length its rest edge's, on the same
/// slivers): the layout keeps the constants once and the step takes each rest length from its
/// edge vector, and steps as the reference to float32 rounding, before and after patches of
/// the same material. A patch bringing a spring of another stiffness is refused (a uniform
/// layout cannot hold it) before anything changes, and the simulation rebuilds the engine with
/// per-end constants: the rebuilt engine steps as one built on the new model, and as the
/// reference.
#[test]
fn one_material_layout_steps_as_the_reference_and_a_cut_off_its_material_rebuilds() {
    use lancet::engine::{EngineKind, Simulation};
    use lancet::model::{ModelDiff, PackedSpring};
    for (seed, damped) in [(5u64, false), (6, true)] {
        let model = one_material(sliver_model(seed, damped));
        let (k, c) = (model.springs()[0].stiffness, model.springs()[0].damping);
        for integrator in [Integrator::SymplecticEuler, Integrator::Verlet] {
            let mut config = SimConfig::new(0.5 * stable_time_step(&model).dt);
            config.integrator = integrator;
            config.allow_unstable = true;
            let mut fast = FastEngine::new(&model, config);
            let what = format!("seed {seed} damped {damped} {integrator:?}");
            assert_eq!(
                fast.uniform_springs(),
                Some((k as f32 as f64, c as f32 as f64))
            );
            let (x, v) = random_state(&model, seed + 10);
            let (e, node) = one_step_error(&mut fast, &model, config, &x, &v);
            assert!(
                e < TOLERANCE,
                "{what}: node {node} off by {e:.2e} of its terms"
            );
            let mut patched = model.clone();
            for round in 0..3 {
                let mut diff = random_diff(&patched, seed * 100 + round);
                // The new and changed springs of the one material, at rest.
                let mut rest = patched.rest.clone();
                rest.extend(diff.added_nodes.iter().map(|a| a.rest));
                for s in diff
                    .added_springs
                    .iter_mut()
                    .chain(&mut diff.changed_springs)
                {
                    (s.stiffness, s.damping) = (k, c);
                    s.rest_length = rest_length(&rest, s.nodes);
                }
                patched.apply(&diff).unwrap();
                assert!(fast.patch(&patched, &diff).unwrap().is_some(), "{what}");
                assert!(fast.uniform_springs().is_some(), "{what} round {round}");
                let rebuilt = fast.differences_from_rebuild(&patched).unwrap();
                assert!(rebuilt.is_empty(), "{what} round {round}: {rebuilt:?}");
                let (x, v) = random_state(&patched, seed + round);
                let (e, node) = one_step_error(&mut fast, &patched, config, &x, &v);
                assert!(
                    e < TOLERANCE,
                    "{what} after patch {round}: node {node} off by {e:.2e} of its terms"
                );
            }
            // One spring made 1.5 times as stiff.
            let s = patched.springs()[7];
            let stiffer = ModelDiff {
                changed_springs: vec![PackedSpring {
                    stiffness: 1.5 * s.stiffness,
                    ..s
                }],
                ..Default::default()
            };
            let mut off = patched.clone();
            off.apply(&stiffer).unwrap();
            assert!(fast.patch(&off, &stiffer).unwrap().is_none(), "{what}");
            let mut sim = Simulation::new(patched.clone(), EngineKind::Fast, config).unwrap();
            let (x, v) = random_state(&patched, seed + 20);
            sim.set_state(&x, &v).unwrap();
            assert!(sim.apply(&stiffer).unwrap().reallocated, "{what}");
            let mut fresh = FastEngine::new(&off, config);
            assert_eq!(fresh.uniform_springs(), None, "{what}");
            fresh.set_state(&x, &v);
            sim.step_unchecked(3);
            fresh.step(3);
            assert_eq!(sim.positions(), fresh.positions(), "{what}");
            let (e, node) = one_step_error(&mut fresh, &off, config, &x, &v);
            assert!(e < TOLERANCE, "{what}, rebuilt: node {node} off by {e:.2e}");
        }
        // One spring prestressed by 1e-5 of its length (20 float32 ulps): its rest length is
        // no longer its edge's, so the constants are stored per end (a rest length taken from
        // the edge would silently drop the prestress).
        let mut loaded = model.clone();
        loaded.springs_mut()[11].rest_length *= 1.0 + 1e-5;
        loaded.reindex();
        let config = SimConfig::new(0.5 * stable_time_step(&loaded).dt);
        let mut fast = FastEngine::new(&loaded, config);
        assert_eq!(fast.uniform_springs(), None, "seed {seed}");
        let (x, v) = random_state(&loaded, seed + 30);
        let (e, node) = one_step_error(&mut fast, &loaded, config, &x, &v);
        assert!(
            e < TOLERANCE,
            "seed {seed} prestressed: node {node} off by {e:.2e}"
        );
    }
}

/// Each spring end is stored once, in the sliced layout, and the valence sort keeps the slices'
/// padding small: on the peer benchmark's five-tet grid (a small one) and on a six-tet box,
/// damped and undamped, the engine's memory is its node arrays (four 16-byte state buffers,
/// order and rank, inverse mass, fixed flag, row length; per slice its groups' place and the
/// first and last node its step reads, 16 bytes) plus 16 bytes a spring
/// end (neighbour and rest edge vector: the benchmark's springs are of one material, whose
/// stiffness and damping are kept once) and the padding, which is under a tenth of the spring
/// bytes; with the stiffness varied per spring (the random box's), 24 bytes an end, 28 damped.
/// A second, row-wise copy of the springs (36 bytes an end) would double the spring bytes.
#[test]
fn each_spring_end_is_stored_once_with_little_padding() {
    use lancet::mesh::generate::{BoxGrid, TetSplit};
    use lancet::report::bench::Preset;
    let node_bytes = |n: u64| n * (4 * 16 + 8 + 4 + 1 + 4) + n.div_ceil(8) * 16;
    for split in [TetSplit::Five, TetSplit::Six] {
        let mut grid = BoxGrid::cube_cells([12, 8, 8], Preset::CELL);
        grid.split = split;
        let mesh = grid.build().unwrap();
        for preset in [Preset::Damped, Preset::Undamped] {
            let model = preset.model(&mesh).unwrap();
            let fast = FastEngine::new(&model, SimConfig::new(Preset::DT));
            let mem = fast.memory().stats;
            let ends = 2 * model.springs().len() as u64;
            let spring_bytes = mem.total - node_bytes(model.node_count() as u64);
            let live = ends * 16;
            assert!(
                spring_bytes >= live && spring_bytes - mem.padding == live,
                "{split:?} {preset:?}: {spring_bytes} B of springs, {} B of padding, {live} B \
                 of spring ends",
                mem.padding
            );
            assert!(
                mem.padding * 10 < spring_bytes,
                "{split:?}: padding {} B of {spring_bytes} B of springs",
                mem.padding
            );
        }
    }
    for (damped, per_end) in [(false, 24), (true, 28)] {
        let model = random_model(9, damped);
        let fast = FastEngine::new(&model, SimConfig::new(1e-5));
        assert_eq!(fast.uniform_springs(), None);
        let mem = fast.memory().stats;
        let spring_bytes = mem.total - node_bytes(model.node_count() as u64);
        let live = 2 * model.springs().len() as u64 * per_end;
        assert_eq!(spring_bytes - mem.padding, live, "damped {damped}");
    }
}
