//! The constant-strain (linear) tetrahedron of isotropic linear elasticity: each tet's 12x12
//! stiffness as 4x4 blocks of 3x3, the shape-function gradients that give its deformation
//! gradient, and the per-node Gershgorin sums a stable time step is bounded with.
//!
//! With `b_a` the (constant) gradient of the linear shape function of corner `a` at rest,
//! `V` the rest volume and the Lamé constants `lambda = E nu / ((1 + nu) (1 - 2 nu))`,
//! `mu = E / (2 (1 + nu))`, the block coupling corners `a` and `b` is
//!
//! ```text
//! K_ab = V (lambda b_a b_b^T + mu b_b b_a^T + mu (b_a . b_b) I)
//! ```
//!
//! so that `1/2 u^T K u = V (mu eps:eps + lambda/2 tr(eps)^2)` for the tet's constant strain
//! `eps = sym(sum_a u_a b_a^T)` (Zienkiewicz and Taylor, "The Finite Element Method", vol. 1,
//! chapter 6). `K_ba = K_ab^T`, and each block row sums to zero (`sum_a b_a = 0`): a translation
//! stores no energy, nor does an infinitesimal rotation.

use super::force_model::{Mat3, Vec3};
use crate::error::{Error, Result};
use crate::model::{PackedTet, SpringDamping, Stiffness};
use nalgebra::{Matrix3, Vector3};

/// The Lamé constants `(lambda, mu)`, Pa, of Young's modulus `e` (Pa) and Poisson's ratio
/// `nu`.
pub fn lame(e: f64, nu: f64) -> (f64, f64) {
    (
        e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
        e / (2.0 * (1.0 + nu)),
    )
}

/// One tet of a finite-element model, with everything its force needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TetElement {
    /// Dense node indices of its corners.
    pub nodes: [u32; 4],
    /// Rest positions of its corners, m.
    pub rest: [Vec3; 4],
    /// Gradients of the corners' linear shape functions at rest, 1/m (they sum to zero).
    pub gradients: [Vec3; 4],
    /// Rest volume, m^3.
    pub volume: f64,
    /// The 12x12 stiffness as blocks: `stiffness[a][b]` is `K_ab`, N/m.
    pub stiffness: [[Mat3; 4]; 4],
    /// Rayleigh's stiffness-proportional damping `beta`, s: the element's damping matrix is
    /// `beta K`.
    pub beta: f64,
    /// The Lamé constants `(lambda, mu)` of its material, Pa (what the GPU's per-tet pass
    /// computes the stress from, instead of storing `stiffness`).
    pub lame: (f64, f64),
}

/// The element stiffness of a tet with corners `p`, Young's modulus `e` and Poisson's ratio
/// `nu`, with its shape-function gradients and volume; `None` where the tet has no volume.
pub fn element_stiffness(
    p: &[Vec3; 4],
    e: f64,
    nu: f64,
) -> Option<([[Mat3; 4]; 4], [Vec3; 4], f64)> {
    let column = |k: usize| Vector3::from([0, 1, 2].map(|c| p[k][c] - p[0][c]));
    let dm = Matrix3::from_columns(&[column(1), column(2), column(3)]);
    let volume = dm.determinant() / 6.0;
    let inverse = dm
        .try_inverse()
        .filter(|_| volume > 0.0 && volume.is_finite())?;
    // Row k of Dm^-1 is the gradient of corner k+1's shape function; corner 0's is minus
    // their sum.
    let mut gradients = [[0.0; 3]; 4];
    for k in 0..3 {
        let row = [inverse[(k, 0)], inverse[(k, 1)], inverse[(k, 2)]];
        gradients[k + 1] = row;
        for (g, r) in gradients[0].iter_mut().zip(row) {
            *g -= r;
        }
    }
    let (lambda, mu) = lame(e, nu);
    let mut k = [[[[0.0; 3]; 3]; 4]; 4];
    for a in 0..4 {
        for b in 0..4 {
            let (ga, gb) = (gradients[a], gradients[b]);
            let dot = ga[0] * gb[0] + ga[1] * gb[1] + ga[2] * gb[2];
            for i in 0..3 {
                for j in 0..3 {
                    let identity = if i == j { dot } else { 0.0 };
                    k[a][b][i][j] =
                        volume * (lambda * ga[i] * gb[j] + mu * (ga[j] * gb[i] + identity));
                }
            }
        }
    }
    Some((k, gradients, volume))
}

