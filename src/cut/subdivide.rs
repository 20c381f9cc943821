//! Subdividing: the tets the blade crosses are split along its sweep, with new nodes where it
//! crosses their edges, and the faces on the sweep then open as in splitting along faces.
//!
//! Every crossed edge gets a node at its crossing point, and every tet around it is subdivided
//! by a template of its marked edges (`template.rs`): the marked edges of the tet as it was
//! before any cut split it (its parent) are bisected in one global order, which keeps the mesh
//! conforming and gives the same sub-tets whatever order the blade marked the edges in. So a
//! blade moving in its own plane makes the same tets in one step as in many (a blade moving out
//! of its plane sweeps a curved surface, whose steps can snap differently; and where a tet split
//! by an earlier cut meets one re-made now, both are split edge by edge, see
//! `Cutter::parents_of`). Once every
//! crossed edge is split, no edge joins the two sides of the sweep any more, so each tet lies on
//! one side and the sweep is a union of faces whose corners are all on the cut; those faces open
//! (the node splitting of [`super::CutMethod::Separate`]). Where the sweep ends inside the
//! tissue, the edges it has not reached are not split and the cut stops there.
//!
//! A crossing within [`EDGE_SNAP`] of an edge's end is snapped to that node instead (the node
//! joins the cut, and the edges at it are not split): no sliver thinner than that fraction of an
//! edge is made. The cut happens in rest space: a new node sits at the crossing's parameter
//! along the rest edge.
//!
//! A fraction of one edge says little about the tets around it, so with a quality floor
//! ([`Cutter::with_quality_floor`]) more rules hold:
//!
//! - A node closer to the plane of the sweep than [`NODE_SNAP`] of its shortest rest edge joins
//!   the cut. Along an edge nearly parallel to the sweep the crossing can be anywhere though both
//!   ends are close to it, and splitting there would leave flat tets between the sweep and those
//!   nodes. With this rule a sweep passing close to an existing edge or face puts all its
//!   corners on the cut, and that edge or face opens as it is, with no new node. The plane, not
//!   the swept triangle, so that a blade in steps snaps the nodes a blade in one step does.
//! - A subdivision that would make a tet whose rest volume-length ratio (what the invariants
//!   check) is below the floor is not made: the crossings at that tet snap to the nearer ends of
//!   their edges. Snapping moves no node and makes no tet, so no tet below the floor is ever
//!   made; the price is a cut surface up to half an edge off the sweep there.
//! - Each parent is judged whole: subdivided by the marks the blade will have made once through
//!   it, going on in the plane of its crossing. A blade in steps marks a tet's edges one cut at a
//!   time, and the part made so far can fall below the floor where the whole does not; snapping
//!   then would make it cut unlike a blade in one step. So a crossing whose split now would make
//!   such a part waits (`Cutter::pending`) until the blade crosses the parent's other edges;
//!   where the blade stops inside a tet, those crossings stay waiting and the cut ends before
//!   it.
//!
//! All snaps are decided before any edge is split, on copies of the parents' subdivisions,
//! until every one passes; the edit then makes those subdivisions. A node that joined the cut
//! after edges at it were split could leave a tet with every corner on the cut, on neither side
//! of the sweep; deciding first keeps a corner off the cut in every tet a split makes, so each
//! tet still lies on one side and the faces that open are exactly those between the sides.
//!
//! Nodes stay on the cut from one cut to the next, so where a later cut snaps next to an
//! earlier one a tet can still end with every corner on a cut. Its fourth corner then says
//! nothing about its side of the new sweep (it lies on a cut plane, where rounding picks the
//! side), so it goes with its centroid's side: taking the corner's side instead opens faces
//! across such tets and leaves them as loose pieces where two cuts cross, which snapping far from
//! the sweep makes common. Two snapped surfaces crossing can still pinch off a few tets near the
//! line where they meet.
//!
//! A new node starts with the state interpolated along its edge (displacement and velocity, at
//! the crossing's parameter), so the deformed tissue does not jump when the cut is applied: its
//! position is the point of the deformed edge, and the two halves of a split edge keep its
//! strain.

