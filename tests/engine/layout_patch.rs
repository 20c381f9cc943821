//! Incremental patches of the three layouts after cut-like random edits: the patched layout
//! equals a from-scratch packing of the changed model in the same arrangement, every byte that
//! changed lies in a reported dirty range, node state follows its node, and stepping the patched
//! layout equals stepping a rebuilt one bit for bit.

use crate::models;
use lancet::engine::gpu::step_params;
use lancet::engine::{Integrator, SimConfig};
use lancet::layout::connectivity::ConnectivityLayout;
use lancet::layout::edges::{Accumulation, EdgeLayout};
use lancet::layout::patch::{LayoutArray, LayoutPatch};
use lancet::layout::{LayoutKind, NodeOrder, PackedLayout};
use lancet::model::{ModelDiff, PackedModel};
use lancet::twin::move_state::move_state_cpu;
use models::{fresh, random_diff, random_model, widen_node_0, Rng};
use rstest::rstest;

const ARRAYS: [LayoutArray; 6] = LayoutArray::ALL;

/// The model after `diff`.
pub(crate) fn applied(model: &PackedModel, diff: &ModelDiff) -> PackedModel {
    let mut m = model.clone();
    m.apply(diff).expect("a consistent random diff");
    m
}

/// Every byte that differs between `before` and `after` (or is new) lies in a dirty range.
fn assert_dirty_covers(before: &PackedLayout, after: &PackedLayout, patch: &LayoutPatch) {
    for a in ARRAYS {
        let (old, new) = (before.array(a), after.array(a));
        let dirty: Vec<_> = patch.dirty.iter().filter(|d| d.array == a).collect();
        for (i, &byte) in new.iter().enumerate() {
            let changed = old.get(i) != Some(&byte);
            let covered = dirty.iter().any(|d| d.bytes.contains(&(i as u64)));
            assert!(
                !changed || covered,
                "{a:?} byte {i} changed but is not in a dirty range {dirty:?}"
            );
        }
    }
}

/// Patch `layout` with `diff` (`next`: the model after it) and check the result: it equals a
/// fresh packing of `next` in the patched arrangement, and every changed byte lies in a dirty
/// range.
pub(crate) fn patch_checked(
    layout: &mut PackedLayout,
    next: &PackedModel,
    diff: &ModelDiff,
    round: u64,
) -> LayoutPatch {
    let before = layout.clone();
    let patch = layout.patch(next, diff).unwrap();
    // Not assert_eq: the Debug output of a layout is thousands of lines.
    assert!(
        *layout == fresh(next, layout),
        "round {round}: differs from a fresh packing"
    );
    assert_dirty_covers(&before, layout, &patch);
    patch
}

#[rstest]
fn patched_layout_equals_a_fresh_packing_after_successive_cuts(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence)] kind: LayoutKind,
    #[values(1, 2, 3, 4, 5, 6, 7, 8)] seed: u64,
) {
    let mut model = random_model(seed, true);
    let mut layout = PackedLayout::pack(&model, kind, NodeOrder::locality(&model)).unwrap();
    for round in 0..4 {
        let diff = random_diff(&model, seed * 31 + round);
        let next = applied(&model, &diff);
        patch_checked(&mut layout, &next, &diff, round);
        model = next;
    }
}

/// A model that is not the one the diff gives (a spring the diff changes left as it was, a
/// spring it removes still there) is refused with an error naming the spring, and the layout
/// is left as it was.
#[rstest]
fn a_model_that_does_not_match_the_diff_is_refused_and_the_layout_kept(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence)] kind: LayoutKind,
) {
    let model = random_model(5, true);
    let diff = random_diff(&model, 77);
    assert!(!diff.changed_springs.is_empty() && !diff.removed_springs.is_empty());
    let next = applied(&model, &diff);
    let layout = PackedLayout::pack(&model, kind, NodeOrder::locality(&model)).unwrap();
    // The changed spring as it was before the diff.
    let mut stale = next.clone();
    let c = diff.changed_springs[0];
    let i = stale.spring_index(c.nodes[0], c.nodes[1]).unwrap();
    stale.springs_mut()[i].stiffness =
        model.springs()[model.spring_index(c.nodes[0], c.nodes[1]).unwrap()].stiffness;
    assert_ne!(
        stale.springs()[i].stiffness,
        c.stiffness,
        "the diff changes the stiffness"
    );
    // A removed spring put back.
    let mut kept = next.clone();
    let [a, b] = diff.removed_springs[0];
    let gone = model.springs()[model.spring_index(a, b).unwrap()];
    kept.springs_mut().push(gone);
    for (wrong, what) in [(&stale, "adds or changes"), (&kept, "removes")] {
        let mut patched = layout.clone();
        let err = patched.patch(wrong, &diff).unwrap_err().to_string();
        assert!(err.contains(what) && err.contains("the model"), "{err}");
        assert!(patched == layout, "{what}: the layout changed");
    }
}

