//! Corotational linear elasticity: each tet's linear stiffness, applied in the tet's own
//! rotated frame, so that rigid motions store no energy.
//!
//! Each tet's rotation `R` is the rotation of the polar decomposition of its deformation
//! gradient `F = R S`. With `u~_a = R^T x_a - X_a` the corners' displacements seen in the
//! tet's frame, the element force is `f = -R K_e u~` and its energy `1/2 u~^T K_e u~` (Müller
//! and Gross, "Interactive virtual materials", GI 2004; SOFA's TetrahedronFEMForceField with
//! the polar method). Because `S = R^T F` is symmetric, that energy is the corotated
//! elasticity `V (mu |S - I|^2 + lambda/2 tr(S - I)^2)` and the force is exactly minus its
//! gradient (the terms in `dR` cancel, McAdams et al. 2011).
//!
//! The polar rotation comes from a singular value decomposition `F = U Sigma V^T`, with
//! `R = U V^T`; where `det(U V^T) < 0` (an inverted tet) the column of `U` of the smallest
//! singular value changes sign (Irving, Teran and Fedkiw, "Invertible finite elements for
//! robust simulation of large deformation", SCA 2004), so that `R` stays a rotation and the
//! force pushes the tet back through its inversion instead of flattening it further.
//!
//! The stiffness product uses `R K_e R^T`: the derivative of `R` is neglected, as SOFA
//! neglects it. That is the exact derivative at any rigid placement of an undeformed tet and
//! close to it under small strain; it is symmetric negative semi-definite, so an implicit step
//! on it is always solvable (both linearisations are the same). Damping is Rayleigh's `beta
//! R K_e R^T` per tet (and the model's mass damping, which the integrators apply).

use std::sync::Mutex;

use nalgebra::Matrix3;

use super::force_model::{axpy, dot, sub, ForceModel, Linearization, Mat3, Vec3};
use super::linear_tet::TetElement;
use crate::error::{Error, Result};
use crate::model::{corner_set, ModelDiff, PackedTet};
use rustc_hash::FxHashMap;

/// The corotational force model of a set of tets.
#[derive(Debug)]
pub struct Corotational {
    /// The elements, in the order of the model's tets (a patch moves the last into the place
    /// of each it removes, as [`crate::model::PackedModel::apply`] does).
    elements: Vec<TetElement>,
    /// Where each element is in `elements`, by its corners as a set (never iterated).
    by_corners: FxHashMap<[u32; 4], usize>,
    /// The rotations at the positions they were last computed at: an implicit solver asks
    /// for many products at the same positions, and the decompositions are most of a
    /// product's cost.
    rotations: Mutex<RotationCache>,
}

/// Rotations of every element at positions `x`.
#[derive(Debug, Default)]
struct RotationCache {
    x: Vec<Vec3>,
    r: Vec<Mat3>,
}

