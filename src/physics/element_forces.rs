//! The finite-element force models as one value an engine holds and patches: what a cut
//! changes ([`ElementForces::patch`]), the check that a patched model equals one built from
//! scratch ([`ElementForces::differences_from_rebuild`]), and the energy of single elements
//! that the divergence check's bookkeeping of a cut needs ([`element_energy`]).

use super::force_model::{dot, mat_vec, sub, ForceModel, Linearization, Mat3, Vec3};
use super::linear_tet::TetElement;
use super::{Corotational, ForceModelKind, TensorMass};
use crate::error::Result;
use crate::model::{corner_set, ModelDiff, PackedModel};

/// Relative tolerance of [`ElementForces::differences_from_rebuild`]: a patched tensor differs
/// from the rebuilt one by the rounding of the shares added and subtracted in another order.
pub const REBUILD_TOLERANCE: f64 = 1e-12;

/// A finite-element force model: tensor-mass or corotational.
#[derive(Debug)]
pub enum ElementForces {
    /// [`TensorMass`].
    TensorMass(TensorMass),
    /// [`Corotational`].
    Corotational(Corotational),
}

impl ElementForces {
    /// The model `kind` of `model`'s tets, or `None` for springs (see
    /// [`ForceModelKind::element_forces`]).
    pub fn new(kind: ForceModelKind, model: &PackedModel) -> Result<Option<Self>> {
        Ok(match kind {
            ForceModelKind::Springs => None,
            ForceModelKind::TensorMass => Some(ElementForces::TensorMass(TensorMass::new(
                &model.rest,
                &model.tets,
            )?)),
            ForceModelKind::Corotational => Some(ElementForces::Corotational(Corotational::new(
                &model.rest,
                &model.tets,
            )?)),
        })
    }

    /// Which model this is.
    pub fn kind(&self) -> ForceModelKind {
        match self {
            ElementForces::TensorMass(_) => ForceModelKind::TensorMass,
            ElementForces::Corotational(_) => ForceModelKind::Corotational,
        }
    }

    fn inner(&self) -> &dyn ForceModel {
        match self {
            ElementForces::TensorMass(m) => m,
            ElementForces::Corotational(m) => m,
        }
    }

    /// Follow a change of the model: the removed tets' shares subtracted, the added tets'
    /// added (`rest`: every node's rest position after the change). On error nothing changes.
    pub fn patch(&mut self, rest: &[Vec3], diff: &ModelDiff) -> Result<()> {
        match self {
            ElementForces::TensorMass(m) => m.patch(rest, diff),
            ElementForces::Corotational(m) => m.patch(rest, diff),
        }
    }

    /// The elements in the model.
    pub fn elements(&self) -> Vec<&TetElement> {
        match self {
            ElementForces::TensorMass(m) => m.elements().collect(),
            ElementForces::Corotational(m) => m.elements().iter().collect(),
        }
    }

