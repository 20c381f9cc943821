//! Rebinding a render surface after a cut, so that each vertex follows the side of the cut it
//! lies on instead of the nodes it was bound to at rest.
//!
//! A cut removes tets (carving), gives tets new corners (a separated tet takes the copies of
//! the nodes on its side) or replaces tets by sub-tets (subdividing). Only the vertices bound
//! to those tets ([`crate::cut::CutOutcome::tets_changed`]) are looked at again, at their rest
//! positions, against the cut mesh's rest geometry:
//!
//! - a vertex **inside** a changed tet goes to the changed tet that holds it at rest: the same
//!   tet with its new corners (separating, so it follows the copies on its tet's side), or the
//!   sub-tet holding it (subdividing, so the side is the side of the sub-tets' cut, which
//!   follows the blade's sweep);
//! - a vertex **outside** the mesh keeps its face where that tet is still there and the face
//!   still on the boundary, with the tet's new corners;
//! - a vertex whose tet is gone (carved) goes to the nearest boundary face, among the tets
//!   around its old tet's corners (two rings), of a tet on the vertex's side of the blade's
//!   swept surface (the side of its rest position; a face's side is its centroid's): bound
//!   to it by the outside frame of [`super::embed`]. With no such face left (the carving took
//!   all the material on its side there) it is **dropped**: [`Embedding::dropped`] says so,
//!   its weights are zero, and [`Embedding::drawn_triangles`] leaves out its triangles.
//!
//! The triangles the blade crossed are split, and the opening capped, by [`super::cap`] after
//! the rebinding, so that the drawn surface stays closed.

use std::time::Instant;

use nalgebra::Point3;
use rustc_hash::{FxHashMap, FxHashSet};
use slotmap::SecondaryMap;

use super::embed::{barycentric, closest_on_triangle, INSIDE_TOLERANCE};
use super::grid::Grid;
use super::{Binding, Embedding};
use crate::cut::{FaceIndex, Sweep};
use crate::mesh::{NodeKey, TetKey, TetMesh, TET_FACES};

/// What one cut changed, as a render surface needs it.
#[derive(Debug, Clone, Copy)]
pub struct CutChange<'a> {
    /// The mesh after the cut.
    pub mesh: &'a TetMesh,
    /// Its face adjacency.
    pub faces: &'a FaceIndex,
    /// The tets the cut removed, gave new corners or made
    /// ([`crate::cut::CutOutcome::tets_changed`]).
    pub tets: &'a [TetKey],
    /// The blade's swept surface: the side of a vertex whose tet was carved.
    pub sweep: &'a Sweep,
}

/// What a rebind did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Rebound {
    /// The vertices rebound (sorted): the only ones whose nodes or weights changed.
    pub vertices: Vec<u32>,
    /// Of those, the vertices dropped (nothing left on their side to bind them to).
    pub dropped: usize,
    /// Seconds taken.
    pub seconds: f64,
}

/// The bookkeeping that lets a cut rebind only what it touched: the vertices of each tet and
/// the mesh's dense node numbering (nodes are only ever added by cuts).
#[derive(Debug, Clone)]
pub struct Rebinder {
    by_tet: FxHashMap<TetKey, Vec<u32>>,
    keys: Vec<NodeKey>,
    dense: SecondaryMap<NodeKey, u32>,
}

impl Rebinder {
    /// The index of `embedding`, made in `mesh` (the mesh the cuts start from).
    pub fn new(mesh: &TetMesh, embedding: &Embedding) -> Self {
        let mut by_tet: FxHashMap<TetKey, Vec<u32>> = FxHashMap::default();
        for (v, b) in embedding.bindings.iter().enumerate() {
            if !embedding.dropped[v] {
                by_tet.entry(b.tet()).or_default().push(v as u32);
            }
        }
        let mut r = Rebinder {
            by_tet,
            keys: Vec::new(),
            dense: SecondaryMap::new(),
        };
        r.take_new_nodes(mesh);
        r
    }

    /// Number the nodes a cut added (appended in storage order, as the cutter numbers them).
    fn take_new_nodes(&mut self, mesh: &TetMesh) {
        for (k, _) in mesh.nodes().skip(self.keys.len()) {
            self.dense.insert(k, self.keys.len() as u32);
            self.keys.push(k);
        }
    }

