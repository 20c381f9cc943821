//! Subdividing: the tets the blade crosses are split along its sweep, with new nodes where it
//! crosses their edges, and the faces on the sweep then open as in splitting along faces.
//!
//! Every crossed edge is split at its crossing point, one edge at a time: splitting an edge
//! splits every tet around it in two (one keeps each end), which keeps the mesh conforming.
//! Once every crossed edge is split, no edge joins the two sides of the sweep any more, so each
//! tet lies on one side and the sweep is a union of faces whose corners are all on the cut;
//! those faces open (the node splitting of [`super::CutMethod::Separate`]). Where the sweep
//! ends inside the tissue, the edges it has not reached are not split and the cut stops there.
//!
//! A crossing within [`EDGE_SNAP`] of an edge's end is snapped to that node instead (the node
//! joins the cut, and the edges at it are not split): no sliver thinner than that fraction of an
//! edge is made. The cut happens in rest space: a new node sits at the crossing's parameter
//! along the rest edge.
//!
//! A new node starts with the state of the nearer end of its edge (a diff copies whole node
//! states); in a strained region this differs from the interpolated state by up to the strain
//! times half an edge.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use nalgebra::Point3;

use super::exact::segment_crosses_triangle;
use super::snapshot::Snapshot;
use super::sweep::Sweep;
use super::{CutOutcome, Cutter};
use crate::error::Result;
use crate::mesh::{NodeKey, TetKey, TET_EDGES, TET_FACES};

/// Crossings closer than this fraction of an edge to one of its ends snap to that end.
pub const EDGE_SNAP: f64 = 0.2;