/// What `lancet run --check` asks of a layout after cuts: nothing differs from a rebuild; and
/// one wrong entry (a slot, a mass, a spring at a node) is found.
#[rstest]
fn a_patched_layout_agrees_with_a_rebuild_and_a_wrong_entry_is_found(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    let mut model = random_model(21, true);
    let mut layout = PackedLayout::pack(&model, kind, NodeOrder::locality(&model)).unwrap();
    for round in 0..4 {
        let diff = random_diff(&model, 900 + round);
        model = applied(&model, &diff);
        layout.patch(&model, &diff).unwrap();
        let found = layout.differences_from_rebuild(&model).unwrap();
        assert!(found.is_empty(), "round {round}: {found:?}");
    }
    // A free node's mass, and a slot or spring of its row.
    let node = (0..model.node_count())
        .find(|&i| !model.fixed[i])
        .expect("a free node");
    let idx = layout.order().rank[node] as usize;
    let mut wrong_mass = layout.clone();
    let mut wrong_spring = layout.clone();
    match (&mut wrong_mass, &mut wrong_spring) {
        (PackedLayout::Connectivity(m), PackedLayout::Connectivity(s)) => {
            m.nodes.inv_mass[idx] *= 2.0;
            let at = idx * s.capacity as usize;
            s.slots[at].rest *= 1.5;
        }
        (PackedLayout::Valence(m), PackedLayout::Valence(s)) => {
            m.nodes.inv_mass[idx] *= 2.0;
            s.slots.iter_mut().find(|x| x.rest > 0.0).unwrap().rest *= 1.5;
        }
        (PackedLayout::Edges(m), PackedLayout::Edges(s)) => {
            m.nodes.inv_mass[idx] *= 2.0;
            let [start, _] = s.incidence_rows[idx];
            let spring = s.incidence[start as usize] & !lancet::layout::edges::B_END;
            s.springs[spring as usize].k *= 1.5;
        }
        _ => unreachable!(),
    }
    for (what, wrong) in [("mass", wrong_mass), ("spring", wrong_spring)] {
        let found = wrong.differences_from_rebuild(&model).unwrap();
        assert_eq!(found.len(), 1, "{kind:?} wrong {what}: {found:?}");
    }
}

#[rstest]
fn state_moves_keep_every_node_its_own_state(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
    #[values(11, 12, 13, 14)] seed: u64,
) {
    let model = random_model(seed, false);
    let mut layout = PackedLayout::pack(&model, kind, NodeOrder::locality(&model)).unwrap();
    let mut rng = Rng(seed);
    let state: Vec<[f32; 4]> = (0..layout.node_slots())
        .map(|_| [rng.next() as f32, rng.next() as f32, rng.next() as f32, 0.0])
        .collect();
    let old = layout.order().clone();
    let diff = random_diff(&model, seed);
    let next = applied(&model, &diff);
    let patch = layout.patch(&next, &diff).unwrap();
    let moved = move_state_cpu(&state, &patch.moves, layout.node_slots());
    let new = layout.order();
    let touched = diff.touched_nodes(model.node_count());
    for t in 0..next.node_count() {
        let want = if next.fixed[t] && touched.contains(&(t as u32)) {
            // Fixed by the change: at rest from now on.
            [0.0; 4]
        } else if t < model.node_count() {
            state[old.rank[t] as usize]
        } else {
            let a = &diff.added_nodes[t - model.node_count()];
            let from = state[old.rank[a.state_from.unwrap() as usize] as usize];
            match a.blend {
                None => from,
                // A node put on an edge starts between its ends.
                Some(bl) => {
                    let with = state[old.rank[bl.with as usize] as usize];
                    let t = bl.t as f32;
                    [0, 1, 2, 3].map(|c| from[c] * (1.0 - t) + with[c] * t)
                }
            }
        };
        assert_eq!(moved[new.rank[t] as usize], want, "node {t}");
    }
}