    /// Rebind the vertices of `embedding` bound to a tet `change` touched.
    pub fn rebind(&mut self, embedding: &mut Embedding, change: &CutChange) -> Rebound {
        let start = Instant::now();
        self.take_new_nodes(change.mesh);
        let mesh = change.mesh;
        // Grouped by the tet they were bound to: those of a carved tet share its candidates.
        let affected: Vec<u32> = change
            .tets
            .iter()
            .filter_map(|t| self.by_tet.remove(t))
            .flatten()
            .collect();
        // The boundary faces near the last carved tet looked at, with their sides.
        let mut near: Option<(TetKey, Vec<Candidate>)> = None;
        let alive: Vec<(TetKey, [Point3<f64>; 4])> = change
            .tets
            .iter()
            .filter_map(|&t| mesh.tet(t).map(|tet| (t, mesh.tet_points(tet))))
            .collect();
        let grid = Grid::new(
            &alive
                .iter()
                .map(|(_, p)| super::embed::bounds(p))
                .collect::<Vec<_>>(),
        );
        let mut out = Rebound::default();
        for &v in &affected {
            let vi = v as usize;
            let p = Point3::from(embedding.rest[vi]);
            let old = embedding.bindings[vi];
            let found = match old {
                Binding::Inside(_) => {
                    holding(&grid, &alive, &p).map(|(t, w)| (Binding::Inside(t), w))
                }
                // The same face, if still on the boundary with the vertex beyond it (a
                // subdivision may have given the tet's key to another sub-tet).
                Binding::Outside {
                    tet,
                    face,
                    distance,
                } => mesh
                    .tet(tet)
                    .filter(|t| change.faces.neighbour(tet, t, face as usize).is_none())
                    .map(|t| barycentric(&mesh.tet_points(t), &p))
                    .filter(|w| w[face as usize] <= INSIDE_TOLERANCE)
                    .map(|w| {
                        (
                            Binding::Outside {
                                tet,
                                face,
                                distance,
                            },
                            w,
                        )
                    }),
            };
            let found = found.or_else(|| {
                if near.as_ref().is_none_or(|(t, _)| *t != old.tet()) {
                    near = Some((old.tet(), self.candidates(embedding.nodes[vi], change)));
                }
                let faces = &near.as_ref().expect("just made").1;
                nearest_on_side(faces, &p, side_of(change.sweep, &p), mesh)
            });
            match found {
                Some((binding, w)) => {
                    let t = mesh.tet(binding.tet()).expect("a tet of the cut mesh");
                    embedding.nodes[vi] = t.nodes.map(|k| self.dense[k]);
                    embedding.weights[vi] = w;
                    embedding.bindings[vi] = binding;
                    self.by_tet.entry(binding.tet()).or_default().push(v);
                }
                None => {
                    embedding.dropped[vi] = true;
                    embedding.weights[vi] = [0.0; 4];
                    out.dropped += 1;
                }
            }
        }
        out.vertices = affected;
        out.vertices.sort_unstable();
        out.seconds = start.elapsed().as_secs_f64();
        out
    }

    /// The boundary faces of the tets within two rings of the nodes `corners` (dense; a
    /// carved tet's), each with the side of the sweep its centroid lies on.
    fn candidates(&self, corners: [u32; 4], change: &CutChange) -> Vec<Candidate> {
        let (mesh, faces) = (change.mesh, change.faces);
        let mut ring: FxHashSet<TetKey> = FxHashSet::default();
        for i in corners {
            ring.extend(faces.tets_at(self.keys[i as usize]));
        }
        let first: Vec<TetKey> = ring.iter().copied().collect();
        for t in first {
            for n in mesh.tet(t).expect("a tet at a node").nodes {
                ring.extend(faces.tets_at(n));
            }
        }
        let mut ring: Vec<TetKey> = ring.into_iter().collect();
        // Ties go the same way every run.
        ring.sort_unstable();
        let mut out = Vec::new();
        for t in ring {
            let tet = mesh.tet(t).expect("a tet at a node");
            for (local, corners) in TET_FACES.iter().enumerate() {
                if faces.neighbour(t, tet, local).is_some() {
                    continue;
                }
                let points = corners.map(|i| mesh.rest(tet.nodes[i]));
                let centre =
                    Point3::from((points[0].coords + points[1].coords + points[2].coords) / 3.0);
                out.push(Candidate {
                    tet: t,
                    face: local as u8,
                    points,
                    side: side_of(change.sweep, &centre),
                });
            }
        }
        out
    }
}

/// A boundary face a carved vertex may be bound to.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    tet: TetKey,
    face: u8,
    points: [Point3<f64>; 3],
    /// The side of the sweep its centroid lies on.
    side: bool,
}

/// The outside binding of `p` to the nearest of `faces` on `side`.
fn nearest_on_side(
    faces: &[Candidate],
    p: &Point3<f64>,
    side: bool,
    mesh: &TetMesh,
) -> Option<(Binding, [f64; 4])> {
    let mut best: Option<(f64, &Candidate)> = None;
    for c in faces.iter().filter(|c| c.side == side) {
        let [a, b, d] = &c.points;
        let dist = (closest_on_triangle(p, a, b, d) - p).norm();
        if best.is_none_or(|b| dist < b.0) {
            best = Some((dist, c));
        }
    }
    let (distance, c) = best?;
    let w = barycentric(&mesh.tet_points(mesh.tet(c.tet)?), p);
    Some((
        Binding::Outside {
            tet: c.tet,
            face: c.face,
            distance,
        },
        w,
    ))
}

/// The tet among `alive` holding `p` (the one whose smallest weight is largest), with `p`'s
/// weights in it.
fn holding(
    grid: &Grid,
    alive: &[(TetKey, [Point3<f64>; 4])],
    p: &Point3<f64>,
) -> Option<(TetKey, [f64; 4])> {
    let min4 = |w: &[f64; 4]| w.iter().copied().fold(f64::INFINITY, f64::min);
    grid.at(p.coords.into())
        .iter()
        .map(|&i| (alive[i as usize].0, barycentric(&alive[i as usize].1, p)))
        .filter(|(_, w)| w.iter().all(|&w| w >= -INSIDE_TOLERANCE))
        .max_by(|a, b| min4(&a.1).total_cmp(&min4(&b.1)).then(b.0.cmp(&a.0)))
}

/// Which side of `sweep` `p` lies on: that of its nearest sweep triangle's plane (the sweep's
/// normals all point to the blade's +y side); a point on it counts as on the + side.
pub fn side_of(sweep: &Sweep, p: &Point3<f64>) -> bool {
    let nearest = sweep
        .triangles
        .iter()
        .map(|t| {
            (
                t,
                (closest_on_triangle(p, &t[0], &t[1], &t[2]) - p).norm_squared(),
            )
        })
        .min_by(|a, b| a.1.total_cmp(&b.1));
    match nearest {
        Some((t, _)) => (t[1] - t[0]).cross(&(t[2] - t[0])).dot(&(p - t[0])) >= 0.0,
        None => true,
    }
}
