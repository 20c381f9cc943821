//! Incisions: a blade sweeps through the tissue, the tetrahedral mesh is cut, and the change
//! goes to the engine as a [`ModelDiff`] so that only what changed is uploaded.
//!
//! The pipeline, one stage per file:
//!
//! - `sweep.rs`: the surface a blade sweeps between two poses ([`Sweep`]).
//! - `exact.rs`: exact float64 orientation predicates (Shewchuk's, from the `robust` crate)
//!   with one tie rule, so that a sweep exactly through nodes, edges or faces classifies the
//!   same way every time.
//! - `classify.rs`: the tets the sweep meets and the inside faces it crosses, at the current
//!   (deformed) positions.
//! - `faces.rs`: face adjacency, node-to-tet incidence and the boundary, updated per touched
//!   tet.
//! - `edit.rs`: the topology edits ([`CutMethod`]) on the mesh and the spring model.
//! - `subdivide.rs`, `template.rs`, `resubdivide.rs`, `floor.rs`: splitting tets along the
//!   sweep, each tet by one template of its marked edges whatever order the blade marked them
//!   in, families of sub-tets re-made as marks come, and the quality floor's trial.
//! - `changes.rs`: what the edit changed (noted by the spring model), as a [`ModelDiff`].
//! - `invariants.rs`: the checks a cut mesh must pass (volume, mass, closed fragment
//!   surfaces, quality, agreement with a rebuild).
//!
//! A [`Cutter`] owns the mesh and spring model being cut. Node keys are only ever added, never
//! removed, so the mesh's node storage order stays the packed model's dense order: a node left
//! with no tet (carving) stays as a fixed node without springs.

mod changes;
mod classify;
mod edit;
pub mod exact;
pub mod faces;
mod floor;
pub mod invariants;
pub mod reading;
mod rest_index;
mod resubdivide;
mod resweep;
pub mod subdivide;
pub mod sweep;
mod template;
mod tet_table;

use std::collections::BTreeSet;
use std::time::Instant;

use rustc_hash::FxHashSet;

use crate::model::room::with_room;

use nalgebra::Point3;
use serde::{Deserialize, Serialize};
use slotmap::SecondaryMap;

use crate::collide::broad::SurfaceEdit;
use crate::error::{Error, Result};
use crate::mesh::{NodeKey, TetKey, TetMesh, TET_FACES};
use crate::model::{ModelDiff, SpringModel};

pub use faces::FaceIndex;
pub use reading::{AllPositions, PositionSource, ReadPositions};
pub use sweep::Sweep;

/// Nodes closer to their rest position than this fraction of the mesh's rest diagonal are
/// classified at rest. Float32 engines drift by rounding even with no load (about 1e-7 of the
/// size over a few hundred steps); without this a sweep drawn exactly through rest nodes, whose
/// tie the exact predicates break one way, would meet them a hair off on either side.
pub const SNAP_RELATIVE: f64 = 1e-5;

/// How a cut edits the mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
pub enum CutMethod {
    /// Delete the tets the blade passes (carving). Removes material.
    Remove,
    /// Open the inside faces the blade passes between two tets, duplicating their nodes (one
    /// copy per group of tets still joined across uncut faces). No new elements, no material
    /// lost; the cut follows the existing faces.
    #[default]
    Separate,
    /// Split the tets the blade crosses along its sweep, with new nodes on the crossed edges
    /// (snapped to a node when the crossing is near it, and, with a quality floor
    /// ([`Cutter::with_quality_floor`]), wherever a split would make a tet below the floor),
    /// then open the faces on the sweep. The cut follows the blade, at the price of new nodes
    /// and tets.
    Subdivide,
}

impl std::fmt::Display for CutMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            CutMethod::Remove => "remove",
            CutMethod::Separate => "separate",
            CutMethod::Subdivide => "subdivide",
        })
    }
}

