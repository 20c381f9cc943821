//! Derived connectivity: unique edges, tet-face adjacency, the boundary surface and connected
//! components.

use std::collections::HashMap;

use petgraph::unionfind::UnionFind;
use slotmap::SecondaryMap;

use super::{DenseNodes, NodeKey, TetKey, TetMesh, TET_EDGES, TET_FACES};

/// A boundary triangle: a tet face used by exactly one tet, oriented with its normal pointing out
/// of the mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoundaryFace {
    /// The tet the face belongs to.
    pub tet: TetKey,
    /// Which face of the tet (the index of the node opposite it).
    pub local: u8,
    /// The three corners, counter-clockwise seen from outside.
    pub nodes: [NodeKey; 3],
}

/// Tet-face adjacency and the boundary surface of a mesh.
#[derive(Debug, Clone)]
pub struct Topology {
    /// For each tet, the neighbour across each of its four faces (face `i` is opposite node `i`),
    /// `None` where the face is on the boundary.
    pub neighbours: SecondaryMap<TetKey, [Option<TetKey>; 4]>,
    /// The boundary faces, outward oriented, in tet storage order.
    pub boundary: Vec<BoundaryFace>,
    /// Faces shared by more than two tets (a non-manifold mesh); empty for a valid mesh.
    pub non_manifold_faces: usize,
}

/// Sorted node triple identifying a face regardless of orientation. Three compare-exchanges:
/// `slice::sort` on three keys costs more than the lookups it serves, and a cut names every
/// face of every tet it touches this way.
pub fn face_id([mut a, mut b, mut c]: [NodeKey; 3]) -> [NodeKey; 3] {
    if a > b {
        std::mem::swap(&mut a, &mut b);
    }
    if b > c {
        std::mem::swap(&mut b, &mut c);
    }
    if a > b {
        std::mem::swap(&mut a, &mut b);
    }
    [a, b, c]
}

impl Topology {
    /// Compute adjacency and the boundary of `mesh`.
    pub fn of(mesh: &TetMesh) -> Self {
        let mut faces: HashMap<[NodeKey; 3], (TetKey, u8, u32)> =
            HashMap::with_capacity(mesh.tet_count() * 2);
        let mut neighbours: SecondaryMap<TetKey, [Option<TetKey>; 4]> =
            SecondaryMap::with_capacity(mesh.tet_count());
        let mut non_manifold = 0;
        for (tk, _) in mesh.tets() {
            neighbours.insert(tk, [None; 4]);
        }
        for (tk, tet) in mesh.tets() {
            for (f, local) in TET_FACES.iter().enumerate() {
                let id = face_id(local.map(|i| tet.nodes[i]));
                match faces.get_mut(&id) {
                    None => {
                        faces.insert(id, (tk, f as u8, 1));
                    }
                    Some(entry) => {
                        entry.2 += 1;
                        if entry.2 == 2 {
                            let (other, of, _) = *entry;
                            neighbours[tk][f] = Some(other);
                            neighbours[other][of as usize] = Some(tk);
                        } else {
                            non_manifold += 1;
                        }
                    }
                }
            }
        }
        let mut boundary = Vec::new();
        for (tk, tet) in mesh.tets() {
            for (f, local) in TET_FACES.iter().enumerate() {
                if neighbours[tk][f].is_none() {
                    let id = face_id(local.map(|i| tet.nodes[i]));
                    // A face seen three times has no neighbour recorded for the third tet but is
                    // not on the boundary.
                    if faces[&id].2 == 1 {
                        boundary.push(BoundaryFace {
                            tet: tk,
                            local: f as u8,
                            nodes: local.map(|i| tet.nodes[i]),
                        });
                    }
                }
            }
        }
        Topology {
            neighbours,
            boundary,
            non_manifold_faces: non_manifold,
        }
    }

    /// Volume enclosed by the boundary surface (divergence theorem). Equals the tet volume for a
    /// closed, outward-oriented surface.
    pub fn enclosed_volume(&self, mesh: &TetMesh) -> f64 {
        self.boundary
            .iter()
            .map(|f| {
                let [a, b, c] = f.nodes.map(|k| mesh.rest(k).coords);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }
}

/// Unique tet edges as sorted dense index pairs.
pub(crate) fn unique_edges(mesh: &TetMesh, dense: &DenseNodes) -> Vec<[u32; 2]> {
    let mut edges: Vec<[u32; 2]> = Vec::with_capacity(mesh.tet_count() * 6);
    for (_, tet) in mesh.tets() {
        for [a, b] in TET_EDGES {
            let (i, j) = (dense.index[tet.nodes[a]], dense.index[tet.nodes[b]]);
            edges.push([i.min(j), i.max(j)]);
        }
    }
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// Connected components: groups of nodes joined through tets (two tets sharing only a node are
/// connected, since springs meet there). Returns for each tet the component it belongs to,
/// numbered `0..count` in order of first appearance, and the count.
pub fn components(mesh: &TetMesh) -> (SecondaryMap<TetKey, u32>, usize) {
    let dense = mesh.dense_nodes();
    let mut uf = UnionFind::<u32>::new(mesh.node_count());
    for (_, tet) in mesh.tets() {
        let i0 = dense.index[tet.nodes[0]];
        for &n in &tet.nodes[1..] {
            uf.union(i0, dense.index[n]);
        }
    }
    let mut label: HashMap<u32, u32> = HashMap::new();
    let mut of_tet = SecondaryMap::with_capacity(mesh.tet_count());
    for (tk, tet) in mesh.tets() {
        let root = uf.find(dense.index[tet.nodes[0]]);
        let next = label.len() as u32;
        let c = *label.entry(root).or_insert(next);
        of_tet.insert(tk, c);
    }
    let count = label.len();
    (of_tet, count)
}

impl TetMesh {
    /// Tet-face adjacency and the outward boundary surface.
    pub fn topology(&self) -> Topology {
        Topology::of(self)
    }

    /// Number of connected components (see [`components`]).
    pub fn component_count(&self) -> usize {
        components(self).1
    }
}
