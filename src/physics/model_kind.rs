//! Which force model a simulation runs, and what the finite-element ones need from a packed
//! model: their force model and their stable time step.

use serde::{Deserialize, Serialize};

use super::force_model::ForceModel;
use super::linear_tet::{gershgorin_rows, TetElement};
use super::{Corotational, TensorMass};
use crate::error::Result;
use crate::model::{stable_time_step_from_rows, PackedModel, StabilityBound};

/// The force model of a simulation: what the elements of the model exert on its nodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum ForceModelKind {
    /// The mass-spring model: a scalar stiffness along each tet edge
    /// ([`super::SpringForces`]). Every engine runs it.
    #[default]
    Springs,
    /// Linear elasticity on constant-strain tets as node and edge tensors
    /// ([`TensorMass`]): exact for small displacements, with ghost forces under rotation.
    /// The float64 reference engine only, for now.
    TensorMass,
    /// Corotational linear elasticity ([`Corotational`]): no force under rigid motion. The
    /// float64 reference engine only, for now.
    Corotational,
}

impl ForceModelKind {
    /// Whether this is a finite-element model (built from the model's tets and their
    /// materials rather than from its springs).
    pub fn is_finite_element(self) -> bool {
        self != ForceModelKind::Springs
    }

    /// The finite-element force model of `model`'s tets, or `None` for springs (which the
    /// engines build from the springs themselves). Fails where the model has no tets or a tet's
    /// material has no Young's modulus (see [`TetElement::new`]).
    pub fn element_forces(self, model: &PackedModel) -> Result<Option<Box<dyn ForceModel + Send>>> {
        Ok(match self {
            ForceModelKind::Springs => None,
            ForceModelKind::TensorMass => {
                Some(Box::new(TensorMass::new(&model.rest, &model.tets)?))
            }
            ForceModelKind::Corotational => {
                Some(Box::new(Corotational::new(&model.rest, &model.tets)?))
            }
        })
    }

    /// The stable time step of explicit integration of `model` under this force model: the
    /// springs' bound ([`crate::model::stable_time_step`]), or for the finite-element models
    /// the block-Gershgorin bound on `M^-1 K` from the element blocks
    /// ([`gershgorin_rows`]), which holds for the linear model and for the corotational one in
    /// any rotation. Rayleigh's `beta` damps as the springs' damping does in the bound.
    pub fn stable_time_step(self, model: &PackedModel) -> Result<StabilityBound> {
        if !self.is_finite_element() {
            return Ok(crate::model::stable_time_step(model));
        }
        let elements = TetElement::all(&model.rest, &model.tets)?;
        let (k, c) = gershgorin_rows(&elements, model.node_count());
        Ok(stable_time_step_from_rows(
            &k,
            &c,
            &model.mass,
            &model.fixed,
            model.mass_damping,
        ))
    }
}

impl std::fmt::Display for ForceModelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            ForceModelKind::Springs => "springs",
            ForceModelKind::TensorMass => "tensor-mass",
            ForceModelKind::Corotational => "corotational",
        })
    }
}