use std::collections::{BTreeMap, BTreeSet};

use rustc_hash::{FxHashMap, FxHashSet};

use nalgebra::Point3;

use super::changes::{diff_of, StateSource};
use super::exact::segment_crosses_triangle;
use super::sweep::Sweep;
use super::{CutOutcome, Cutter};
use crate::error::Result;
use crate::mesh::quality::volume_length_ratio;
use crate::mesh::{NodeKey, TetKey, TET_EDGES, TET_FACES};

/// Crossings closer than this fraction of an edge to one of its ends snap to that end.
pub const EDGE_SNAP: f64 = 0.2;

/// The quality floor a [`Cutter`] starts with ([`Cutter::with_quality_floor`]): the rest
/// volume-length ratio below which subdividing makes no tet. Without a floor, random planar cuts
/// of a box made tets down to 0.025, and a subdivided box's stable time step fell to a third;
/// at 0.2 the lowest was 0.206 and half as many nodes were made.
pub const DEFAULT_QUALITY_FLOOR: f64 = 0.2;

/// With a quality floor, a node at the end of a crossed edge that is closer to the plane of the
/// sweep triangle it crosses than this fraction of its shortest rest edge joins the cut. No
/// larger than [`EDGE_SNAP`], so it moves the cut no further from the sweep than the parameter
/// rule can.
pub const NODE_SNAP: f64 = 0.2;

