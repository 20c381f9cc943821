//! Valence layouts after many patches: a regroup packs the fragmented buckets by valence
//! again, keeping the packing's own and every node's state; arrangements it cannot regroup
//! in place are packed anew or refused.

use super::layout_patch::{applied, patch_checked};
use crate::models;
use lancet::layout::{LayoutKind, NodeOrder, PackedLayout};
use lancet::model::ModelDiff;
use lancet::twin::move_state::move_state_cpu;
use models::{random_diff, random_model, widen_node_0, Rng};
use rstest::rstest;

/// The buckets of a valence layout that its packing laid out, which a regroup keeps.
fn rising_prefix(layout: &PackedLayout) -> Vec<lancet::layout::valence::Bucket> {
    let PackedLayout::Valence(v) = layout else {
        unreachable!("packed as valence")
    };
    v.buckets[..v.packing].to_vec()
}

/// A valence arrangement whose first bucket's slot table lies past the others' (as no patch
/// lays it out, but [`ValenceLayout::arranged`] accepts), cut into up to sixteen buckets per
/// valence: the regroup cannot keep the packing's buckets apart from the appended ones, so it
/// packs the whole layout anew by valence, from layout index 0. The result equals a packing
/// from scratch of its arrangement, has one bucket per valence, and every node keeps its state.
#[test]
fn a_regroup_of_an_arrangement_without_a_packing_before_it_packs_everything() {
    use lancet::layout::valence::{Bucket, ValenceLayout};
    let model = random_model(31, false);
    let packed = ValenceLayout::new(&model, &NodeOrder::locality(&model));
    // Each bucket in up to sixteen pieces (more buckets than the bound), then the first
    // piece's table moved past every other.
    let mut buckets: Vec<Bucket> = Vec::new();
    for b in &packed.buckets {
        let pieces = b.count.min(16);
        let cut: Vec<u32> = (0..=pieces).map(|k| k * b.count / pieces).collect();
        for w in cut.windows(2) {
            buckets.push(Bucket {
                valence: b.valence,
                first: b.first + w[0],
                count: w[1] - w[0],
                offset: b.offset + w[0] * b.valence,
            });
        }
    }
    let first_table = buckets[0].count * buckets[0].valence;
    for b in &mut buckets[1..] {
        b.offset -= first_table;
    }
    buckets[0].offset = packed.slots.len() as u32 - first_table;
    let valences: std::collections::BTreeSet<u32> = buckets.iter().map(|b| b.valence).collect();
    let room: Vec<u32> = buckets.iter().map(|b| b.count).collect();
    let arranged = ValenceLayout::arranged(&model, packed.order.clone(), buckets, room).unwrap();
    assert!(arranged.dispatched_buckets() > arranged.bucket_limit());
    let mut layout = PackedLayout::Valence(arranged);
    let mut rng = Rng(31);
    let want: Vec<[f32; 4]> = (0..model.node_count())
        .map(|_| [rng.next() as f32, rng.next() as f32, rng.next() as f32, 1.0])
        .collect();
    let mut state = vec![[0.0f32; 4]; layout.node_slots()];
    for (new, old) in layout.order().pairs() {
        state[new] = want[old];
    }
    let patch = patch_checked(&mut layout, &model, &ModelDiff::default(), 0);
    assert_eq!(
        dispatched_buckets(&layout),
        valences.len(),
        "one bucket per valence"
    );
    let state = move_state_cpu(&state, &patch.moves, layout.node_slots());
    for (t, w) in want.iter().enumerate() {
        assert_eq!(state[layout.order().rank[t] as usize], *w, "node {t}");
    }
}

