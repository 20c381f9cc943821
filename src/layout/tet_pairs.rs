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

use rustc_hash::FxHashMap;

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
