//! The tets of a packed model with their region's material: what the finite-element force
//! models ([`crate::physics::TensorMass`], [`crate::physics::Corotational`]) are built from,
//! and where each is in the model's array, by its corners, so that a diff
//! ([`super::ModelDiff::removed_tets`]) can name the tets it removes.

use rustc_hash::FxHashMap;

use super::material::Material;

/// A tet in dense form, with the material of its region.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PackedTet {
    /// Dense node indices of its four corners, positively oriented (as the mesh keeps them).
    pub nodes: [u32; 4],
    /// Its region tag (0 where the mesh has none), for messages.
    pub region: i32,
    /// The material of its region: a finite-element model reads Young's modulus and Poisson's
    /// ratio from [`super::Stiffness::Material`] and Rayleigh's `beta` from
    /// [`super::SpringDamping::StiffnessProportional`].
    pub material: Material,
}

/// A tet's corners as a set: ascending. Two tets of a conforming mesh never share all four
/// corners, so this names a tet whatever order its corners are listed in.
pub fn corner_set(nodes: [u32; 4]) -> [u32; 4] {
    let mut c = nodes;
    c.sort_unstable();
    c
}

/// Where each tet is in a model's array, by [`corner_set`]. Checked at every lookup against
/// the array (which is public and may be edited in place): a stale entry rebuilds the index.
#[derive(Clone, Default)]
pub(crate) struct TetIndex {
    at: FxHashMap<[u32; 4], u32>,
}

impl std::fmt::Debug for TetIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "TetIndex({} tets)", self.at.len())
    }
}

impl PartialEq for TetIndex {
    /// Always: the index follows from the tets, which the model compares.
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl TetIndex {
    /// The index of `tets` as they lie.
    pub(crate) fn of(tets: &[PackedTet]) -> Self {
        TetIndex {
            at: tets
                .iter()
                .enumerate()
                .map(|(i, t)| (corner_set(t.nodes), i as u32))
                .collect(),
        }
    }

    /// Rebuild the index if it holds another number of tets than `tets` (the array was
    /// edited by hand); [`TetIndex::get`] finds an entry edited in place.
    pub(crate) fn refresh(&mut self, tets: &[PackedTet]) {
        if self.at.len() != tets.len() {
            *self = Self::of(tets);
        }
    }

    /// Where the tet with corners `nodes` (any order) is.
    pub(crate) fn get(&self, tets: &[PackedTet], nodes: [u32; 4]) -> Option<usize> {
        let key = corner_set(nodes);
        let i = *self.at.get(&key)? as usize;
        (tets.get(i).map(|t| corner_set(t.nodes)) == Some(key)).then_some(i)
    }

    /// Remove the tet at `i`, moving the last tet into its place (as `Vec::swap_remove`).
    pub(crate) fn swap_remove(&mut self, tets: &mut Vec<PackedTet>, i: usize) {
        self.at.remove(&corner_set(tets[i].nodes));
        tets.swap_remove(i);
        if let Some(moved) = tets.get(i) {
            self.at.insert(corner_set(moved.nodes), i as u32);
        }
    }

    /// Append `tet`.
    pub(crate) fn push(&mut self, tets: &mut Vec<PackedTet>, tet: PackedTet) {
        self.at.insert(corner_set(tet.nodes), tets.len() as u32);
        tets.push(tet);
    }
}
