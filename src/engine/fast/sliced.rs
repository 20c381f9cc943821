//! The fast engine's one spring layout: slices of [`LANES`] consecutive nodes, each slice's
//! rows padded to its longest and stored column by column (a "sliced ELLPACK" layout), so that
//! one SIMD lane evaluates one node's springs and the lanes of a group are eight nodes' k-th
//! springs. A node's forces then sum in its own lane, in row order, with no horizontal
//! reduction, and the square roots and divisions of eight springs are one instruction each.
//! Everything else that reads a node's springs (the patch path, backward Euler's assembly, the
//! finite elements' rows) reads its row out of its lane ([`Sliced::row`]); no row-wise copy
//! of the springs is kept.
//!
//! Per spring end a group stores 16 bytes: the neighbour (u32, stored as twice its index: see
//! [`Group::at`]) and the rest edge vector (f32).
//! Where the springs' materials are one ([`Uniform`]: one stiffness, one damping coefficient,
//! and every rest length the length of its rest edge, as in the peer benchmark and any scene
//! of one spring material at rest), that is all: the stiffness and damping are two constants
//! of the step and the rest length is recomputed from the edge vector (`|e|^2 / |d|^2` under
//! the square root the force takes anyway), 16 bytes an end where storing them takes 28.
//! Otherwise parallel arrays keep each end's rest length and stiffness ([`Material`], 8 bytes)
//! and, when any spring is damped, its damping (4 bytes). Each node keeps its row length
//! (4 bytes) so that a row is read without its padding. Padding lanes point at their own node
//! with zero edge and zero stiffness, so they contribute exactly nothing (a zero-length spring
//! has no direction: see [`group_force`]).
//!
//! Which of the two a layout is is fixed when it is built; a patch whose springs leave the
//! uniform material (a subdividing cut whose new springs take another stiffness) is refused
//! ([`Sliced::fits`]) and the engine rebuilt with per-end constants.
//!
//! A patch rewrites the slices of the rows it edits: in place when the slice does not widen,
//! appended otherwise, leaving a hole; holes are compacted in place (slices slid down over
//! them, nothing allocated) when they reach a quarter of the groups or before an appended
//! slice would outgrow the room kept.

use super::pages::{self, PageVec};
use super::{Entry, P};

/// Nodes per slice: one AVX2 vector of f32.
pub(super) const LANES: usize = 8;

/// The k-th spring of the eight nodes of a slice: what every layout stores.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(32))]
pub(super) struct Group {
    /// The other end of each lane's spring (the lane's own node for padding) as twice its
    /// internal index: the place of its row, in 8-byte units, in a node array of 16-byte rows
    /// ([`P`]). The step's gather then addresses a row as `base + at * 8`, which x86 encodes in
    /// the load itself, instead of shifting each index first: 12% of an undamped step and 6%
    /// of a damped one on the 18k peer box, 11% undamped at 100k (measurements.md, thirteenth
    /// slice). Written only by [`Group::set_node`], so every entry is even; read it with
    /// [`Group::node`], or [`Group::at`] for the gather.
    at: [u32; LANES],
    /// Rest vector from the lane's node to the other end, per axis, m.
    pub edge: [[f32; LANES]; 3],
}

/// Nodes a layout can index: [`Group::at`] holds twice an index in a `u32`.
pub(super) const MAX_NODES: usize = 1 << 31;

/// Why the fast engine cannot lay out `model`'s nodes, if it cannot: its spring layout indexes
/// fewer than [`MAX_NODES`] (2^31, far past any memory that holds their state). The caller
/// makes it an [`Error::Unsupported`](crate::Error::Unsupported), with its own context.
pub(crate) fn check_size(model: &crate::model::PackedModel) -> Result<(), String> {
    check_nodes(model.node_count())
}

