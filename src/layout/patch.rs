//! What an incremental edit of a layout hands to the device: the byte ranges of each array that
//! changed, and how node state moves between layout indices.
//!
//! Every layout's `patch(model_after, diff)` edits its CPU arrays in place so that they equal
//! a from-scratch packing of the changed model in the same arrangement (same node order, same
//! capacities), and returns a [`LayoutPatch`]. The GPU engine writes only the dirty ranges; an
//! array that outgrew its device buffer moves to a buffer of the next size class (its old
//! contents copied on the device, then its dirty ranges and new tail written).

use std::ops::Range;

/// The arrays a layout uploads, by role.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum LayoutArray {
    /// Node-centric slot table (connectivity, valence).
    Slots,
    /// Inverse masses, one `f32` per node.
    InvMass,
    /// Valence bucket table.
    Buckets,
    /// Edge-layout spring records.
    EdgeSprings,
    /// Edge-layout incidence rows, `[start, end)` per node (8 bytes each).
    IncidenceRows,
    /// Edge-layout incidence entries.
    Incidence,
}

impl LayoutArray {
    /// Every array a layout may upload.
    pub const ALL: [LayoutArray; 6] = [
        LayoutArray::Slots,
        LayoutArray::InvMass,
        LayoutArray::Buckets,
        LayoutArray::EdgeSprings,
        LayoutArray::IncidenceRows,
        LayoutArray::Incidence,
    ];
}

/// A changed byte range of one array.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Dirty {
    /// Which array.
    pub array: LayoutArray,
    /// Byte range within it.
    pub bytes: Range<u64>,
}

/// A write of node state: `state[to] = old_state[from]`, or zero where `from` is `None`; with
/// a blend, `state[to] = (1 - t) * old_state[from] + t * old_state[with]`. All moves of a patch
/// read the state as it was before the patch, so they may permute nodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StateMove {
    /// Destination layout index.
    pub to: u32,
    /// Source layout index (in the order before the patch), or `None` to start at rest.
    pub from: Option<u32>,
    /// A second source mixed in (a node put on an edge starts between its ends).
    pub blend: Option<MoveBlend>,
}

/// The second source of a [`StateMove`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveBlend {
    /// Source layout index (in the order before the patch).
    pub with: u32,
    /// Its weight, in [0, 1].
    pub t: f32,
}

impl StateMove {
    /// The move that starts a node added by a diff at layout index `to`: from its source and
    /// blend partner, mapped to layout indices before the patch by `rank`.
    pub(crate) fn added(to: u32, a: &crate::model::AddedNode, rank: &[u32]) -> Self {
        let from = a.state_from.map(|s| rank[s as usize]);
        StateMove {
            to,
            from,
            blend: a.blend.filter(|_| from.is_some()).map(|b| MoveBlend {
                with: rank[b.with as usize],
                t: b.t as f32,
            }),
        }
    }
}

/// The result of patching a layout.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LayoutPatch {
    /// Changed byte ranges, ascending per array, not overlapping.
    pub dirty: Vec<Dirty>,
    /// Node state to move or clear, one entry per destination. A patch that shrinks the node
    /// slots (a valence regroup) clears the slots it drops: those destinations lie past the
    /// new slots, within those before the patch.
    pub moves: Vec<StateMove>,
    /// Whether the layout was repacked whole (a slot row outgrew its capacity, or the edge
    /// layout's incidence table compacted the holes its moved rows left); every array the
    /// repack rewrote is then dirty from start to end.
    pub repacked: bool,
}

impl LayoutPatch {
    /// Bytes in all dirty ranges.
    pub fn dirty_bytes(&self) -> u64 {
        self.dirty.iter().map(|d| d.bytes.end - d.bytes.start).sum()
    }

    /// Mark elements `items` (each `span` elements of `elem` bytes, e.g. whole rows) of `array`
    /// dirty, merging runs of neighbouring items into one range.
    pub(crate) fn mark(
        &mut self,
        array: LayoutArray,
        items: impl IntoIterator<Item = u32>,
        span: u64,
        elem: u64,
    ) {
        let mut items: Vec<u32> = items.into_iter().collect();
        items.sort_unstable();
        items.dedup();
        let bytes = span * elem;
        let mut run: Option<Range<u64>> = None;
        for i in items {
            let r = i as u64 * bytes..(i as u64 + 1) * bytes;
            run = match run {
                Some(cur) if cur.end == r.start => Some(cur.start..r.end),
                Some(cur) => {
                    self.push(array, cur);
                    Some(r)
                }
                None => Some(r),
            };
        }
        if let Some(cur) = run {
            self.push(array, cur);
        }
    }

