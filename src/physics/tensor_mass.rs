//! The tensor-mass model (Cotin, Delingette and Ayache, "A hybrid elastic model for real-time
//! cutting, deformations, and force feedback for surgery training and simulation", The Visual
//! Computer 16, 2000): linear elasticity on constant-strain tets, assembled into one 3x3 tensor
//! per node (`K_ii`) and one per edge (`K_ij`), the connectivity of the springs.
//!
//! The force on node `i` is `F_i = -K_ii u_i - sum_j K_ij u_j` with `u = x - rest`, the energy
//! `1/2 u^T K u`. Each tet's share (its [`TetElement`] blocks) is kept, so that removing a tet
//! subtracts exactly what it added ([`TensorMass::remove_tet`]), as the springs' shares are.
//!
//! The model is linear in `u`: it is exact for small displacements and small rotations only.
//! A rigid rotation of the body stores energy and gives forces (the "ghost forces" of linear
//! elasticity under rotation); [`super::Corotational`] removes them.
//!
//! Damping is Rayleigh's `alpha M + beta K`: the `beta K` part is here (`beta` per region,
//! [`crate::model::SpringDamping::StiffnessProportional`]); the `alpha M` part is the model's
//! mass damping, which the integrators apply to every node (as for springs), so it is not
//! counted twice.

use rustc_hash::FxHashMap;

use super::force_model::{axpy, dot, mat_vec, sub, ForceModel, Linearization, Mat3, Vec3};
use super::linear_tet::TetElement;
use crate::error::{Error, Result};
use crate::model::{corner_set, ModelDiff, PackedTet};

/// The tensors of one edge: the block coupling its lower node `a` to its higher node `b`
/// (the force on `a` is `-K_ab u_b`, on `b` is `-K_ab^T u_a`), for stiffness and damping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeTensor {
    /// The two nodes, `nodes[0] < nodes[1]`.
    pub nodes: [u32; 2],
    /// `K_ab`, N/m.
    pub stiffness: Mat3,
    /// `C_ab = sum_e beta_e K_e,ab`, N s/m.
    pub damping: Mat3,
    /// How many tets hold the edge; it is deleted when the last one goes.
    pub tets: u32,
}

/// The tensor-mass force model of a set of tets.
#[derive(Debug, Clone)]
pub struct TensorMass {
    rest: Vec<Vec3>,
    node_stiffness: Vec<Mat3>,
    node_damping: Vec<Mat3>,
    edges: Vec<EdgeTensor>,
    /// Where each edge is in `edges`, by node pair (never iterated).
    edge_index: FxHashMap<[u32; 2], usize>,
    /// Each tet's share, `None` once removed.
    shares: Vec<Option<TetElement>>,
    /// Where each tet still in the model is in `shares`, by its corners as a set (never
    /// iterated).
    by_corners: FxHashMap<[u32; 4], usize>,
}

fn add_scaled(target: &mut Mat3, s: f64, m: &Mat3) {
    for r in 0..3 {
        for c in 0..3 {
            target[r][c] += s * m[r][c];
        }
    }
}

/// `m^T`.
pub(crate) fn transpose(m: &Mat3) -> Mat3 {
    [0, 1, 2].map(|r| [0, 1, 2].map(|c| m[c][r]))
}

/// `m^T v`.
fn mat_t_vec(m: &Mat3, v: Vec3) -> Vec3 {
    [0, 1, 2].map(|c| m[0][c] * v[0] + m[1][c] * v[1] + m[2][c] * v[2])
}

impl TensorMass {
    /// The model of `tets` on rest positions `rest` (see [`TetElement::new`] for what each tet
    /// must satisfy).
    pub fn new(rest: &[Vec3], tets: &[PackedTet]) -> Result<Self> {
        let elements = TetElement::all(rest, tets)?;
        let n = rest.len();
        let mut model = TensorMass {
            rest: rest.to_vec(),
            node_stiffness: vec![[[0.0; 3]; 3]; n],
            node_damping: vec![[[0.0; 3]; 3]; n],
            edges: Vec::new(),
            edge_index: FxHashMap::default(),
            shares: Vec::with_capacity(elements.len()),
            by_corners: FxHashMap::default(),
        };
        for e in elements {
            model.push_share(e);
        }
        Ok(model)
    }