/// [`check_size`] of a model of `n` nodes.
fn check_nodes(n: usize) -> Result<(), String> {
    if n < MAX_NODES {
        return Ok(());
    }
    Err(format!(
        "the fast CPU engine indexes fewer than {MAX_NODES} nodes and the model has {n}: split \
         the mesh, or run the float64 reference engine (`--engine reference`, \
         `EngineKind::Reference`)"
    ))
}

impl Group {
    /// Lane `l`'s other end, internal index.
    #[inline(always)]
    pub fn node(&self, l: usize) -> usize {
        (self.at[l] / 2) as usize
    }

    /// Every lane's other end as twice its internal index (each even, below `2 * nodes`),
    /// the form the AVX2 gather takes (`gather.rs`, `rows_at`).
    #[inline(always)]
    pub fn at(&self) -> &[u32; LANES] {
        &self.at
    }

    /// Make node `j` lane `l`'s other end. Models past [`MAX_NODES`] never reach a layout
    /// ([`check_size`] refuses them first); a wrapped index would read the wrong rows, so
    /// this is checked in every build, once per spring end when a layout is written.
    #[inline(always)]
    fn set_node(&mut self, l: usize, j: u32) {
        assert!(
            (j as usize) < MAX_NODES,
            "node {j} past the fast layout's reach"
        );
        self.at[l] = 2 * j;
    }
}

/// The constants of a group's springs where they are stored per end (not [`Uniform`]).
#[derive(Debug, Clone, Copy)]
#[repr(C, align(32))]
pub(super) struct Material {
    /// Rest length, m.
    pub rest: [f32; LANES],
    /// Stiffness, N/m (0 for padding).
    pub k: [f32; LANES],
}

/// One stiffness and one damping coefficient for every spring, each rest length the length of
/// its rest edge: the constants a uniform layout keeps once instead of per end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Uniform {
    /// Stiffness, N/m.
    pub k: f32,
    /// Damping along the spring, N s/m.
    pub c: f32,
}

impl Uniform {
    /// The constants shared by every spring end in `ends`, if they are shared (and every rest
    /// length is its edge's length to float32 rounding); `None` for a layout with no springs,
    /// which has nothing to share.
    fn of<'a>(mut ends: impl Iterator<Item = &'a (Entry, f32)>) -> Option<Uniform> {
        let (first, c) = ends.next()?;
        let u = Uniform { k: first.k, c: *c };
        (u.fits(first, *c) && ends.all(|(e, c)| u.fits(e, *c))).then_some(u)
    }

    /// Whether the spring end `e` with damping `c` has these constants and a rest length its
    /// edge's, within a few float32 roundings (the edge is rounded from float64 once per axis,
    /// the rest length once: a spring built at rest differs by an ulp or two; a prestressed
    /// one by its strain, 1e-6 of it or far more).
    pub fn fits(&self, e: &Entry, c: f32) -> bool {
        let len = e
            .edge
            .iter()
            .map(|&a| (a as f64) * (a as f64))
            .sum::<f64>()
            .sqrt();
        e.k.to_bits() == self.k.to_bits()
            && c.to_bits() == self.c.to_bits()
            && (len - e.rest as f64).abs() <= 4.0 * f32::EPSILON as f64 * len
    }
}

/// The rest length of a uniform layout's spring: its edge's length, in float32 (as a row is
/// read out; the step takes it under the square root of its force, [`group_force`]).
#[inline(always)]
pub(super) fn rest_of(edge: [f32; 3]) -> f32 {
    (edge[0] * edge[0] + edge[1] * edge[1] + edge[2] * edge[2]).sqrt()
}

const BLANK: Group = Group {
    at: [0; LANES],
    edge: [[0.0; LANES]; 3],
};

const NO_MATERIAL: Material = Material {
    rest: [0.0; LANES],
    k: [0.0; LANES],
};

/// One node's row: its springs as seen from it, each with its damping, sorted by the other
/// end.
pub(super) type Row = Vec<(Entry, f32)>;