/// `steps` Verlet steps of a layout's CPU twin in `accumulation` from raw state.
fn twin_steps(
    layout: &EdgeLayout,
    model: &PackedModel,
    accumulation: Accumulation,
    fp: &lancet::layout::edges::FixedPoint,
    cur: Vec<[f32; 4]>,
    prev: Vec<[f32; 4]>,
    steps: usize,
) -> Vec<[f32; 4]> {
    let config = SimConfig::new(2e-5);
    let p = step_params(model, config);
    assert_eq!(p.integrator, Integrator::Verlet);
    PackedLayout::Edges(layout.clone())
        .steps_cpu(&p, accumulation, fp, (cur, prev), steps)
        .0
}

#[rstest]
fn patched_edges_step_bitwise_like_a_rebuild(
    #[values(Accumulation::Gather, Accumulation::AtomicFixed)] accumulation: Accumulation,
    #[values(21, 22, 23, 24, 25, 26)] seed: u64,
) {
    let mut model = random_model(seed, true);
    let order = NodeOrder::locality(&model);
    let mut layout = EdgeLayout::new(&model, order);
    let fp = layout.fixed_point(&model);
    let mut rng = Rng(seed);
    let mut cur: Vec<[f32; 4]> = Vec::new();
    let mut prev: Vec<[f32; 4]> = Vec::new();
    for t in 0..model.node_count() {
        let free = !model.fixed[layout.order.order[t] as usize];
        let mut u = [0.0f32; 4];
        for x in u.iter_mut().take(3) {
            *x = if free {
                ((rng.next() - 0.5) * 1e-4) as f32
            } else {
                0.0
            };
        }
        cur.push(u);
        prev.push([u[0] * 0.99, u[1] * 0.99, u[2] * 0.99, 0.0]);
    }
    for round in 0..3 {
        let diff = random_diff(&model, seed * 7 + round);
        let next = applied(&model, &diff);
        let before = PackedLayout::Edges(layout.clone());
        let patch = layout.patch(&next, &diff).unwrap();
        assert_dirty_covers(&before, &PackedLayout::Edges(layout.clone()), &patch);
        cur = move_state_cpu(&cur, &patch.moves, layout.node_count());
        prev = move_state_cpu(&prev, &patch.moves, layout.node_count());
        model = next;
        let rebuilt = EdgeLayout::new(&model, layout.order.clone());
        let a = twin_steps(
            &layout,
            &model,
            accumulation,
            &fp,
            cur.clone(),
            prev.clone(),
            25,
        );
        let b = twin_steps(
            &rebuilt,
            &model,
            accumulation,
            &fp,
            cur.clone(),
            prev.clone(),
            25,
        );
        assert!(
            a.iter()
                .zip(&b)
                .all(|(x, y)| x.map(f32::to_bits) == y.map(f32::to_bits)),
            "round {round}: patched and rebuilt edge layouts step differently"
        );
        assert!(a.iter().flatten().any(|&x| x != 0.0), "the state moved");
    }
}

#[test]
fn a_small_cut_dirties_a_small_part_of_each_layout() {
    // A 12^3-cell box (2,197 nodes): big enough that the room a valence bucket is appended
    // with (64 nodes) is small beside it, as on real meshes.
    let mesh = lancet::mesh::generate::BoxGrid::cube_cells([12; 3], 0.01)
        .build()
        .unwrap();
    let model = lancet::model::SpringModel::build(
        &mesh,
        &lancet::model::ModelConfig::new(lancet::model::Material::elastic(5e3, 0.25, 1000.0)),
    )
    .unwrap()
    .pack(&mesh)
    .unwrap();
    // Remove three springs of one node: a few rows change.
    let node = model.springs()[40].nodes[0];
    let diff = ModelDiff {
        removed_springs: model
            .springs()
            .iter()
            .filter(|s| s.nodes.contains(&node))
            .take(3)
            .map(|s| s.nodes)
            .collect(),
        ..ModelDiff::default()
    };
    let next = applied(&model, &diff);
    for kind in [
        LayoutKind::Connectivity,
        LayoutKind::Valence,
        LayoutKind::Edges,
    ] {
        let mut layout = PackedLayout::pack(&model, kind, NodeOrder::locality(&model)).unwrap();
        let total: u64 = ARRAYS.iter().map(|&a| layout.array(a).len() as u64).sum();
        let patch = layout.patch(&next, &diff).unwrap();
        assert!(!patch.repacked, "{kind:?}");
        // Four nodes' rows out of 2,197; for valence also the rows pointing at the moved
        // nodes and the buckets appended for them, room included.
        assert!(
            patch.dirty_bytes() * 12 < total,
            "{kind:?}: {} of {total} bytes dirty",
            patch.dirty_bytes()
        );
    }
}