impl TetElement {
    /// The element of tet `tet` (the `index`-th of its model, for messages) on the rest
    /// positions `rest`. Its region's material must be a continuum one (Young's modulus and
    /// Poisson's ratio), its damping none or stiffness-proportional (Rayleigh's `beta`), its
    /// corners distinct nodes of `rest` spanning a positive volume.
    pub fn new(rest: &[Vec3], tet: &PackedTet, index: usize) -> Result<Self> {
        let what = format!("tet {index} (region {})", tet.region);
        let (e, nu) = match tet.material.stiffness {
            Stiffness::Material {
                youngs_modulus,
                poisson_ratio,
                ..
            } => (youngs_modulus, poisson_ratio),
            Stiffness::Spring(_) => {
                return Err(Error::Model(format!(
                    "{what}: its material gives a spring stiffness, which a finite-element \
                     model cannot use; give the region Material(youngs_modulus, poisson_ratio)"
                )))
            }
        };
        tet.material
            .validate()
            .map_err(|err| Error::Model(format!("{what}: {err}")))?;
        let beta = match tet.material.damping {
            SpringDamping::None => 0.0,
            SpringDamping::StiffnessProportional(beta) => beta,
            SpringDamping::Absolute(_) => {
                return Err(Error::Model(format!(
                    "{what}: damping Absolute (N s/m per spring) has no finite-element meaning; \
                     give StiffnessProportional(beta) (Rayleigh) and the model's mass_damping"
                )))
            }
        };
        if let Some(&n) = tet.nodes.iter().find(|&&n| n as usize >= rest.len()) {
            return Err(Error::NodeOutOfRange {
                node: n as u64,
                count: rest.len(),
                message: format!(
                    "{what} names node {n}, but the model has {} nodes",
                    rest.len()
                ),
            });
        }
        let p = tet.nodes.map(|n| rest[n as usize]);
        let (stiffness, gradients, volume) = element_stiffness(&p, e, nu).ok_or_else(|| {
            Error::Model(format!(
                "{what} has no positive rest volume (corners {:?}): remove or reorient it",
                tet.nodes
            ))
        })?;
        Ok(TetElement {
            nodes: tet.nodes,
            rest: p,
            gradients,
            volume,
            stiffness,
            beta,
            lame: lame(e, nu),
        })
    }

    /// The elements of every tet of a model, or the first one's error. A model without tets
    /// (made from springs alone) is an error: a finite-element model needs them.
    pub fn all(rest: &[Vec3], tets: &[PackedTet]) -> Result<Vec<Self>> {
        if tets.is_empty() {
            return Err(Error::Model(
                "the model has no tets: a finite-element force model needs a model packed from \
                 a tet mesh (SpringModel::pack)"
                    .into(),
            ));
        }
        tets.iter()
            .enumerate()
            .map(|(i, t)| Self::new(rest, t, i))
            .collect()
    }

    /// The deformation gradient `F = sum_a x_a b_a^T` at positions `x` (the tet's rest shape
    /// maps to its current one by `F`, up to a translation).
    pub fn deformation_gradient(&self, x: &[Vec3]) -> Matrix3<f64> {
        let mut f = Matrix3::zeros();
        for a in 0..4 {
            let (p, g) = (x[self.nodes[a] as usize], self.gradients[a]);
            for i in 0..3 {
                for j in 0..3 {
                    f[(i, j)] += p[i] * g[j];
                }
            }
        }
        f
    }
}

/// The spectral norm (largest singular value) of a 3x3 block.
pub fn spectral_norm(m: &Mat3) -> f64 {
    Matrix3::from_fn(|i, j| m[i][j]).singular_values().max()
}

/// Per-node Gershgorin sums of the elements' stiffness and damping: node `i` gets
/// `sum_e sum_b |K_e,ib|_2` and the same times each element's `beta`. A bound on each block row
/// of the assembled `K` (by the triangle inequality), and one that holds for every rotation of
/// the elements (a rotated block `R K R^T` has the same norm), so it bounds the corotational
/// stiffness in any state as well as the linear one.
pub fn gershgorin_rows(elements: &[TetElement], nodes: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut k, mut c) = (vec![0.0; nodes], vec![0.0; nodes]);
    for e in elements {
        for a in 0..4 {
            let row: f64 = e.stiffness[a].iter().map(spectral_norm).sum();
            k[e.nodes[a] as usize] += row;
            c[e.nodes[a] as usize] += e.beta * row;
        }
    }
    (k, c)
}
