//! The valence layout (the "valence textures"): nodes are renumbered so that nodes of equal
//! valence are contiguous, and each such bucket has a slot table exactly as wide as its valence,
//! `slots[bucket.offset + local * valence + s]`. No padding; the price is a permutation of the
//! nodes (kept here, invisible to users) and, on the device, a search of the bucket table by
//! each node's invocation (one dispatch steps every bucket: `shaders/springs_valence.wgsl`).

use bytemuck::{Pod, Zeroable};

use std::collections::{BTreeMap, BTreeSet};

use rustc_hash::FxHashMap;

use super::connectivity::{
    inv_mass_of, patched_row_slots, row_slots, touched_rows, DiffSprings, NodeArrays,
};
use super::patch::{LayoutArray, LayoutPatch, StateMove};
use super::{MemoryStats, NodeOrder, Slot};
use crate::error::{Error, Result};
use crate::model::{ModelDiff, PackedModel};
use crate::physics::{state_buffers, state_traffic, Integrator};

/// Springs at each node of `model`.
fn valences(model: &PackedModel) -> Vec<u32> {
    let mut valence = vec![0u32; model.node_count()];
    for s in model.springs() {
        valence[s.nodes[0] as usize] += 1;
        valence[s.nodes[1] as usize] += 1;
    }
    valence
}

/// Buckets a patched layout may have beyond its bound ([`ValenceLayout::bucket_limit`]) before
/// the buckets patches appended are regrouped (packed anew by valence): see
/// [`ValenceLayout::patch`].
pub const SPARE_BUCKETS: usize = 8;

/// The least room a bucket appended to a layout of a `nodes`-node model gets: room for a few
/// more cuts, 32 nodes, or a sixteenth of a mesh smaller than 512 nodes (32 slots of a high
/// valence would outgrow a small mesh's buffers at every cut), at least 4.
fn least_room(nodes: usize) -> u32 {
    (nodes as u32 / 16).clamp(4, 32)
}

/// Put layout index `new`, of valence `v` with its row at slot `offset`, into the buckets of a
/// packing laid out up to it: the last bucket where it has that valence, else a new one.
fn push_node(buckets: &mut Vec<Bucket>, new: u32, v: u32, offset: u32) {
    match buckets.last_mut() {
        Some(b) if b.valence == v => b.count += 1,
        _ => buckets.push(Bucket {
            valence: v,
            first: new,
            count: 1,
            offset,
        }),
    }
}

/// `row` with its other ends renumbered by `remap` (the new layout index of one that moved,
/// `None` for the others), sorted by layout index as every packing sorts a row.
fn renumbered(row: &[Slot], remap: impl Fn(u32) -> Option<u32>) -> Vec<Slot> {
    let mut row: Vec<Slot> = row
        .iter()
        .map(|s| Slot {
            other: remap(s.other).unwrap_or(s.other),
            ..*s
        })
        .collect();
    row.sort_unstable_by_key(|s| s.other);
    row
}

/// Bytes of the device's bucket table before its first bucket: the count of buckets, padded to
/// a bucket's size (`struct BucketTable` in `shaders/springs_valence.wgsl`).
pub const TABLE_HEADER: u64 = 16;

/// Bytes of a device bucket table holding `buckets` buckets, header included.
pub fn table_bytes(buckets: usize) -> u64 {
    TABLE_HEADER + buckets as u64 * std::mem::size_of::<Bucket>() as u64
}

/// One bucket of nodes with the same valence. Mirrors `struct Bucket` in
/// `shaders/springs_valence.wgsl` (16 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Pod, Zeroable)]
pub struct Bucket {
    /// Springs per node in this bucket (the table's width).
    pub valence: u32,
    /// First node of the bucket, layout order.
    pub first: u32,
    /// Nodes in the bucket.
    pub count: u32,
    /// First slot of the bucket's table.
    pub offset: u32,
}

const _: () = assert!(std::mem::size_of::<Bucket>() == 16);