/// Steps of the connectivity twin equal bit for bit: the same slots summed in the same order.
fn assert_steps_alike(a: &ConnectivityLayout, b: &ConnectivityLayout, model: &PackedModel) {
    let p = step_params(model, SimConfig::new(2e-5));
    let mut rng = Rng(5);
    let mut state = || -> Vec<[f32; 4]> {
        (0..a.node_count())
            .map(|_| [1e-4 * rng.next() as f32, 1e-4 * rng.next() as f32, 0.0, 0.0])
            .collect()
    };
    let (cur, prev) = (state(), state());
    let bits =
        |v: Vec<[f32; 4]>| -> Vec<[u32; 4]> { v.iter().map(|x| x.map(f32::to_bits)).collect() };
    assert_eq!(
        bits(a.step_cpu(&p, &cur, &prev).0),
        bits(b.step_cpu(&p, &cur, &prev).0)
    );
}

#[test]
fn a_row_that_outgrows_its_capacity_continues_in_an_overflow_row() {
    let mut model = random_model(3, false);
    let mut c = ConnectivityLayout::new(&model, NodeOrder::locality(&model), None).unwrap();
    let k = c.capacity;
    // 2k springs: k - 1 and a continuation, k - 1 and a continuation, 2: a chain of three rows.
    let diff = widen_node_0(&model, k, k);
    let next = applied(&model, &diff);
    let before = PackedLayout::Connectivity(c.clone());
    let patch = c.patch(&next, &diff).unwrap();
    assert!(!patch.repacked);
    assert_eq!(c.capacity, k);
    assert_eq!(c.overflow_rows(), 2);
    let total = c.slots.len() as u64 * 32;
    assert!(
        patch.dirty_bytes() * 4 < total,
        "{} of {total} bytes dirty",
        patch.dirty_bytes()
    );
    assert_dirty_covers(&before, &PackedLayout::Connectivity(c.clone()), &patch);
    assert!(c == ConnectivityLayout::new(&next, c.order.clone(), Some(k)).unwrap());
    // Summed in the same order as a table wide enough for node 0.
    let wide = ConnectivityLayout::new(&next, c.order.clone(), None).unwrap();
    assert!(wide.capacity > k && wide.overflow_rows() == 0);
    assert_steps_alike(&c, &wide, &next);
    model = next;
    // Cuts that add nodes move the overflow rows up past the new node rows; one that narrows
    // node 0 again frees its overflow rows for reuse.
    for round in 0..3 {
        let diff = random_diff(&model, 70 + round);
        let next = applied(&model, &diff);
        let before = PackedLayout::Connectivity(c.clone());
        let patch = c.patch(&next, &diff).unwrap();
        assert!(!patch.repacked, "round {round}");
        assert_dirty_covers(&before, &PackedLayout::Connectivity(c.clone()), &patch);
        assert!(
            c == ConnectivityLayout::new(&next, c.order.clone(), Some(k)).unwrap(),
            "round {round}"
        );
        assert_steps_alike(
            &c,
            &ConnectivityLayout::new(&next, c.order.clone(), None).unwrap(),
            &next,
        );
        model = next;
    }
    let narrow = ModelDiff {
        removed_springs: diff
            .added_springs
            .iter()
            .map(|s| s.nodes)
            .filter(|&[a, b]| model.spring_index(a, b).is_some())
            .collect(),
        ..ModelDiff::default()
    };
    let next = applied(&model, &narrow);
    let rows = c.overflow_rows();
    c.patch(&next, &narrow).unwrap();
    assert_eq!(c.overflow_rows(), rows, "freed rows stay, for reuse");
    assert!(c == ConnectivityLayout::new(&next, c.order.clone(), Some(k)).unwrap());
    let again = widen_node_0(&next, k, k - 4);
    let wider = applied(&next, &again);
    c.patch(&wider, &again).unwrap();
    assert_eq!(c.overflow_rows(), rows, "a freed row is reused");
    assert!(c == ConnectivityLayout::new(&wider, c.order.clone(), Some(k)).unwrap());
}

