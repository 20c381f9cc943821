//! The edge-centric layout: one record per spring. A first pass computes each spring's force
//! once (half the length computations of a node-centric gather); the forces reach the nodes
//! through a second pass in which every node sums its incident springs' forces from a
//! node-to-spring incidence table and integrates itself.
//!
//! That gather ([`Accumulation::Gather`], the default) is deterministic (each node sums in a
//! fixed order) and needs no atomics. The alternatives accumulate from the spring pass with
//! atomics into three accumulators per node, which a node pass then reads, integrates and
//! clears:
//!
//! - [`Accumulation::AtomicFixed`]: `atomic<i32>` in fixed point ([`FixedPoint`]); integer
//!   addition is associative, so the result is deterministic whatever the order of the adds.
//! - [`Accumulation::AtomicFloat`]: `atomic<f32>`, only on adapters with
//!   `SHADER_FLOAT32_ATOMIC`; the order of the additions, hence the rounding, changes between
//!   runs.
//!
//! On lavapipe the atomic variants measured 2.4x (fixed point) and 3.5x (float) slower than the
//! gather (DESIGN.md section 5), which is why the gather is the default; on real GPUs atomics
//! are cheaper and the variants are kept for measuring there.

use bytemuck::{Pod, Zeroable};
use serde::{Deserialize, Serialize};

use super::connectivity::NodeArrays;

use std::collections::BTreeSet;

use super::connectivity::inv_mass_of;
use super::patch::{incidence_room, LayoutArray, LayoutPatch, StateMove};
use super::{MemoryStats, NodeOrder};
use crate::error::{Error, Result};
use crate::model::{ModelDiff, PackedModel};
use crate::physics::{state_buffers, state_traffic, Integrator};

/// One spring. Mirrors `struct EdgeSpring` in `shaders/springs_edges.wgsl` (32 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct EdgeSpring {
    /// Rest vector from `a` to `b`, m (float64 difference rounded once).
    pub edge: [f32; 3],
    /// Rest length, m.
    pub rest: f32,
    /// Stiffness, N/m.
    pub k: f32,
    /// Damping along the spring, N s/m.
    pub c: f32,
    /// First end, layout order.
    pub a: u32,
    /// Second end, layout order.
    pub b: u32,
}

const _: () = assert!(std::mem::size_of::<EdgeSpring>() == 32);

/// How spring forces reach the nodes in the edge layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Accumulation {
    /// Spring pass stores one force per spring; a node pass sums each node's incident forces
    /// in incidence-table order. Deterministic, no atomics; fastest on lavapipe.
    #[default]
    Gather,
    /// Spring pass adds each force to per-node `atomic<i32>` accumulators in fixed point.
    /// Deterministic (integer addition is associative).
    AtomicFixed,
    /// Spring pass adds each force to per-node `atomic<f32>` accumulators. Needs the adapter
    /// feature `SHADER_FLOAT32_ATOMIC`; the summation order is not deterministic.
    AtomicFloat,
}

/// Fixed-point constants of [`Accumulation::AtomicFixed`]; mirrors `struct FixedPoint` in
/// `shaders/accumulate_fixed.wgsl` and `shaders/integrate_fixed.wgsl` (16 bytes).
///
/// A spring force component `f` (N) becomes `q = i32(clamp(round(f * scale), -limit, limit))`
/// (round half to even, as WGSL `round`), added to both ends (negated at `b`); a node's force is
/// `f32(sum) * inv_scale`. `scale` and `limit` are powers of two, so the products are exact:
///
/// - `limit = 2^(30 - ceil(log2(max valence)))`: a node sums at most `max valence` terms of at
///   most `limit`, i.e. at most `2^30`, so an accumulator can never wrap.
/// - `scale` is the largest power of two with `limit / scale >= bound`, where `bound` is
///   [`FixedPoint::HEADROOM`] times the larger of `max k * rest` over springs (the force of a
///   spring stretched to twice its length) and `max m * |g|` over nodes (a node's weight);
///   with the tensor-mass model, also the blocks' plausible end force
///   (`TensorBlocks::plausible_end_force`), since each record then adds two end forces.
///
/// Resolution: one unit is `1 / scale` N; a node's force is off by at most
/// `valence / (2 * scale)` N per component from the exact float32 sum of its springs' forces.
/// A spring force beyond `limit / scale` is saturated and sets the overflow flag
/// ([`EdgeLayout::accumulate_fixed_cpu`]'s second result, `overflow` in the shader), which the
/// host can read back.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct FixedPoint {
    /// Units per newton (a power of two).
    pub scale: f32,
    /// `1 / scale`, N per unit (exact).
    pub inv_scale: f32,
    /// Largest magnitude of one spring's quantized component (a power of two).
    pub limit: f32,
    /// Padding to 16 bytes.
    pub pad: u32,
}

