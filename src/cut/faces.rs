//! Tet-face adjacency kept up to date through cuts: which tets use each face, which tets meet
//! at each node, and the boundary surface. A cut touches a few tets; only their faces are
//! re-examined, so the boundary is updated incrementally instead of recomputed.
//!
//! The maps are hashed (a cut looks faces up many times per tet it edits); whatever is iterated
//! is sorted by face id first, so the same history of edits gives the same boundary in the same
//! order (bit-identical runs).
//!
//! Boundary changes are journaled: [`FaceIndex::take_boundary_changes`] says which boundary
//! triangles a cut removed and added, so the simulation's copy of the surface (and the device's)
//! is edited in place rather than rebuilt.

use rustc_hash::FxHashMap;

use slotmap::SecondaryMap;

use crate::error::{Error, Result};
use crate::mesh::{NodeKey, Tet, TetKey, TetMesh, TET_FACES};

/// A face as its sorted node triple, the same whichever tet names it.
pub type FaceId = [NodeKey; 3];

/// The face id of local face `local` of `tet`.
pub fn face_id(tet: &Tet, local: usize) -> FaceId {
    let [mut a, mut b, mut c] = TET_FACES[local].map(|i| tet.nodes[i]);
    // Three compare-exchanges: `slice::sort` on three keys costs more than the lookups it
    // serves, and every face of every tet a cut touches is named this way.
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

/// The tets using one face (one on the boundary, two inside).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct FaceUse {
    tets: [(TetKey, u8); 2],
    count: u8,
}

/// A boundary face: the tet it belongs to, its local face, and its corners as that tet
/// orients them (outward).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct BoundaryFace {
    tet: TetKey,
    local: u8,
    corners: [NodeKey; 3],
}

impl BoundaryFace {
    fn of(tk: TetKey, tet: &Tet, local: usize) -> Self {
        BoundaryFace {
            tet: tk,
            local: local as u8,
            corners: TET_FACES[local].map(|i| tet.nodes[i]),
        }
    }
}

/// How the boundary changed since the journal was last taken: outward triangles removed and
/// added (a face whose owning tet or orientation changed is in both).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct BoundaryChanges {
    /// Triangles no longer on the boundary (as they were).
    pub removed: Vec<[NodeKey; 3]>,
    /// Triangles now on the boundary.
    pub added: Vec<[NodeKey; 3]>,
}

/// Face adjacency, node-to-tet incidence and the boundary of a mesh.
#[derive(Debug, Clone, Default)]
pub struct FaceIndex {
    faces: FxHashMap<FaceId, FaceUse>,
    boundary: FxHashMap<FaceId, BoundaryFace>,
    node_tets: SecondaryMap<NodeKey, Vec<TetKey>>,
    /// Each face touched since the journal was last taken, with its boundary triangle before
    /// the first touch (`None`: it was not on the boundary).
    journal: FxHashMap<FaceId, Option<[NodeKey; 3]>>,
}

impl FaceIndex {
    /// Index `mesh`. Fails on a face shared by more than two tets (a non-manifold mesh cannot be
    /// cut consistently).
    pub fn of(mesh: &TetMesh) -> Result<Self> {
        let mut index = FaceIndex::default();
        for (tk, tet) in mesh.tets() {
            index.insert(tk, tet)?;
        }
        index.journal.clear();
        Ok(index)
    }

    /// Add a tet's faces and incidences.
    pub fn insert(&mut self, tk: TetKey, tet: &Tet) -> Result<()> {
        for local in 0..4 {
            let id = face_id(tet, local);
            self.note(id);
            match self.faces.get_mut(&id) {
                None => {
                    self.faces.insert(
                        id,
                        FaceUse {
                            tets: [(tk, local as u8), (tk, local as u8)],
                            count: 1,
                        },
                    );
                    self.boundary.insert(id, BoundaryFace::of(tk, tet, local));
                }
                Some(u) if u.count == 1 => {
                    u.tets[1] = (tk, local as u8);
                    u.count = 2;
                    self.boundary.remove(&id);
                }
                Some(_) => {
                    return Err(Error::Mesh(
                        "a face is shared by more than two tets; a non-manifold mesh cannot be \
                         cut (repair it, e.g. with TetGen -d)"
                            .into(),
                    ))
                }
            }
        }
        for &n in &tet.nodes {
            if let Some(e) = self.node_tets.entry(n) {
                let v = e.or_default();
                let at = v.partition_point(|t| *t < tk);
                v.insert(at, tk);
            }
        }
        Ok(())
    }