impl Cutter {
    /// Subdivide along `sweep`. `position` gives the current (classification) position of an
    /// existing node; `candidates` are the tets near the sweep.
    pub(super) fn subdivide(
        &mut self,
        sweep: &Sweep,
        position: &dyn Fn(NodeKey) -> Point3<f64>,
        candidates: &[TetKey],
        outcome: &mut CutOutcome,
    ) -> Result<()> {
        let nodes_before = self.dense.len() as u32;
        // 1. Crossed edges and where (parameter from the smaller key).
        let mut crossed: BTreeMap<[NodeKey; 2], f64> = BTreeMap::new();
        for &tk in candidates {
            let t = self.mesh.tet(tk).expect("a candidate tet").nodes;
            for [i, j] in TET_EDGES {
                let (p, q) = if t[i] < t[j] {
                    (t[i], t[j])
                } else {
                    (t[j], t[i])
                };
                if crossed.contains_key(&[p, q]) {
                    continue;
                }
                let (xp, xq) = (position(p), position(q));
                if let Some(s) = sweep
                    .triangles
                    .iter()
                    .find(|s| segment_crosses_triangle(&xp, &xq, s))
                {
                    let n = (s[1] - s[0]).cross(&(s[2] - s[0]));
                    let (dp, dq) = (n.dot(&(xp - s[0])), n.dot(&(xq - s[0])));
                    let t = if dp == dq {
                        0.5
                    } else {
                        (dp / (dp - dq)).clamp(0.0, 1.0)
                    };
                    crossed.insert([p, q], t);
                }
            }
        }
        if crossed.is_empty() {
            return Ok(());
        }
        // 2. Snap crossings near an end; split the others.
        let mut snapped: BTreeSet<NodeKey> = BTreeSet::new();
        for (&[p, q], &t) in &crossed {
            if t < EDGE_SNAP {
                snapped.insert(p);
            } else if t > 1.0 - EDGE_SNAP {
                snapped.insert(q);
            }
        }
        let on_cut = |n: NodeKey| snapped.contains(&n) || self.on_cut.contains(&n);
        let splits: Vec<([NodeKey; 2], f64)> = crossed
            .iter()
            .filter(|(e, _)| !on_cut(e[0]) && !on_cut(e[1]))
            .map(|(e, t)| (*e, *t))
            .collect();
        // 3. Record what the edit may change, before it.
        let mut touched: BTreeSet<TetKey> = BTreeSet::new();
        for (e, _) in &splits {
            touched.extend(self.tets_with_edge(e[0], e[1]));
        }
        for &n in &snapped {
            touched.extend(self.faces.tets_at(n).iter().copied());
        }
        let before: Vec<[NodeKey; 4]> = touched
            .iter()
            .map(|&t| self.mesh.tet(t).expect("a tet").nodes)
            .collect();
        let mut snapshot = Snapshot::take(&self.model, &before);
        self.on_cut.extend(snapped.iter().copied());

        // 4. Split the edges, one at a time.
        let mut extra: HashMap<NodeKey, Point3<f64>> = HashMap::new();
        let mut source: HashMap<NodeKey, NodeKey> = HashMap::new();
        let mut added: Vec<(NodeKey, NodeKey)> = Vec::new();
        let mut children: BTreeSet<TetKey> = BTreeSet::new();
        for ([a, b], t) in splits {
            let rest = self.mesh.rest(a) + (self.mesh.rest(b) - self.mesh.rest(a)) * t;
            let k = self.mesh.add_node(rest);
            self.dense.insert(k, self.dense.len() as u32);
            self.on_cut.insert(k);
            let (xa, xb) = (position(a), position(b));
            extra.insert(k, xa + (xb - xa) * t);
            let from = if t < 0.5 { a } else { b };
            source.insert(k, from);
            added.push((k, from));
            for tk in self.tets_with_edge(a, b) {
                let tet = *self.mesh.tet(tk).expect("a tet");
                let one = tet.nodes.map(|n| if n == b { k } else { n });
                let two = tet.nodes.map(|n| if n == a { k } else { n });
                self.faces.remove(tk, &tet, &self.mesh);
                self.model.remove_tet(&self.mesh, tk)?;
                self.mesh.set_tet_nodes(tk, one)?;
                self.model.add_tet(&self.mesh, tk)?;
                self.faces.insert(tk, self.mesh.tet(tk).expect("a tet"))?;
                let other = self.mesh.add_tet(two, tet.region)?;
                self.model.add_tet(&self.mesh, other)?;
                self.faces
                    .insert(other, self.mesh.tet(other).expect("a tet"))?;
                children.extend([tk, other]);
            }
        }

        // 5. Open the faces on the cut: all three corners on it, the two tets' other corners on
        //    either side of the sweep (the plane of the sweep triangle nearest the face). Such a
        //    face lies in the cut surface whichever step made its corners, so a cut made in many
        //    steps opens the same faces as one made in one.
        let at = |n: NodeKey| extra.get(&n).copied().unwrap_or_else(|| position(n));
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
                    at(k)
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
        let renoded: Vec<[NodeKey; 4]> = plan
            .replace
            .keys()
            .map(|&t| self.mesh.tet(t).expect("a tet").nodes)
            .collect();
        let dense = &self.dense;
        snapshot.extend(&self.model, &renoded, &|n| dense[n] < nodes_before);
        let source_of = |n: NodeKey| source.get(&n).copied().unwrap_or(n);
        let (copies, _) = self.apply_split(&plan, &source_of)?;
        added.extend(copies);

        let all: BTreeSet<TetKey> = children
            .iter()
            .chain(plan.replace.keys())
            .chain(&touched)
            .copied()
            .collect();
        let after: Vec<[NodeKey; 4]> = all
            .iter()
            .filter_map(|&t| self.mesh.tet(t).map(|t| t.nodes))
            .collect();
        outcome.tets_touched = all.len();
        outcome.nodes_added = added.len();
        outcome.diff = snapshot.diff(&self.mesh, &self.model, &after, &added, &self.dense);
        Ok(())
    }

    /// The tets holding both `a` and `b`, in key order.
    fn tets_with_edge(&self, a: NodeKey, b: NodeKey) -> Vec<TetKey> {
        let tb = self.faces.tets_at(b);
        self.faces
            .tets_at(a)
            .iter()
            .copied()
            .filter(|t| tb.binary_search(t).is_ok())
            .collect()
    }
}