/// An arrangement whose buckets do not follow each other in layout order (one starting inside
/// the room of the one before it) is refused: the device finds a node's bucket by searching
/// the buckets by their first node.
#[test]
fn an_arrangement_with_overlapping_buckets_is_refused() {
    use lancet::layout::valence::ValenceLayout;
    let model = random_model(32, false);
    let packed = ValenceLayout::new(&model, &NodeOrder::locality(&model));
    let mut buckets = packed.buckets.clone();
    let mut room = packed.room.clone();
    buckets.swap(0, 1);
    room.swap(0, 1);
    let err = ValenceLayout::arranged(&model, packed.order.clone(), buckets, room).unwrap_err();
    assert!(err.to_string().contains("inside the room"), "{err}");
    let short = packed.room[1..].to_vec();
    let err = ValenceLayout::arranged(&model, packed.order, packed.buckets, short).unwrap_err();
    assert!(err.to_string().contains("room given for"), "{err}");
}

/// Buckets of a valence layout that are dispatched (hold nodes or holes).
fn dispatched_buckets(layout: &PackedLayout) -> usize {
    let PackedLayout::Valence(v) = layout else {
        unreachable!("packed as valence")
    };
    v.buckets.iter().filter(|b| b.count > 0).count()
}

/// A long run of cut-like patches on a valence layout that starts fragmented (as a long run of
/// cuts that changed many valences would leave it: half of each valence's nodes in small
/// buckets after the packing's, more buckets than its bound): the first patch regroups the
/// buckets after the packing's (packs them anew by valence), and the patches after it append a
/// bucket only where a node's new valence has no hole or room left, each with as much room as
/// that valence's appended buckets had, so the buckets stay within
/// [`ValenceLayout::bucket_limit`] for the rest of the run. A regroup leaves the packing's
/// buckets in place and at most two buckets per valence (the packing's and the regrouped
/// tail's), every patch still equals a packing from scratch of its arrangement with every
/// changed byte in a dirty range, no move writes past the slots before and after the patch,
/// and the state moves keep every node its own state through the regroups.
#[rstest]
fn a_fragmented_valence_layout_regroups_and_keeps_every_node_its_state(
    #[values(21, 22, 23)] seed: u64,
) {
    let mut model = random_model(seed, false);
    let mut layout = PackedLayout::Valence(models::fragmented_valence(
        &model,
        &NodeOrder::locality(&model),
    ));
    let mut rng = Rng(seed);
    // The state each model node should have, and the device's, by layout index.
    let mut want: Vec<[f32; 4]> = (0..model.node_count())
        .map(|_| [rng.next() as f32, rng.next() as f32, rng.next() as f32, 1.0])
        .collect();
    let mut state: Vec<[f32; 4]> = vec![[0.0; 4]; layout.node_slots()];
    for (new, old) in layout.order().pairs() {
        state[new] = want[old];
    }
    let mut regrouped = 0;
    let mut most = 0;
    for round in 0..100 {
        let diff = random_diff(&model, seed * 1009 + round);
        let next = applied(&model, &diff);
        let slots_before = layout.node_slots();
        let dispatched_before = dispatched_buckets(&layout);
        let head_before = rising_prefix(&layout);
        let patch = patch_checked(&mut layout, &next, &diff, round);
        // The device's state buffers hold the slots before the patch and those after it: no
        // move may write past both (a regroup clears only the slots it had before).
        let held = slots_before.max(layout.node_slots());
        assert!(
            patch.moves.iter().all(|m| (m.to as usize) < held),
            "round {round}: a move past {held} slots"
        );
        let PackedLayout::Valence(v) = &layout else {
            unreachable!("packed as valence")
        };
        let dispatched = dispatched_buckets(&layout);
        let valences: std::collections::BTreeSet<u32> = v
            .buckets
            .iter()
            .filter(|b| b.count > 0)
            .map(|b| b.valence)
            .collect();
        assert!(
            dispatched <= v.bucket_limit(),
            "round {round}: {dispatched} buckets for {} valences",
            valences.len()
        );
        most = most.max(dispatched);
        // Each bucket appended for a valence has room for at least as many nodes as those
        // appended for it before (after the packing's rising buckets): their number grows with
        // the logarithm of the nodes a valence takes, not with the count.
        let prefix = rising_prefix(&layout).len();
        let mut appended: std::collections::BTreeMap<u32, u32> = Default::default();
        for (b, &room) in v.buckets.iter().zip(&v.room).skip(prefix) {
            let before = appended.entry(b.valence).or_default();
            assert!(
                *before == 0 || room >= (*before).min(next.node_count().max(32) as u32),
                "round {round}: a valence-{} bucket with room {room} after {before}",
                b.valence
            );
            *before += room;
        }
        // Nothing else lowers the buckets dispatched: a node that leaves one leaves a hole.
        if dispatched < dispatched_before {
            regrouped += 1;
            // The tail's holes and room are gone: the slots dropped are cleared by moves.
            assert!(
                layout.node_slots() < slots_before
                    && patch
                        .moves
                        .iter()
                        .any(|m| m.from.is_none() && m.to as usize >= layout.node_slots()),
                "round {round}: the regroup kept {} of {slots_before} slots",
                layout.node_slots()
            );
            for &valence in &valences {
                let of = v
                    .buckets
                    .iter()
                    .filter(|b| b.count > 0 && b.valence == valence)
                    .count();
                assert!(of <= 2, "round {round}: {of} buckets of valence {valence}");
            }
            // Only the appended buckets were packed anew: the packing's stay where they were
            // (the incremental part may only have filled their room).
            let head = &v.buckets[..head_before.len()];
            for (b, a) in head_before.iter().zip(head) {
                assert_eq!(
                    (b.first, b.offset, b.valence),
                    (a.first, a.offset, a.valence),
                    "round {round}: a bucket of the packing moved"
                );
            }
        }
        // What each node's state becomes: copies and blends of their sources, zero where the
        // change fixed a node.
        let n = model.node_count();
        let touched = diff.touched_nodes(n);
        for a in &diff.added_nodes {
            let from = want[a.state_from.unwrap() as usize];
            want.push(match a.blend {
                None => from,
                Some(b) => {
                    let with = want[b.with as usize];
                    let t = b.t as f32;
                    [0, 1, 2, 3].map(|c| from[c] * (1.0 - t) + with[c] * t)
                }
            });
        }
        for &t in &touched {
            if next.fixed[t as usize] {
                want[t as usize] = [0.0; 4];
            }
        }
        state = move_state_cpu(&state, &patch.moves, layout.node_slots());
        for (t, w) in want.iter().enumerate() {
            assert_eq!(
                state[layout.order().rank[t] as usize],
                *w,
                "round {round}: node {t}"
            );
        }
        model = next;
    }
    assert!(regrouped > 0, "no patch regrouped (at most {most} buckets)");
    // Ever more buckets would have regrouped again and again: the run's appended buckets keep
    // well inside the bound.
    assert_eq!(regrouped, 1, "regrouped {regrouped} times");
}

/// A patch that appends a bucket of a valence above all of the packing's leaves the packing's
/// count as it was: the appended bucket is not taken for one of the packing's (a regroup would
/// keep it where it is, and the room rule would not count it among the valence's appended
/// buckets), as a guess from rising valences would take it.
#[test]
fn a_bucket_appended_above_the_packings_valences_is_not_the_packings() {
    let model = random_model(41, false);
    let mut layout =
        PackedLayout::pack(&model, LayoutKind::Valence, NodeOrder::locality(&model)).unwrap();
    let PackedLayout::Valence(v) = &layout else {
        unreachable!("packed as valence")
    };
    let packing = v.packing;
    assert_eq!(
        packing,
        v.buckets.len(),
        "a packing's buckets are all its own"
    );
    let top = v.buckets.iter().map(|b| b.valence).max().unwrap();
    // Node 0, the first touched, takes valence top + 1: the first bucket appended.
    let diff = widen_node_0(&model, top, 1);
    let next = applied(&model, &diff);
    patch_checked(&mut layout, &next, &diff, 0);
    let PackedLayout::Valence(v) = &layout else {
        unreachable!("packed as valence")
    };
    assert_eq!(v.buckets[packing].valence, top + 1);
    assert_eq!(v.packing, packing);
}