const _: () = assert!(std::mem::size_of::<FixedPoint>() == 16);

impl FixedPoint {
    /// Safety factor between the plausible force of one spring and its saturation level.
    pub const HEADROOM: f64 = 16.0;

    /// Constants for springs of plausible force `force` (N) summed at nodes of at most
    /// `max_valence` springs.
    pub fn new(force: f64, max_valence: u32) -> Self {
        let bits = 30 - max_valence.max(1).next_power_of_two().trailing_zeros() as i32;
        let limit = 2f64.powi(bits);
        let bound = Self::HEADROOM * force;
        let exp = if bound > 0.0 && bound.is_finite() {
            ((limit / bound).log2().floor() as i32).clamp(-100, 100)
        } else {
            0
        };
        let scale = 2f64.powi(exp);
        FixedPoint {
            scale: scale as f32,
            inv_scale: (1.0 / scale) as f32,
            limit: limit as f32,
            pad: 0,
        }
    }

    /// One unit, N: the resolution of one quantized spring force component.
    pub fn resolution(&self) -> f64 {
        self.inv_scale as f64
    }

    /// Largest spring force component stored without saturating, N.
    pub fn max_force(&self) -> f64 {
        self.limit as f64 * self.inv_scale as f64
    }

    /// `f` quantized as the shader does it, and whether it saturated.
    pub fn quantize(&self, f: f32) -> (i32, bool) {
        let q = (f * self.scale).round_ties_even();
        let c = q.clamp(-self.limit, self.limit);
        // NaN fails the comparison too: it is reported as an overflow.
        (c as i32, c != q)
    }
}

/// Marks an incidence entry where the node is the spring's `b` end (the force acts reversed).
pub const B_END: u32 = 1 << 31;

/// An unused incidence entry: room a patch left at the end of a row. A row's entries come
/// first, then only these; the gather stops at the first.
pub const NO_SPRING: u32 = u32::MAX;

/// A patch compacts the incidence table once the entries no row owns (left behind by rows that
/// moved) exceed `1 / HOLE_FRACTION` of it. A moved row writes its entries once at the end; the
/// compaction that removes the hole costs the whole table, so taking it only after holes reach a
/// quarter of the table charges each moved entry a bounded share of it (amortized O(1) per
/// entry written), while the holes never cost more than a third of the live table in memory.
/// The gather never reads a hole, so they cost no step bandwidth. The fast CPU engine uses the
/// same rule for its adjacency (`engine/fast/patch.rs`).
const HOLE_FRACTION: usize = 4;

/// Springs as records plus the node-to-spring incidence table.
#[derive(Debug, Clone, PartialEq)]
pub struct EdgeLayout {
    /// Node renumbering (RCM locality).
    pub order: NodeOrder,
    /// Springs sorted by their layout-order ends.
    pub springs: Vec<EdgeSpring>,
    /// Each node's incidence row, `[start, end)` in `incidence`, room included (`n` entries;
    /// `array<vec2<u32>>` in `shaders/gather_edges.wgsl`). Rows need not be contiguous or in
    /// node order: a patch moves a row that outgrows its room to the end of the table, leaving
    /// the other rows where they are.
    pub incidence_rows: Vec<[u32; 2]>,
    /// Spring indices, with [`B_END`] set where the node is the `b` end; [`NO_SPRING`] for room
    /// at the end of a row. Entries outside every row are holes left by moved rows.
    pub incidence: Vec<u32>,
    /// Per-node arrays.
    pub nodes: NodeArrays,
    /// Records of removed springs (zero stiffness, both ends on one node), reused first.
    free: BTreeSet<u32>,
    /// Entries of `incidence` that no row owns (see [`HOLE_FRACTION`]).
    holes: usize,
}