/// What one cut did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CutOutcome {
    /// The change to the packed model (empty when the sweep cut nothing new).
    pub diff: ModelDiff,
    /// The change to the boundary surface, for [`crate::Simulation::edit_surface`].
    pub surface: SurfaceEdit,
    /// Tets removed or given new corners.
    pub tets_touched: usize,
    /// Tets removed (carving).
    pub tets_removed: usize,
    /// Rest volume removed, m^3.
    pub volume_removed: f64,
    /// Inside faces newly cut (separating), opened or still on the crack front.
    pub faces_cut: usize,
    /// Nodes created (copies).
    pub nodes_added: usize,
    /// Nodes left without any tet (fixed from now on).
    pub nodes_retired: usize,
    /// Springs removed, added or changed.
    pub springs_touched: usize,
    /// Seconds spent reading current positions near the blade (included in `classify_s`).
    pub read_s: f64,
    /// Nodes whose current positions the cut read.
    pub nodes_read: usize,
    /// Seconds spent finding what the sweep cuts.
    pub classify_s: f64,
    /// Seconds spent editing the mesh and model and building the diff.
    pub edit_s: f64,
    /// The tets this cut removed, gave new corners or made, sorted: what a render surface
    /// embedded in the mesh rebinds ([`crate::surface::Rebinder::rebind`]).
    pub tets_changed: Vec<TetKey>,
}

impl CutOutcome {
    /// Whether the sweep changed nothing.
    pub fn is_empty(&self) -> bool {
        self.diff.is_empty() && self.surface.is_empty()
    }
}

/// The mesh and spring model being cut, with the adjacency the cuts need.
#[derive(Debug, Clone)]
pub struct Cutter {
    mesh: TetMesh,
    model: SpringModel,
    faces: FaceIndex,
    dense: SecondaryMap<NodeKey, u32>,
    /// The key of each dense index (the inverse of `dense`).
    keys: Vec<NodeKey>,
    /// The rest position of each dense index (the mesh's, which never changes once a node is
    /// made): a cut settles each node it read against it, in ascending order, instead of
    /// looking each up in the mesh's node map.
    rest: Vec<Point3<f64>>,
    /// The dense indices by rest position: where a cut looks for nodes pulled out of the box
    /// it read ([`Cutter::pulled_out`]).
    rest_index: rest_index::RestIndex,
    method: CutMethod,
    /// Face-neighbour pairs a sweep has crossed whose face is still shared: the crack front of
    /// a partial cut. They stay cut when the blade moves on.
    crack: BTreeSet<(TetKey, TetKey)>,
    /// Tets separated by a cut along faces, per tet: a later sweep along that cut makes nothing
    /// new where the load carried a lip across the blade's plane (see `resweep.rs`).
    partners: resweep::CutPartners,
    volume_removed: f64,
    /// Total node mass when the cutter was made, kg, and the mass carving has removed since:
    /// every other cut conserves mass, whatever the mass model (the mass invariant).
    mass_before: f64,
    mass_removed: f64,
    /// Nodes displaced less than this from rest are classified at rest (m).
    snap: f64,
    /// The mesh's longest rest edge: with how far apart the displacements near the blade are,
    /// it bounds how far from a sweep the tets it meets reach ([`Cutter::scan_reach`]).
    longest_rest: f64,
    /// How far apart the displacements the last cut read were
    /// ([`ReadPositions::displacement_spread`]); `None` before the first cut. The box the next
    /// cut reads is sized by it ([`Cutter::reading_pad`]).
    spread: Option<f64>,
    /// Nodes on a cut surface (subdividing: made on crossed edges, or snapped), whose faces
    /// may open. Looked up for every edge near the sweep, and it grows with every cut: a hash
    /// set, not an ordered one (a tree walk per edge), nor a secondary map (sized to the
    /// largest node key on a cut, it grew to the whole mesh at the first cut near its last
    /// nodes, a pause on a large mesh).
    on_cut: FxHashSet<NodeKey>,
    /// Each tet's dense corners and the last cut that looked at it (the candidate scan).
    tet_table: tet_table::TetTable,
    epoch: u32,
    /// The positions the last cut read.
    read: ReadPositions,
    /// Smallest rest volume-length ratio a subdividing split may make (0: no floor).
    quality_floor: f64,
    /// Subdivided tets whose sub-tets a later mark on their edges re-makes (`template.rs`).
    families: template::Families,
    /// Rest area of the uncut mesh's boundary, m^2 (the conformity invariant).
    surface_area: f64,
    /// Crossings whose split waits for the blade to finish the tets around them (a split of
    /// part of a tet would fall below the quality floor).
    pending: std::collections::BTreeMap<[NodeKey; 2], subdivide::Crossing>,
    /// Tets removed, re-cornered or made by the cut in progress (`CutOutcome::tets_changed`).
    changed: Vec<TetKey>,
}