/// Every node's springs, in slices.
pub(super) struct Sliced {
    /// Each slice's groups, as (start, end): `groups[start..end]`.
    pub slices: Vec<[u32; 2]>,
    pub groups: PageVec<Group>,
    /// Rest length and stiffness of each lane's spring (empty when [`Sliced::uniform`]).
    pub material: PageVec<Material>,
    /// Damping of each lane's spring, N s/m (empty when no spring is damped or when
    /// [`Sliced::uniform`]).
    pub damping: PageVec<[f32; LANES]>,
    /// The springs' one material, when they have one: the step reads it instead of
    /// `material` and `damping` (fixed for the layout's life, as `damped` is).
    pub uniform: Option<Uniform>,
    /// Each node's row length (the lanes of its slice past it are padding).
    lens: Vec<u32>,
    /// Spring ends in all rows: twice the springs.
    pub live: usize,
    /// At least the largest `|i - j|` of a spring between nodes `i` and `j` (the bandwidth):
    /// exact when built, raised by a patch's new rows and never lowered by one, so that it
    /// bounds which nodes a node's step reads (`fused.rs` relies on that).
    pub reach: usize,
    /// Each slice's smallest and largest node its step reads (its own nodes and their
    /// neighbours): exact, rewritten with the slice by a patch.
    pub bounds: Vec<[u32; 2]>,
    /// Groups no slice uses.
    pub holes: usize,
    /// Compactions run since the layout was built.
    pub compactions: usize,
    /// Whether any spring is damped (fixed for the layout's life: the first damped spring of
    /// an undamped model rebuilds the engine).
    pub damped: bool,
}

impl Sliced {
    /// The layout of the rows `rows` (node `i`'s row `rows[i]`), with room for cuts.
    pub fn build(rows: &[Row], damped: bool) -> Self {
        use crate::model::room::spare;
        let n = rows.len();
        let count = n.div_ceil(LANES);
        let width = |b: usize| {
            rows[b * LANES..((b + 1) * LANES).min(n)]
                .iter()
                .map(Vec::len)
                .max()
                .unwrap_or(0)
        };
        let total: usize = (0..count).map(width).sum();
        let uniform = Uniform::of(rows.iter().flatten());
        let room = |kept: bool| if kept { total + spare(total) } else { 0 };
        let mut s = Sliced {
            slices: Vec::with_capacity(count + spare(count)),
            groups: pages::with_capacity(total + spare(total)),
            material: pages::with_capacity(room(uniform.is_none())),
            damping: pages::with_capacity(room(damped && uniform.is_none())),
            uniform,
            lens: Vec::with_capacity(n + spare(n)),
            live: 0,
            reach: 0,
            bounds: Vec::with_capacity(count + spare(count)),
            holes: 0,
            compactions: 0,
            damped,
        };
        for b in 0..count {
            let lanes = &rows[b * LANES..((b + 1) * LANES).min(n)];
            let at = s.groups.len();
            let w = width(b);
            s.append(w);
            s.write(b, at, w, lanes, [true; LANES]);
            s.slices.push([at as u32, (at + w) as u32]);
            s.bounds.push(slice_bounds(b, lanes));
        }
        s.lens = rows.iter().map(|r| row_len(r.len())).collect();
        s.live = rows.iter().map(Vec::len).sum();
        s.reach = rows
            .iter()
            .enumerate()
            .map(|(i, r)| row_reach(i, r))
            .max()
            .unwrap_or(0);
        s
    }

    /// Whether the layout keeps each end's damping (`damping`).
    fn damping_kept(&self) -> bool {
        self.damped && self.uniform.is_none()
    }

