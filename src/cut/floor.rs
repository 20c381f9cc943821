//! The quality floor's trial for subdividing: which crossings snap to a node and which wait
//! for the blade, judged on copies of the parents' subdivisions (see `subdivide.rs`).

use std::collections::{BTreeMap, BTreeSet};

use rustc_hash::FxHashMap;

use nalgebra::Point3;

use super::subdivide::{edge_key, signed_plane, Classify, Crossing, EDGE_SNAP, NODE_SNAP};
use super::template;
use super::Cutter;
use crate::mesh::quality::volume_length_ratio;
use crate::mesh::{NodeKey, TET_EDGES};

impl Cutter {
    /// What keeps splitting `splits` from making a tet below `floor` (rest volume-length
    /// ratio), now or once the blade has gone on through the tets it is in.
    ///
    /// Every parent whose subdivision the splits change is subdivided on a copy by its template,
    /// twice: with the marks the blade will have made once through it, if it goes on in the
    /// plane of a crossing (the parent's edges across that plane, but at nodes that snap), and
    /// with the marks it has and the new ones (what this cut would make). Where a sub-tet of
    /// the whole subdivision falls below the floor, each crossing at a corner of such a sub-tet
    /// (each new one of the parent, if none is) snaps to the nearer end of its edge, crossings
    /// still ahead of the blade included. Where only the part made so far would, its new
    /// crossings at such sub-tets wait: the blade has not finished the parent, and splitting
    /// part of it now would force a snap that a blade through it in one step does not make.
    /// All parents are judged on the same splits, so the answer does not depend on an order.
    pub(super) fn floor_verdict(
        &self,
        splits: &BTreeMap<[NodeKey; 2], Crossing>,
        waiting: &BTreeMap<[NodeKey; 2], Crossing>,
        on_cut: &dyn Fn(NodeKey) -> bool,
        classify: &Classify,
        floor: f64,
    ) -> FloorVerdict {
        let parents = self.parents_of(splits.keys().chain(waiting.keys()).copied());
        let mut verdict = FloorVerdict::default();
        let mut shortest: FxHashMap<NodeKey, f64> = FxHashMap::default();
        for plan in parents.list.values() {
            let corners = plan.corners;
            let rest = corners.map(|n| self.mesh.rest(n));
            // Corners 0..4, then one point per mark.
            let mut at: Vec<Point3<f64>> = rest.to_vec();
            let mut now: Vec<(usize, usize)> = Vec::with_capacity(6);
            for &(e, k) in &plan.marks {
                now.push((e, at.len()));
                at.push(self.mesh.rest(k));
            }
            let point = |key: [NodeKey; 2], t: f64| {
                let (a, b) = (self.mesh.rest(key[0]), self.mesh.rest(key[1]));
                a + (b - a) * t
            };
            // (point, edge, parameter) of each crossing this cut would split, and of each
            // crossing waiting (known to be ahead).
            let mut new: Vec<(usize, [NodeKey; 2], f64)> = Vec::new();
            let mut known: Vec<(usize, usize, [NodeKey; 2], f64)> = Vec::new();
            let mut plane = None;
            for (e, [i, j]) in TET_EDGES.iter().enumerate() {
                let key = edge_key(corners[*i], corners[*j]);
                if let Some(c) = splits.get(&key) {
                    new.push((at.len(), key, c.t));
                    now.push((e, at.len()));
                    at.push(point(key, c.t));
                    plane.get_or_insert(c.plane);
                } else if let Some(c) = waiting.get(&key) {
                    known.push((e, at.len(), key, c.t));
                    at.push(point(key, c.t));
                    plane.get_or_insert(c.plane);
                }
            }
            let Some(plane) = plane else {
                continue;
            };
            // The crossings still ahead: the parent's other edges across the plane, but where
            // an end is on a cut or snaps (near the plane, or a crossing near it).
            let d = corners.map(|n| signed_plane(&self.classified(classify, n), &plane));
            let mut off = [0, 1, 2, 3].map(|i| {
                let n = corners[i];
                !on_cut(n)
                    && d[i].abs()
                        >= NODE_SNAP
                            * *shortest
                                .entry(n)
                                .or_insert_with(|| self.shortest_rest_edge_at(n))
            });
            let marked =
                |e: usize| now.iter().any(|&(m, _)| m == e) || known.iter().any(|&(m, ..)| m == e);
            let across = |i: usize, j: usize| (d[i] < 0.0) != (d[j] < 0.0);
            for (e, &[i, j]) in TET_EDGES.iter().enumerate() {
                if !marked(e) && across(i, j) && off[i] && off[j] {
                    let t = d[i] / (d[i] - d[j]);
                    if t < EDGE_SNAP {
                        off[i] = false;
                    } else if t > 1.0 - EDGE_SNAP {
                        off[j] = false;
                    }
                }
            }
            let mut whole = now.clone();
            let mut ahead = new.clone();
            for &(e, l, key, t) in &known {
                whole.push((e, l));
                ahead.push((l, key, t));
            }
            for (e, &[i, j]) in TET_EDGES.iter().enumerate() {
                if !marked(e) && across(i, j) && off[i] && off[j] {
                    let key = edge_key(corners[i], corners[j]);
                    let t = d[i] / (d[i] - d[j]);
                    let t = if key[0] == corners[i] { t } else { 1.0 - t };
                    ahead.push((at.len(), key, t));
                    whole.push((e, at.len()));
                    at.push(point(key, t));
                }
            }
            let order = template::edge_order(&rest);
            // The crossings of `blamable` at a sub-tet of `marks` below the floor (the new ones
            // where no such crossing is at one); empty when every sub-tet keeps to it.
            let blame = |marks: &[(usize, usize)], blamable: &[(usize, [NodeKey; 2], f64)]| {
                let tets = template::subdivide([0, 1, 2, 3], marks, &order);
                let failing: Vec<&[usize; 4]> = tets
                    .iter()
                    .filter(|c| volume_length_ratio(&c.map(|l| at[l])) < floor)
                    .collect();
                if failing.is_empty() {
                    return Vec::new();
                }
                let at_failing: Vec<([NodeKey; 2], f64)> = blamable
                    .iter()
                    .filter(|(l, _, _)| failing.iter().any(|c| c.contains(l)))
                    .map(|&(_, e, t)| (e, t))
                    .collect();
                if at_failing.is_empty() {
                    new.iter().map(|&(_, e, t)| (e, t)).collect()
                } else {
                    at_failing
                }
            };
            let snap = blame(&whole, &ahead);
            if !snap.is_empty() {
                for (key, t) in snap {
                    verdict.snap.insert(if t < 0.5 { key[0] } else { key[1] });
                }
            } else if new.is_empty() {
                // Nothing new for this parent: it was judged with its waiting crossings only.
            } else if whole.len() > now.len() {
                verdict
                    .wait
                    .extend(blame(&now, &new).into_iter().map(|(e, _)| e));
            } else {
                // The blade has finished the parent, so the two are the same and keep to it.
                debug_assert!(blame(&now, &new).is_empty());
            }
        }
        verdict
    }

    /// The length at rest of the shortest edge at `n` (at rest, so that whether a node snaps
    /// does not depend on when the blade reaches it).
    pub(super) fn shortest_rest_edge_at(&self, n: NodeKey) -> f64 {
        let x = self.mesh.rest(n);
        self.faces
            .tets_at(n)
            .iter()
            .flat_map(|&t| self.mesh.tet(t).expect("a tet").nodes)
            .filter(|&m| m != n)
            .map(|m| (self.mesh.rest(m) - x).norm())
            .fold(f64::INFINITY, f64::min)
    }
}

/// What the quality floor asks of a cut's splits: nodes to put on the cut, and crossings to
/// leave for a later cut.
#[derive(Debug, Default)]
pub(super) struct FloorVerdict {
    pub snap: BTreeSet<NodeKey>,
    pub wait: BTreeSet<[NodeKey; 2]>,
}