impl Cutter {
    /// Prepare to cut `mesh`, whose model is `model` (packed with [`SpringModel::pack`], so
    /// dense indices follow the mesh's node order).
    pub fn new(mesh: TetMesh, model: SpringModel, method: CutMethod) -> Result<Self> {
        let faces = FaceIndex::of(&mesh)?;
        let nodes = mesh.dense_nodes();
        let (dense, keys) = (nodes.index, nodes.keys);
        // Room for the nodes cuts add (see `model::room`).
        let node_count = keys.len();
        let keys = with_room(keys);
        let rest: Vec<Point3<f64>> = with_room(keys.iter().map(|&k| mesh.rest(k)).collect());
        let mut tet_table = tet_table::TetTable::default();
        for (tk, t) in mesh.tets() {
            tet_table.set(tk, t.nodes.map(|k| dense[k]));
        }
        let snap = mesh
            .bounds()
            .map_or(0.0, |(lo, hi)| SNAP_RELATIVE * (hi - lo).norm());
        let longest_rest = model
            .springs()
            .map(|(_, s)| s.rest_length)
            .fold(0.0, f64::max);
        let rest_index = rest_index::RestIndex::of(&rest, longest_rest);
        let surface_area = faces
            .boundary()
            .into_iter()
            .map(|(tk, local)| {
                let t = mesh.tet(tk).expect("boundary faces belong to tets");
                let p = TET_FACES[local as usize].map(|i| mesh.rest(t.nodes[i]));
                0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm()
            })
            .sum();
        Ok(Cutter {
            mass_before: model.total_mass(),
            mass_removed: 0.0,
            surface_area,
            longest_rest,
            spread: None,
            mesh,
            model,
            faces,
            dense,
            keys,
            rest,
            rest_index,
            method,
            crack: BTreeSet::new(),
            partners: resweep::CutPartners::default(),
            volume_removed: 0.0,
            snap,
            on_cut: FxHashSet::default(),
            tet_table,
            epoch: 0,
            read: ReadPositions::for_nodes(node_count),
            quality_floor: subdivide::DEFAULT_QUALITY_FLOOR,
            families: template::Families::default(),
            pending: Default::default(),
            changed: Vec::new(),
        })
    }

    /// Subdivide without making any tet whose rest volume-length ratio is below `floor`: a
    /// crossing whose split would make one snaps to the nearer end of its edge instead, a node
    /// closer to the sweep's plane than [`subdivide::NODE_SNAP`] of its shortest edge joins the
    /// cut, and a crossing whose split would make one only because the blade has not finished
    /// the tet waits for it (see [`subdivide`]). [`Cutter::new`] starts at
    /// [`subdivide::DEFAULT_QUALITY_FLOOR`]. A floor of 0, a negative or a NaN one subdivides
    /// without a floor: only the parameter rule ([`subdivide::EDGE_SNAP`]), at the price of
    /// slivers that lower the stable time step. Tets already below the floor are left as they
    /// are; the other methods make no new tets and ignore the floor.
    pub fn with_quality_floor(mut self, floor: f64) -> Self {
        self.quality_floor = floor;
        self
    }

    /// The quality floor subdividing keeps to (0: none).
    pub fn quality_floor(&self) -> f64 {
        self.quality_floor
    }

    /// The mesh as cut so far.
    pub fn mesh(&self) -> &TetMesh {
        &self.mesh
    }

    /// The spring model as cut so far.
    pub fn model(&self) -> &SpringModel {
        &self.model
    }

    /// The face adjacency and boundary.
    pub fn faces(&self) -> &FaceIndex {
        &self.faces
    }

    /// The cut method.
    pub fn method(&self) -> CutMethod {
        self.method
    }

    /// Total rest volume removed by carving so far, m^3.
    pub fn volume_removed(&self) -> f64 {
        self.volume_removed
    }

    /// Total node mass removed by carving so far, kg (what the removed tets gave their nodes).
    pub fn mass_removed(&self) -> f64 {
        self.mass_removed
    }

    /// Face-neighbour pairs cut but not yet opened (the crack front of a partial cut).
    pub fn crack_front(&self) -> usize {
        self.crack.len()
    }

    /// Dense (packed model) index of a node.
    pub fn dense_index(&self, n: NodeKey) -> Option<u32> {
        self.dense.get(n).copied()
    }