/// Springs packed into per-valence tables.
///
/// After incremental patches a valence may have several buckets (the first ones from the
/// packing, later ones appended at the end with room to spare), and a bucket may hold holes
/// ([`NodeOrder::HOLE`] layout indices with no springs and zero inverse mass, which the pass
/// skips). The step dispatches over every node slot; invocations past a bucket's `count` (its
/// room) do nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct ValenceLayout {
    /// Node renumbering: `order.order[layout] = model` (or a hole), `order.rank[model] = layout`.
    pub order: NodeOrder,
    /// Buckets in increasing `first`: by valence from the packing, then those patches added.
    pub buckets: Vec<Bucket>,
    /// Nodes each bucket has room for (`>= count`); its layout indices and slot table extend
    /// that far.
    pub room: Vec<u32>,
    /// How many of the first buckets the packing laid out (one per valence, rising); those
    /// after them were appended by patches or regrouped from such. Kept, not guessed from the
    /// valences: a patch may append a bucket of a valence above all of the packing's.
    pub packing: usize,
    /// All tables, back to back; exactly two slots per spring until patches leave room.
    pub slots: Vec<Slot>,
    /// Per-node arrays, layout order.
    pub nodes: NodeArrays,
    /// Holes inside dispatched ranges, by valence, to refill first.
    free: BTreeMap<u32, BTreeSet<u32>>,
}

impl ValenceLayout {
    /// Pack `model`, grouping nodes by valence and keeping `base` order (for locality) within
    /// each bucket.
    pub fn new(model: &PackedModel, base: &NodeOrder) -> Self {
        let valence = valences(model);
        // Stable sort of the base order by valence: buckets keep the locality within them.
        let mut order = base.order.clone();
        order.sort_by_key(|&old| valence[old as usize]);
        let order = NodeOrder::from_order(order);
        let mut buckets: Vec<Bucket> = Vec::new();
        let mut offset = 0u32;
        for (new, &old) in order.order.iter().enumerate() {
            let v = valence[old as usize];
            push_node(&mut buckets, new as u32, v, offset);
            offset += v;
        }
        let room = buckets.iter().map(|b| b.count).collect();
        Self::arranged(model, order, buckets, room)
            .expect("buckets made from the model's own valences")
    }

    /// Pack `model` in a given arrangement: node order (with holes), buckets and their room.
    /// Every node must sit in a bucket of its valence, inside the bucket's `count`. This is the
    /// from-scratch packing that a patched layout equals (with the patched layout's
    /// [`ValenceLayout::packing`]: here the buckets of rising valence at the start).
    pub fn arranged(
        model: &PackedModel,
        order: NodeOrder,
        buckets: Vec<Bucket>,
        room: Vec<u32>,
    ) -> Result<Self> {
        // The device finds a node's bucket by searching the table by `first`
        // (`shaders/springs_valence.wgsl`), as `bucket_of` does here.
        if room.len() != buckets.len() {
            return Err(Error::LengthMismatch {
                given: room.len(),
                expected: buckets.len(),
                message: format!(
                    "{} valence buckets but room given for {}",
                    buckets.len(),
                    room.len()
                ),
            });
        }
        if let Some(w) =
            (1..buckets.len()).find(|&i| buckets[i - 1].first + room[i - 1] > buckets[i].first)
        {
            return Err(Error::LayoutCapacity(format!(
                "valence bucket {w} starts at layout index {}, inside the room of the bucket \
                 before it (from {}, room {}): buckets must follow each other",
                buckets[w].first,
                buckets[w - 1].first,
                room[w - 1]
            )));
        }
        let valence = valences(model);
        let (graph_rows, graph_cols) = super::spring_graph(model);
        let slot_count = buckets
            .iter()
            .zip(&room)
            .map(|(b, &r)| b.offset + r * b.valence)
            .max()
            .unwrap_or(0);
        let mut slots = vec![Slot::empty(); slot_count as usize];
        let mut free: BTreeMap<u32, BTreeSet<u32>> = BTreeMap::new();
        let mut placed = 0usize;
        for (b, &r) in buckets.iter().zip(&room) {
            if b.count > r {
                return Err(Error::LayoutCapacity(format!(
                    "a valence bucket dispatches {} nodes but has room for {r}",
                    b.count
                )));
            }
            for local in 0..r {
                let idx = b.first + local;
                let node = order
                    .order
                    .get(idx as usize)
                    .copied()
                    .unwrap_or(NodeOrder::HOLE);
                if node == NodeOrder::HOLE {
                    if local < b.count {
                        free.entry(b.valence).or_default().insert(idx);
                    }
                    continue;
                }
                if valence[node as usize] != b.valence || local >= b.count {
                    return Err(Error::LayoutCapacity(format!(
                        "node {node} (valence {}) sits at layout index {idx}, which is not a \
                         dispatched place of a valence-{} bucket",
                        valence[node as usize], b.valence
                    )));
                }
                placed += 1;
                let (lo, hi) = (graph_rows[node as usize], graph_rows[node as usize + 1]);
                let row = row_slots(
                    model,
                    node,
                    &graph_cols[lo as usize..hi as usize],
                    &order.rank,
                )?;
                let at = (b.offset + local * b.valence) as usize;
                slots[at..at + row.len()].copy_from_slice(&row);
            }
        }
        if placed != model.node_count() {
            return Err(Error::LayoutCapacity(format!(
                "the arrangement places {placed} of the model's {} nodes",
                model.node_count()
            )));
        }
        let nodes = NodeArrays::new(model, &order);
        // The buckets of rising valence at the start, as a packing lays them out; a patched
        // layout's own count replaces this where it differs (see `packing`).
        let packing = (1..buckets.len())
            .find(|&k| buckets[k].valence <= buckets[k - 1].valence)
            .unwrap_or(buckets.len());
        Ok(ValenceLayout {
            order,
            buckets,
            room,
            packing,
            slots,
            nodes,
            free,
        })
    }

