//! The connectivity layout (the 2005 "connectivity texture"): every node owns `K` fixed slots,
//! `slots[i * K + s]`, filled from the front, the rest marked [`Slot::EMPTY`]; a node a cut
//! gave more than `K` springs goes on in overflow rows past the node rows
//! ([`Slot::CONTINUE`]). One invocation
//! per node gathers its springs and integrates itself, so no two invocations write the same
//! node. The price is padding: every node pays for the widest one.

use std::collections::BTreeMap;

use rustc_hash::FxHashMap;

use super::patch::{row_size_class, LayoutArray, LayoutPatch, StateMove};
use super::{MemoryStats, NodeOrder, Slot};
use crate::error::{Error, Result};
use crate::model::{ModelDiff, PackedModel, PackedSpring};
use crate::physics::{state_buffers, state_traffic, Integrator};

/// Per-node data shared by the node-centric layouts, in the layout's node order.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeArrays {
    /// Inverse lumped mass, 1/kg; 0 for fixed nodes (they never move).
    pub inv_mass: Vec<f32>,
}

impl NodeArrays {
    /// The arrays of `model` in `order`.
    pub fn new(model: &PackedModel, order: &NodeOrder) -> Self {
        let inv_mass = order
            .order
            .iter()
            .map(|&old| inv_mass_of(model, old))
            .collect();
        NodeArrays { inv_mass }
    }
}

/// Inverse mass of model node `node` as the layouts store it: 0 for fixed nodes and for
/// [`NodeOrder::HOLE`] (an unused layout index).
pub(crate) fn inv_mass_of(model: &PackedModel, node: u32) -> f32 {
    if node == NodeOrder::HOLE || model.fixed[node as usize] {
        0.0
    } else {
        (1.0 / model.mass[node as usize]) as f32
    }
}

/// The nodes a diff touches (model indices, ascending), each with its row before the diff
/// (an existing node's slots, each with the model index of its other end; empty for an added
/// node) and its neighbours in the model after it (added nodes included). Sorted arrays
/// searched by node: a cut touches a few dozen nodes, and every patch walks them in order.
pub(crate) struct TouchedRows {
    nodes: Vec<u32>,
    old: Vec<Vec<(Slot, u32)>>,
    lists: Vec<Vec<u32>>,
}

impl TouchedRows {
    /// The touched nodes with their neighbours after the diff, ascending.
    pub(crate) fn iter(&self) -> impl Iterator<Item = (u32, &[u32])> {
        self.nodes
            .iter()
            .zip(&self.lists)
            .map(|(&t, l)| (t, l.as_slice()))
    }

    /// The touched nodes, ascending.
    pub(crate) fn nodes(&self) -> &[u32] {
        &self.nodes
    }

    /// Whether the diff touches node `t`.
    pub(crate) fn contains(&self, t: u32) -> bool {
        self.nodes.binary_search(&t).is_ok()
    }

    /// Node `t`'s neighbours after the diff (empty if it is not touched).
    pub(crate) fn list(&self, t: u32) -> &[u32] {
        self.nodes
            .binary_search(&t)
            .map_or(&[][..], |i| self.lists[i].as_slice())
    }

    /// Node `t`'s row before the diff (empty for an added or untouched node).
    pub(crate) fn old(&self, t: u32) -> &[(Slot, u32)] {
        self.nodes
            .binary_search(&t)
            .map_or(&[][..], |i| self.old[i].as_slice())
    }
}

/// The rows of the existing nodes `diff` touches as they are before it (`row_of(node)`: a
/// node's slots, each with the model index of its other end), and the neighbours (model
/// indices) of every node it touches in the model after it (added nodes included).
pub(crate) fn touched_rows(
    diff: &ModelDiff,
    nodes_before: usize,
    mut row_of: impl FnMut(u32) -> Vec<(Slot, u32)>,
) -> TouchedRows {
    // The springs the diff removes and adds at each node: a few per node, so short lists.
    let mut removed: FxHashMap<u32, Vec<u32>> = FxHashMap::default();
    for &[a, b] in &diff.removed_springs {
        removed.entry(a).or_default().push(b);
        removed.entry(b).or_default().push(a);
    }
    let mut added: FxHashMap<u32, Vec<u32>> = FxHashMap::default();
    for s in &diff.added_springs {
        let [a, b] = s.nodes;
        added.entry(a).or_default().push(b);
        added.entry(b).or_default().push(a);
    }
    let nodes = diff.touched_nodes(nodes_before);
    let mut old = Vec::with_capacity(nodes.len());
    let mut lists = Vec::with_capacity(nodes.len());
    for &t in &nodes {
        let row = if (t as usize) < nodes_before {
            row_of(t)
        } else {
            Vec::new()
        };
        let mut list: Vec<u32> = row.iter().map(|e| e.1).collect();
        if let Some(r) = removed.get(&t) {
            list.retain(|x| !r.contains(x));
        }
        if let Some(a) = added.get(&t) {
            list.extend(a);
        }
        old.push(row);
        lists.push(list);
    }
    TouchedRows { nodes, old, lists }
}