    /// The boundary triangles as dense node indices, outward oriented, for
    /// [`crate::Simulation::set_surface`] (once; after that each cut's
    /// [`CutOutcome::surface`] edits it).
    pub fn surface(&self) -> Vec<[u32; 3]> {
        self.faces
            .boundary()
            .into_iter()
            .map(|(tk, local)| {
                let t = &self
                    .mesh
                    .tet(tk)
                    .expect("boundary faces belong to tets")
                    .nodes;
                TET_FACES[local as usize].map(|i| self.dense[t[i]])
            })
            .collect()
    }

    /// Cut with `sweep`, classifying at `positions` (current positions of every node, dense
    /// order, as [`crate::Simulation::positions`] gives them). The mesh and model are edited;
    /// give the returned diff to [`crate::Simulation::apply`] and its surface change to
    /// [`crate::Simulation::edit_surface`].
    pub fn cut(&mut self, sweep: &Sweep, positions: &[[f64; 3]]) -> Result<CutOutcome> {
        if positions.len() != self.mesh.node_count() {
            return Err(Error::LengthMismatch {
                given: positions.len(),
                expected: self.mesh.node_count(),
                message: format!(
                    "{} positions for {} nodes; give the current position of every node",
                    positions.len(),
                    self.mesh.node_count()
                ),
            });
        }
        self.cut_from(sweep, &mut AllPositions(positions))
    }

    /// Cut with `sweep` as [`Cutter::cut`] does, reading from `source` only the positions the
    /// cut looks at: the nodes in a box around the sweep ([`Cutter::reading_box`]), then any
    /// node of a tet around a candidate that the box missed. A
    /// simulation is such a source ([`crate::Simulation::nodes_near`]): on the GPU this reads
    /// back a few hundred nodes instead of all of them. The outcome is the same as
    /// [`Cutter::cut`] with every position; what was read stays in
    /// [`Cutter::positions_read`] for [`crate::Simulation::apply_at`].
    pub fn cut_from(
        &mut self,
        sweep: &Sweep,
        source: &mut dyn PositionSource,
    ) -> Result<CutOutcome> {
        let mut read = std::mem::take(&mut self.read);
        read.begin(self.mesh.node_count());
        // Put back whatever happens, so that the next cut reuses the arrays.
        let result = self.cut_reading(sweep, source, &mut read);
        self.read = read;
        if result.is_err() {
            // An edit that failed partway leaves the model recording: stop it.
            self.model.take_changes();
        }
        result
    }

    /// The box of current positions a cut with `sweep` asks its source for
    /// ([`Cutter::cut_from`]): the sweep's bounds grown by two to three of the mesh's longest
    /// rest edges, as strained as the tissue the last cut read was (three before the first
    /// cut; `Cutter::reading_pad`). `None` for an empty sweep.
    pub fn reading_box(&self, sweep: &Sweep) -> Option<([f64; 3], [f64; 3])> {
        self.reading_box_ahead(sweep, 0.0)
    }

    /// A box holding [`Cutter::reading_box`] of every sweep that strays no further than
    /// `margin` (m) from `predicted`: what a simulator that extrapolates its blade's motion (a
    /// haptic device reports a velocity) gives [`crate::Simulation::prefetch_near`] before the
    /// steps that come before the cut, so that on the GPU the cut's read comes back with them.
    /// A cut whose sweep strays further reads with a round trip of its own, as without the
    /// prediction. `None` for an empty sweep.
    pub fn reading_box_ahead(
        &self,
        predicted: &Sweep,
        margin: f64,
    ) -> Option<([f64; 3], [f64; 3])> {
        let b = predicted.aabb()?;
        let pad = self.reading_pad() + margin.max(0.0);
        Some((
            [0, 1, 2].map(|c| b.min[c] - pad),
            [0, 1, 2].map(|c| b.max[c] + pad),
        ))
    }

    /// Dense indices of the corners of tet `tk`.
    fn dense_corners(&self, tk: TetKey) -> [u32; 4] {
        let c = self.tet_table.corners(tk);
        debug_assert_eq!(
            c,
            self.mesh
                .tet(tk)
                .expect("a tet near the sweep")
                .nodes
                .map(|k| self.dense[k]),
            "the tet table is behind the mesh"
        );
        c
    }