    /// Apply `diff` (already applied to `model`, the model after the change). A node whose
    /// valence changes moves to a bucket of its new valence: into a hole, into room at the end
    /// of a bucket, or into a new bucket appended with room for more (the size class of a
    /// sixteenth of that valence's nodes or of all the room the buckets appended for it already
    /// have, whichever is larger; at least 32, or a sixteenth of the nodes on a mesh of fewer
    /// than 512); no other node moves, the rows pointing at a moved node are rewritten, and its
    /// state moves with it. The result equals [`ValenceLayout::arranged`] of `model` in the
    /// patched arrangement. When that leaves more buckets than [`ValenceLayout::bucket_limit`],
    /// the buckets patches appended are instead packed anew by valence, keeping the node order
    /// within each valence: their nodes may move, the packing's buckets before them stay (see
    /// `regroup`). Not a repack: the device writes the tail and the rows that point into it, as
    /// for any patch.
    pub fn patch(&mut self, model: &PackedModel, diff: &ModelDiff) -> Result<LayoutPatch> {
        let before = self.order.rank.len();
        let slots_before = self.order.order.len();
        super::patch::check_model(before, diff, model)?;
        // Checked before anything changes: on error the layout is as it was.
        let springs = DiffSprings::of(diff, model)?;
        // Where added nodes' state comes from, in the order before the patch (nodes move below).
        let added_sources: Vec<StateMove> = diff
            .added_nodes
            .iter()
            .map(|a| StateMove::added(0, a, &self.order.rank))
            .collect();
        // The touched nodes' rows before the patch: the springs the diff leaves alone are taken
        // from them.
        let touched = touched_rows(diff, before, |t| self.row_of(t));
        // Where each moved node was and where it goes (layout indices): the rows of untouched
        // neighbours that point at one are remapped through it below. Their springs do not
        // change, only where a slot points, and their rows stay where they are.
        let mut remap: FxHashMap<u32, u32> = FxHashMap::default();
        let mut patch = LayoutPatch::default();
        let buckets_before = self.buckets.len();
        let mut moves: BTreeMap<u32, StateMove> = BTreeMap::new();
        let mut moved: Vec<u32> = Vec::new();
        let mut rows: Vec<u32> = Vec::new();
        let mut buckets_changed = false;
        self.order.rank.resize(model.node_count(), NodeOrder::HOLE);
        // How many nodes each valence receives, so that one appended bucket holds them all
        // (every bucket brings room and a table entry to search).
        let mut demand: BTreeMap<u32, u32> = BTreeMap::new();
        for (t, list) in touched.iter() {
            let v = list.len() as u32;
            let new_node = t as usize >= before;
            if new_node || self.buckets[self.bucket_of(self.order.rank[t as usize])].valence != v {
                *demand.entry(v).or_default() += 1;
            }
        }
        for (t, list) in touched.iter() {
            let v = list.len() as u32;
            let new_node = t as usize >= before;
            let stays = !new_node && {
                let idx = self.order.rank[t as usize];
                self.buckets[self.bucket_of(idx)].valence == v
            };
            if stays {
                rows.push(self.order.rank[t as usize]);
                continue;
            }
            // Where the node's state comes from, in the order before the patch.
            let source = if new_node {
                added_sources[t as usize - before]
            } else {
                let idx = self.order.rank[t as usize];
                self.vacate(idx);
                rows.push(idx);
                moves.entry(idx).or_insert(StateMove {
                    to: idx,
                    from: None,
                    blend: None,
                });
                StateMove {
                    to: 0,
                    from: Some(idx),
                    blend: None,
                }
            };
            let want = demand.get_mut(&v).expect("counted above");
            let (idx, table_changed) = self.place(v, *want, model.node_count());
            if let Some(from) = source.from.filter(|_| !new_node) {
                remap.insert(from, idx);
            }
            *want -= 1;
            buckets_changed |= table_changed;
            self.order.order[idx as usize] = t;
            self.order.rank[t as usize] = idx;
            moves.insert(idx, StateMove { to: idx, ..source });
            rows.push(idx);
            moved.push(t);
        }
        // Rewrite the rows of touched nodes, and of neighbours that point at a moved node.
        for (t, list) in touched.iter() {
            let old = touched.old(t);
            let row = patched_row_slots(model, t, list, old, &springs, &self.order.rank)?;
            self.write_row(t, &row, model);
            rows.push(self.order.rank[t as usize]);
        }
        let mut pointing: Vec<u32> = moved
            .iter()
            .flat_map(|&t| touched.list(t))
            .copied()
            .filter(|&nb| !touched.contains(nb))
            .collect();
        pointing.sort_unstable();
        pointing.dedup();
        for t in pointing {
            let row = renumbered(self.row_slots_of(t), |o| remap.get(&o).copied());
            self.write_row(t, &row, model);
            rows.push(self.order.rank[t as usize]);
        }
        rows.sort_unstable();
        rows.dedup();
        for &idx in &rows {
            let row = self.row_range(idx);
            patch.mark(LayoutArray::Slots, row.start as u32..row.end as u32, 1, 32);
        }
        patch.mark(LayoutArray::InvMass, rows.iter().copied(), 1, 4);
        // Appended buckets go up whole (empty slots, zero masses), so the device mirrors the
        // arrays everywhere, not only where nodes were placed.
        for (b, &room) in self.buckets.iter().zip(&self.room).skip(buckets_before) {
            patch.mark(
                LayoutArray::Slots,
                b.offset..b.offset + room * b.valence,
                1,
                32,
            );
            patch.mark(LayoutArray::InvMass, b.first..b.first + room, 1, 4);
        }
        if buckets_changed {
            patch.mark_all(LayoutArray::Buckets, self.buckets.len() as u64 * 16);
        }
        if self.fragmented() {
            return Ok(self.regroup(model, diff, &moves, &rows, slots_before));
        }
        patch.moves = moves.into_values().collect();
        patch.rest_fixed(model, diff, &self.order.rank);
        patch.normalize();
        Ok(patch)
    }