impl Cutter {
    /// Subdivide along `sweep`. `classify` gives the current (classification) position of an
    /// existing node; `candidates` are the tets near the sweep.
    pub(super) fn subdivide(
        &mut self,
        sweep: &Sweep,
        classify: &Classify,
        candidates: &[TetKey],
        outcome: &mut CutOutcome,
    ) -> Result<()> {
        // 1. Crossed edges, where (parameter from the smaller key) and which sweep triangle.
        let mut crossed: BTreeMap<[NodeKey; 2], Crossing> = BTreeMap::new();
        // Waiting crossings on the candidates' edges: those around the tets the blade is in.
        let mut waiting_here: BTreeMap<[NodeKey; 2], Crossing> = BTreeMap::new();
        // An edge is shared by about five candidates: test it against the sweep once.
        let mut tested: FxHashSet<[NodeKey; 2]> = FxHashSet::default();
        for &tk in candidates {
            let t = self.mesh.tet(tk).expect("a candidate tet").nodes;
            for [i, j] in TET_EDGES {
                let key = edge_key(t[i], t[j]);
                if !tested.insert(key) {
                    continue;
                }
                if let Some(c) = self.pending.get(&key) {
                    waiting_here.insert(key, *c);
                }
                let [p, q] = key;
                let (xp, xq) = (self.classified(classify, p), self.classified(classify, q));
                if let Some(s) = sweep
                    .triangles
                    .iter()
                    .find(|s| segment_crosses_triangle(&xp, &xq, s))
                {
                    let (dp, dq) = (signed_plane(&xp, s), signed_plane(&xq, s));
                    let t = if dp == dq {
                        0.5
                    } else {
                        (dp / (dp - dq)).clamp(0.0, 1.0)
                    };
                    crossed.insert(key, Crossing { t, plane: *s });
                }
            }
        }
        // An edge that meets the sweep at an end already on a cut (a node an earlier sweep made
        // or snapped) crosses nothing new; counting it would pull its other end onto the cut
        // when the same sweep comes again.
        let old_cut = |[p, q]: [NodeKey; 2], c: &Crossing| {
            (c.t < EDGE_SNAP && self.on_cut.contains(&p))
                || (c.t > 1.0 - EDGE_SNAP && self.on_cut.contains(&q))
        };
        crossed.retain(|&e, c| !old_cut(e, c));
        // Crossings an earlier cut left waiting for the blade to finish the tets around them
        // join in where it is (on the candidates' edges, whose nodes the cut has read), when it
        // crosses a new edge (one off every cut that is not waiting already); else they go on
        // waiting, and a blade moved along its cut changes nothing.
        let fresh = crossed.keys().any(|e| {
            !self.on_cut.contains(&e[0])
                && !self.on_cut.contains(&e[1])
                && !self.pending.contains_key(e)
        });
        if fresh {
            for (e, c) in waiting_here {
                self.pending.remove(&e);
                if !old_cut(e, &c) {
                    crossed.insert(e, c);
                }
            }
        } else {
            crossed.retain(|e, _| !self.pending.contains_key(e));
        }
        if crossed.is_empty() {
            return Ok(());
        }
        // 2. Snap crossings near an end (and, with a floor, nodes near the sweep's plane and the
        //    ends of splits that would make a tet below it); split the others, but those whose
        //    tets the blade has not finished and whose split now would make a tet below the
        //    floor: those wait for the next cut.
        let mut snapped: BTreeSet<NodeKey> = BTreeSet::new();
        for (&[p, q], c) in &crossed {
            if c.t < EDGE_SNAP {
                snapped.insert(p);
            } else if c.t > 1.0 - EDGE_SNAP {
                snapped.insert(q);
            }
        }
        let mut waiting: BTreeSet<[NodeKey; 2]> = BTreeSet::new();
        let floor = self.quality_floor;
        let guarded = floor > 0.0;
        if guarded {
            // Each end's distance to the plane of the sweep triangle its edge crosses: the plane,
            // not the triangle, so that a blade in steps, whose triangle of the moment may end
            // short of a node the whole sweep passes, snaps the same nodes as one in one step.
            let mut distance: BTreeMap<NodeKey, f64> = BTreeMap::new();
            for (&[p, q], c) in &crossed {
                for n in [p, q] {
                    if snapped.contains(&n) || self.on_cut.contains(&n) {
                        continue;
                    }
                    let d = signed_plane(&self.classified(classify, n), &c.plane).abs();
                    let e = distance.entry(n).or_insert(f64::INFINITY);
                    *e = e.min(d);
                }
            }
            for (n, d) in distance {
                if d < NODE_SNAP * self.shortest_rest_edge_at(n) {
                    snapped.insert(n);
                }
            }
            loop {
                let on_cut = |n: NodeKey| snapped.contains(&n) || self.on_cut.contains(&n);
                let (waits, splits): (BTreeMap<_, _>, BTreeMap<_, _>) = crossed
                    .iter()
                    .filter(|(e, _)| !on_cut(e[0]) && !on_cut(e[1]))
                    .map(|(e, c)| (*e, *c))
                    .partition(|(e, _)| waiting.contains(e));
                let verdict = self.floor_verdict(&splits, &waits, &on_cut, classify, floor);
                if verdict.snap.is_empty() && verdict.wait.is_empty() {
                    break;
                }
                snapped.extend(verdict.snap);
                waiting.extend(verdict.wait);
            }
        }
        let on_cut = |n: NodeKey| snapped.contains(&n) || self.on_cut.contains(&n);
        self.pending.extend(
            crossed
                .iter()
                .filter(|(e, _)| waiting.contains(*e) && !on_cut(e[0]) && !on_cut(e[1]))
                .map(|(e, c)| (*e, *c)),
        );
        // A crossing at a node now on the cut has nothing left to wait for.
        self.pending.retain(|e, _| !on_cut(e[0]) && !on_cut(e[1]));
        let splits: Vec<([NodeKey; 2], f64)> = crossed
            .iter()
            .filter(|(e, _)| !on_cut(e[0]) && !on_cut(e[1]) && !waiting.contains(*e))
            .map(|(e, c)| (*e, c.t))
            .collect();
        // 3. What the edit may change (reported as touched): every sub-tet of the tets whose
        //    subdivision changes, and the tets at snapped nodes. From here the spring model
        //    notes what it changes, for the diff.
        let parents = self.parents_of(splits.iter().map(|s| s.0));
        let mut touched: BTreeSet<TetKey> = BTreeSet::new();
        for plan in parents.list.values() {
            touched.extend(plan.children.iter().copied());
        }
        for &n in &snapped {
            touched.extend(self.faces.tets_at(n).iter().copied());
        }
        self.model.record_changes();
        self.on_cut.extend(snapped.iter().copied());

        // 4. A node on each split edge, then each parent's sub-tets from all its marks.
        let mut extra: FxHashMap<NodeKey, Point3<f64>> = FxHashMap::default();
        let mut source: FxHashMap<NodeKey, StateSource> = FxHashMap::default();
        let mut added: Vec<(NodeKey, StateSource)> = Vec::new();
        let mut made: BTreeMap<[NodeKey; 2], NodeKey> = BTreeMap::new();
        for &([a, b], t) in &splits {
            let rest = self.mesh.rest(a) + (self.mesh.rest(b) - self.mesh.rest(a)) * t;
            let k = self.add_node(rest);
            self.on_cut.insert(k);
            let (xa, xb) = (self.classified(classify, a), self.classified(classify, b));
            extra.insert(k, xa + (xb - xa) * t);
            // It starts where the deformed edge puts it, moving as the edge moves there.
            let from = StateSource::Between(a, b, t);
            source.insert(k, from);
            added.push((k, from));
            made.insert([a, b], k);
        }
        let children = self.subdivide_parents(parents, &made)?;
        if guarded {
            debug_assert!(
                children.iter().all(|&t| {
                    let points = self.mesh.tet_points(self.mesh.tet(t).expect("a tet"));
                    volume_length_ratio(&points) >= floor
                }),
                "a sub-tet below the quality floor: the edit left the checked trial"
            );
        }

        // 5. Open the faces on the cut: all three corners on it, the two tets' other corners on
        //    either side of the sweep (the plane of the sweep triangle nearest the face). Such a
        //    face lies in the cut surface whichever step made its corners, so a cut made in many
        //    steps opens the same faces as one made in one. A tet whose other corner is on a cut
        //    too lies on its centroid's side.
        let at = |n: NodeKey| {
            extra
                .get(&n)
                .copied()
                .unwrap_or_else(|| self.classified(classify, n))
        };
        let side = |p: &Point3<f64>, near: &Point3<f64>| {
            let s = sweep
                .triangles
                .iter()
                .min_by(|a, b| {
                    let da = (Point3::from((a[0].coords + a[1].coords + a[2].coords) / 3.0) - near)
                        .norm();
                    let db = (Point3::from((b[0].coords + b[1].coords + b[2].coords) / 3.0) - near)
                        .norm();
                    da.total_cmp(&db)
                })
                .expect("a sweep with triangles");
            (s[1] - s[0]).cross(&(s[2] - s[0])).dot(&(p - s[0]))
        };
        let mut pairs: BTreeSet<(TetKey, TetKey)> = BTreeSet::new();
        for &tk in children.iter().chain(candidates) {
            let Some(tet) = self.mesh.tet(tk) else {
                continue;
            };
            for (local, f) in TET_FACES.iter().enumerate() {
                if !f.iter().all(|&i| self.on_cut.contains(&tet.nodes[i])) {
                    continue;
                }
                let Some(other) = self.faces.neighbour(tk, tet, local) else {
                    continue;
                };
                let pair = if tk < other { (tk, other) } else { (other, tk) };
                if self.crack.contains(&pair) || pairs.contains(&pair) {
                    continue;
                }
                let face = f.map(|i| tet.nodes[i]);
                let apex = |t: TetKey| {
                    let nodes = self.mesh.tet(t).expect("a tet").nodes;
                    let k = *nodes
                        .iter()
                        .find(|n| !face.contains(n))
                        .expect("a tet has four");
                    if self.on_cut.contains(&k) {
                        centroid(nodes.map(at))
                    } else {
                        at(k)
                    }
                };
                let centre = Point3::from(
                    face.iter()
                        .map(|&n| at(n).coords)
                        .sum::<nalgebra::Vector3<f64>>()
                        / 3.0,
                );
                let (da, db) = (side(&apex(pair.0), &centre), side(&apex(pair.1), &centre));
                if da * db < 0.0 {
                    pairs.insert(pair);
                }
            }
        }
        let pairs: Vec<(TetKey, TetKey)> = pairs.into_iter().collect();
        outcome.faces_cut = pairs.len();
        let plan = self.plan_split(&pairs);
        let source_of = |n: NodeKey| source.get(&n).copied().unwrap_or(StateSource::Node(n));
        let copies = self.apply_split(&plan, &source_of)?;
        added.extend(copies);
        // Sub-tets whose corners were renamed, or whose face is cut, no longer follow their
        // parent's template: those families end.
        for &t in plan.replace.keys() {
            self.families.end_family_of(t);
        }
        for &(a, b) in &pairs {
            self.families.end_family_of(a);
            self.families.end_family_of(b);
        }

        let all: BTreeSet<TetKey> = children
            .iter()
            .chain(plan.replace.keys())
            .chain(&touched)
            .copied()
            .collect();
        outcome.tets_touched = all.len();
        outcome.nodes_added = added.len();
        let changes = self.model.take_changes();
        outcome.diff = diff_of(changes, &self.mesh, &self.model, &added, &self.dense);
        Ok(())
    }