    /// Add a tet (given as in [`TensorMass::new`]); returns its index for
    /// [`TensorMass::remove_tet`].
    pub fn add_tet(&mut self, tet: &PackedTet) -> Result<usize> {
        let e = TetElement::new(&self.rest, tet, self.shares.len())?;
        Ok(self.push_share(e))
    }

    /// Add element `e`'s share; returns its index.
    fn push_share(&mut self, e: TetElement) -> usize {
        let index = self.shares.len();
        self.apply_share(&e, 1.0);
        self.by_corners.insert(corner_set(e.nodes), index);
        self.shares.push(Some(e));
        index
    }

    /// Follow a change of the model (what a cut makes): the rest positions of the nodes it
    /// added (`rest` holds every node's, after the change), the removed tets' shares
    /// subtracted and the added tets' shares added, in the diff's order. Touches only the
    /// tensors of the tets named. On error (a removed tet the model does not hold, an added
    /// one that is not a valid element) nothing changes.
    pub fn patch(&mut self, rest: &[Vec3], diff: &ModelDiff) -> Result<()> {
        let gone = diff
            .removed_tets
            .iter()
            .map(|&t| {
                self.by_corners.get(&corner_set(t)).copied().ok_or_else(|| {
                    Error::DiffMismatch(format!(
                        "cannot remove tet {t:?}: the finite-element model holds no tet with \
                         those corners"
                    ))
                })
            })
            .collect::<Result<Vec<usize>>>()?;
        let first = self.shares.len();
        let added = diff
            .added_tets
            .iter()
            .enumerate()
            .map(|(k, t)| TetElement::new(rest, t, first + k))
            .collect::<Result<Vec<TetElement>>>()?;
        if rest.len() > self.rest.len() {
            self.rest.extend_from_slice(&rest[self.rest.len()..]);
            self.node_stiffness.resize(rest.len(), [[0.0; 3]; 3]);
            self.node_damping.resize(rest.len(), [[0.0; 3]; 3]);
        }
        for i in gone {
            self.remove_tet(i)?;
        }
        for e in added {
            self.push_share(e);
        }
        Ok(())
    }

    /// Subtract exactly what tet `index` (in the order given to [`TensorMass::new`], then
    /// [`TensorMass::add_tet`]) added; an edge no other tet holds is deleted.
    pub fn remove_tet(&mut self, index: usize) -> Result<()> {
        let e = self
            .shares
            .get_mut(index)
            .and_then(Option::take)
            .ok_or_else(|| Error::Model(format!("tet {index} has no share in the model")))?;
        self.by_corners.remove(&corner_set(e.nodes));
        self.apply_share(&e, -1.0);
        Ok(())
    }

    /// Add (`sign = 1`) or subtract (`sign = -1`) an element's blocks.
    fn apply_share(&mut self, e: &TetElement, sign: f64) {
        for a in 0..4 {
            let i = e.nodes[a] as usize;
            add_scaled(&mut self.node_stiffness[i], sign, &e.stiffness[a][a]);
            add_scaled(&mut self.node_damping[i], sign * e.beta, &e.stiffness[a][a]);
            for b in a + 1..4 {
                // Stored from the lower node to the higher: K_ab, or K_ba = K_ab^T.
                let (p, q) = (e.nodes[a], e.nodes[b]);
                let block = if p < q {
                    e.stiffness[a][b]
                } else {
                    e.stiffness[b][a]
                };
                let key = [p.min(q), p.max(q)];
                let slot = match self.edge_index.get(&key) {
                    Some(&s) => s,
                    None => {
                        self.edges.push(EdgeTensor {
                            nodes: key,
                            stiffness: [[0.0; 3]; 3],
                            damping: [[0.0; 3]; 3],
                            tets: 0,
                        });
                        self.edge_index.insert(key, self.edges.len() - 1);
                        self.edges.len() - 1
                    }
                };
                let edge = &mut self.edges[slot];
                add_scaled(&mut edge.stiffness, sign, &block);
                add_scaled(&mut edge.damping, sign * e.beta, &block);
                if sign > 0.0 {
                    edge.tets += 1;
                } else {
                    edge.tets = edge.tets.saturating_sub(1);
                    if edge.tets == 0 {
                        self.delete_edge(slot);
                    }
                }
            }
        }
    }