    /// Forget removed tet `tk` in the tet table, and note it as changed.
    fn forget_tet(&mut self, tk: TetKey) {
        self.tet_table.forget(tk);
        self.changed.push(tk);
    }

    /// Bring tet `tk`'s entry in the tet table up to date (added, or given new corners).
    fn note_tet(&mut self, tk: TetKey) {
        let t = self.mesh.tet(tk).expect("a tet just made or changed");
        let c = t.nodes.map(|k| self.dense[k]);
        self.tet_table.set(tk, c);
        self.changed.push(tk);
    }

    /// Dense indices of the corners of `tets` (repeats included).
    fn corners_of<'a>(&'a self, tets: &'a [TetKey]) -> impl Iterator<Item = u32> + 'a {
        tets.iter().flat_map(|&t| self.dense_corners(t))
    }

    /// Dense indices of the corners of every tet at a corner of `tets`, of the tets a cut
    /// separated from those, and of the parents of those subdivided and their sub-tets (repeats
    /// included; each family once).
    fn ring_of<'a>(&'a self, tets: &'a [TetKey]) -> impl Iterator<Item = u32> + 'a {
        let mut corners: Vec<NodeKey> = tets
            .iter()
            .flat_map(|&t| self.mesh.tet(t).expect("a candidate tet").nodes)
            .collect();
        corners.sort_unstable();
        corners.dedup();
        // A subdivision's trial looks at the corners of the tet a sub-tet came from, and
        // re-making it opens faces among all of its sub-tets.
        let mut families: Vec<_> = corners
            .iter()
            .flat_map(|&n| self.faces.tets_at(n))
            .filter_map(|&t| self.families.of(t).map(|(f, _)| f))
            .collect();
        families.sort_unstable();
        families.dedup();
        // Corners from the tet table (the scan has just read these entries), not the mesh's
        // tets and the dense map: about seven thousand tets are looked at.
        let around = corners.into_iter().flat_map(move |n| {
            self.faces.tets_at(n).iter().flat_map(move |&t| {
                std::iter::once(t)
                    .chain(self.partners.of(t).iter().map(|p| p.0))
                    .filter_map(|t| self.tet_table.get(t))
                    .flatten()
            })
        });
        let subdivided = families.into_iter().flat_map(move |f| {
            let family = self.families.get(f);
            family
                .corners
                .into_iter()
                .chain(
                    family
                        .children
                        .iter()
                        .flat_map(|&c| self.mesh.tet(c).expect("a sub-tet").nodes),
                )
                .map(|k| self.dense[k])
        });
        around.chain(subdivided)
    }

    /// Add a node at `rest` to the mesh, with the next dense index.
    fn add_node(&mut self, rest: Point3<f64>) -> NodeKey {
        let k = self.mesh.add_node(rest);
        self.dense.insert(k, self.keys.len() as u32);
        self.rest_index.insert(self.keys.len() as u32, rest);
        self.keys.push(k);
        self.rest.push(rest);
        k
    }

    /// Work out where the cut classifies the nodes `read` has read since the last call: at
    /// rest within the snap distance of it, else where they are.
    fn settle(&self, read: &mut ReadPositions) {
        let rest = &self.rest;
        read.settle(|i| rest[i as usize], self.snap * self.snap);
    }

    /// How far from the sweep's bounds (at current positions) the corners of a tet it may meet
    /// lie, given the nodes `read` in the box: a tet is at most its longest rest edge across
    /// plus how far apart its corners' displacements are (bounded by
    /// [`ReadPositions::displacement_spread`] where they were all read), its bounds may meet
    /// the sweep's a snap distance off, and a corner's current position lies within a snap
    /// distance of where it is classified. In tissue near rest this is about half the fixed
    /// reach it replaces (twice the longest rest edge), and the scan visits a fifth of the
    /// tets; stretched tissue widens it, up to the box read.
    ///
    /// The bound holds for tets whose corners were all read. A tet with a corner the box
    /// missed is longer: the cut finds those whose missing corner was pulled out of the box,
    /// its rest position lying well inside ([`Cutter::pulled_out`]: a node pulled out of quiet
    /// tissue, whose tets stretch across the box). What no cut that reads near its blade finds
    /// is a tet with no corner in the box nor pulled out of it, or one that reaches into it
    /// only from its edge: stretched across more than the box.
    fn scan_reach(&self, read: &ReadPositions) -> f64 {
        (self.longest_rest + read.displacement_spread() + 2.0 * self.snap).min(self.reading_pad())
    }