    /// The tets holding both `a` and `b`, in key order.
    pub(super) fn tets_with_edge(&self, a: NodeKey, b: NodeKey) -> Vec<TetKey> {
        let tb = self.faces.tets_at(b);
        self.faces
            .tets_at(a)
            .iter()
            .copied()
            .filter(|t| tb.binary_search(t).is_ok())
            .collect()
    }
}

/// Where the cutter classifies existing nodes: at their current positions, or at rest where
/// they are within the snap distance of it, so that a resting mesh is cut exactly as its rest
/// geometry says (worked out once per node read, [`super::ReadPositions`]).
pub(super) struct Classify<'a> {
    pub(super) read: &'a super::ReadPositions,
}

impl Cutter {
    /// The classification position of existing node `k`.
    pub(super) fn classified(&self, at: &Classify, k: NodeKey) -> Point3<f64> {
        at.read.class(self.dense[k])
    }
}

fn centroid(p: [Point3<f64>; 4]) -> Point3<f64> {
    Point3::from((p[0].coords + p[1].coords + p[2].coords + p[3].coords) / 4.0)
}

/// The edge `(a, b)` as its ends in key order.
pub(super) fn edge_key(a: NodeKey, b: NodeKey) -> [NodeKey; 2] {
    if a < b {
        [a, b]
    } else {
        [b, a]
    }
}