/// The springs a diff adds or changes, by end pair, as the model holds them after it (a
/// change wins over an addition, as in `PackedModel::apply`): with a touched node's slots from
/// before the patch, all its new row needs ([`patched_row_slots`]).
pub(crate) struct DiffSprings(FxHashMap<[u32; 2], PackedSpring>);

impl DiffSprings {
    /// The springs `diff` adds or changes, checked against `model` (the model after it): each
    /// must be there as the diff gives it, and each spring it removes (and does not add back)
    /// gone. A search per spring the diff names, not per slot of every row it touches.
    pub(crate) fn of(diff: &ModelDiff, model: &PackedModel) -> Result<Self> {
        let mut map = FxHashMap::default();
        for s in diff.added_springs.iter().chain(&diff.changed_springs) {
            let [a, b] = s.nodes;
            map.insert([a.min(b), a.max(b)], *s);
        }
        let mismatch = |a: u32, b: u32, what: &str, model_has: &str| {
            Error::DiffMismatch(format!(
                "the diff {what} the spring between nodes {a} and {b}, but the model given \
                 with it {model_has}; give the model the diff was applied to"
            ))
        };
        for (&[a, b], s) in &map {
            let held = model.spring_index(a, b).map(|i| &model.springs()[i]);
            let same = held.is_some_and(|h| {
                h.rest_length == s.rest_length
                    && h.stiffness == s.stiffness
                    && h.damping == s.damping
            });
            if !same {
                return Err(mismatch(a, b, "adds or changes", "does not have it so"));
            }
        }
        for &[a, b] in &diff.removed_springs {
            let key = [a.min(b), a.max(b)];
            if !map.contains_key(&key) && model.spring_index(a, b).is_some() {
                return Err(mismatch(a, b, "removes", "still has it"));
            }
        }
        Ok(DiffSprings(map))
    }
}

/// The slots of touched model node `node` after a diff, with neighbours `neighbours` (model
/// indices, as [`touched_rows`] gives them), pointing at their layout indices `rank`,
/// sorted by layout index: a spring the diff adds or changes from `springs`, any other from
/// `old` (the node's slots before the patch, each with the model index of its other end),
/// which holds it as it was. Equal to [`row_slots`] of the model after the diff, without a
/// search of the model's springs per slot.
pub(crate) fn patched_row_slots(
    model: &PackedModel,
    node: u32,
    neighbours: &[u32],
    old: &[(Slot, u32)],
    springs: &DiffSprings,
    rank: &[u32],
) -> Result<Vec<Slot>> {
    let mut row = neighbours
        .iter()
        .map(|&nb| {
            let other = rank[nb as usize];
            if let Some(s) = springs.0.get(&[node.min(nb), node.max(nb)]) {
                return Ok(Slot::of(model, s, node, other));
            }
            old.iter()
                .find(|e| e.1 == nb)
                .map(|e| Slot { other, ..e.0 })
                .ok_or_else(|| {
                    Error::DiffMismatch(format!(
                        "the layout joins nodes {node} and {nb} but neither the layout nor the \
                         diff has that spring; the diff does not match the layout"
                    ))
                })
        })
        .collect::<Result<Vec<Slot>>>()?;
    row.sort_by_key(|s| s.other);
    Ok(row)
}