    /// The most buckets a patched layout dispatches before it regroups: per valence it holds,
    /// the packing's bucket, the buckets patches append for it (each with room for as many
    /// nodes as those before it, from the smallest room `place` gives, so at most the
    /// logarithm of the model's nodes over that room), and one more, plus [`SPARE_BUCKETS`].
    /// Patches append buckets (a node whose valence changes goes to a hole, to room at a
    /// bucket's end, or to a new bucket), each with room that the step's dispatch covers idly
    /// and the host and device hold, and an entry that every node's search of the table reads;
    /// without a bound a long run of cuts would make the step ever slower and the arrays ever
    /// larger.
    pub fn bucket_limit(&self) -> usize {
        let valences: BTreeSet<u32> = self
            .buckets
            .iter()
            .filter(|b| b.count > 0)
            .map(|b| b.valence)
            .collect();
        let nodes = self.order.rank.len().max(1) as u32;
        let doublings = nodes
            .div_ceil(least_room(nodes as usize))
            .next_power_of_two()
            .trailing_zeros() as usize;
        valences.len() * (2 + doublings) + SPARE_BUCKETS
    }

    /// Buckets that hold nodes or holes (the step dispatches them).
    pub fn dispatched_buckets(&self) -> usize {
        self.buckets.iter().filter(|b| b.count > 0).count()
    }

