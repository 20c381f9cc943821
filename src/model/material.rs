//! How spring stiffness, damping and node mass are derived, per region.
//!
//! # Stiffness from a continuum material
//!
//! Each tet `T` contributes to each of its six edges `e` a share
//!
//! ```text
//! k_e^T = C * V_T / l_e^2
//! ```
//!
//! where `V_T` is the tet's rest volume and `l_e` the edge's rest length. With `C = E` this is
//! Van Gelder's rule (A. Van Gelder, "Approximate simulation of elastic membranes by triangulated
//! spring meshes", Journal of Graphics Tools 3(2), 1998, eq. for tetrahedra). Its property that
//! we test: under a uniform dilation `x -> (1 + s) x` the springs of any tet store
//! `3 C V s^2`, while an isotropic solid stores `9/2 K V s^2` (`K` the bulk modulus), so the
//! rule reproduces the bulk modulus exactly when `C = 3K/2`. For `nu = 1/4`, `3K/2 = E`: Van
//! Gelder's rule is exact in dilation for the one Poisson ratio a central-force spring network
//! can represent (Cauchy relations). [`StiffnessRule::BulkMatched`] uses `C = 3K/2 =
//! E / (2 (1 - 2 nu))` for other ratios; it stiffens quickly as `nu -> 1/2`.
//!
//! # Mass
//!
//! Lumped: each tet gives `rho V_T / 4` to each of its nodes. With a uniform node mass `m`
//! instead, each tet gives `m / n_i` to node `i`, `n_i` being the number of tets at that node.
//!
//! Cuts conserve mass whatever the mass model: separating moves each tet's share with it to
//! the copies of its nodes, carving removes exactly the carved tets' shares, and a tet split by
//! subdividing passes its mass to its sub-tets by volume. A sub-tet of a parent holding mass
//! `M_T` in rest volume `V_T` gives `(M_T / V_T) V / 4` to each of its corners, as if the parent
//! had the density `M_T / V_T` (with a density, that is the density itself): the nodes a split
//! makes get their mass from the parent's nodes, not a new node's `m`, so after subdividing a
//! per-node model's nodes no longer all weigh `m`, but the whole still weighs what it did.
//!
//! # Damping
//!
//! Along each spring, `c_e (v_b - v_a) . u u`, with `c_e` given in N s/m per spring or as
//! `beta * k_e` (stiffness-proportional, Rayleigh's `beta` in seconds); plus a global
//! mass-proportional damping `-alpha m v` (`alpha` in 1/s, see the model configuration).

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// How the continuum stiffness constant `C` is chosen from `E` and `nu`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum StiffnessRule {
    /// `C = E` (Van Gelder 1998); exact in dilation for `nu = 1/4`, `nu` otherwise unused.
    #[default]
    VanGelder,
    /// `C = 3K/2 = E / (2 (1 - 2 nu))`: reproduces the bulk modulus for any `nu < 1/2`.
    BulkMatched,
}

/// Spring stiffness of a region.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Stiffness {
    /// From a continuum material.
    Material {
        /// Young's modulus, Pa.
        youngs_modulus: f64,
        /// Poisson ratio, in `[0, 1/2)`.
        poisson_ratio: f64,
        /// How `C` is chosen.
        #[serde(default)]
        rule: StiffnessRule,
    },
    /// Every spring of the region has this stiffness, N/m, shared equally among the tets of the
    /// region that hold the edge.
    Spring(f64),
}

/// Node mass of a region.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Mass {
    /// Density, kg/m^3: each tet gives `rho V / 4` to each of its nodes.
    Density(f64),
    /// Uniform mass per node, kg, shared equally among the tets at the node. A subdividing cut
    /// passes a split tet's mass to its sub-tets by volume (see the module documentation), so
    /// the nodes it makes take their mass from their neighbours': mass is conserved.
    PerNode(f64),
}

/// Damping along the springs of a region.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub enum SpringDamping {
    /// No damping along springs.
    #[default]
    None,
    /// Every spring has this damping coefficient, N s/m (shared like [`Stiffness::Spring`]).
    Absolute(f64),
    /// `c = beta * k`, `beta` in seconds (Rayleigh stiffness-proportional damping).
    StiffnessProportional(f64),
}

/// The mechanical parameters of one region.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Spring stiffness.
    pub stiffness: Stiffness,
    /// Node mass.
    pub mass: Mass,
    /// Damping along springs.
    #[serde(default)]
    pub damping: SpringDamping,
}

impl Material {
    /// A soft-tissue-like material: `E` in Pa, Poisson ratio, density in kg/m^3, no damping.
    pub fn elastic(youngs_modulus: f64, poisson_ratio: f64, density: f64) -> Self {
        Material {
            stiffness: Stiffness::Material {
                youngs_modulus,
                poisson_ratio,
                rule: StiffnessRule::VanGelder,
            },
            mass: Mass::Density(density),
            damping: SpringDamping::None,
        }
    }

    /// Springs of stiffness `k` N/m and nodes of mass `m` kg, no damping.
    pub fn springs(k: f64, m: f64) -> Self {
        Material {
            stiffness: Stiffness::Spring(k),
            mass: Mass::PerNode(m),
            damping: SpringDamping::None,
        }
    }

    /// The same material with damping along springs.
    pub fn with_damping(mut self, damping: SpringDamping) -> Self {
        self.damping = damping;
        self
    }

    /// Check that every parameter is finite and in range; the message says which is not.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str, v: f64| {
            Err(Error::InvalidParameter {
                name: what.into(),
                value: v,
                requirement: "be finite and positive".into(),
            })
        };
        match self.stiffness {
            Stiffness::Material {
                youngs_modulus: e,
                poisson_ratio: nu,
                ..
            } => {
                if !(e.is_finite() && e > 0.0) {
                    return bad("young's modulus", e);
                }
                if !(0.0..0.5).contains(&nu) {
                    return Err(Error::InvalidParameter {
                        name: "poisson ratio".into(),
                        value: nu,
                        requirement: "lie in [0, 0.5)".into(),
                    });
                }
            }
            Stiffness::Spring(k) if !(k.is_finite() && k > 0.0) => {
                return bad("spring stiffness", k)
            }
            Stiffness::Spring(_) => {}
        }
        match self.mass {
            Mass::Density(r) | Mass::PerNode(r) if !(r.is_finite() && r > 0.0) => {
                return bad("mass (density or per-node mass)", r)
            }
            _ => {}
        }
        match self.damping {
            SpringDamping::Absolute(c) | SpringDamping::StiffnessProportional(c)
                if !(c.is_finite() && c >= 0.0) =>
            {
                Err(Error::InvalidParameter {
                    name: "spring damping".into(),
                    value: c,
                    requirement: "be finite and not negative".into(),
                })
            }
            _ => Ok(()),
        }
    }

    /// The constant `C` of `k_e^T = C V_T / l_e^2`, for material stiffness.
    pub fn stiffness_constant(&self) -> Option<f64> {
        match self.stiffness {
            Stiffness::Material {
                youngs_modulus: e,
                poisson_ratio: nu,
                rule,
            } => Some(match rule {
                StiffnessRule::VanGelder => e,
                StiffnessRule::BulkMatched => e / (2.0 * (1.0 - 2.0 * nu)),
            }),
            Stiffness::Spring(_) => None,
        }
    }
}