    /// Whether every spring end of `rows` fits the layout: any does where constants are kept
    /// per end; in a uniform layout, those of its material only.
    pub fn fits<'a>(&self, mut ends: impl Iterator<Item = &'a (Entry, f32)>) -> bool {
        self.uniform
            .is_none_or(|u| ends.all(|(e, c)| u.fits(e, *c)))
    }

    /// Nodes laid out.
    pub fn nodes(&self) -> usize {
        self.lens.len()
    }

    /// Node `i`'s row length.
    #[inline(always)]
    pub fn len(&self, i: usize) -> usize {
        self.lens[i] as usize
    }

    /// Node `i`'s row, read out of its lane, in row order.
    #[inline(always)]
    pub fn row(&self, i: usize) -> impl Iterator<Item = (Entry, f32)> + '_ {
        let (b, l) = (i / LANES, i % LANES);
        let start = self.slices.get(b).map_or(0, |s| s[0] as usize);
        let len = self.lens.get(i).map_or(0, |&n| n as usize);
        (start..start + len).map(move |k| {
            let g = &self.groups[k];
            let edge = [g.edge[0][l], g.edge[1][l], g.edge[2][l]];
            let (rest, stiffness, c) = match self.uniform {
                Some(u) => (rest_of(edge), u.k, u.c),
                None => {
                    let m = &self.material[k];
                    let c = if self.damped { self.damping[k][l] } else { 0.0 };
                    (m.rest[l], m.k[l], c)
                }
            };
            let e = Entry {
                other: g.node(l) as u32,
                edge,
                rest,
                k: stiffness,
            };
            (e, c)
        })
    }

    /// Set the rows of the nodes in `rows` (internal index to its new row) and lay out `n`
    /// nodes (new nodes, past the old count, start with empty rows): the slices of edited
    /// rows and of new nodes are rewritten, in place (only the changed lanes) when they do not
    /// widen. Returns the lanes written with new rows and the lanes copied (a widened slice's
    /// unchanged lanes moved with it, and the slices compaction slid), a group holding
    /// [`LANES`], and whether compaction ran (rewriting every slice's bounds). Every new row
    /// must [`Sliced::fits`] the layout.
    pub fn patch(
        &mut self,
        n: usize,
        mut rows: std::collections::BTreeMap<usize, Row>,
    ) -> (usize, usize, bool) {
        debug_assert!(
            self.fits(rows.values().flatten()),
            "a row off the uniform material"
        );
        let count = n.div_ceil(LANES);
        let old_n = self.lens.len();
        let mut dirty: Vec<usize> = rows.keys().map(|i| i / LANES).collect();
        for (&i, r) in &rows {
            self.reach = self.reach.max(row_reach(i, r));
        }
        // Slices new nodes made or filled.
        dirty.extend(self.lens.len() / LANES..count);
        dirty.sort_unstable();
        dirty.dedup();
        self.lens.resize(n, 0);
        let (mut written, mut copied, mut compacted) = (0, 0, false);
        for b in dirty {
            // The slice's rows, new or as they are, read out before it is rewritten, and
            // which lanes changed (an edited row or a new node).
            let mut changed = [false; LANES];
            let lanes: Vec<Row> = (b * LANES..((b + 1) * LANES).min(n))
                .map(|i| {
                    let new = rows.remove(&i);
                    changed[i % LANES] = new.is_some() || i >= old_n;
                    new.unwrap_or_else(|| self.row(i).collect())
                })
                .collect();
            for (l, r) in lanes.iter().enumerate() {
                let i = b * LANES + l;
                self.live = self.live + r.len() - self.len(i);
                self.lens[i] = row_len(r.len());
            }
            let w = lanes.iter().map(Vec::len).max().unwrap_or(0);
            // In place, only the changed lanes are written (the others' rows, no longer than
            // `w`, stay as they are); appended, every lane.
            let (at, mask) = match self.slices.get(b) {
                Some(&[start, end]) if (end - start) as usize >= w => {
                    self.holes += (end - start) as usize - w;
                    (start as usize, changed)
                }
                old => {
                    if let Some(&[start, end]) = old {
                        self.holes += (end - start) as usize;
                        // Its old place is a hole too, should compaction run now.
                        self.slices[b] = [start, start];
                    }
                    let full = self.groups.len() + w > self.groups.capacity();
                    // Compact only where that makes real room: else grow.
                    if full && self.holes >= w.max(self.groups.len() / 16) {
                        copied += self.compact() * LANES;
                        compacted = true;
                    }
                    let at = self.groups.len();
                    self.append(w);
                    (at, [true; LANES])
                }
            };
            self.write(b, at, w, &lanes, mask);
            let range = [at as u32, (at + w) as u32];
            if b < self.slices.len() {
                self.slices[b] = range;
                self.bounds[b] = slice_bounds(b, &lanes);
            } else {
                self.slices.push(range);
                self.bounds.push(slice_bounds(b, &lanes));
            }
            // A widened slice's unchanged lanes are copied to its new place, as compaction
            // copies whole slices: moved, not new data.
            let fresh = lanes.iter().zip(changed).filter(|(_, c)| *c).count();
            written += w * fresh;
            copied += w * (mask.iter().filter(|&&m| m).count() - fresh);
        }
        if self.holes * 4 > self.groups.len() {
            copied += self.compact() * LANES;
            compacted = true;
        }
        (written, copied, compacted)
    }

    /// Slide every slice down over the holes, in the order the slices lie in (each moves to a
    /// place at or before its own, so nothing is overwritten before it is moved); nothing is
    /// allocated but the list of slice starts. The number of groups moved.
    pub fn compact(&mut self) -> usize {
        if self.holes == 0 {
            return 0;
        }
        let mut by_start: Vec<(u32, u32)> = self
            .slices
            .iter()
            .enumerate()
            .map(|(b, s)| (s[0], b as u32))
            .collect();
        by_start.sort_unstable();
        let (mut to, mut moved) = (0usize, 0);
        for (_, b) in by_start {
            let [start, end] = self.slices[b as usize];
            let (start, len) = (start as usize, (end - start) as usize);
            if start != to {
                self.groups.copy_within(start..start + len, to);
                if self.uniform.is_none() {
                    self.material.copy_within(start..start + len, to);
                }
                if self.damping_kept() {
                    self.damping.copy_within(start..start + len, to);
                }
                moved += len;
            }
            self.slices[b as usize] = [to as u32, (to + len) as u32];
            to += len;
        }
        self.groups.truncate(to);
        self.material
            .truncate(if self.uniform.is_none() { to } else { 0 });
        self.damping
            .truncate(if self.damping_kept() { to } else { 0 });
        self.holes = 0;
        self.compactions += 1;
        moved
    }

    /// The first slice whose groups differ from `other`'s, bit for bit (constants missing on
    /// one side read as zeros), or whose count or row lengths differ; slice 0 where one layout
    /// is uniform and the other is not, or their materials differ.
    pub fn first_difference(&self, other: &Sliced) -> Option<usize> {
        if self.uniform != other.uniform {
            return Some(0);
        }
        let bits = |s: &Sliced, b: usize| -> Vec<u32> {
            let [start, end] = s.slices[b];
            let lens = s.lens[b * LANES..((b + 1) * LANES).min(s.lens.len())]
                .iter()
                .copied();
            lens.chain((start as usize..end as usize).flat_map(|k| {
                let g = &s.groups[k];
                let c = s.damping.get(k).copied().unwrap_or([0.0; LANES]);
                let m = s.material.get(k).copied().unwrap_or(NO_MATERIAL);
                let floats = g.edge.iter().chain([&m.rest, &m.k, &c]).flatten();
                g.at.into_iter()
                    .chain(floats.map(|f| f.to_bits()))
                    .collect::<Vec<_>>()
            }))
            .collect()
        };
        let n = self.slices.len().max(other.slices.len());
        (0..n).find(|&b| {
            b >= self.slices.len() || b >= other.slices.len() || bits(self, b) != bits(other, b)
        })
    }

    /// Bytes of groups no slice uses and of padding lanes.
    pub fn padding_bytes(&self) -> u64 {
        let lanes = (self.groups.len() - self.holes) * LANES;
        let per_lane = (self.group_bytes() / LANES) as u64;
        (self.holes * self.group_bytes()) as u64 + lanes.saturating_sub(self.live) as u64 * per_lane
    }

    /// Bytes per group, the per-end constants included where kept.
    pub fn group_bytes(&self) -> usize {
        let kept = |yes: bool, size: usize| if yes { size } else { 0 };
        std::mem::size_of::<Group>()
            + kept(self.uniform.is_none(), std::mem::size_of::<Material>())
            + kept(self.damping_kept(), std::mem::size_of::<[f32; LANES]>())
    }

    /// Bytes of everything but the groups: the slices' places and the nodes they read, and
    /// the row lengths.
    pub fn index_bytes(&self) -> u64 {
        self.slices.len() as u64 * 16 + self.lens.len() as u64 * 4
    }

    /// (capacity, length, bytes per item) of each array, for a patch's growth report.
    pub fn capacities(&self) -> [(usize, usize, usize); 6] {
        use super::pages::Room;
        [
            self.slices.room(),
            self.groups.room(),
            self.material.room(),
            self.damping.room(),
            self.lens.room(),
            self.bounds.room(),
        ]
    }

    fn append(&mut self, w: usize) {
        self.groups.resize(self.groups.len() + w, BLANK);
        if self.uniform.is_none() {
            self.material.resize(self.groups.len(), NO_MATERIAL);
        }
        if self.damping_kept() {
            self.damping.resize(self.groups.len(), [0.0; LANES]);
        }
    }

    /// Write slice `b`'s rows `lanes` (fewer than [`LANES`] in a last, partial slice) into
    /// `w` groups from `at`, padding lanes with null springs; only the lanes `mask` holds.
    fn write(&mut self, b: usize, at: usize, w: usize, lanes: &[Row], mask: [bool; LANES]) {
        let (per_end, damping) = (self.uniform.is_none(), self.damping_kept());
        for k in 0..w {
            let grp = &mut self.groups[at + k];
            let mut m = self.material.get(at + k).copied().unwrap_or(NO_MATERIAL);
            let mut c = self.damping.get(at + k).copied().unwrap_or([0.0; LANES]);
            for (l, cl) in c.iter_mut().enumerate() {
                if !mask[l] {
                    continue;
                }
                // A lane past the last node points at the slice's first node (its result is
                // never stored): the step then reads nothing outside the slice's own nodes for
                // it, which two steps in one sweep rely on (`fused.rs`), and the lane stays
                // as it is when new nodes fill the slice.
                let own = (b * LANES + if l < lanes.len() { l } else { 0 }) as u32;
                match lanes.get(l).and_then(|r| r.get(k)) {
                    Some((e, d)) => {
                        grp.set_node(l, e.other);
                        for a in 0..3 {
                            grp.edge[a][l] = e.edge[a];
                        }
                        m.rest[l] = e.rest;
                        m.k[l] = e.k;
                        *cl = *d;
                    }
                    None => {
                        grp.set_node(l, own);
                        for a in 0..3 {
                            grp.edge[a][l] = 0.0;
                        }
                        m.rest[l] = 0.0;
                        m.k[l] = 0.0;
                        *cl = 0.0;
                    }
                }
            }
            if per_end {
                self.material[at + k] = m;
            }
            if damping {
                self.damping[at + k] = c;
            }
        }
    }
}