/// `p`'s signed distance from the plane of triangle `t` (positive on its normal's side).
pub(super) fn signed_plane(p: &Point3<f64>, t: &[Point3<f64>; 3]) -> f64 {
    let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
    let len = n.norm();
    if len == 0.0 {
        return 0.0;
    }
    n.dot(&(p - t[0])) / len
}

/// Where the blade crosses an edge: the parameter from the edge's smaller key, and the sweep
/// triangle it crosses (whose plane says where the blade goes on).
#[derive(Debug, Clone, Copy)]
pub(super) struct Crossing {
    pub t: f64,
    pub plane: [Point3<f64>; 3],
}

#[cfg(test)]
mod tests {
    use super::signed_plane;
    use nalgebra::Point3;

    #[test]
    fn the_signed_distance_from_a_plane_follows_the_normal_and_ignores_the_sides() {
        let t = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(2.0, 0.0, 0.0),
            Point3::new(0.0, 2.0, 0.0),
        ];
        assert_eq!(signed_plane(&Point3::new(0.25, 0.25, 0.5), &t), 0.5);
        assert_eq!(signed_plane(&Point3::new(9.0, -7.0, -0.5), &t), -0.5);
        assert_eq!(
            signed_plane(&Point3::new(0.25, 0.25, 0.5), &[t[0], t[2], t[1]]),
            -0.5
        );
        assert_eq!(
            signed_plane(&Point3::new(1.0, 1.0, 1.0), &[t[0], t[0], t[1]]),
            0.0
        );
    }
}