impl EdgeLayout {
    /// Pack `model` in node order `order`.
    pub fn new(model: &PackedModel, order: NodeOrder) -> Self {
        let n = model.node_count();
        let mut springs: Vec<EdgeSpring> = model
            .springs()
            .iter()
            .map(|s| {
                let (ra, rb) = (
                    order.rank[s.nodes[0] as usize],
                    order.rank[s.nodes[1] as usize],
                );
                // Store with a < b in layout order so the records stream by their first end.
                let (from, a, b) = if ra < rb {
                    (s.nodes[0], ra, rb)
                } else {
                    (s.nodes[1], rb, ra)
                };
                let slot = super::Slot::of(model, s, from, b);
                EdgeSpring {
                    edge: slot.edge,
                    rest: slot.rest,
                    k: slot.k,
                    c: slot.c,
                    a,
                    b,
                }
            })
            .collect();
        springs.sort_by_key(|s| (s.a, s.b));
        let (incidence_rows, incidence) = incidence_table(n, &springs);
        let nodes = NodeArrays::new(model, &order);
        EdgeLayout {
            order,
            springs,
            incidence_rows,
            incidence,
            nodes,
            free: BTreeSet::new(),
            holes: 0,
        }
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.inv_mass.len()
    }

    /// Device memory of the layout with node state in `accumulation`, and the bytes one step
    /// moves.
    ///
    /// Gather: the spring pass reads the records and writes one force per spring; the node
    /// pass reads the row records and the rows (room included; holes left by moved rows are
    /// allocated but never read) and the forces. Atomics: the spring pass reads the
    /// records and adds to both ends' accumulators (3 x 4 bytes each); the node pass reads and
    /// clears its accumulators.
    pub fn memory(&self, integrator: Integrator, accumulation: Accumulation) -> (MemoryStats, u64) {
        let n = self.node_count() as u64;
        let m = self.springs.len() as u64;
        let records = m * 32;
        let mut buffers = vec![("springs".to_string(), records)];
        let per_step = match accumulation {
            Accumulation::Gather => {
                let forces = m * 16;
                let rows = self.incidence_rows.len() as u64 * 8;
                let table = rows + self.incidence.len() as u64 * 4;
                let read = rows + (self.incidence.len() - self.holes) as u64 * 4;
                buffers.push(("spring forces".to_string(), forces));
                buffers.push(("incidence table".to_string(), table));
                // Forces are written once and read once.
                records + 2 * forces + read
            }
            Accumulation::AtomicFixed | Accumulation::AtomicFloat => {
                let acc = n * 12;
                buffers.push(("accumulators (3 x 32-bit)".to_string(), acc));
                if accumulation == Accumulation::AtomicFixed {
                    buffers.push(("fixed-point constants".to_string(), 16));
                    buffers.push(("overflow flag".to_string(), 16));
                }
                records + 2 * m * 12 + 2 * acc
            }
        };
        buffers.push(("inverse masses".to_string(), n * 4));
        buffers.extend(state_buffers(n, integrator));
        let stats = MemoryStats::new(buffers, 0, n as usize, m as usize);
        (stats, per_step + n * 4 + state_traffic(n, integrator))
    }

    /// Largest number of springs at one node.
    pub fn max_valence(&self) -> u32 {
        (0..self.node_count())
            .map(|i| self.row(i).len() as u32)
            .max()
            .unwrap_or(0)
    }

    /// The entries of node `i`'s row (layout order), room included.
    fn row_room(&self, i: usize) -> std::ops::Range<usize> {
        let [lo, hi] = self.incidence_rows[i];
        lo as usize..hi as usize
    }

    /// Entries of `incidence` that belong to no row: left behind by rows a patch moved, until
    /// a patch compacts the table.
    pub fn holes(&self) -> usize {
        self.holes
    }

    /// The used incidence entries of node `i` (layout order): the springs its gather sums, in
    /// the order it sums them.
    pub fn row(&self, i: usize) -> &[u32] {
        let row = &self.incidence[self.row_room(i)];
        let used = row
            .iter()
            .position(|&e| e == NO_SPRING)
            .unwrap_or(row.len());
        &row[..used]
    }

    /// The other end (layout order) of incidence entry `e`.
    fn other_end(&self, e: u32) -> u32 {
        let s = &self.springs[(e & !B_END) as usize];
        if e & B_END != 0 {
            s.a
        } else {
            s.b
        }
    }

