//! Which force model a simulation runs, and what the finite-element ones need from a packed
//! model: their force model and their stable time step.

use serde::{Deserialize, Serialize};

use super::element_forces::ElementForces;
use super::linear_tet::{gershgorin_rows, spectral_norm, TetElement};
use crate::error::{Error, Result};
use crate::model::{stable_time_step_from_rows, BoundUndo, ModelDiff, PackedModel, StabilityBound};

/// The force model of a simulation: what the elements of the model exert on its nodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum ForceModelKind {
    /// The mass-spring model: a scalar stiffness along each tet edge
    /// ([`super::SpringForces`]). Every engine runs it.
    #[default]
    Springs,
    /// Linear elasticity on constant-strain tets as node and edge tensors
    /// ([`super::TensorMass`]): exact for small displacements, with ghost forces under
    /// rotation. The float64 reference engine and the fast float32 engine (explicit schemes);
    /// not the GPU layouts yet.
    TensorMass,
    /// Corotational linear elasticity ([`super::Corotational`]): no force under rigid motion.
    /// The float64 reference engine and the fast float32 engine (explicit schemes); not the
    /// GPU layouts yet.
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
    pub fn element_forces(self, model: &PackedModel) -> Result<Option<ElementForces>> {
        ElementForces::new(self, model)
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

impl ForceModelKind {
    /// The elements a change removes (as they are in `before`) and adds (on the rest positions
    /// after it: `before`'s and the added nodes'). Fails where a removed tet is not in
    /// `before` or an added one is not a valid element, before anything changes.
    pub fn diff_elements(
        before: &PackedModel,
        diff: &ModelDiff,
    ) -> Result<(Vec<TetElement>, Vec<TetElement>)> {
        let removed = diff
            .removed_tets
            .iter()
            .map(|&t| {
                let tet = before.tet(t).ok_or_else(|| {
                    Error::DiffMismatch(format!(
                        "cannot remove tet {t:?}: the model has no tet with those corners"
                    ))
                })?;
                TetElement::new(&before.rest, tet, 0)
            })
            .collect::<Result<Vec<_>>>()?;
        let rest: Vec<[f64; 3]> = before
            .rest
            .iter()
            .copied()
            .chain(diff.added_nodes.iter().map(|a| a.rest))
            .collect();
        let added = diff
            .added_tets
            .iter()
            .enumerate()
            .map(|(k, t)| TetElement::new(&rest, t, before.tets.len() + k))
            .collect::<Result<Vec<_>>>()?;
        Ok((removed, added))
    }

    /// Update `bound` (the stable step of `before` under this force model) for `diff`, touching
    /// only the nodes the diff names: the springs' update, or for a finite-element model the
    /// removed elements' Gershgorin rows subtracted and the added ones' added
    /// ([`gershgorin_rows`]). Returns what [`StabilityBound::undo`] needs; on error (a tet the
    /// diff names that cannot be an element) the bound is unchanged.
    pub fn update_bound(
        self,
        bound: &mut StabilityBound,
        before: &PackedModel,
        diff: &ModelDiff,
    ) -> Result<BoundUndo> {
        if !self.is_finite_element() {
            return Ok(bound.update(before, diff));
        }
        let (removed, added) = Self::diff_elements(before, diff)?;
        Ok(bound.update_with(before, diff, |k_sum, c_sum| {
            for (elements, sign) in [(&removed, -0.5), (&added, 0.5)] {
                for e in elements {
                    for a in 0..4 {
                        let row: f64 = e.stiffness[a].iter().map(spectral_norm).sum();
                        let i = e.nodes[a] as usize;
                        k_sum[i] += sign * row;
                        c_sum[i] += sign * e.beta * row;
                    }
                }
            }
        }))
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