/// The slots of model node `node` with neighbours `neighbours` (model indices), pointing at
/// their layout indices `rank`, sorted by layout index as every packing sorts them.
pub(crate) fn row_slots(
    model: &PackedModel,
    node: u32,
    neighbours: &[u32],
    rank: &[u32],
) -> Result<Vec<Slot>> {
    let mut row = neighbours
        .iter()
        .map(|&nb| {
            let s = model.spring_index(node, nb).ok_or_else(|| {
                Error::DiffMismatch(format!(
                    "the layout joins nodes {node} and {nb} but the model has no such spring; \
                     the diff does not match the model it was applied to"
                ))
            })?;
            Ok(Slot::of(
                model,
                &model.springs()[s],
                node,
                rank[nb as usize],
            ))
        })
        .collect::<Result<Vec<Slot>>>()?;
    row.sort_by_key(|s| s.other);
    Ok(row)
}

/// Springs packed into `K` slots per node.
///
/// A node with more than `K` springs continues its row: the row's last slot is a
/// [`Slot::CONTINUE`] naming an overflow row past the node rows, which holds the next `K - 1`
/// springs and, if needed, another continuation. Packing sizes `K` so that no row continues;
/// the rows a cut makes too wide continue instead of repacking the whole table (which on a
/// 100k-tet mesh re-uploaded it whole, 10-20 ms, one cut in four).
#[derive(Debug, Clone)]
pub struct ConnectivityLayout {
    /// Node renumbering (model index <-> layout index).
    pub order: NodeOrder,
    /// Slots per row.
    pub capacity: u32,
    /// `capacity` slots per row: one row per node in layout order, then the overflow rows.
    pub slots: Vec<Slot>,
    /// Per-node arrays.
    pub nodes: NodeArrays,
    /// For each overflow row (row `node_count() + j`), the row whose last slot continues into
    /// it, or [`FREE_ROW`].
    overflow: Vec<u32>,
    /// Overflow rows no chain uses, for reuse.
    free: Vec<u32>,
}

/// An overflow row that no chain uses.
const FREE_ROW: u32 = u32::MAX;

/// Two layouts are equal when every node sums the same slots in the same order, whatever rows
/// its chain went to: a patched layout places overflow rows in the order cuts needed them.
impl PartialEq for ConnectivityLayout {
    fn eq(&self, other: &Self) -> bool {
        self.order == other.order
            && self.capacity == other.capacity
            && self.nodes == other.nodes
            && (0..self.node_count()).all(|i| self.row(i) == other.row(i))
    }
}

impl ConnectivityLayout {
    /// Pack `model` in node order `order`, with `capacity` slots per row (default: the next
    /// multiple of 4 above the largest valence, so that every row has a free slot: a cut that
    /// splits a node gives the nodes on its crack front one more neighbour). Nodes with more
    /// springs than `capacity` continue their rows in overflow rows; a capacity below 2 (no
    /// room for a spring and a continuation) is an error.
    pub fn new(model: &PackedModel, order: NodeOrder, capacity: Option<u32>) -> Result<Self> {
        let n = model.node_count();
        let mut valence = vec![0u32; n];
        for s in model.springs() {
            valence[s.nodes[0] as usize] += 1;
            valence[s.nodes[1] as usize] += 1;
        }
        let widest = valence.iter().copied().max().unwrap_or(0);
        let k = capacity.unwrap_or_else(|| row_size_class(widest));
        if k < 2 {
            return Err(Error::LayoutCapacity(format!(
                "the connectivity layout needs at least 2 slots per node (a spring and a \
                 continuation), not {k}"
            )));
        }
        let total = n
            .checked_mul(k as usize)
            .filter(|&t| t <= u32::MAX as usize)
            .ok_or_else(|| {
                Error::LayoutCapacity("connectivity table too large for u32 indices".into())
            })?;
        let mut slots = vec![Slot::empty(); total];
        let mut fill = vec![0u32; n];
        // Rows wider than `k`, gathered whole and written as chains below.
        let mut wide: BTreeMap<usize, Vec<Slot>> = BTreeMap::new();
        // In the springs' order (none in particular after a cut); each row is sorted below.
        for s in model.springs() {
            for (from, to) in [(s.nodes[0], s.nodes[1]), (s.nodes[1], s.nodes[0])] {
                let slot = Slot::of(model, s, from, order.rank[to as usize]);
                let row = order.rank[from as usize] as usize;
                if valence[from as usize] > k {
                    wide.entry(row).or_default().push(slot);
                } else {
                    slots[row * k as usize + fill[row] as usize] = slot;
                    fill[row] += 1;
                }
            }
        }
        // Within a row, put neighbours in ascending layout order so the gather walks memory
        // forwards.
        for row in slots.chunks_mut(k as usize) {
            row.sort_by_key(|s| s.other);
        }
        let nodes = NodeArrays::new(model, &order);
        let mut layout = ConnectivityLayout {
            order,
            capacity: k,
            slots,
            nodes,
            overflow: Vec::new(),
            free: Vec::new(),
        };
        for (row, mut list) in wide {
            list.sort_by_key(|s| s.other);
            layout.write_row(row, &list, &mut Vec::new())?;
        }
        Ok(layout)
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.inv_mass.len()
    }