/// A cut that adds a node moves only the overflow row in the way of its node row, however
/// many overflow rows earlier cuts left: the upload follows what the cut touched.
#[test]
fn adding_a_node_moves_only_the_overflow_row_in_its_way() {
    let model = random_model(3, false);
    let order = NodeOrder::locality(&model);
    let widest = (0..model.node_count())
        .map(|i| {
            model
                .springs()
                .iter()
                .filter(|s| s.nodes.contains(&(i as u32)))
                .count()
        })
        .max()
        .unwrap() as u32;
    // The narrowest table that stays under the repack threshold, with many overflow rows.
    let mut c = (2..widest)
        .rev()
        .map(|k| ConnectivityLayout::new(&model, order.clone(), Some(k)).unwrap())
        .take_while(|c| c.overflow_rows() <= 64.max(c.node_count() / 8))
        .last()
        .unwrap();
    let k = c.capacity as u64;
    assert!(
        c.overflow_rows() >= 8,
        "{} overflow rows",
        c.overflow_rows()
    );
    // A copy of a node with one spring to it.
    let src = model.springs()[0].nodes[0];
    let n = model.node_count() as u32;
    let diff = ModelDiff {
        added_nodes: vec![lancet::model::AddedNode {
            key: model.node_keys[src as usize],
            rest: model.rest[src as usize],
            mass: model.mass[src as usize],
            fixed: false,
            state_from: Some(src),
            blend: None,
        }],
        added_springs: vec![lancet::model::PackedSpring {
            nodes: [src, n],
            rest_length: 0.01,
            stiffness: 10.0,
            damping: 0.0,
        }],
        ..ModelDiff::default()
    };
    let next = applied(&model, &diff);
    let before = PackedLayout::Connectivity(c.clone());
    let patch = c.patch(&next, &diff).unwrap();
    assert!(!patch.repacked);
    assert_dirty_covers(&before, &PackedLayout::Connectivity(c.clone()), &patch);
    // The new node's row, the overflow row moved out of it, the source's chain (rewritten),
    // and the slot that pointed at the moved row: rows, not the overflow region.
    let chain = c.row(c.order.rank[src as usize] as usize).len() as u64 / (k - 1) + 1;
    let slot_bytes: u64 = patch
        .dirty
        .iter()
        .filter(|d| d.array == LayoutArray::Slots)
        .map(|d| d.bytes.end - d.bytes.start)
        .sum();
    assert!(
        slot_bytes <= (2 + chain) * k * 32 + 32,
        "{slot_bytes} slot bytes dirty for one node ({} overflow rows of {k} slots)",
        c.overflow_rows()
    );
    assert!(c == ConnectivityLayout::new(&next, c.order.clone(), Some(c.capacity)).unwrap());
    assert_steps_alike(
        &c,
        &ConnectivityLayout::new(&next, c.order.clone(), None).unwrap(),
        &next,
    );
}

#[test]
fn a_table_with_many_overflow_rows_repacks_by_size_class() {
    let model = random_model(3, false);
    // Four slots per row: most rows continue, far past an eighth of the nodes.
    let mut c = ConnectivityLayout::new(&model, NodeOrder::locality(&model), Some(4)).unwrap();
    assert!(c.overflow_rows() > 64.max(c.node_count() / 8));
    let widest = (0..c.node_count()).map(|i| c.row(i).len()).max().unwrap() as u32;
    let diff = random_diff(&model, 9);
    let next = applied(&model, &diff);
    let patch = c.patch(&next, &diff).unwrap();
    assert!(patch.repacked);
    assert_eq!(c.overflow_rows(), 0);
    assert!(
        c.capacity > widest.max(4) && c.capacity.is_multiple_of(4),
        "{}",
        c.capacity
    );
    assert!(c == ConnectivityLayout::new(&next, c.order.clone(), None).unwrap());
}