    /// The nodes pulled out of the box read for `sweep`: not read, though their rest positions
    /// lie far enough inside the box that, displaced as any node read was (within the bounds of
    /// the displacements read, per axis, and two snap distances), they would lie in it. Their
    /// tets may stretch across the sweep from outside the box, with no corner within the
    /// scan's reach ([`Cutter::scan_reach`]). In tissue moved as a whole there are none. A
    /// node read with a displacement far from the others' (one dragged into the box) narrows
    /// the region looked at, possibly to nothing: the query then finds less, never more.
    fn pulled_out(&self, sweep: &Sweep, read: &ReadPositions) -> Vec<u32> {
        let (Some((lo, hi)), Some((moved_lo, moved_hi))) =
            (self.reading_box(sweep), read.displacement_bounds())
        else {
            return Vec::new();
        };
        let margin = 2.0 * self.snap;
        let lo = [0, 1, 2].map(|c| lo[c] - moved_lo[c] + margin);
        let hi = [0, 1, 2].map(|c| hi[c] - moved_hi[c] - margin);
        // Nearly always every node there was read: counted, not looked up one by one.
        let rest = &self.rest;
        let read_there = read
            .all()
            .iter()
            .filter(|&&i| reading::inside(&rest[i as usize].into(), &lo, &hi))
            .count();
        if read_there == self.rest_index.count_within(lo, hi) {
            return Vec::new();
        }
        self.rest_index.within(lo, hi, |i| !read.knows(i))
    }

    /// How far the box a cut reads reaches past its sweep's bounds. The candidates' corners
    /// lie within [`Cutter::scan_reach`] of the sweep, and the tets around them (which a cut
    /// also reads: face neighbours, a subdivision's trial splits) within as much again: twice
    /// the longest rest edge and the displacements' spread, taken from the last cut with half
    /// as much again for room, but no more than half the longest rest edge (before the first
    /// cut, that half): between two and three rest edges in all. The spread over a box grows
    /// with the box in stretched tissue, so a box sized by it alone would grow from cut to
    /// cut. What the box misses where the tissue stretched more is fetched by the cut, with a
    /// round trip of its own on the GPU.
    fn reading_pad(&self) -> f64 {
        let half = 0.5 * self.longest_rest;
        let spread = self.spread.map_or(half, |d| (1.5 * d).min(half));
        2.0 * (self.longest_rest + spread) + 2.0 * self.snap
    }

    /// The positions the last cut read: valid at the nodes it read, stale elsewhere.
    pub fn positions_read(&self) -> &ReadPositions {
        &self.read
    }