    /// Overflow rows (in use or free) past the node rows.
    pub fn overflow_rows(&self) -> usize {
        self.overflow.len()
    }

    /// The slots node row `i` sums, in order, its continuation rows followed.
    pub fn row(&self, i: usize) -> Vec<Slot> {
        let k = self.capacity as usize;
        let mut out = Vec::new();
        for r in self.chain(i) {
            out.extend(
                self.slots[r * k..(r + 1) * k]
                    .iter()
                    .take_while(|s| s.other != Slot::EMPTY && s.other != Slot::CONTINUE),
            );
        }
        out
    }

    /// The rows of node row `i`'s chain: its own, then each continuation.
    fn chain(&self, i: usize) -> Vec<usize> {
        let k = self.capacity as usize;
        let mut rows = vec![i];
        loop {
            let last = self.slots[(rows[rows.len() - 1] + 1) * k - 1];
            if last.other != Slot::CONTINUE {
                return rows;
            }
            rows.push(last.pad as usize);
        }
    }

    /// Write `list` (sorted by layout index) as node row `row`'s chain, reusing the rows it
    /// has, freeing those it no longer needs and taking free or new overflow rows for those it
    /// lacks. Every row written or freed is pushed to `dirty`.
    fn write_row(&mut self, row: usize, list: &[Slot], dirty: &mut Vec<u32>) -> Result<()> {
        let k = self.capacity as usize;
        let n = self.node_count();
        let needed = if list.len() <= k {
            1
        } else {
            1 + (list.len() - k).div_ceil(k - 1)
        };
        let mut rows = self.chain(row);
        for &r in &rows[needed.min(rows.len())..] {
            self.slots[r * k..(r + 1) * k].fill(Slot::empty());
            self.overflow[r - n] = FREE_ROW;
            self.free.push(r as u32);
            dirty.push(r as u32);
        }
        rows.truncate(needed);
        while rows.len() < needed {
            let owner = rows[rows.len() - 1] as u32;
            let r = match self.free.pop() {
                Some(r) => {
                    self.overflow[r as usize - n] = owner;
                    r as usize
                }
                None => {
                    let r = n + self.overflow.len();
                    if (r + 1) * k > u32::MAX as usize {
                        return Err(Error::LayoutCapacity(
                            "connectivity table too large for u32 indices".into(),
                        ));
                    }
                    self.overflow.push(owner);
                    self.slots.extend(std::iter::repeat_n(Slot::empty(), k));
                    r
                }
            };
            rows.push(r);
        }
        let mut rest = list;
        for (j, &r) in rows.iter().enumerate() {
            let dst = &mut self.slots[r * k..(r + 1) * k];
            dst.fill(Slot::empty());
            match rows.get(j + 1) {
                Some(&next) => {
                    dst[..k - 1].copy_from_slice(&rest[..k - 1]);
                    dst[k - 1] = Slot::continuation(next as u32);
                    rest = &rest[k - 1..];
                }
                None => dst[..rest.len()].copy_from_slice(rest),
            }
            dirty.push(r as u32);
        }
        Ok(())
    }