    /// Whether the dispatched buckets outnumber [`ValenceLayout::bucket_limit`].
    fn fragmented(&self) -> bool {
        self.dispatched_buckets() > self.bucket_limit()
    }

    /// Where the buckets patches appended begin: the bucket after the packing's
    /// ([`ValenceLayout::packing`]), with the first layout index and slot of that tail. Every
    /// bucket before it lies, with its room, below both; where an arrangement does not (one
    /// given to [`ValenceLayout::arranged`]), the whole layout is the tail.
    fn tail_start(&self) -> (usize, u32, u32) {
        let b = &self.buckets;
        let k = self.packing.min(b.len());
        if k == 0 || k == b.len() {
            return (0, 0, 0);
        }
        let (first, offset) = (b[k].first, b[k].offset);
        let head_below = b[..k]
            .iter()
            .zip(&self.room)
            .all(|(h, &r)| h.first + r <= first && h.offset + r * h.valence <= offset);
        let tail_above = b[k..]
            .iter()
            .all(|t| t.first >= first && t.offset >= offset);
        if head_below && tail_above {
            (k, first, offset)
        } else {
            (0, 0, 0)
        }
    }

    /// Pack the buckets patches appended anew by valence (one bucket per valence, no holes, no
    /// room), keeping the node order within each valence, after the incremental part of a patch
    /// left the layout fragmented. The buckets of the packing before them keep their nodes and
    /// holes: their valences are distinct, so the layout is left with at most two buckets per
    /// valence. Only the tail's nodes move; their rows are taken from the rows the patch left
    /// (their other ends renumbered), and the rows pointing at them are remapped. `moves` are that
    /// part's state moves (destination in the fragmented layout, sources before the patch), `rows`
    /// the rows it rewrote (ascending); each moved node's state goes on from there to its new
    /// place. The node slots may shrink: the slots dropped that the layout had before the patch
    /// (`slots_before`) are cleared.
    fn regroup(
        &mut self,
        model: &PackedModel,
        diff: &ModelDiff,
        moves: &BTreeMap<u32, StateMove>,
        rows: &[u32],
        slots_before: usize,
    ) -> LayoutPatch {
        let (k, first, offset) = self.tail_start();
        // The tail's nodes in layout order, with valence and where their rows start; stably
        // sorted by valence below, so each valence keeps its order.
        let mut tail: Vec<(u32, u32, u32)> = Vec::new();
        for b in &self.buckets[k..] {
            for local in 0..b.count {
                let idx = b.first + local;
                if self.order.order[idx as usize] != NodeOrder::HOLE {
                    tail.push((idx, b.valence, b.offset + local * b.valence));
                }
            }
        }
        tail.sort_by_key(|e| e.1);
        // New layout index by old, over the tail's indices (dense: the tail is a few thousand
        // slots, and a row's lookups are most of a regroup's time).
        let mut moved_to = vec![NodeOrder::HOLE; self.order.order.len() - first as usize];
        for (j, e) in tail.iter().enumerate() {
            moved_to[(e.0 - first) as usize] = first + j as u32;
        }
        let remap = |o: u32| {
            o.checked_sub(first)
                .and_then(|i| moved_to.get(i as usize).copied())
        };
        let mut buckets: Vec<Bucket> = Vec::new();
        let mut slots: Vec<Slot> = Vec::new();
        let mut heads: Vec<u32> = Vec::new();
        for (j, &(_, v, start)) in tail.iter().enumerate() {
            push_node(
                &mut buckets,
                first + j as u32,
                v,
                offset + slots.len() as u32,
            );
            let row = &self.slots[start as usize..(start + v) as usize];
            heads.extend(row.iter().map(|s| s.other).filter(|&o| o < first));
            slots.extend(renumbered(row, remap));
        }
        let nodes: Vec<u32> = tail
            .iter()
            .map(|e| self.order.order[e.0 as usize])
            .collect();
        let inv_mass: Vec<f32> = tail
            .iter()
            .map(|e| self.nodes.inv_mass[e.0 as usize])
            .collect();
        // The rows before the tail that point into it.
        heads.sort_unstable();
        heads.dedup();
        for &h in &heads {
            let at = self.row_range(h);
            let row = renumbered(&self.slots[at.clone()], remap);
            self.slots[at].copy_from_slice(&row);
        }
        let end = first as usize + tail.len();
        self.order.order.truncate(first as usize);
        self.order.order.extend_from_slice(&nodes);
        for (j, &t) in nodes.iter().enumerate() {
            self.order.rank[t as usize] = first + j as u32;
        }
        self.slots.truncate(offset as usize);
        self.slots.extend_from_slice(&slots);
        self.nodes.inv_mass.truncate(first as usize);
        self.nodes.inv_mass.extend_from_slice(&inv_mass);
        self.room.truncate(k);
        self.room.extend(buckets.iter().map(|b| b.count));
        self.buckets.truncate(k);
        self.buckets.extend_from_slice(&buckets);
        // Regrouping the whole layout (no packing before the tail) packed it anew.
        if k == 0 {
            self.packing = self.buckets.len();
        }
        self.free.retain(|_, holes| {
            holes.retain(|&h| h < first);
            !holes.is_empty()
        });
        debug_assert!(
            ValenceLayout::arranged(
                model,
                self.order.clone(),
                self.buckets.clone(),
                self.room.clone()
            )
            .is_ok_and(|mut packed| {
                packed.packing = self.packing;
                packed == *self
            }),
            "a regroup packs what a packing from scratch of its arrangement does"
        );
        let mut patch = LayoutPatch::default();
        // Moves into the buckets before the tail stand; a tail node's state goes on from where
        // the incremental part put it (or from where it was) to its new place.
        patch.moves.extend(moves.range(..first).map(|(_, &m)| m));
        for (&(at, _, _), j) in tail.iter().zip(first..) {
            let source = moves.get(&at).copied().unwrap_or(StateMove {
                to: at,
                from: Some(at),
                blend: None,
            });
            if j != at || source.from != Some(at) || source.blend.is_some() {
                patch.moves.push(StateMove { to: j, ..source });
            }
        }
        // The slots the regroup drops are cleared: a bucket appended later lays holes there,
        // which must read as zero state again, as past the slots of a layout that never shrank.
        // Only those the layout had before the patch: the device's state past them is zero
        // already (and may not exist: the buckets this patch appended were never uploaded).
        patch.moves.extend((end..slots_before).map(|to| StateMove {
            to: to as u32,
            from: None,
            blend: None,
        }));
        // The rows the incremental part rewrote before the tail, those remapped, and the tail.
        let before_tail = &rows[..rows.partition_point(|&r| r < first)];
        for &idx in before_tail.iter().chain(&heads) {
            let row = self.row_range(idx);
            patch.mark(LayoutArray::Slots, row.start as u32..row.end as u32, 1, 32);
        }
        patch.mark(LayoutArray::InvMass, before_tail.iter().copied(), 1, 4);
        patch.mark_range(
            LayoutArray::Slots,
            offset as u64..self.slots.len() as u64,
            32,
        );
        patch.mark_range(LayoutArray::InvMass, first as u64..end as u64, 4);
        patch.mark_all(LayoutArray::Buckets, self.buckets.len() as u64 * 16);
        patch.rest_fixed(model, diff, &self.order.rank);
        patch.normalize();
        patch
    }

