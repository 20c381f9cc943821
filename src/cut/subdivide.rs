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
//! A fraction of one edge says little about the tets around it, so with a quality floor
//! ([`Cutter::with_quality_floor`]) two more rules hold:
//!
//! - A node closer to the sweep than [`NODE_SNAP`] of its shortest edge joins the cut. Along an
//!   edge nearly parallel to the sweep the crossing can be anywhere though both ends are close
//!   to it, and splitting there would leave flat tets between the sweep and those nodes. With
//!   this rule a sweep passing close to an existing edge or face puts all its corners on the
//!   cut, and that edge or face opens as it is, with no new node.
//! - A split that would make a tet whose rest volume-length ratio (what the invariants check)
//!   is below the floor is not made: the crossing snaps to the nearer end of its edge. Snapping
//!   moves no node and makes no tet, so no tet below the floor is ever made; the price is a cut
//!   surface up to half an edge off the sweep there.
//!
//! All snaps are decided before any edge is split: the splits are played on a copy of the tets
//! around them, and each time a split fails the floor its nearer end joins the cut and the play
//! starts again, until one play passes; the edit then repeats that play. A node that joined the
//! cut after edges at it were split could leave a tet with every corner on the cut, on neither
//! side of the sweep; deciding first keeps a corner off the cut in every tet a split makes, so
//! each tet still lies on one side and the faces that open are exactly those between the sides.
//!
//! Nodes stay on the cut from one cut to the next, so where a later cut snaps next to an
//! earlier one a tet can still end with every corner on a cut. Its fourth corner then says
//! nothing about its side of the new sweep, so with a floor it goes with its centroid's side:
//! taking the corner's side instead opens faces across such tets and leaves them as loose pieces
//! where two cuts cross, which snapping far from the sweep makes common. Two snapped surfaces
//! crossing can still pinch off a few tets near the line where they meet.
//!
//! A new node starts with the state interpolated along its edge (displacement and velocity, at
//! the crossing's parameter), so the deformed tissue does not jump when the cut is applied: its
//! position is the point of the deformed edge, and the two halves of a split edge keep its
//! strain.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use nalgebra::Point3;

use super::exact::segment_crosses_triangle;
use super::snapshot::{Snapshot, StateSource};
use super::sweep::Sweep;
use super::{CutOutcome, Cutter};
use crate::error::Result;
use crate::mesh::quality::tet_quality;
use crate::mesh::{NodeKey, TetKey, TET_EDGES, TET_FACES};

/// Crossings closer than this fraction of an edge to one of its ends snap to that end.
pub const EDGE_SNAP: f64 = 0.2;

/// The quality floor a [`Cutter`] starts with ([`Cutter::with_quality_floor`]): the rest
/// volume-length ratio below which subdividing makes no tet. Without a floor, random planar cuts
/// of a box made tets down to 0.025, and a subdivided box's stable time step fell to a third;
/// at 0.2 the lowest was 0.206 and half as many nodes were made.
pub const DEFAULT_QUALITY_FLOOR: f64 = 0.2;