    /// Mark elements `elems` of `array`, each `elem` bytes, dirty as one range.
    pub(crate) fn mark_range(&mut self, array: LayoutArray, elems: Range<u64>, elem: u64) {
        self.push(array, elems.start * elem..elems.end * elem);
    }

    /// Mark a whole array of `bytes` bytes dirty.
    pub(crate) fn mark_all(&mut self, array: LayoutArray, bytes: u64) {
        self.dirty.retain(|d| d.array != array);
        if bytes > 0 {
            self.dirty.push(Dirty {
                array,
                bytes: 0..bytes,
            });
        }
    }

    fn push(&mut self, array: LayoutArray, bytes: Range<u64>) {
        if bytes.end > bytes.start {
            self.dirty.push(Dirty { array, bytes });
        }
    }

    /// Clear the state of every node the diff touches that is fixed afterwards: a node that
    /// becomes fixed sits at rest from now on, and its neighbours must see it there at the next
    /// step, not where it was. Overrides any move to the same place.
    pub(crate) fn rest_fixed(
        &mut self,
        model: &crate::model::PackedModel,
        diff: &crate::model::ModelDiff,
        rank: &[u32],
    ) {
        let before = model.node_count() - diff.added_nodes.len();
        for t in diff.touched_nodes(before) {
            if model.fixed[t as usize] {
                let to = rank[t as usize];
                self.moves.retain(|m| m.to != to);
                self.moves.push(StateMove {
                    to,
                    from: None,
                    blend: None,
                });
            }
        }
    }

    /// Sort the ranges by array and start and merge overlapping or touching ones.
    pub(crate) fn normalize(&mut self) {
        self.dirty
            .sort_by_key(|d| (d.array, d.bytes.start, d.bytes.end));
        let mut out: Vec<Dirty> = Vec::with_capacity(self.dirty.len());
        for d in self.dirty.drain(..) {
            match out.last_mut() {
                Some(last) if last.array == d.array && d.bytes.start <= last.bytes.end => {
                    last.bytes.end = last.bytes.end.max(d.bytes.end);
                }
                _ => out.push(d),
            }
        }
        self.dirty = out;
        self.moves.sort_by_key(|m| m.to);
        self.moves.dedup_by_key(|m| m.to);
    }
}

/// Refuse a patch whose model is not the layout's model after `diff`: the layout holds
/// `before` nodes, so the model must hold those plus the added ones.
pub(crate) fn check_model(
    before: usize,
    diff: &crate::model::ModelDiff,
    model: &crate::model::PackedModel,
) -> crate::Result<()> {
    if model.node_count() == before + diff.added_nodes.len() {
        return Ok(());
    }
    Err(crate::Error::DiffMismatch(format!(
        "the layout has {before} nodes and the diff adds {}, but the model has {}; apply the \
         diff to the model first, once",
        diff.added_nodes.len(),
        model.node_count()
    )))
}

/// Slots for a row of `needed` entries: the next multiple of four strictly above it, so every
/// row keeps at least one free slot. A cut that splits a node gives each node on its crack front
/// one more neighbour; without room the first such cut would repack the whole table.
pub fn row_size_class(needed: u32) -> u32 {
    (needed / 4 + 1) * 4
}

/// Entries for an incidence row of `needed` springs in the edge layout: at least four free, in
/// multiples of four. A node on a crack front gains one spring per neighbour the cut splits,
/// often several in one cut; an entry costs 4 bytes (a connectivity slot costs 32), so the
/// edge layout can afford the room that keeps cuts from repacking its incidence table.
pub fn incidence_room(needed: u32) -> u32 {
    (needed + 4).div_ceil(4) * 4
}

/// Write `list` as the row `row` (`[start, end)` into `data`) of a table of rows: in its old
/// place when it fits there, else appended (its old place left as a hole for the next
/// compaction). Returns the range written (empty for an empty list), for the patch's upload.
pub(crate) fn rewrite_row(row: &mut [u32; 2], data: &mut Vec<u32>, list: &[u32]) -> Range<u32> {
    let [start, end] = *row;
    let at = if list.len() <= (end - start) as usize {
        start
    } else {
        data.len() as u32
    };
    let stop = at + list.len() as u32;
    if stop as usize > data.len() {
        data.resize(stop as usize, 0);
    }
    data[at as usize..stop as usize].copy_from_slice(list);
    *row = [at, stop];
    at..stop
}