    /// The fixed-point constants for this layout of `model` (see [`FixedPoint`]).
    pub fn fixed_point(&self, model: &PackedModel) -> FixedPoint {
        FixedPoint::new(self.plausible_force(model), self.max_valence())
    }

    /// The plausible force of one record on one end that [`FixedPoint`] is sized for, N: the
    /// larger of `max k * rest` over springs and `max m * |g|` over nodes.
    pub fn plausible_force(&self, model: &PackedModel) -> f64 {
        let spring = self
            .springs
            .iter()
            .map(|s| (s.k as f64 * s.rest as f64).abs())
            .fold(0.0, f64::max);
        let g = model.gravity;
        let g = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
        let weight = model.mass.iter().map(|m| m * g).fold(0.0, f64::max);
        spring.max(weight)
    }

    /// Reorder the spring records (`perm[new] = old`) and rebuild the incidence table to match.
    /// Only the summation order of the passes changes.
    pub fn permute_springs(&mut self, perm: &[u32]) {
        assert_eq!(
            perm.len(),
            self.springs.len(),
            "a permutation of the springs"
        );
        self.springs = perm.iter().map(|&old| self.springs[old as usize]).collect();
        let (rows, incidence) = incidence_table(self.node_count(), &self.springs);
        self.incidence_rows = rows;
        self.incidence = incidence;
        self.holes = 0;
        self.free = self
            .springs
            .iter()
            .enumerate()
            .filter(|(_, s)| s.a == s.b)
            .map(|(i, _)| i as u32)
            .collect();
    }

