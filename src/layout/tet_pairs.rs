//! Which tets couple each spring slot's pair of nodes, for the GPU's corotational implicit step
//! (`engine::gpu::corotational_implicit`): a slot (or edge record) of node `i` pointing at `j`
//! holds the block `sum_t R_t K_t,ab R_t^T` over the tets `t` holding both, `a` the corner of
//! `i` and `b` that of `j`, so that the tensor-mass solve reads the rotated stiffness where it
//! reads the constant one ([`super::tensor_blocks`]). The list names those `(tet, a, b)` per
//! slot, tets ascending, so that the block pass sums a fixed set in a fixed order
//! (deterministic, no float atomics).
//!
//! Each pair is one `u32`: `16 t + 4 a + b`. Slots that hold no pair (empty, continuation, a
//! dead edge record, a pair no tet holds) get an empty range, and the pass writes them zero.
//!
//! A cut patches the lists ([`TetPairs::patch`]) where the tet table's patch moved, removed or
//! added tets and where the layout's patch rewrote slots, as the tet table patches its node
//! records: a slot's list is rewritten in place where it fits, else appended, so that a cut's
//! upload follows the cut, not the mesh.

use std::collections::BTreeMap;
use std::ops::Range;

use rustc_hash::{FxHashMap, FxHashSet};

use super::patch::rewrite_row;
use super::tensor_blocks::slot_walk;
use super::tet_table::TetTable;
use super::PackedLayout;

/// Per slot (or edge record) of a layout, the `(tet, corner, corner)` pairs its block sums.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct TetPairs {
    /// Per slot, `[start, end)` in `pairs`.
    pub rows: Vec<[u32; 2]>,
    /// `16 t + 4 a + b` per pair, each slot's tets ascending.
    pub pairs: Vec<u32>,
}

/// Records of the layout array the blocks run beside (slots, or edge records).
pub fn records(layout: &PackedLayout) -> usize {
    match layout {
        PackedLayout::Connectivity(c) => c.slots.len(),
        PackedLayout::Valence(v) => v.slots.len(),
        PackedLayout::Edges(e) => e.springs.len(),
    }
}

impl TetPairs {
    /// The pairs of `table` (corners in `layout`'s order) for every slot of `layout`.
    pub fn new(table: &TetTable, layout: &PackedLayout) -> Self {
        // Every ordered pair of corners of every tet, tets ascending.
        let mut by_nodes: FxHashMap<(u32, u32), Vec<u32>> = FxHashMap::default();
        for (t, c) in table.corners.iter().enumerate() {
            for a in 0..4 {
                for b in 0..4 {
                    if a != b && c[a] != c[b] {
                        by_nodes
                            .entry((c[a], c[b]))
                            .or_default()
                            .push(16 * t as u32 + 4 * a as u32 + b as u32);
                    }
                }
            }
        }
        let mut out = TetPairs {
            rows: vec![[0, 0]; records(layout)],
            pairs: Vec::new(),
        };
        for (i, slot, j) in slot_walk(layout) {
            let start = out.pairs.len() as u32;
            if let Some(list) = by_nodes.get(&(i, j)) {
                out.pairs.extend_from_slice(list);
            }
            out.rows[slot] = [start, out.pairs.len() as u32];
        }
        out
    }

    /// Bytes of the two arrays as uploaded.
    pub fn bytes(&self) -> u64 {
        (self.rows.len() * 8 + self.pairs.len() * 4) as u64
    }
}

/// What [`TetPairs::patch`] wrote, for the device copy to follow: nothing else differs.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PairsPatch {
    /// Slots whose range (`rows`) was written, ascending.
    pub slots: Vec<u32>,
    /// Ranges of `pairs` written, ascending, not overlapping.
    pub pairs: Vec<Range<u32>>,
}

/// Append the pairs of the slot of node `i` pointing at `j` to `out`, from `table`'s records
/// of node `i` (tets ascending, as [`TetPairs::new`] lists them): each tet holding both, with
/// the corners they are.
fn pairs_of(table: &TetTable, i: u32, j: u32, out: &mut Vec<u32>) {
    let Some(&[start, end]) = table.rows.get(i as usize) else {
        return;
    };
    for &r in &table.incidence[start as usize..end as usize] {
        let (t, a) = (r / 4, r % 4);
        if let Some(b) = table.corners[t as usize].iter().position(|&n| n == j) {
            out.push(16 * t + 4 * a + b as u32);
        }
    }
}

impl TetPairs {
    /// Follow a patch of the tet table and of the layout (`table` and `layout` as they are
    /// now): the slots in `changed` (records the layout's patch rewrote or moved, emptied or
    /// not) and every slot in use whose pair of nodes is in `coupled` (the ordered corner pairs
    /// of the tets the table's patch removed, moved or added, layout indices) get their lists
    /// again from `table`'s node records; the others keep theirs, whose tets kept their
    /// indices. A list is written in place where it fits its old range, else at the end of
    /// `pairs` (its old range left as a hole, see [`TetPairs::holes`]). Each list equals the
    /// one [`TetPairs::new`] gives that slot: the layout must have kept every old node at its
    /// index and every slot it did not rewrite.
    pub fn patch(
        &mut self,
        table: &TetTable,
        layout: &PackedLayout,
        changed: &[Range<usize>],
        coupled: &FxHashSet<(u32, u32)>,
    ) -> PairsPatch {
        let n = records(layout);
        self.rows.resize(n, [0, 0]);
        let mut lists: BTreeMap<usize, Vec<u32>> = BTreeMap::new();
        for r in changed {
            for slot in r.start..r.end.min(n) {
                lists.insert(slot, Vec::new());
            }
        }
        for (i, slot, j) in slot_walk(layout) {
            if coupled.contains(&(i, j)) || lists.contains_key(&slot) {
                let list = lists.entry(slot).or_default();
                list.clear();
                pairs_of(table, i, j, list);
            }
        }
        let mut patch = PairsPatch::default();
        for (slot, list) in lists {
            let written = rewrite_row(&mut self.rows[slot], &mut self.pairs, &list);
            patch.slots.push(slot as u32);
            if !written.is_empty() {
                patch.pairs.push(written);
            }
        }
        patch.pairs.sort_unstable_by_key(|r| r.start);
        patch
    }

    /// Pairs `pairs` holds that no slot's range covers (left by lists that grew and moved).
    pub fn holes(&self) -> usize {
        self.pairs.len()
            - self
                .rows
                .iter()
                .map(|r| (r[1] - r[0]) as usize)
                .sum::<usize>()
    }

    /// Slot `slot`'s pairs.
    pub fn list(&self, slot: usize) -> &[u32] {
        let [start, end] = self.rows[slot];
        &self.pairs[start as usize..end as usize]
    }

    /// Whether these lists differ from `other`'s in what the block pass reads: each slot's
    /// pairs in order (not where in `pairs` they lie).
    pub fn differs_from(&self, other: &TetPairs) -> bool {
        self.rows.len() != other.rows.len()
            || (0..self.rows.len()).any(|s| self.list(s) != other.list(s))
    }
}