/// The largest `|i - j|` of node `i`'s row `row`.
fn row_reach(i: usize, row: &Row) -> usize {
    row.iter()
        .map(|(e, _)| i.abs_diff(e.other as usize))
        .max()
        .unwrap_or(0)
}

/// The smallest and largest node the step of slice `b`, whose rows are `lanes`, reads.
fn slice_bounds(b: usize, lanes: &[Row]) -> [u32; 2] {
    let own = b * LANES;
    let mut out = [own as u32, (own + lanes.len().max(1) - 1) as u32];
    for (e, _) in lanes.iter().flatten() {
        out = [out[0].min(e.other), out[1].max(e.other)];
    }
    out
}

/// A row length as stored (adjacency indices are u32 throughout the engine).
fn row_len(n: usize) -> u32 {
    n as u32
}

/// Eight lanes of three axes.
pub(super) type V3 = [[f32; LANES]; 3];

/// The spring force of one group on its eight nodes, added to `acc`: elastic `k (l - L) / l`
/// times the spring vector `d = e + (u_j - u_i)`, plus, when `DAMPED`, `c ((w_j - w_i) . d) /
/// l^2` times it, `w` scaled by `w_scale`; `k`, `L` and `c` from `m` and `c` per lane, or, when
/// `UNIFORM`, `k` and `c` the lanes' one value (lane 0) and `k (1 - L / l)` taken as
/// `k (1 - sqrt(|e|^2 / l^2))`: the rest length's square root and the spring's division are the
/// same two operations as `1 / sqrt(l^2)`. A zero-length spring (padding, or coincident nodes)
/// has no direction and gives nothing, as in the reference engine.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn group_force<const DAMPED: bool, const UNIFORM: bool>(
    grp: &Group,
    m: &Material,
    c: &[f32; LANES],
    x: &[P],
    w: &[P],
    ui: &V3,
    wi: &V3,
    w_scale: f32,
    acc: &mut V3,
) {
    let mut d = [[0.0f32; LANES]; 3];
    let mut dw = [[0.0f32; LANES]; 3];
    for l in 0..LANES {
        let j = grp.node(l);
        let uj = x[j];
        for a in 0..3 {
            d[a][l] = grp.edge[a][l] + (uj[a] - ui[a][l]);
        }
        if DAMPED {
            let wj = w[j];
            for a in 0..3 {
                dw[a][l] = wj[a] - wi[a][l];
            }
        }
    }
    for l in 0..LANES {
        let l2 = d[0][l] * d[0][l] + d[1][l] * d[1][l] + d[2][l] * d[2][l];
        // The damping's 1 / l^2 as two factors: 1 / l twice (per end), or 1 / l^2 and 1
        // (uniform); zero for a spring of no length.
        let (mut s, f1, f2) = if UNIFORM {
            let e = [grp.edge[0][l], grp.edge[1][l], grp.edge[2][l]];
            let le2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
            let inv2 = if l2 > 0.0 { 1.0 / l2 } else { 0.0 };
            (m.k[0] * (1.0 - (le2 * inv2).sqrt()), inv2, 1.0)
        } else {
            let inv_raw = 1.0 / l2.sqrt();
            let inv = if l2 > 0.0 { inv_raw } else { 0.0 };
            (m.k[l] * (1.0 - m.rest[l] * inv), inv, inv)
        };
        if DAMPED {
            let along = dw[0][l] * d[0][l] + dw[1][l] * d[1][l] + dw[2][l] * d[2][l];
            let cl = if UNIFORM { c[0] } else { c[l] };
            s += cl * along * w_scale * f1 * f2;
        }
        for a in 0..3 {
            acc[a][l] += s * d[a][l];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_group_keeps_each_lanes_node_as_twice_its_index() {
        let mut g = BLANK;
        let nodes = [0, 1, 7, 1 << 20, 123_456_789, (MAX_NODES - 1) as u32, 5, 2];
        for (l, &j) in nodes.iter().enumerate() {
            g.set_node(l, j);
        }
        for (l, &j) in nodes.iter().enumerate() {
            assert_eq!(g.node(l), j as usize, "lane {l}");
            assert_eq!(
                g.at[l] as u64,
                2 * j as u64,
                "lane {l}: the gather's address"
            );
        }
    }

    #[test]
    fn models_past_the_layouts_reach_are_refused_with_the_count() {
        assert!(check_nodes(MAX_NODES - 1).is_ok());
        let e = check_nodes(MAX_NODES).unwrap_err();
        assert!(e.contains(&MAX_NODES.to_string()), "{e}");
        assert!(
            e.contains("reference engine"),
            "says what to do instead: {e}"
        );
    }
}