    /// Apply `diff` (already applied to `model`, the model after the change). Added nodes get
    /// the next layout indices and an incidence row with room (a multiple of four entries)
    /// appended to the table; removed springs become dead records (zero stiffness, both ends
    /// on one node) that added springs reuse before the array grows; incidence rows are edited
    /// in place, keeping their entries sorted by the other end, as a fresh packing sorts them.
    /// A row with no room left for an added spring is written anew, with room, at the end of
    /// the table: only it and its `[start, end)` record are dirty, and its old place becomes a
    /// hole. Once holes exceed a quarter of the table (`HOLE_FRACTION`) the table is
    /// compacted, every row with room, and the patch says `repacked`.
    ///
    /// Each node then sums the same forces in the same order as in
    /// `EdgeLayout::new(model, self.order.clone())`, so both step bit for bit alike (gather and
    /// fixed point), though the records and rows sit elsewhere.
    pub fn patch(&mut self, model: &PackedModel, diff: &ModelDiff) -> Result<LayoutPatch> {
        let before = self.node_count();
        super::patch::check_model(before, diff, model)?;
        let mut patch = LayoutPatch::default();
        let mut degree = vec![0u32; diff.added_nodes.len()];
        for s in &diff.added_springs {
            for end in s.nodes {
                if end as usize >= before {
                    degree[end as usize - before] += 1;
                }
            }
        }
        for (i, a) in diff.added_nodes.iter().enumerate() {
            let node = (before + i) as u32;
            self.order.order.push(node);
            self.order.rank.push(node);
            self.nodes.inv_mass.push(0.0);
            let end = self.incidence.len() as u32;
            let room = incidence_room(degree[i]);
            self.incidence_rows.push([end, end + room]);
            self.incidence
                .extend(std::iter::repeat_n(NO_SPRING, room as usize));
            patch
                .moves
                .push(StateMove::added(node, a, &self.order.rank));
        }
        if !diff.added_nodes.is_empty() {
            patch.mark(
                LayoutArray::IncidenceRows,
                before as u32..self.incidence_rows.len() as u32,
                1,
                8,
            );
            let from = self.incidence_rows[before][0];
            patch.mark(
                LayoutArray::Incidence,
                from..self.incidence.len() as u32,
                1,
                4,
            );
        }
        // Rows the diff's springs overfill move first, with room for every spring the diff
        // adds there, before any entry of theirs is edited: each moves once, and its old place
        // becomes a hole that nothing writes, so nothing there needs an upload.
        let mut growth: std::collections::BTreeMap<u32, (usize, usize)> = Default::default();
        for s in &diff.added_springs {
            for end in s.nodes {
                growth.entry(self.order.rank[end as usize]).or_default().0 += 1;
            }
        }
        for nodes in &diff.removed_springs {
            for end in nodes {
                if let Some(g) = growth.get_mut(&self.order.rank[*end as usize]) {
                    g.1 += 1;
                }
            }
        }
        let mut moved: BTreeSet<u32> = BTreeSet::new();
        for (&r, &(adds, removes)) in &growth {
            if self.row(r as usize).len() + adds > self.row_room(r as usize).len() + removes {
                self.move_row(r, adds as u32);
                moved.insert(r);
            }
        }
        let mut records: BTreeSet<u32> = BTreeSet::new();
        let mut rows: BTreeSet<u32> = BTreeSet::new();
        for &[a, b] in &diff.removed_springs {
            let (ra, rb) = (self.order.rank[a as usize], self.order.rank[b as usize]);
            let s = self.find(ra, rb).ok_or_else(|| no_spring(a, b))?;
            self.unlink(ra, s);
            self.unlink(rb, s);
            self.springs[s as usize] = EdgeSpring {
                a: ra,
                b: ra,
                ..Zeroable::zeroed()
            };
            self.free.insert(s);
            records.insert(s);
            rows.extend([ra, rb]);
        }
        for s in &diff.added_springs {
            let record = self.record(model, s.nodes[0], s.nodes[1])?;
            let idx = match self.free.pop_first() {
                Some(i) => i,
                None => {
                    self.springs.push(record);
                    self.springs.len() as u32 - 1
                }
            };
            self.springs[idx as usize] = record;
            records.insert(idx);
            for (node, flag) in [(record.a, 0), (record.b, B_END)] {
                let linked = self.link(node, idx | flag);
                assert!(
                    linked,
                    "rows the diff overfills were moved with room for it"
                );
                rows.insert(node);
            }
        }
        for s in &diff.changed_springs {
            let [a, b] = s.nodes;
            let (ra, rb) = (self.order.rank[a as usize], self.order.rank[b as usize]);
            let idx = self.find(ra, rb).ok_or_else(|| no_spring(a, b))?;
            self.springs[idx as usize] = self.record(model, a, b)?;
            records.insert(idx);
        }
        for t in diff.touched_nodes(before) {
            let r = self.order.rank[t as usize];
            self.nodes.inv_mass[r as usize] = inv_mass_of(model, t);
            patch.mark(LayoutArray::InvMass, [r], 1, 4);
        }
        patch.mark(LayoutArray::EdgeSprings, records, 1, 32);
        if self.holes * HOLE_FRACTION > self.incidence.len() {
            let (rows, incidence) = sorted_incidence(self.node_count(), &self.springs);
            self.incidence_rows = rows;
            self.incidence = incidence;
            self.holes = 0;
            patch.repacked = true;
            patch.mark_all(
                LayoutArray::IncidenceRows,
                self.incidence_rows.len() as u64 * 8,
            );
            patch.mark_all(LayoutArray::Incidence, self.incidence.len() as u64 * 4);
        } else {
            patch.mark(LayoutArray::IncidenceRows, moved, 1, 8);
            for r in rows {
                let [lo, hi] = self.incidence_rows[r as usize];
                patch.mark(LayoutArray::Incidence, lo..hi, 1, 4);
            }
        }
        patch.rest_fixed(model, diff, &self.order.rank);
        patch.normalize();
        Ok(patch)
    }

    /// The record of the spring between model nodes `a` and `b` in `model`, ends in layout
    /// order `a < b`.
    fn record(&self, model: &PackedModel, a: u32, b: u32) -> Result<EdgeSpring> {
        let s = model.spring_index(a, b).ok_or_else(|| no_spring(a, b))?;
        let s = &model.springs()[s];
        let (ra, rb) = (self.order.rank[a as usize], self.order.rank[b as usize]);
        let (from, lo, hi) = if ra < rb { (a, ra, rb) } else { (b, rb, ra) };
        let slot = super::Slot::of(model, s, from, hi);
        Ok(EdgeSpring {
            edge: slot.edge,
            rest: slot.rest,
            k: slot.k,
            c: slot.c,
            a: lo,
            b: hi,
        })
    }

    /// The record joining layout nodes `ra` and `rb`, found in `ra`'s row.
    fn find(&self, ra: u32, rb: u32) -> Option<u32> {
        self.row(ra as usize)
            .iter()
            .find(|&&e| self.other_end(e) == rb)
            .map(|&e| e & !B_END)
    }