    /// Delete the edge in `slot`, moving the last edge into it.
    fn delete_edge(&mut self, slot: usize) {
        let gone = self.edges.swap_remove(slot);
        self.edge_index.remove(&gone.nodes);
        if let Some(moved) = self.edges.get(slot) {
            self.edge_index.insert(moved.nodes, slot);
        }
    }

    /// The node tensors `K_ii`, N/m, by node.
    pub fn node_tensors(&self) -> &[Mat3] {
        &self.node_stiffness
    }

    /// The node damping tensors `C_ii`, N s/m, by node.
    pub fn node_damping_tensors(&self) -> &[Mat3] {
        &self.node_damping
    }

    /// The edge tensors, in no particular order.
    pub fn edge_tensors(&self) -> &[EdgeTensor] {
        &self.edges
    }

    /// The edge tensor of nodes `a` and `b` (either order), if a tet holds that edge.
    pub fn edge_tensor(&self, a: u32, b: u32) -> Option<&EdgeTensor> {
        self.edge_index
            .get(&[a.min(b), a.max(b)])
            .map(|&s| &self.edges[s])
    }

    /// The elements still in the model.
    pub fn elements(&self) -> impl Iterator<Item = &TetElement> + '_ {
        self.shares.iter().flatten()
    }

    /// Add `-(node, edge blocks) w` into `out`: `-K w` or `-C w`.
    fn add_minus_product(&self, damping: bool, w: &[Vec3], out: &mut [Vec3]) {
        let nodes = if damping {
            &self.node_damping
        } else {
            &self.node_stiffness
        };
        for (i, m) in nodes.iter().enumerate() {
            axpy(&mut out[i], -1.0, mat_vec(m, w[i]));
        }
        for e in &self.edges {
            let m = if damping { &e.damping } else { &e.stiffness };
            let (a, b) = (e.nodes[0] as usize, e.nodes[1] as usize);
            axpy(&mut out[a], -1.0, mat_vec(m, w[b]));
            axpy(&mut out[b], -1.0, mat_t_vec(m, w[a]));
        }
    }

    /// The displacements `x - rest`.
    fn displacements(&self, x: &[Vec3]) -> Vec<Vec3> {
        x.iter().zip(&self.rest).map(|(x, r)| sub(*x, *r)).collect()
    }
}

impl ForceModel for TensorMass {
    fn name(&self) -> &'static str {
        "tensor-mass"
    }

    fn add_forces(&self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        self.add_minus_product(false, &self.displacements(x), f);
        self.add_minus_product(true, v, f);
    }

    fn potential_energy(&self, x: &[Vec3]) -> f64 {
        let u = self.displacements(x);
        let nodes: f64 = self
            .node_stiffness
            .iter()
            .zip(&u)
            .map(|(m, u)| 0.5 * dot(*u, mat_vec(m, *u)))
            .sum();
        let edges: f64 = self
            .edges
            .iter()
            .map(|e| {
                dot(
                    u[e.nodes[0] as usize],
                    mat_vec(&e.stiffness, u[e.nodes[1] as usize]),
                )
            })
            .sum();
        nodes + edges
    }

    /// The model is linear: `K` is the same at every `x`, and symmetric negative
    /// semi-definite, so both linearisations are the same.
    fn add_stiffness_product(&self, _: &[Vec3], _: Linearization, w: &[Vec3], out: &mut [Vec3]) {
        self.add_minus_product(false, w, out);
    }

    fn add_damping_product(&self, _: &[Vec3], w: &[Vec3], out: &mut [Vec3]) {
        self.add_minus_product(true, w, out);
    }

    fn add_diagonal_blocks(
        &self,
        _: &[Vec3],
        _: Linearization,
        stiffness: &mut [Mat3],
        damping: &mut [Mat3],
    ) {
        for i in 0..self.node_stiffness.len() {
            add_scaled(&mut stiffness[i], -1.0, &self.node_stiffness[i]);
            add_scaled(&mut damping[i], -1.0, &self.node_damping[i]);
        }
    }
}