/// The rotation of the polar decomposition of `f`, robust to inverted and degenerate tets (see
/// the module documentation). A matrix the decomposition does not converge on (non-finite
/// entries) gives the identity: the force is then as non-finite as the positions, and the
/// simulation's divergence check reports it.
pub fn polar_rotation(f: &Matrix3<f64>) -> Matrix3<f64> {
    let Some(svd) = f.try_svd(true, true, f64::EPSILON, 200) else {
        return Matrix3::identity();
    };
    let (Some(mut u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    if (u * v_t).determinant() < 0.0 {
        let smallest = svd.singular_values.imin();
        u.column_mut(smallest).neg_mut();
    }
    u * v_t
}

fn to_mat3(m: &Matrix3<f64>) -> Mat3 {
    [0, 1, 2].map(|r| [0, 1, 2].map(|c| m[(r, c)]))
}

fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
    [0, 1, 2].map(|r| [0, 1, 2].map(|c| (0..3).map(|k| a[r][k] * b[k][c]).sum()))
}

/// `R^T v`.
fn rotate_back(r: &Mat3, v: Vec3) -> Vec3 {
    [0, 1, 2].map(|c| r[0][c] * v[0] + r[1][c] * v[1] + r[2][c] * v[2])
}

/// `R v`.
fn rotate(r: &Mat3, v: Vec3) -> Vec3 {
    [dot(r[0], v), dot(r[1], v), dot(r[2], v)]
}

impl Corotational {
    /// The model of `tets` on rest positions `rest` (see [`TetElement::new`] for what each tet
    /// must satisfy).
    pub fn new(rest: &[Vec3], tets: &[PackedTet]) -> Result<Self> {
        let elements = TetElement::all(rest, tets)?;
        Ok(Corotational {
            by_corners: elements
                .iter()
                .enumerate()
                .map(|(i, e)| (corner_set(e.nodes), i))
                .collect(),
            elements,
            rotations: Mutex::new(RotationCache::default()),
        })
    }

    /// Follow a change of the model (what a cut makes): the elements of the removed tets go
    /// (the last element taking each one's place, as the model's tets do), those of the added
    /// tets, on `rest` (every node's rest position after the change), are appended. On error
    /// (a removed tet the model does not hold, an added one that is not a valid element)
    /// nothing changes.
    pub fn patch(&mut self, rest: &[Vec3], diff: &ModelDiff) -> Result<()> {
        let mut gone = std::collections::HashSet::new();
        for &t in &diff.removed_tets {
            let key = corner_set(t);
            if !self.by_corners.contains_key(&key) || !gone.insert(key) {
                return Err(Error::DiffMismatch(format!(
                    "cannot remove tet {t:?}: the finite-element model holds no tet with those \
                     corners (or it is removed twice)"
                )));
            }
        }
        let first = self.elements.len();
        let added = diff
            .added_tets
            .iter()
            .enumerate()
            .map(|(k, t)| TetElement::new(rest, t, first + k))
            .collect::<Result<Vec<TetElement>>>()?;
        for &t in &diff.removed_tets {
            let i = self
                .by_corners
                .remove(&corner_set(t))
                .expect("checked above");
            self.elements.swap_remove(i);
            if let Some(moved) = self.elements.get(i) {
                self.by_corners.insert(corner_set(moved.nodes), i);
            }
        }
        for e in added {
            self.by_corners
                .insert(corner_set(e.nodes), self.elements.len());
            self.elements.push(e);
        }
        // The cached rotations are by element: stale now.
        let mut cache = self.rotations.lock().unwrap_or_else(|p| p.into_inner());
        *cache = RotationCache::default();
        Ok(())
    }

    /// The rotation of every element at positions `x`, computed once per positions.
    fn rotations(&self, x: &[Vec3]) -> Vec<Mat3> {
        // A poisoned lock only means another thread panicked mid-update: recompute.
        let mut cache = self.rotations.lock().unwrap_or_else(|p| p.into_inner());
        if cache.x.as_slice() != x || cache.r.len() != self.elements.len() {
            cache.r = self.elements.iter().map(|e| Self::rotation(e, x)).collect();
            cache.x.clear();
            cache.x.extend_from_slice(x);
        }
        cache.r.clone()
    }

    /// The elements.
    pub fn elements(&self) -> &[TetElement] {
        &self.elements
    }

    /// The rotation of element `e` at positions `x`.
    pub fn rotation(e: &TetElement, x: &[Vec3]) -> Mat3 {
        to_mat3(&polar_rotation(&e.deformation_gradient(x)))
    }

    /// `-R K_e R^T w` of element `e` (rotation `r`), added into `out` scaled by `s`.
    fn add_rotated_product(e: &TetElement, r: &Mat3, s: f64, w: &[Vec3], out: &mut [Vec3]) {
        let local = e.nodes.map(|n| rotate_back(r, w[n as usize]));
        Self::add_local_product(e, r, s, &local, out);
    }

    /// `-R K_e local`, added into `out` scaled by `s`.
    fn add_local_product(e: &TetElement, r: &Mat3, s: f64, local: &[Vec3; 4], out: &mut [Vec3]) {
        for a in 0..4 {
            let mut sum = [0.0; 3];
            for (block, &u) in e.stiffness[a].iter().zip(local) {
                axpy(&mut sum, 1.0, super::force_model::mat_vec(block, u));
            }
            axpy(&mut out[e.nodes[a] as usize], -s, rotate(r, sum));
        }
    }

    /// The corners' displacements in the element's frame, `R^T x_a - X_a`, each less corner
    /// 0's: `K_e` ignores a common translation, and the differences keep the rounding of a
    /// body far from the origin out of them.
    pub(crate) fn local_displacements(e: &TetElement, r: &Mat3, x: &[Vec3]) -> [Vec3; 4] {
        let origin = x[e.nodes[0] as usize];
        [0, 1, 2, 3].map(|a| {
            let p = rotate_back(r, sub(x[e.nodes[a] as usize], origin));
            [0, 1, 2].map(|c| p[c] - (e.rest[a][c] - e.rest[0][c]))
        })
    }
}

impl ForceModel for Corotational {
    fn name(&self) -> &'static str {
        "corotational"
    }

    fn add_forces(&self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        for (e, r) in self.elements.iter().zip(self.rotations(x)) {
            let u = Self::local_displacements(e, &r, x);
            Self::add_local_product(e, &r, 1.0, &u, f);
            if e.beta != 0.0 {
                Self::add_rotated_product(e, &r, e.beta, v, f);
            }
        }
    }

    fn potential_energy(&self, x: &[Vec3]) -> f64 {
        self.elements
            .iter()
            .zip(self.rotations(x))
            .map(|(e, r)| {
                let u = Self::local_displacements(e, &r, x);
                let mut energy = 0.0;
                for a in 0..4 {
                    for b in 0..4 {
                        energy +=
                            0.5 * dot(u[a], super::force_model::mat_vec(&e.stiffness[a][b], u[b]));
                    }
                }
                energy
            })
            .sum()
    }

    fn add_stiffness_product(&self, x: &[Vec3], _: Linearization, w: &[Vec3], out: &mut [Vec3]) {
        for (e, r) in self.elements.iter().zip(self.rotations(x)) {
            Self::add_rotated_product(e, &r, 1.0, w, out);
        }
    }

    fn add_damping_product(&self, x: &[Vec3], w: &[Vec3], out: &mut [Vec3]) {
        for (e, r) in self.elements.iter().zip(self.rotations(x)) {
            if e.beta != 0.0 {
                Self::add_rotated_product(e, &r, e.beta, w, out);
            }
        }
    }

    fn add_diagonal_blocks(
        &self,
        x: &[Vec3],
        _: Linearization,
        stiffness: &mut [Mat3],
        damping: &mut [Mat3],
    ) {
        for (e, r) in self.elements.iter().zip(self.rotations(x)) {
            let r_t = super::tensor_mass::transpose(&r);
            for a in 0..4 {
                let block = mul(&mul(&r, &e.stiffness[a][a]), &r_t);
                let i = e.nodes[a] as usize;
                for (row, values) in block.iter().enumerate() {
                    for (col, value) in values.iter().enumerate() {
                        stiffness[i][row][col] -= value;
                        damping[i][row][col] -= e.beta * value;
                    }
                }
            }
        }
    }
}