    /// The slots of model node `t`'s row, each with the model index of its other end.
    fn row_of(&self, t: u32) -> Vec<(Slot, u32)> {
        self.row_slots_of(t)
            .iter()
            .map(|s| (*s, self.order.order[s.other as usize]))
            .collect()
    }

    /// The filled slots of model node `t`'s row.
    fn row_slots_of(&self, t: u32) -> &[Slot] {
        let row = &self.slots[self.row_range(self.order.rank[t as usize])];
        let filled = row
            .iter()
            .position(|s| s.other == Slot::EMPTY)
            .unwrap_or(row.len());
        &row[..filled]
    }

    /// Write `row` as model node `t`'s row (at its place after the patch) and its mass.
    fn write_row(&mut self, t: u32, row: &[Slot], model: &PackedModel) {
        let idx = self.order.rank[t as usize];
        let at = self.row_range(idx).start;
        self.slots[at..at + row.len()].copy_from_slice(row);
        self.nodes.inv_mass[idx as usize] = inv_mass_of(model, t);
    }

    /// The slots of layout index `idx`'s row (its bucket's valence of them).
    fn row_range(&self, idx: u32) -> std::ops::Range<usize> {
        let b = self.buckets[self.bucket_of(idx)];
        let at = (b.offset + (idx - b.first) * b.valence) as usize;
        at..at + b.valence as usize
    }