    /// Make room for `added` node rows after the `before` node rows. The overflow rows in the
    /// way (the first `added` of them) move to the end of the table and the slots pointing at
    /// them follow; the others stay, so the cost follows the nodes added, not the overflow rows
    /// earlier cuts left. The node rows and the moved rows are pushed to `dirty_rows`, the
    /// changed continuation slots to `dirty_slots`.
    fn insert_node_rows(
        &mut self,
        before: usize,
        added: usize,
        dirty_rows: &mut Vec<u32>,
        dirty_slots: &mut Vec<u32>,
    ) {
        let k = self.capacity as usize;
        let m = self.overflow.len();
        // The new node rows: new bytes, or where the moved overflow rows were.
        dirty_rows.extend(before as u32..(before + added) as u32);
        if m == 0 {
            self.slots
                .extend(std::iter::repeat_n(Slot::empty(), added * k));
            return;
        }
        // Rows [before, before + moving) move to [dest, dest + moving); the overflow rows then
        // fill [before + added, before + added + m).
        let moving = added.min(m);
        let dest = before + added.max(m);
        self.slots.resize((before + added + m) * k, Slot::empty());
        let new_row = |r: usize| {
            if (before..before + moving).contains(&r) {
                dest + (r - before)
            } else {
                r
            }
        };
        for j in 0..moving {
            let (from, to) = ((before + j) * k, (dest + j) * k);
            self.slots.copy_within(from..from + k, to);
            dirty_rows.push((dest + j) as u32);
        }
        let mut overflow = vec![FREE_ROW; m];
        for j in 0..m {
            let (old, new) = (before + j, new_row(before + j));
            let owner = match self.overflow[j] {
                FREE_ROW => FREE_ROW,
                o if o as usize >= before => new_row(o as usize) as u32,
                o => o,
            };
            overflow[new - before - added] = owner;
            // The owner's row was copied whole if it moved, so its continuation still names
            // this row's old place when this row moved.
            if owner != FREE_ROW && new != old {
                let slot = (owner as usize + 1) * k - 1;
                self.slots[slot].pad = new as u32;
                dirty_slots.push(slot as u32);
            }
        }
        self.overflow = overflow;
        for r in &mut self.free {
            *r = new_row(*r as usize) as u32;
        }
        for r in before..before + added {
            self.slots[r * k..(r + 1) * k].fill(Slot::empty());
        }
    }

    /// Device memory of this layout with its node state (three vec4 displacement buffers, and
    /// two velocity buffers for symplectic Euler), and the bytes one step moves.
    pub fn memory(&self, integrator: Integrator) -> (MemoryStats, u64) {
        let n = self.node_count() as u64;
        let slots = self.slots.len() as u64 * 32;
        let springs = self
            .slots
            .iter()
            .filter(|s| s.other != Slot::EMPTY && s.other != Slot::CONTINUE)
            .count() as u64;
        let state = state_buffers(n, integrator);
        let mut buffers = vec![
            ("slots".to_string(), slots),
            ("inverse masses".to_string(), n * 4),
        ];
        buffers.extend(state.iter().cloned());
        let stats = MemoryStats::new(
            buffers,
            (self.slots.len() as u64 - springs) * 32,
            n as usize,
            (springs / 2) as usize,
        );
        // The padded rows a step reads are streamed whole (empty slots end a row's loop, but they
        // share cache lines with used ones): every node row and the overflow rows in use, not
        // the free ones; plus masses and the state read and written once.
        let in_use = self.overflow.iter().filter(|&&o| o != FREE_ROW).count() as u64;
        let read = (n + in_use) * self.capacity as u64 * 32;
        let per_step = read + n * 4 + state_traffic(n, integrator);
        (stats, per_step)
    }
}