    /// Write node `r`'s row anew at the end of the table with room for `more` entries beyond
    /// its used ones (and at least four free, [`incidence_room`]). Its old place becomes a
    /// hole; its stale entries stay there unread, so they need no upload.
    fn move_row(&mut self, r: u32, more: u32) {
        let old = self.row_room(r as usize);
        let used = self.row(r as usize).len();
        let room = incidence_room(used as u32 + more) as usize;
        let start = self.incidence.len();
        self.incidence
            .extend_from_within(old.start..old.start + used);
        self.incidence
            .extend(std::iter::repeat_n(NO_SPRING, room - used));
        self.incidence_rows[r as usize] = [start as u32, (start + room) as u32];
        self.holes += old.len();
    }

    /// Remove record `s` from node `r`'s row, closing the gap.
    fn unlink(&mut self, r: u32, s: u32) {
        let range = self.row_room(r as usize);
        let row = &mut self.incidence[range];
        if let Some(p) = row.iter().position(|&e| e & !B_END == s && e != NO_SPRING) {
            row.copy_within(p + 1.., p);
            row[row.len() - 1] = NO_SPRING;
        }
    }

    /// Insert entry `e` into node `r`'s row at its place by other end; false if the row is
    /// full.
    fn link(&mut self, r: u32, e: u32) -> bool {
        let used = self.row(r as usize).len();
        let range = self.row_room(r as usize);
        let (lo, hi) = (range.start, range.end);
        if used == hi - lo {
            return false;
        }
        let other = self.other_end(e);
        let at = self
            .row(r as usize)
            .iter()
            .position(|&x| self.other_end(x) > other)
            .unwrap_or(used);
        let row = &mut self.incidence[lo..hi];
        row.copy_within(at..used, at + 1);
        row[at] = e;
        true
    }
}

/// The error for a spring the layout does not have.
fn no_spring(a: u32, b: u32) -> Error {
    Error::DiffMismatch(format!(
        "there is no spring {a}-{b} in the layout or the model; the diff does not match the \
         model it was applied to"
    ))
}

/// The incidence table of a spring pool (dead records skipped), rows contiguous in node order,
/// each sorted by the other end and with at least four free entries ([`incidence_room`]),
/// [`NO_SPRING`] after the entries.
fn sorted_incidence(n: usize, springs: &[EdgeSpring]) -> (Vec<[u32; 2]>, Vec<u32>) {
    let mut lists: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n];
    for (idx, s) in springs.iter().enumerate() {
        if s.a == s.b {
            continue;
        }
        lists[s.a as usize].push((s.b, idx as u32));
        lists[s.b as usize].push((s.a, idx as u32 | B_END));
    }
    let mut rows = Vec::with_capacity(n);
    let mut incidence = Vec::new();
    for mut list in lists {
        list.sort_unstable();
        let room = incidence_room(list.len() as u32) as usize;
        let start = incidence.len() as u32;
        incidence.extend(list.iter().map(|&(_, e)| e));
        incidence.extend(std::iter::repeat_n(NO_SPRING, room - list.len()));
        rows.push([start, incidence.len() as u32]);
    }
    (rows, incidence)
}

/// The node-to-spring incidence table of `springs` over `n` nodes: rows (`[start, end)`,
/// contiguous in node order, no room) and entries (spring index, [`B_END`] where the node is
/// the `b` end), each row in spring order.
fn incidence_table(n: usize, springs: &[EdgeSpring]) -> (Vec<[u32; 2]>, Vec<u32>) {
    let mut rows = vec![0u32; n + 1];
    for s in springs {
        rows[s.a as usize + 1] += 1;
        rows[s.b as usize + 1] += 1;
    }
    for i in 0..n {
        rows[i + 1] += rows[i];
    }
    let mut fill = rows.clone();
    let mut incidence = vec![0u32; rows[n] as usize];
    for (idx, s) in springs.iter().enumerate() {
        for (node, flag) in [(s.a, 0), (s.b, B_END)] {
            incidence[fill[node as usize] as usize] = idx as u32 | flag;
            fill[node as usize] += 1;
        }
    }
    let rows = rows.windows(2).map(|w| [w[0], w[1]]).collect();
    (rows, incidence)
}
