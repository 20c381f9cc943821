//! Tet-face adjacency kept up to date through cuts: which tets use each face, which tets meet
//! at each node, and the boundary surface. A cut touches a few tets; only their faces are
//! re-examined, so the boundary is updated incrementally instead of recomputed.
//!
//! Whatever is iterated is sorted by face id first, so the same history of edits gives the same
//! boundary in the same order (bit-identical runs).
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
    face_of(&tet.nodes, local)
}

/// The face id of local face `local` of a tet with corners `nodes`.
fn face_of(nodes: &[NodeKey; 4], local: usize) -> FaceId {
    crate::mesh::topology::face_id(TET_FACES[local].map(|i| nodes[i]))
}

/// The tets using one face, as the index finds them: none, one (a boundary face), two (an
/// inner face) or, in a non-manifold mesh, three (it stops counting there).
#[derive(Debug, Clone, Copy, Default)]
struct Users {
    tets: [Option<TetKey>; 3],
    count: usize,
}

impl Users {
    fn push(&mut self, t: TetKey) {
        if self.count < 3 {
            self.tets[self.count] = Some(t);
        }
        self.count += 1;
    }

    fn iter(&self) -> impl Iterator<Item = TetKey> + '_ {
        self.tets.iter().flatten().copied()
    }

    /// The user other than `tk` of an inner face.
    fn other_than(&self, tk: TetKey) -> Option<TetKey> {
        (self.count == 2).then(|| self.iter().find(|&t| t != tk).unwrap_or(tk))
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
///
/// Each indexed tet keeps the tet across each of its faces, as tet meshes usually do; there is
/// no table of faces. A face's tets are found from its corners' (sorted) tet lists when a tet
/// is inserted, and linked both ways. A face table would cost tens of bytes per face of the
/// whole mesh and, hashed, a pause of milliseconds whenever a cut grew it past its capacity
/// (it rehashes every face).
#[derive(Debug, Clone, Default)]
pub struct FaceIndex {
    /// The tets at each node, in key order.
    node_tets: SecondaryMap<NodeKey, Vec<TetKey>>,
    /// Each indexed tet: its corners as indexed and the tet across each local face.
    tets: SecondaryMap<TetKey, Indexed>,
    boundary_faces: usize,
    /// Each face touched since the journal was last taken, with its boundary triangle before
    /// the first touch (`None`: it was not on the boundary).
    journal: FxHashMap<FaceId, Option<[NodeKey; 3]>>,
}

/// An indexed tet.
#[derive(Debug, Clone, Copy)]
struct Indexed {
    nodes: [NodeKey; 4],
    /// The tet across local face `i` (opposite corner `i`), if the face is inside.
    across: [Option<TetKey>; 4],
}

impl Indexed {
    /// Local face `local` as an outward boundary triangle.
    fn triangle(&self, local: usize) -> [NodeKey; 3] {
        TET_FACES[local].map(|i| self.nodes[i])
    }
}

/// The error for a face of more than two tets: the face's corners and the tets, numbered as
/// in `mesh` (a pass over the mesh, on this error only). A tet not in `mesh` is left out.
fn crowded(mesh: &TetMesh, face: FaceId, tets: impl Iterator<Item = TetKey>) -> Error {
    let dense = mesh.dense_nodes();
    let order: FxHashMap<TetKey, usize> =
        mesh.tets().enumerate().map(|(i, (k, _))| (k, i)).collect();
    let mut tets: Vec<usize> = tets.filter_map(|t| order.get(&t).copied()).collect();
    tets.sort_unstable();
    tets.dedup();
    Error::NonManifold {
        face: face.map(|n| dense.index.get(n).map_or(usize::MAX, |&i| i as usize)),
        tets,
    }
}

impl FaceIndex {
    /// Index `mesh`. Fails on a face shared by more than two tets (a non-manifold mesh cannot be
    /// cut consistently).
    pub fn of(mesh: &TetMesh) -> Result<Self> {
        let mut index = FaceIndex::default();
        for (tk, tet) in mesh.tets() {
            index.insert(tk, tet, mesh)?;
        }
        // Not `clear`: that keeps room for every face of the mesh, and each take would scan
        // and reset all of it (tens of microseconds a cut on a 100k-tet mesh).
        index.journal = FxHashMap::default();
        Ok(index)
    }

    /// The tets indexed with all three corners of `id`.
    fn users(&self, id: &FaceId) -> Users {
        let mut users = Users::default();
        let lists = id.map(|n| self.tets_at(n));
        let Some(shortest) = (0..3).min_by_key(|&i| lists[i].len()) else {
            return users;
        };
        for &t in lists[shortest] {
            if (0..3).all(|i| i == shortest || lists[i].binary_search(&t).is_ok()) {
                users.push(t);
            }
        }
        users
    }

    /// The boundary triangle of face `id` (outward, as its one tet orients it), if it is on
    /// the boundary.
    fn boundary_triangle(&self, id: &FaceId) -> Option<[NodeKey; 3]> {
        let users = self.users(id);
        if users.count != 1 {
            return None;
        }
        let t = self.tets.get(users.iter().next()?)?;
        Some(t.triangle(local_face(&t.nodes, id)?))
    }

    /// Add a tet's faces and incidences. A face that would have a third tet is refused, naming
    /// the face and its tets as numbered in `mesh` (the mesh the tets are in).
    pub fn insert(&mut self, tk: TetKey, tet: &Tet, mesh: &TetMesh) -> Result<()> {
        debug_assert!(
            !self.tets.contains_key(tk),
            "a tet is indexed twice; remove it first"
        );
        let ids: [FaceId; 4] = std::array::from_fn(|local| face_id(tet, local));
        let users = ids.map(|id| self.users(&id));
        if let Some(l) = users.iter().position(|u| u.count >= 2) {
            return Err(crowded(mesh, ids[l], users[l].iter().chain([tk])));
        }
        let mut me = Indexed {
            nodes: tet.nodes,
            across: [None; 4],
        };
        for (local, (id, u)) in ids.iter().zip(&users).enumerate() {
            let other = u.iter().next();
            let link = other.and_then(|o| {
                let t = self.tets.get(o)?;
                Some((o, local_face(&t.nodes, id)?))
            });
            let before = link.map(|(o, l)| self.tets[o].triangle(l));
            self.note(*id, before);
            match link {
                Some((o, l)) => {
                    self.tets[o].across[l] = Some(tk);
                    me.across[local] = Some(o);
                    self.boundary_faces -= 1;
                }
                None => self.boundary_faces += 1,
            }
        }
        for &n in &tet.nodes {
            if let Some(e) = self.node_tets.entry(n) {
                let v = e.or_default();
                let at = v.partition_point(|t| *t < tk);
                v.insert(at, tk);
            }
        }
        self.tets.insert(tk, me);
        Ok(())
    }

    /// Remove a tet's faces and incidences (as they were indexed; a tet not indexed changes
    /// nothing). The faces it shared come back on the boundary, oriented by the tet left
    /// holding them.
    pub fn remove(&mut self, tk: TetKey) {
        let Some(me) = self.tets.remove(tk) else {
            return;
        };
        for local in 0..4 {
            let id = face_of(&me.nodes, local);
            match me.across[local] {
                Some(o) => {
                    self.note(id, None);
                    if let Some(l) = self.tets.get(o).and_then(|t| local_face(&t.nodes, &id)) {
                        self.tets[o].across[l] = None;
                    }
                    self.boundary_faces += 1;
                }
                None => {
                    self.note(id, Some(me.triangle(local)));
                    self.boundary_faces -= 1;
                }
            }
        }
        for &n in &me.nodes {
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
        match self.tets.get(tk) {
            Some(t) if t.nodes == tet.nodes => t.across[local],
            // Asked with other corners than indexed (mid-edit): find the face's tets.
            _ => self.users(&face_id(tet, local)).other_than(tk),
        }
    }

    /// The tets using `face` (none, one or two).
    pub fn tets_of_face(&self, face: &FaceId) -> Vec<TetKey> {
        self.users(face).iter().collect()
    }

    /// The tets at a node, in key order (empty for a node no tet uses).
    pub fn tets_at(&self, n: NodeKey) -> &[TetKey] {
        self.node_tets.get(n).map_or(&[], |v| v.as_slice())
    }

    /// The boundary faces as (tet, local face), in face-id order (found and sorted on each
    /// call: for building a surface or checking one, not for every cut).
    pub fn boundary(&self) -> Vec<(TetKey, u8)> {
        let mut faces: Vec<(FaceId, TetKey, u8)> = Vec::with_capacity(self.boundary_faces);
        for (tk, t) in &self.tets {
            for local in (0..4).filter(|&l| t.across[l].is_none()) {
                faces.push((face_of(&t.nodes, local), tk, local as u8));
            }
        }
        faces.sort_unstable_by_key(|f| f.0);
        faces.into_iter().map(|(_, t, l)| (t, l)).collect()
    }

    /// Record the boundary state of `id` (`before`) if it is its first change since the last
    /// take.
    fn note(&mut self, id: FaceId, before: Option<[NodeKey; 3]>) {
        self.journal.entry(id).or_insert(before);
    }

    /// The boundary triangles removed and added since the last call (or since the index was
    /// built), in face-id order; the journal is emptied.
    pub fn take_boundary_changes(&mut self) -> BoundaryChanges {
        let mut changes = BoundaryChanges::default();
        let mut journal: Vec<_> = self.journal.drain().collect();
        // A drain scans and resets the table's whole capacity: after an edit far larger than
        // usual (a cut through a whole organ), give the room back rather than pay for it at
        // every later cut.
        if self.journal.capacity() > 4 * journal.len().max(1024) {
            self.journal.shrink_to(journal.len());
        }
        journal.sort_unstable_by_key(|(id, _)| *id);
        for (id, before) in journal {
            let after = self.boundary_triangle(&id);
            if before != after {
                changes.removed.extend(before);
                changes.added.extend(after);
            }
        }
        changes
    }

    /// Number of boundary faces.
    pub fn boundary_len(&self) -> usize {
        self.boundary_faces
    }

    /// Number of faces.
    pub fn face_count(&self) -> usize {
        (4 * self.tets.len() + self.boundary_faces) / 2
    }
}

/// The local face of a tet with corners `nodes` whose corners are `id`: the one opposite the
/// corner not in `id`.
fn local_face(nodes: &[NodeKey; 4], id: &FaceId) -> Option<usize> {
    let mut opposite = (0..4).filter(|&i| !id.contains(&nodes[i]));
    let first = opposite.next()?;
    opposite.next().is_none().then_some(first)
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

    /// Everything the index answers, worked out from scratch from the tets indexed.
    fn check_against_brute_force(index: &FaceIndex, tets: &[(TetKey, Tet)]) {
        let mut users: std::collections::BTreeMap<FaceId, Vec<(TetKey, usize)>> =
            Default::default();
        for (tk, tet) in tets {
            for local in 0..4 {
                users
                    .entry(face_id(tet, local))
                    .or_default()
                    .push((*tk, local));
            }
        }
        for (tk, tet) in tets {
            for local in 0..4 {
                let id = face_id(tet, local);
                let want = users[&id].iter().find(|u| u.0 != *tk).map(|u| u.0);
                assert_eq!(index.neighbour(*tk, tet, local), want);
                let mut of_face = index.tets_of_face(&id);
                of_face.sort();
                let mut all: Vec<TetKey> = users[&id].iter().map(|u| u.0).collect();
                all.sort();
                assert_eq!(of_face, all);
            }
        }
        let boundary: Vec<(TetKey, u8)> = users
            .values()
            .filter(|u| u.len() == 1)
            .map(|u| (u[0].0, u[0].1 as u8))
            .collect();
        assert_eq!(index.boundary(), boundary, "boundary in face-id order");
        assert_eq!(index.boundary_len(), boundary.len());
        assert_eq!(index.face_count(), users.len());
    }

    /// Tets taken out and put back in a shuffled order: after every change the adjacency, the
    /// boundary and its journal agree with a recomputation from the tets indexed.
    #[test]
    fn the_index_follows_removals_and_insertions_exactly() {
        let mesh = crate::mesh::generate::BoxGrid::cube_cells([3, 3, 2], 1.0)
            .build()
            .expect("a box");
        let mut index = FaceIndex::of(&mesh).expect("a manifold box");
        let all: Vec<(TetKey, Tet)> = mesh.tets().map(|(k, t)| (k, *t)).collect();
        let mut indexed = all.clone();
        check_against_brute_force(&index, &indexed);
        let triangles = |index: &FaceIndex, tets: &[(TetKey, Tet)]| {
            let mut v: Vec<[NodeKey; 3]> = index
                .boundary()
                .into_iter()
                .map(|(tk, l)| {
                    let t = tets.iter().find(|(k, _)| *k == tk).expect("indexed").1;
                    TET_FACES[l as usize].map(|i| t.nodes[i])
                })
                .collect();
            v.sort();
            v
        };
        let mut surface = triangles(&index, &indexed);
        // A fixed pseudo-random order (a multiplicative step coprime to the count).
        let n = all.len();
        let order: Vec<usize> = (0..n).map(|i| (i * 37 + 11) % n).collect();
        let mut out = Vec::new();
        for (step, &i) in order.iter().enumerate() {
            let (tk, _) = all[i];
            index.remove(tk);
            indexed.retain(|(k, _)| *k != tk);
            out.push(all[i]);
            if step % 3 == 2 {
                // Put one back from the middle of what is out.
                let back = out.remove(out.len() / 2);
                index
                    .insert(back.0, &back.1, &mesh)
                    .expect("it fitted before");
                indexed.push(back);
            }
            check_against_brute_force(&index, &indexed);
            let changes = index.take_boundary_changes();
            for r in &changes.removed {
                let at = surface
                    .iter()
                    .position(|t| t == r)
                    .expect("a removed triangle was there");
                surface.remove(at);
            }
            surface.extend(changes.added.iter().copied());
            surface.sort();
            assert_eq!(
                surface,
                triangles(&index, &indexed),
                "journal at step {step}"
            );
        }
        assert!(indexed.is_empty() || index.boundary_len() > 0);
    }

    /// A third tet on a face is refused, and the index is left as it was.
    #[test]
    fn a_third_tet_on_a_face_is_refused_without_changing_the_index() {
        let mesh = crate::mesh::generate::BoxGrid::cube_cells([1, 1, 1], 1.0)
            .build()
            .expect("a box");
        let mut index = FaceIndex::of(&mesh).expect("a manifold box");
        let tets: Vec<(TetKey, Tet)> = mesh.tets().map(|(k, t)| (k, *t)).collect();
        // A key no tet of the mesh has: one past the mesh's slots.
        let mut keys: slotmap::SlotMap<TetKey, ()> = slotmap::SlotMap::with_key();
        let fake = (0..=tets.len())
            .map(|_| keys.insert(()))
            .last()
            .expect("a key");
        assert!(mesh.tet(fake).is_none());
        let inner = tets
            .iter()
            .find(|(k, t)| (0..4).any(|l| index.neighbour(*k, t, l).is_some()))
            .expect("the cube has inner faces");
        let (boundary, faces) = (index.boundary_len(), index.face_count());
        assert!(index.insert(fake, &inner.1, &mesh).is_err());
        assert_eq!(index.boundary_len(), boundary);
        assert_eq!(index.face_count(), faces);
        check_against_brute_force(&index, &tets);
    }
}