impl ConnectivityLayout {
    /// Apply `diff` (already applied to `model`, the model after the change): added nodes get
    /// the next layout indices and a row each (the overflow rows move up to make room), the
    /// rows of touched nodes are rewritten, continuing in overflow rows where they outgrow
    /// `capacity`. Only when the overflow rows outnumber an eighth of the nodes (and 64) is
    /// the table repacked, with the capacity grown to the next size class
    /// ([`row_size_class`]) so that no row continues (unless that table would pass u32 slot
    /// indices: the patched one is kept). The result equals (as [`PartialEq`] compares, slot
    /// for slot in each node's order)
    /// `ConnectivityLayout::new(model, self.order.clone(), Some(self.capacity))`.
    pub fn patch(&mut self, model: &PackedModel, diff: &ModelDiff) -> Result<LayoutPatch> {
        let before = self.node_count();
        super::patch::check_model(before, diff, model)?;
        let k = self.capacity as usize;
        // Checked before anything changes: on error the layout is as it was.
        let springs = DiffSprings::of(diff, model)?;
        // The most rows the patch can add: one per added node, and per touched node one more
        // than the springs it gains (a spring added names two nodes; every node a diff
        // touches is an added or changed node or an end of a spring it names). A table that
        // could pass u32 slot indices is refused here, before anything changes, so that
        // writing the rows below cannot fail halfway.
        let springs_named =
            diff.removed_springs.len() + diff.added_springs.len() + diff.changed_springs.len();
        let touched_most = diff.added_nodes.len() + diff.changed_nodes.len() + 2 * springs_named;
        let most_rows = self.slots.len() / k
            + diff.added_nodes.len()
            + touched_most
            + 2 * diff.added_springs.len();
        if most_rows.saturating_mul(k) > u32::MAX as usize {
            return Err(Error::LayoutCapacity(format!(
                "a connectivity table of up to {most_rows} rows of {k} slots is too large for u32 \
                 indices; use the valence or edge layout"
            )));
        }
        let mut patch = LayoutPatch::default();
        let mut dirty: Vec<u32> = Vec::new();
        let mut dirty_slots: Vec<u32> = Vec::new();
        let added = diff.added_nodes.len();
        if added > 0 {
            self.insert_node_rows(before, added, &mut dirty, &mut dirty_slots);
        }
        for (i, a) in diff.added_nodes.iter().enumerate() {
            let node = (before + i) as u32;
            self.order.order.push(node);
            self.order.rank.push(node);
            self.nodes.inv_mass.push(0.0);
            patch
                .moves
                .push(StateMove::added(node, a, &self.order.rank));
        }
        // The touched nodes' rows before the patch: the springs the diff leaves alone are taken
        // from them.
        let touched = touched_rows(diff, before, |t| {
            self.row(self.order.rank[t as usize] as usize)
                .into_iter()
                .map(|s| (s, self.order.order[s.other as usize]))
                .collect()
        });
        for &t in touched.nodes() {
            let row = self.order.rank[t as usize] as usize;
            self.nodes.inv_mass[row] = inv_mass_of(model, t);
        }
        for (t, list) in touched.iter() {
            let row = self.order.rank[t as usize] as usize;
            let old = touched.old(t);
            let new = patched_row_slots(model, t, list, old, &springs, &self.order.rank)?;
            self.write_row(row, &new, &mut dirty)?;
        }
        // A repack only makes the table faster to read: where the wider table would pass u32
        // indices, the patched one (already valid) is kept.
        let repacked = (self.overflow.len() > 64.max(self.node_count() / 8))
            .then(|| {
                let widest = (0..self.node_count())
                    .map(|i| self.row(i).len() as u32)
                    .max()
                    .unwrap_or(0);
                let class = row_size_class(widest);
                // Its size is known first: a table that cannot fit is not built to be refused.
                let fits = (self.node_count() as u64) * u64::from(class) <= u64::from(u32::MAX);
                fits.then(|| ConnectivityLayout::new(model, self.order.clone(), Some(class)))
            })
            .flatten()
            .transpose()?;
        if let Some(repacked) = repacked {
            *self = repacked;
            patch.repacked = true;
            patch.mark_all(LayoutArray::Slots, self.slots.len() as u64 * 32);
            patch.mark_all(LayoutArray::InvMass, self.nodes.inv_mass.len() as u64 * 4);
            patch.rest_fixed(model, diff, &self.order.rank);
            patch.normalize();
            return Ok(patch);
        }
        let rows: Vec<u32> = touched
            .nodes()
            .iter()
            .map(|&t| self.order.rank[t as usize])
            .collect();
        // Continuation slots in rows that are not rewritten whole.
        let whole: std::collections::HashSet<u32> = dirty.iter().copied().collect();
        dirty_slots.retain(|&s| !whole.contains(&(s / k as u32)));
        patch.mark(LayoutArray::Slots, dirty, k as u64, 32);
        patch.mark(LayoutArray::Slots, dirty_slots, 1, 32);
        patch.mark(LayoutArray::InvMass, rows, 1, 4);
        if added > 0 {
            // New node rows hold the added nodes' masses even when no spring touched them.
            patch.mark(
                LayoutArray::InvMass,
                before as u32..(before + added) as u32,
                1,
                4,
            );
        }
        patch.rest_fixed(model, diff, &self.order.rank);
        patch.normalize();
        Ok(patch)
    }
}