/// With a quality floor, a node at the end of a crossed edge that is closer to the sweep than
/// this fraction of its shortest edge joins the cut. No larger than [`EDGE_SNAP`], so it moves
/// the cut no further from the sweep than the parameter rule can.
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
                let (xp, xq) = (self.classified(classify, p), self.classified(classify, q));
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
        // An edge that meets the sweep at an end already on a cut (a node an earlier sweep made
        // or snapped) crosses nothing new; counting it would pull its other end onto the cut
        // when the same sweep comes again.
        crossed.retain(|&[p, q], t| {
            !((*t < EDGE_SNAP && self.on_cut.contains(&p))
                || (*t > 1.0 - EDGE_SNAP && self.on_cut.contains(&q)))
        });
        if crossed.is_empty() {
            return Ok(());
        }
        // 2. Snap crossings near an end (and, with a floor, nodes near the sweep and the ends
        //    of splits that would make a tet below it); split the others.
        let mut snapped: BTreeSet<NodeKey> = BTreeSet::new();
        for (&[p, q], &t) in &crossed {
            if t < EDGE_SNAP {
                snapped.insert(p);
            } else if t > 1.0 - EDGE_SNAP {
                snapped.insert(q);
            }
        }
        let floor = self.quality_floor;
        let guarded = floor > 0.0;
        if guarded {
            let ends: BTreeSet<NodeKey> = crossed
                .keys()
                .flatten()
                .copied()
                .filter(|n| !snapped.contains(n) && !self.on_cut.contains(n))
                .collect();
            for n in ends {
                let x = self.classified(classify, n);
                let distance = sweep
                    .triangles
                    .iter()
                    .map(|s| distance_to_triangle(&x, s))
                    .fold(f64::INFINITY, f64::min);
                if distance < NODE_SNAP * self.shortest_edge_at(n, classify) {
                    snapped.insert(n);
                }
            }
            loop {
                let on_cut = |n: NodeKey| snapped.contains(&n) || self.on_cut.contains(&n);
                let more = self.sliver_snaps(&crossed, &on_cut, floor);
                if more.is_empty() {
                    break;
                }
                snapped.extend(more);
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
        let mut source: HashMap<NodeKey, StateSource> = HashMap::new();
        let mut added: Vec<(NodeKey, StateSource)> = Vec::new();
        let mut children: BTreeSet<TetKey> = BTreeSet::new();
        for ([a, b], t) in splits {
            let rest = self.mesh.rest(a) + (self.mesh.rest(b) - self.mesh.rest(a)) * t;
            let k = self.add_node(rest);
            self.on_cut.insert(k);
            let (xa, xb) = (self.classified(classify, a), self.classified(classify, b));
            extra.insert(k, xa + (xb - xa) * t);
            // It starts where the deformed edge puts it, moving as the edge moves there.
            let from = StateSource::Between(a, b, t);
            source.insert(k, from);
            added.push((k, from));
            for tk in self.tets_with_edge(a, b) {
                let tet = *self.mesh.tet(tk).expect("a tet");
                let one = tet.nodes.map(|n| if n == b { k } else { n });
                let two = tet.nodes.map(|n| if n == a { k } else { n });
                debug_assert!(
                    !guarded
                        || [one, two].iter().all(|c| {
                            tet_quality(&c.map(|n| self.mesh.rest(n))).volume_length_ratio >= floor
                        }),
                    "a split below the quality floor: the edit left the checked play"
                );
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
        //    steps opens the same faces as one made in one. With a floor, a tet whose other
        //    corner is on a cut too lies on its centroid's side.
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
                    if guarded && self.on_cut.contains(&k) {
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
        let renoded: Vec<[NodeKey; 4]> = plan
            .replace
            .keys()
            .map(|&t| self.mesh.tet(t).expect("a tet").nodes)
            .collect();
        let dense = &self.dense;
        snapshot.extend(&self.model, &renoded, &|n| dense[n] < nodes_before);
        let source_of = |n: NodeKey| source.get(&n).copied().unwrap_or(StateSource::Node(n));
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

    /// The nodes to put on the cut so that splitting the crossings of `crossed` whose ends are
    /// not `on_cut` makes no tet below `floor` (rest volume-length ratio). The splits are played
    /// in order on a copy of the tets around them; one that would make such a tet is not made,
    /// the nearer end of its edge is returned and the play goes on without the splits at that
    /// node. Empty when every split keeps to the floor.
    fn sliver_snaps(
        &self,
        crossed: &BTreeMap<[NodeKey; 2], f64>,
        on_cut: &dyn Fn(NodeKey) -> bool,
        floor: f64,
    ) -> BTreeSet<NodeKey> {
        let splits: Vec<([NodeKey; 2], f64)> = crossed
            .iter()
            .filter(|(e, _)| !on_cut(e[0]) && !on_cut(e[1]))
            .map(|(e, t)| (*e, *t))
            .collect();
        // The copy: corners as indices into `at` (rest positions), with each node's tets.
        let mut index: HashMap<NodeKey, usize> = HashMap::new();
        let mut at: Vec<Point3<f64>> = Vec::new();
        let mut around: Vec<Vec<usize>> = Vec::new();
        let mut tets: Vec<[usize; 4]> = Vec::new();
        let mut copied: BTreeSet<TetKey> = BTreeSet::new();
        for ([a, b], _) in &splits {
            for tk in self.tets_with_edge(*a, *b) {
                if !copied.insert(tk) {
                    continue;
                }
                let mut local = [0; 4];
                for (l, &n) in local
                    .iter_mut()
                    .zip(&self.mesh.tet(tk).expect("a tet").nodes)
                {
                    *l = *index.entry(n).or_insert_with(|| {
                        at.push(self.mesh.rest(n));
                        around.push(Vec::new());
                        at.len() - 1
                    });
                    around[*l].push(tets.len());
                }
                tets.push(local);
            }
        }
        let mut snaps = BTreeSet::new();
        for ([a, b], t) in splits {
            if snaps.contains(&a) || snaps.contains(&b) {
                continue;
            }
            let (la, lb) = (index[&a], index[&b]);
            // As the edit places it.
            let x = self.mesh.rest(a) + (self.mesh.rest(b) - self.mesh.rest(a)) * t;
            let shared: Vec<usize> = around[la]
                .iter()
                .copied()
                .filter(|i| around[lb].contains(i))
                .collect();
            let quality = |c: &[usize; 4], moved: usize| {
                tet_quality(&c.map(|l| if l == moved { x } else { at[l] })).volume_length_ratio
            };
            if shared
                .iter()
                .any(|&i| quality(&tets[i], lb) < floor || quality(&tets[i], la) < floor)
            {
                snaps.insert(if t < 0.5 { a } else { b });
                continue;
            }
            let k = at.len();
            at.push(x);
            around.push(Vec::new());
            for i in shared {
                let tet = tets[i];
                tets[i] = tet.map(|l| if l == lb { k } else { l });
                around[lb].retain(|&j| j != i);
                around[k].push(i);
                let two = tet.map(|l| if l == la { k } else { l });
                for &l in &two {
                    around[l].push(tets.len());
                }
                tets.push(two);
            }
        }
        snaps
    }

    /// The length of the shortest edge at `n`, at the classification positions `classify`.
    fn shortest_edge_at(&self, n: NodeKey, classify: &Classify) -> f64 {
        let x = self.classified(classify, n);
        self.faces
            .tets_at(n)
            .iter()
            .flat_map(|&t| self.mesh.tet(t).expect("a tet").nodes)
            .filter(|&m| m != n)
            .map(|m| (self.classified(classify, m) - x).norm())
            .fold(f64::INFINITY, f64::min)
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

/// Where the cutter classifies existing nodes: at their current positions, or at rest where
/// they are within the snap distance of it, so that a resting mesh is cut exactly as its rest
/// geometry says (worked out once per node read, [`super::ReadPositions`]).
pub(super) struct Classify<'a> {
    pub(super) read: &'a super::ReadPositions,
}

impl Cutter {
    /// The classification position of existing node `k`.
    fn classified(&self, at: &Classify, k: NodeKey) -> Point3<f64> {
        at.read.class(self.dense[k])
    }
}

fn centroid(p: [Point3<f64>; 4]) -> Point3<f64> {
    Point3::from((p[0].coords + p[1].coords + p[2].coords + p[3].coords) / 4.0)
}

/// The distance from `p` to the triangle `t`: to its plane where `p` projects inside it, else to
/// the nearest side.
fn distance_to_triangle(p: &Point3<f64>, t: &[Point3<f64>; 3]) -> f64 {
    let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
    let inside = (0..3).all(|i| (t[(i + 1) % 3] - t[i]).cross(&(p - t[i])).dot(&n) >= 0.0);
    if inside && n.norm_squared() > 0.0 {
        return (p - t[0]).dot(&n).abs() / n.norm();
    }
    (0..3)
        .map(|i| {
            let (a, ab) = (t[i], t[(i + 1) % 3] - t[i]);
            let len2 = ab.norm_squared();
            let s = if len2 > 0.0 {
                ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (p - (a + ab * s)).norm()
        })
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::distance_to_triangle;
    use nalgebra::Point3;

    #[test]
    fn distance_to_a_triangle_is_to_its_plane_side_or_corner() {
        let t = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ];
        let d = |x: f64, y: f64, z: f64| distance_to_triangle(&Point3::new(x, y, z), &t);
        // Above the inside, either way round.
        assert_eq!(d(0.25, 0.25, 0.5), 0.5);
        assert_eq!(
            distance_to_triangle(&Point3::new(0.25, 0.25, -0.5), &[t[0], t[2], t[1]]),
            0.5
        );
        // Beside a side, beyond a corner.
        assert!((d(0.5, -0.3, 0.4) - 0.5).abs() < 1e-15);
        assert!((d(-3.0, -4.0, 0.0) - 5.0).abs() < 1e-15);
        assert!((d(1.0, 1.0, 0.0) - 0.5f64.sqrt()).abs() < 1e-15);
    }
}