    /// The bucket holding layout index `idx`.
    fn bucket_of(&self, idx: u32) -> usize {
        self.buckets.partition_point(|b| b.first <= idx) - 1
    }

    /// Turn layout index `idx` into a hole: no node, no springs, no mass.
    fn vacate(&mut self, idx: u32) {
        let b = self.buckets[self.bucket_of(idx)];
        let row = self.row_range(idx);
        self.slots[row].fill(Slot::empty());
        self.nodes.inv_mass[idx as usize] = 0.0;
        self.order.order[idx as usize] = NodeOrder::HOLE;
        self.free.entry(b.valence).or_default().insert(idx);
    }

    /// A free layout index in a bucket of valence `v`, and whether the bucket table changed (a
    /// count grew or a bucket was appended). `want` nodes (this one included) still need a
    /// place of this valence in this patch: an appended bucket has room for them all.
    fn place(&mut self, v: u32, want: u32, nodes: usize) -> (u32, bool) {
        if let Some(holes) = self.free.get_mut(&v) {
            let idx = holes.pop_first();
            if holes.is_empty() {
                self.free.remove(&v);
            }
            if let Some(idx) = idx {
                return (idx, false);
            }
        }
        if let Some(i) = (0..self.buckets.len())
            .rev()
            .find(|&i| self.buckets[i].valence == v && self.buckets[i].count < self.room[i])
        {
            let b = &mut self.buckets[i];
            b.count += 1;
            return (b.first + b.count - 1, true);
        }
        let same: u32 = self
            .buckets
            .iter()
            .filter(|b| b.valence == v)
            .map(|b| b.count)
            .sum();
        // The room of the buckets patches appended for this valence so far (after the
        // packing's): a new one has as much again, so a valence that
        // keeps receiving nodes takes a number of buckets that grows with the logarithm of
        // their count, not with the count (which made a long run of cuts regroup ever larger
        // tails, each a pause).
        let packing = self.packing.min(self.buckets.len());
        let appended: u32 = self.buckets[packing..]
            .iter()
            .zip(&self.room[packing..])
            .filter(|(b, _)| b.valence == v)
            .map(|(_, &r)| r)
            .sum();
        // Room for a sixteenth more of this valence's nodes, and at least for a few more cuts.
        let room = (same / 16)
            .max(least_room(nodes))
            .max(want)
            .max(appended)
            .next_power_of_two()
            .min(nodes.max(32) as u32)
            .max(want);
        let first = self.order.order.len() as u32;
        let offset = self.slots.len() as u32;
        self.order
            .order
            .extend(std::iter::repeat_n(NodeOrder::HOLE, room as usize));
        self.nodes
            .inv_mass
            .extend(std::iter::repeat_n(0.0, room as usize));
        self.slots
            .extend(std::iter::repeat_n(Slot::empty(), (room * v) as usize));
        self.buckets.push(Bucket {
            valence: v,
            first,
            count: 1,
            offset,
        });
        self.room.push(room);
        (first, true)
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.inv_mass.len()
    }

    /// Device memory with node state, and the bytes one step moves.
    pub fn memory(&self, integrator: Integrator) -> (MemoryStats, u64) {
        let n = self.node_count() as u64;
        let slots = self.slots.len() as u64 * 32;
        let table = table_bytes(self.buckets.len());
        let mut buffers = vec![
            ("slots".to_string(), slots),
            ("inverse masses".to_string(), n * 4),
            ("bucket table".to_string(), table),
        ];
        buffers.extend(state_buffers(n, integrator));
        let stats = MemoryStats::new(buffers, 0, n as usize, self.slots.len() / 2);
        let per_step = slots + n * 4 + table + state_traffic(n, integrator);
        (stats, per_step)
    }
}