    /// Remove a tet's faces and incidences (`tet` as it was when inserted). The faces it
    /// shared come back on the boundary, oriented by the tet left holding them; `mesh` gives
    /// that tet's corners.
    pub fn remove(&mut self, tk: TetKey, tet: &Tet, mesh: &TetMesh) {
        for local in 0..4 {
            let id = face_id(tet, local);
            self.note(id);
            let Some(u) = self.faces.get_mut(&id) else {
                continue;
            };
            if u.count == 2 {
                let keep = if u.tets[0].0 == tk {
                    u.tets[1]
                } else {
                    u.tets[0]
                };
                *u = FaceUse {
                    tets: [keep, keep],
                    count: 1,
                };
                let other = mesh.tet(keep.0).expect("a face's tets are in the mesh");
                self.boundary
                    .insert(id, BoundaryFace::of(keep.0, other, keep.1 as usize));
            } else {
                self.faces.remove(&id);
                self.boundary.remove(&id);
            }
        }
        for &n in &tet.nodes {
            if let Some(v) = self.node_tets.get_mut(n) {
                v.retain(|t| *t != tk);
                if v.is_empty() {
                    self.node_tets.remove(n);
                }
            }
        }
    }

    /// The tet across local face `local` of `tk` (whose nodes are `tet`), if the face is inside.
    pub fn neighbour(&self, tk: TetKey, tet: &Tet, local: usize) -> Option<TetKey> {
        let u = self.faces.get(&face_id(tet, local))?;
        (u.count == 2).then(|| {
            if u.tets[0].0 == tk {
                u.tets[1].0
            } else {
                u.tets[0].0
            }
        })
    }

    /// The tets using `face` (none, one or two).
    pub fn tets_of_face(&self, face: &FaceId) -> Vec<TetKey> {
        match self.faces.get(face) {
            None => Vec::new(),
            Some(u) => u.tets[..u.count as usize].iter().map(|t| t.0).collect(),
        }
    }

    /// The tets at a node, in key order (empty for a node no tet uses).
    pub fn tets_at(&self, n: NodeKey) -> &[TetKey] {
        self.node_tets.get(n).map_or(&[], |v| v.as_slice())
    }

    /// The boundary faces as (tet, local face), in face-id order (sorted on each call: for
    /// building a surface or checking one, not for every cut).
    pub fn boundary(&self) -> Vec<(TetKey, u8)> {
        let mut faces: Vec<(&FaceId, &BoundaryFace)> = self.boundary.iter().collect();
        faces.sort_unstable_by_key(|(id, _)| **id);
        faces.into_iter().map(|(_, b)| (b.tet, b.local)).collect()
    }

    /// Record the boundary state of `id` before its first change since the last take.
    fn note(&mut self, id: FaceId) {
        let boundary = &self.boundary;
        self.journal
            .entry(id)
            .or_insert_with(|| boundary.get(&id).map(|b| b.corners));
    }

    /// The boundary triangles removed and added since the last call (or since the index was
    /// built), in face-id order; the journal is emptied.
    pub fn take_boundary_changes(&mut self) -> BoundaryChanges {
        let mut changes = BoundaryChanges::default();
        let mut journal: Vec<_> = self.journal.drain().collect();
        journal.sort_unstable_by_key(|(id, _)| *id);
        for (id, before) in journal {
            let after = self.boundary.get(&id).map(|b| b.corners);
            if before != after {
                changes.removed.extend(before);
                changes.added.extend(after);
            }
        }
        changes
    }

    /// Number of boundary faces.
    pub fn boundary_len(&self) -> usize {
        self.boundary.len()
    }

    /// Number of faces.
    pub fn face_count(&self) -> usize {
        self.faces.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    /// Every ordering of a tet's corners names each face by the same sorted triple.
    #[test]
    fn a_face_id_is_its_corners_sorted_whatever_their_order() {
        let mut mesh = TetMesh::default();
        let keys: Vec<NodeKey> = (0..4)
            .map(|i| mesh.add_node(Point3::new(i as f64, 0.0, 0.0)))
            .collect();
        let orders: Vec<[usize; 4]> = (0..256)
            .map(|code: usize| [0, 2, 4, 6].map(|s| (code >> s) & 3))
            .filter(|o| (0..4).all(|i| o.contains(&i)))
            .collect();
        assert_eq!(orders.len(), 24);
        for order in orders {
            let tet = Tet {
                nodes: order.map(|i| keys[i]),
                region: 0,
            };
            for (local, face) in TET_FACES.iter().enumerate() {
                let mut want = face.map(|i| tet.nodes[i]);
                want.sort();
                let id = face_id(&tet, local);
                assert_eq!(id, want, "order {order:?}, face {local}");
                assert!(id[0] < id[1] && id[1] < id[2]);
            }
        }
    }
}