#[test]
fn a_diff_that_does_not_fit_the_model_is_refused_and_leaves_it_unchanged() {
    let model = random_model(2, false);
    let mut m = model.clone();
    let bad = ModelDiff {
        removed_springs: vec![[0, 1], [0, 1]],
        ..ModelDiff::default()
    };
    let err = m.apply(&bad).unwrap_err().to_string();
    assert!(err.contains("0-1"), "{err}");
    assert_eq!(m, model);
    let dup = ModelDiff {
        added_springs: vec![model.springs()[0]],
        ..ModelDiff::default()
    };
    assert!(m.apply(&dup).is_err());
    assert_eq!(m, model);
    // A layout given a model the diff was not applied to says so.
    let mut layout =
        PackedLayout::pack(&model, LayoutKind::Valence, NodeOrder::locality(&model)).unwrap();
    let grow = random_diff(&model, 9);
    if !grow.added_nodes.is_empty() {
        assert!(layout.patch(&model, &grow).is_err());
    }
}

#[test]
fn applying_a_diff_keeps_every_spring_findable_once() {
    let mut model = random_model(4, true);
    for round in 0..5 {
        let diff = random_diff(&model, round);
        model.apply(&diff).unwrap();
        let mut pairs: Vec<[u32; 2]> = model.springs().iter().map(|s| s.nodes).collect();
        pairs.sort_unstable();
        pairs.dedup();
        assert_eq!(
            pairs.len(),
            model.springs().len(),
            "a spring is there twice"
        );
        for (i, s) in model.springs().iter().enumerate() {
            assert!(s.nodes[0] < s.nodes[1]);
            assert_eq!(model.spring_index(s.nodes[1], s.nodes[0]), Some(i));
        }
        for s in &diff.added_springs {
            let i = model.spring_index(s.nodes[1], s.nodes[0]).unwrap();
            assert_eq!(model.springs()[i].stiffness, s.stiffness);
        }
        for s in &diff.removed_springs {
            let re_added = diff.added_springs.iter().any(|a| a.nodes == s.map(|x| x));
            assert!(re_added || model.spring_index(s[0], s[1]).is_none());
        }
    }
}

/// A packing with room ([`PackedLayout::reserve_room`], as the GPU engine keeps its host copy)
/// takes the patches of a few local cuts, nodes added included, without moving any array:
/// the first cut used to reallocate the arrays that grew (a 12 MB connectivity table on the
/// 100k-tet box), a pause of milliseconds. And the room changes nothing a patch gives.
#[rstest]
fn a_layout_with_room_takes_local_cuts_without_moving_its_arrays(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    let mesh = lancet::mesh::generate::BoxGrid::cube_cells([12; 3], 0.01)
        .build()
        .unwrap();
    let mut model = lancet::model::SpringModel::build(
        &mesh,
        &lancet::model::ModelConfig::new(lancet::model::Material::elastic(5e3, 0.25, 1000.0)),
    )
    .unwrap()
    .pack(&mesh)
    .unwrap();
    let mut roomy = PackedLayout::pack(&model, kind, NodeOrder::locality(&model)).unwrap();
    let mut tight = roomy.clone();
    roomy.reserve_room();
    let at = |l: &PackedLayout| ARRAYS.map(|a| (l.array(a).as_ptr(), l.node_slots()));
    // A quarter of room, not a doubling.
    let bytes = |l: &PackedLayout| ARRAYS.map(|a| l.array(a).len()).iter().sum::<usize>();
    assert!(
        roomy.host_capacity_bytes() <= bytes(&roomy) * 5 / 4 + 64 * 32 * ARRAYS.len(),
        "{kind:?}: {} bytes held for {} bytes of arrays",
        roomy.host_capacity_bytes(),
        bytes(&roomy)
    );
    let before = at(&roomy);
    for round in 0..3 {
        let diff = random_diff(&model, 70 + round);
        assert!(!diff.added_nodes.is_empty(), "the cuts add nodes");
        let next = applied(&model, &diff);
        let (a, b) = (
            roomy.patch(&next, &diff).unwrap(),
            tight.patch(&next, &diff).unwrap(),
        );
        assert!(!a.repacked, "{kind:?} round {round}: a local cut repacked");
        assert_eq!(a, b, "{kind:?} round {round}: the room changed the patch");
        assert!(
            roomy == tight,
            "{kind:?} round {round}: the room changed the layout"
        );
        model = next;
    }
    for (a, (before, after)) in ARRAYS.iter().zip(before.iter().zip(at(&roomy))) {
        assert_eq!(before.0, after.0, "{kind:?}: {a:?} was reallocated");
    }
}