    /// How this model, after the patches applied so far, differs from the same model built
    /// from scratch for `model` (its tets as they are now): empty when they agree. Tensor-mass:
    /// every node and edge tensor within [`REBUILD_TOLERANCE`] of the largest entry, and no
    /// edge tensor between two nodes that no tet joins (across a completed cut); corotational:
    /// the same elements, each with the same stiffness.
    pub fn differences_from_rebuild(&self, model: &PackedModel) -> Result<Vec<String>> {
        let Some(rebuilt) = Self::new(self.kind(), model)? else {
            return Ok(Vec::new());
        };
        let mut out = Vec::new();
        match (self, &rebuilt) {
            (ElementForces::TensorMass(a), ElementForces::TensorMass(b)) => {
                let scale = b
                    .node_tensors()
                    .iter()
                    .map(max_abs)
                    .fold(0.0, f64::max)
                    .max(f64::MIN_POSITIVE);
                let tol = REBUILD_TOLERANCE * scale;
                let (na, nb) = (a.node_tensors(), b.node_tensors());
                if na.len() != nb.len() {
                    out.push(format!(
                        "{} node tensors, a rebuild has {}",
                        na.len(),
                        nb.len()
                    ));
                }
                for (i, (x, y)) in na.iter().zip(nb).enumerate() {
                    if max_abs(&minus(x, y)) > tol {
                        out.push(format!("node {i}: K_ii {x:?}, a rebuild gives {y:?}"));
                    }
                }
                for e in a.edge_tensors() {
                    let [p, q] = e.nodes;
                    match b.edge_tensor(p, q) {
                        None => out.push(format!(
                            "an edge tensor couples nodes {p} and {q}, which no tet joins \
                             (across a cut, or left by a removed tet)"
                        )),
                        Some(r) if max_abs(&minus(&e.stiffness, &r.stiffness)) > tol => {
                            out.push(format!(
                                "edge {p}-{q}: K_ij {:?}, a rebuild gives {:?}",
                                e.stiffness, r.stiffness
                            ))
                        }
                        Some(r) if e.tets != r.tets => out.push(format!(
                            "edge {p}-{q}: held by {} tets, a rebuild counts {}",
                            e.tets, r.tets
                        )),
                        _ => {}
                    }
                }
                for e in b.edge_tensors() {
                    if a.edge_tensor(e.nodes[0], e.nodes[1]).is_none() {
                        out.push(format!(
                            "edge {:?} has no tensor; a rebuild has one",
                            e.nodes
                        ));
                    }
                }
            }
            (ElementForces::Corotational(a), ElementForces::Corotational(b)) => {
                if a.elements().len() != b.elements().len() {
                    out.push(format!(
                        "{} elements, a rebuild has {}",
                        a.elements().len(),
                        b.elements().len()
                    ));
                }
                let by: rustc_hash::FxHashMap<[u32; 4], &TetElement> = b
                    .elements()
                    .iter()
                    .map(|e| (corner_set(e.nodes), e))
                    .collect();
                for e in a.elements() {
                    match by.get(&corner_set(e.nodes)) {
                        None => {
                            out.push(format!("element {:?} is not a tet of the model", e.nodes))
                        }
                        Some(r) => {
                            let scale = r
                                .stiffness
                                .iter()
                                .flatten()
                                .map(max_abs)
                                .fold(0.0, f64::max);
                            let worst = (0..4)
                                .flat_map(|a| (0..4).map(move |b| (a, b)))
                                .map(|(p, q)| {
                                    max_abs(&minus(&e.stiffness[p][q], &r.stiffness[p][q]))
                                })
                                .fold(0.0, f64::max);
                            if worst > REBUILD_TOLERANCE * scale || e.nodes != r.nodes {
                                out.push(format!(
                                    "element {:?}: its stiffness differs from a rebuild's by {worst:e}",
                                    e.nodes
                                ));
                            }
                        }
                    }
                }
            }
            _ => unreachable!("rebuilt as the same kind"),
        }
        Ok(out)
    }
}

fn max_abs(m: &Mat3) -> f64 {
    m.iter().flatten().fold(0.0, |a, b| a.max(b.abs()))
}

fn minus(a: &Mat3, b: &Mat3) -> Mat3 {
    [0, 1, 2].map(|r| [0, 1, 2].map(|c| a[r][c] - b[r][c]))
}

/// The elastic energy, J, of element `e` under force model `kind` with its corners at `x`
/// (in corner order): `1/2 u^T K_e u` with `u = x - rest` for tensor-mass, the corotated
/// energy for corotational, zero for springs (which have no elements).
pub fn element_energy(kind: ForceModelKind, e: &TetElement, x: [Vec3; 4]) -> f64 {
    let u: [Vec3; 4] = match kind {
        ForceModelKind::Springs => return 0.0,
        ForceModelKind::TensorMass => [0, 1, 2, 3].map(|a| sub(x[a], e.rest[a])),
        ForceModelKind::Corotational => {
            let local = TetElement {
                nodes: [0, 1, 2, 3],
                ..*e
            };
            let r = Corotational::rotation(&local, &x);
            Corotational::local_displacements(&local, &r, &x)
        }
    };
    let mut energy = 0.0;
    for a in 0..4 {
        for b in 0..4 {
            energy += 0.5 * dot(u[a], mat_vec(&e.stiffness[a][b], u[b]));
        }
    }
    energy
}

impl ForceModel for ElementForces {
    fn name(&self) -> &'static str {
        self.inner().name()
    }

    fn add_forces(&self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        self.inner().add_forces(x, v, f)
    }

    fn potential_energy(&self, x: &[Vec3]) -> f64 {
        self.inner().potential_energy(x)
    }

    fn add_stiffness_product(&self, x: &[Vec3], lin: Linearization, w: &[Vec3], out: &mut [Vec3]) {
        self.inner().add_stiffness_product(x, lin, w, out)
    }

    fn add_damping_product(&self, x: &[Vec3], w: &[Vec3], out: &mut [Vec3]) {
        self.inner().add_damping_product(x, w, out)
    }

    fn add_diagonal_blocks(
        &self,
        x: &[Vec3],
        lin: Linearization,
        stiffness: &mut [Mat3],
        damping: &mut [Mat3],
    ) {
        self.inner().add_diagonal_blocks(x, lin, stiffness, damping)
    }
}