    fn cut_reading(
        &mut self,
        sweep: &Sweep,
        source: &mut dyn PositionSource,
        read: &mut ReadPositions,
    ) -> Result<CutOutcome> {
        let start = Instant::now();
        // What a failed cut noted is not this one's.
        self.changed.clear();
        if let Some((lo, hi)) = self.reading_box(sweep) {
            read.take_near(source.near(lo, hi)?)?;
            self.settle(read);
        }
        let read_near_s = start.elapsed().as_secs_f64();
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            // Wrapped: stale stamps could equal the new epoch.
            self.tet_table.clear_stamps();
            self.epoch = 1;
        }
        let keys = &self.keys;
        let reach = self.scan_reach(read);
        let near = {
            let at = read.positions();
            let nodes = read
                .near()
                .iter()
                .map(|&i| (keys[i as usize], at[i as usize]));
            let (table, epoch) = (&mut self.tet_table, self.epoch);
            classify::tets_near(&self.faces, nodes, reach, sweep, |tk| {
                table.first_visit(tk, epoch)
            })
        };
        // The candidates: tets whose bounds meet the sweep's. Tested at once where the cut has
        // read all four corners (one pass over the tets near); the box missed a corner of the
        // others (stretched tissue), which are read first.
        let mut candidates = Vec::new();
        let mut missed = Vec::new();
        // Tets stretched into the box from a node pulled out of it are read with those the box
        // missed a corner of.
        for x in self.pulled_out(sweep, read) {
            for &tk in self.faces.tets_at(self.keys[x as usize]) {
                if self.tet_table.first_visit(tk, self.epoch) {
                    missed.push(tk);
                }
            }
        }
        if let Some(b) = sweep.aabb() {
            for tk in near {
                let c = self.dense_corners(tk);
                if c.iter().all(|&i| read.knows(i)) {
                    if classify::bounds_overlap(&c.map(|i| read.class(i)), &b, self.snap) {
                        candidates.push(tk);
                    }
                } else {
                    missed.push(tk);
                }
            }
        }
        if !missed.is_empty() {
            read.complete(self.corners_of(&missed), source)?;
            self.settle(read);
            let (table, known) = (&self.tet_table, &*read);
            let corners = |tk: TetKey| corners_at(table, known, tk);
            candidates.extend(classify::overlapping(missed, &corners, sweep, self.snap));
        }
        candidates.sort_unstable();
        // Every classification reads corners of candidates, of their face neighbours and of the
        // tets around their nodes (a subdivision's trial splits): read what the box missed.
        let before = Instant::now();
        read.complete(self.ring_of(&candidates), source)?;
        self.settle(read);
        if !read.near().is_empty() {
            // What sizes the next cut's box: this one's box held nodes (a blade in the air
            // says nothing about the tissue's strain).
            self.spread = Some(read.displacement_spread());
        }
        let read_s = read_near_s + before.elapsed().as_secs_f64();
        let (mesh, table) = (&self.mesh, &self.tet_table);
        let known = &*read;
        let corners = |tk: TetKey| corners_at(table, known, tk);
        let mut outcome = CutOutcome::default();
        match self.method {
            CutMethod::Remove => {
                let met = classify::tets_met(&candidates, &corners, sweep);
                outcome.classify_s = start.elapsed().as_secs_f64();
                if !met.is_empty() {
                    self.remove(&met, &mut outcome)?;
                }
            }
            CutMethod::Separate => {
                let crossed =
                    classify::faces_crossed(mesh, &self.faces, &candidates, &corners, sweep);
                outcome.classify_s = start.elapsed().as_secs_f64();
                let tets = resweep::TetGeometry {
                    now: &corners,
                    rest: |t: TetKey| mesh.tet(t).expect("a tet").nodes.map(|k| mesh.rest(k)),
                };
                let new: Vec<(TetKey, TetKey)> = crossed
                    .into_iter()
                    .filter(|p| !self.crack.contains(p))
                    .filter(|&p| !resweep::along_old_cut(p, &self.partners, sweep, &tets))
                    .collect();
                // Each tet of a separated pair remembers the blade's plane in its rest frame.
                for &(a, b) in &new {
                    let t = tets.separating((a, b), sweep);
                    let at = |k: TetKey| t.and_then(|t| tets.pulled_back(k, t));
                    let (pa, pb) = (at(a), at(b));
                    self.partners.record(a, b, pa);
                    self.partners.record(b, a, pb);
                }
                if !new.is_empty() {
                    self.separate(&new, &mut outcome)?;
                }
            }
            CutMethod::Subdivide => {
                outcome.classify_s = start.elapsed().as_secs_f64();
                let classify = subdivide::Classify { read: known };
                self.subdivide(sweep, &classify, &candidates, &mut outcome)?;
            }
        }
        let changes = self.faces.take_boundary_changes();
        let dense = &self.dense;
        let to_dense = |t: Vec<[NodeKey; 3]>| -> Vec<[u32; 3]> {
            t.into_iter().map(|f| f.map(|k| dense[k])).collect()
        };
        outcome.surface = SurfaceEdit {
            removed: to_dense(changes.removed),
            added: to_dense(changes.added),
        };
        outcome.edit_s = start.elapsed().as_secs_f64() - outcome.classify_s;
        let mut changed = std::mem::take(&mut self.changed);
        changed.sort_unstable();
        changed.dedup();
        outcome.tets_changed = changed;
        outcome.read_s = read_s;
        outcome.nodes_read = read.near().len() + read.fetched();
        let d = &outcome.diff;
        outcome.springs_touched =
            d.removed_springs.len() + d.added_springs.len() + d.changed_springs.len();
        Ok(outcome)
    }
}

/// The classification corners of tet `tk`, as the cut `read` them.
fn corners_at(table: &tet_table::TetTable, read: &ReadPositions, tk: TetKey) -> classify::Corners {
    table.corners(tk).map(|i| read.class(i))
}
