//! Finite elements on the fast float32 engine: tensor-mass as a 3x3 block per adjacency slot,
//! corotational as a per-tet pass and a per-node gather. The explicit step is here; backward
//! Euler's rows of the system, `-(h C + h^2 K)` per adjacency entry, are formed from the same
//! arrays in `elements_jacobian.rs` and solved in `implicit.rs`.
//!
//! **Tensor-mass.** Each node's row holds `K_ij` (and `C_ij` where Rayleigh's `beta` is not
//! zero) for every neighbour `j`, in the springs' row order (the tet edges are the springs),
//! assembled in float64 from the per-tet shares ([`TensorMass`]) and rounded once. The diagonal
//! `K_ii` is not stored: an element's block rows sum to zero (a translation stores no energy),
//! so `K_ii = -sum_j K_ij` and the force is `f_i = -sum_j K_ij (u_j - u_i)`, on displacement
//! differences as the springs' `e_ij + (u_j - u_i)` is, never rounding a large common motion
//! against a small strain.
//!
//! **Corotational.** The rotated blocks `R_e K_e R_e^T` change every step, so instead of
//! assembling them into slots a pass over the tets computes each tet's four corner forces and a
//! pass over the nodes gathers them (each node's list of (tet, corner), in a fixed order). The
//! rotation uses the reference's float64 math: the deformation gradient from the float32
//! displacements in float64, [`polar_rotation`] (robust for inverted tets), the local
//! displacements `R^T (x_a - x_0) - (X_a - X_0)` in float64; the products with the element's
//! stiffness are float32.
//!
//! Every pass writes disjoint outputs and sums in a fixed order, so a step is bit-identical on
//! any number of threads. A cut patches both: the float64 model subtracts and adds per-tet
//! shares, the touched nodes' rows (tensor-mass) or the removed and added tets with their
//! corners' lists (corotational) are rewritten, nothing else.

use nalgebra::Matrix3;
use rustc_hash::FxHashMap;

use super::{FastEngine, Graph, Params, BLOCK, P};
use crate::engine::Integrator;
use crate::error::Result;
use crate::model::{corner_set, ModelDiff, PackedModel, PackedTet};
use crate::physics::corotational::polar_rotation;
use crate::physics::{ElementForces, ForceModel, ForceModelKind, TetElement};

#[path = "elements_jacobian.rs"]
mod jacobian;
#[path = "elements_polar.rs"]
mod polar;

type M3 = [f32; 9];

/// One neighbour's block in a node's row.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Slot {
    /// Internal index of the neighbour.
    other: u32,
    /// `K_ij`, row major, N/m.
    k: M3,
}

/// Tensor-mass blocks by node row.
#[derive(Debug)]
struct Blocks {
    rows: Vec<[u32; 2]>,
    slots: Vec<Slot>,
    /// `C_ij` by slot (empty when no tet is damped).
    damping: Vec<M3>,
    /// Slots no row uses.
    holes: usize,
}

/// Corotational tets, in the model's tet order.
#[derive(Debug)]
struct Tets {
    /// Internal indices of the corners.
    nodes: Vec<[u32; 4]>,
    /// Rest edges `X_a - X_0`, a = 1..3, m.
    edges: Vec<[[f64; 3]; 3]>,
    /// Shape-function gradients of corners 1..3, 1/m (corner 0's is minus their sum).
    gradients: Vec<[[f64; 3]; 3]>,
    /// `K_ab`, N/m.
    stiffness: Vec<[M3; 16]>,
    /// Rayleigh's `beta`, s.
    beta: Vec<f32>,
    /// Each node's (tet * 4 + corner), internal order.
    incidence: Vec<Vec<u32>>,
    /// Each tet's corners (model indices) as a set.
    keys: Vec<[u32; 4]>,
    /// Where each tet is, by its corners (model indices) as a set.
    by_corners: FxHashMap<[u32; 4], usize>,
    /// Each tet's corner forces at the last element pass, N.
    forces: Vec<[[f32; 3]; 4]>,
    /// Each tet's rotation at the last element pass that kept them (backward Euler's), row
    /// major.
    rotations: Vec<M3>,
    /// Where each corner pair `(a, b)` of each tet is in the springs' row of corner `a`
    /// ([`pair_index`] orders the twelve pairs; [`NO_SLOT`] where the row has no such entry):
    /// backward Euler's blocks go straight to their entry instead of searching the row.
    /// Written with the tet, rewritten for the tets at every node a cut touches.
    slots: Vec<[u16; 12]>,
}

/// A corner pair with no entry in the row (an edge without a spring: never, in a model the
/// packer built).
const NO_SLOT: u16 = u16::MAX;

/// Index of corner pair `(a, b)`, `a != b`, among a tet's twelve.
#[inline(always)]
fn pair_index(a: usize, b: usize) -> usize {
    3 * a + b - usize::from(b > a)
}

/// Where each corner pair of the tet with internal corners `nodes` is in the springs' rows
/// of `graph` (see [`Tets::slots`]).
fn slots_of(nodes: [u32; 4], graph: &Graph) -> [u16; 12] {
    let mut out = [NO_SLOT; 12];
    for (a, &i) in nodes.iter().enumerate() {
        for (k, (e, _)) in graph.springs.row(i as usize).enumerate() {
            for (b, &j) in nodes.iter().enumerate() {
                if b != a && e.other == j && k < NO_SLOT as usize {
                    out[pair_index(a, b)] = k as u16;
                }
            }
        }
    }
    out
}

#[derive(Debug)]
enum Layout {
    Blocks(Blocks),
    Tets(Tets),
}

/// The finite-element model of a fast engine.
#[derive(Debug)]
pub(super) struct FastElements {
    /// The float64 model, patched by every diff: the source of the blocks, and the energy.
    reference: ElementForces,
    layout: Layout,
    /// Whether any tet has Rayleigh damping.
    damped: bool,
    /// Each corotational tet's blocks `R K_ab R^T` of its six pairs `a < b` at the last
    /// linearisation (`elements_jacobian.rs`; the pair `b, a` is the transpose).
    rotated: Vec<[M3; 6]>,
}

fn to_m3(m: &[[f64; 3]; 3]) -> M3 {
    std::array::from_fn(|k| m[k / 3][k % 3] as f32)
}

fn transposed(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    [0, 1, 2].map(|r| [0, 1, 2].map(|c| m[c][r]))
}

#[inline(always)]
fn mul(m: &M3, v: [f32; 3]) -> [f32; 3] {
    [0, 1, 2].map(|r| m[3 * r] * v[0] + m[3 * r + 1] * v[1] + m[3 * r + 2] * v[2])
}

#[inline(always)]
fn mul_t(m: &M3, v: [f32; 3]) -> [f32; 3] {
    [0, 1, 2].map(|c| m[c] * v[0] + m[3 + c] * v[1] + m[6 + c] * v[2])
}

impl Tets {
    fn push(&mut self, e: &TetElement, rank: &[u32], graph: &Graph) {
        let t = self.nodes.len();
        let nodes = e.nodes.map(|n| rank[n as usize]);
        self.slots.push(slots_of(nodes, graph));
        for (c, &i) in nodes.iter().enumerate() {
            self.incidence[i as usize].push((4 * t + c) as u32);
        }
        let key = corner_set(e.nodes);
        self.by_corners.insert(key, t);
        self.keys.push(key);
        self.nodes.push(nodes);
        self.edges
            .push([1, 2, 3].map(|a| [0, 1, 2].map(|c| e.rest[a][c] - e.rest[0][c])));
        self.gradients
            .push([e.gradients[1], e.gradients[2], e.gradients[3]]);
        self.stiffness
            .push(std::array::from_fn(|k| to_m3(&e.stiffness[k / 4][k % 4])));
        self.beta.push(e.beta as f32);
        self.forces.push([[0.0; 3]; 4]);
        self.rotations.push([0.0; 9]);
    }

    fn of(elements: &[&TetElement], rank: &[u32], nodes: usize, graph: &Graph) -> Self {
        let mut t = Tets {
            nodes: Vec::with_capacity(elements.len()),
            edges: Vec::with_capacity(elements.len()),
            gradients: Vec::with_capacity(elements.len()),
            stiffness: Vec::with_capacity(elements.len()),
            beta: Vec::with_capacity(elements.len()),
            incidence: vec![Vec::new(); nodes],
            keys: Vec::with_capacity(elements.len()),
            by_corners: FxHashMap::default(),
            forces: Vec::with_capacity(elements.len()),
            rotations: Vec::with_capacity(elements.len()),
            slots: Vec::with_capacity(elements.len()),
        };
        for e in elements {
            t.push(e, rank, graph);
        }
        t
    }

    /// Rewrite the row slots of every tet at one of the internal nodes `touched`, whose
    /// springs' rows a cut rewrote (the other rows keep their order).
    fn reslot(&mut self, touched: &[usize], graph: &Graph) {
        let mut tets: Vec<usize> = touched
            .iter()
            .filter_map(|&i| self.incidence.get(i))
            .flatten()
            .map(|&k| (k / 4) as usize)
            .collect();
        tets.sort_unstable();
        tets.dedup();
        for t in tets {
            self.slots[t] = slots_of(self.nodes[t], graph);
        }
    }

    /// Remove the tet with model corners `corners`, moving the last tet into its place (as
    /// the model's tets move); the corners' lists follow.
    fn swap_remove(&mut self, corners: [u32; 4]) {
        let t = self
            .by_corners
            .remove(&corner_set(corners))
            .expect("the float64 model checked the diff");
        for (c, &i) in self.nodes[t].iter().enumerate() {
            let list = &mut self.incidence[i as usize];
            list.retain(|&k| k != (4 * t + c) as u32);
        }
        let last = self.nodes.len() - 1;
        if t != last {
            for (c, &i) in self.nodes[last].iter().enumerate() {
                for k in self.incidence[i as usize].iter_mut() {
                    if *k == (4 * last + c) as u32 {
                        *k = (4 * t + c) as u32;
                    }
                }
            }
        }
        self.nodes.swap_remove(t);
        self.edges.swap_remove(t);
        self.gradients.swap_remove(t);
        self.stiffness.swap_remove(t);
        self.beta.swap_remove(t);
        self.forces.swap_remove(t);
        self.rotations.swap_remove(t);
        self.slots.swap_remove(t);
        self.keys.swap_remove(t);
        if let Some(&moved) = self.keys.get(t) {
            self.by_corners.insert(moved, t);
        }
    }

    /// Corner forces of tet `t` at displacements `x` and second states `w` (velocity times
    /// `w_scale`), and the tet's rotation.
    #[inline(always)]
    fn element_forces(&self, t: usize, x: &[P], w: &[P], w_scale: f32) -> ([[f32; 3]; 4], M3) {
        let n = self.nodes[t];
        let u0 = x[n[0] as usize];
        // Current edges x_a - x_0 in float64: rest edge plus displacement difference.
        let d: [[f64; 3]; 3] = [1, 2, 3].map(|a| {
            let ua = x[n[a] as usize];
            [0, 1, 2].map(|c| self.edges[t][a - 1][c] + (ua[c] - u0[c]) as f64)
        });
        let g = &self.gradients[t];
        let f = Matrix3::from_fn(|i, j| (0..3).map(|a| d[a][i] * g[a][j]).sum::<f64>());
        // Newton's iteration where it converges to the rotation, the decomposition where the
        // tet is inverted or degenerate (`elements_polar.rs`).
        let r = match polar::rotation(&[0, 1, 2].map(|i| [0, 1, 2].map(|j| f[(i, j)]))) {
            Some(r) => Matrix3::from_fn(|i, j| r[i][j]),
            None => polar_rotation(&f),
        };
        // Local displacements R^T (x_a - x_0) - (X_a - X_0); corner 0's is zero.
        let mut local = [[0.0f32; 3]; 4];
        for a in 0..3 {
            for c in 0..3 {
                let rotated: f64 = (0..3).map(|k| r[(k, c)] * d[a][k]).sum();
                local[a + 1][c] = (rotated - self.edges[t][a][c]) as f32;
            }
        }
        let r32: M3 = std::array::from_fn(|k| r[(k / 3, k % 3)] as f32);
        let damped = self.beta[t] != 0.0;
        let mut wl = [[0.0f32; 3]; 4];
        if damped {
            let w0 = w[n[0] as usize];
            for a in 1..4 {
                let wa = w[n[a] as usize];
                let rel = [0, 1, 2].map(|c| (wa[c] - w0[c]) * w_scale);
                wl[a] = mul_t(&r32, rel);
            }
        }
        let k = &self.stiffness[t];
        let mut out = [[0.0f32; 3]; 4];
        for (a, o) in out.iter_mut().enumerate() {
            let mut sum = [0.0f32; 3];
            for b in 1..4 {
                let p = mul(&k[4 * a + b], local[b]);
                let q = if damped {
                    mul(&k[4 * a + b], wl[b])
                } else {
                    [0.0; 3]
                };
                for c in 0..3 {
                    sum[c] += p[c] + self.beta[t] * q[c];
                }
            }
            let rotated = mul(&r32, sum);
            *o = rotated.map(|v| -v);
        }
        (out, r32)
    }

    /// Every tet's corner forces (and, with `keep`, its rotation), in parallel over blocks of
    /// tets.
    fn element_pass(&mut self, x: &[P], w: &[P], w_scale: f32, keep: bool) {
        let mut forces = std::mem::take(&mut self.forces);
        let mut rotations = std::mem::take(&mut self.rotations);
        {
            let this = &*self;
            let run = |start: usize, chunk: &mut [[[f32; 3]; 4]], r: &mut [M3]| {
                for (k, f) in chunk.iter_mut().enumerate() {
                    let (forces, rotation) = this.element_forces(start + k, x, w, w_scale);
                    *f = forces;
                    if keep {
                        r[k] = rotation;
                    }
                }
            };
            #[cfg(feature = "parallel")]
            {
                use rayon::prelude::*;
                forces
                    .par_chunks_mut(BLOCK)
                    .zip(rotations.par_chunks_mut(BLOCK))
                    .enumerate()
                    .for_each(|(b, (chunk, r))| run(b * BLOCK, chunk, r));
            }
            #[cfg(not(feature = "parallel"))]
            for (b, (chunk, r)) in forces
                .chunks_mut(BLOCK)
                .zip(rotations.chunks_mut(BLOCK))
                .enumerate()
            {
                run(b * BLOCK, chunk, r);
            }
        }
        self.forces = forces;
        self.rotations = rotations;
    }

    #[inline(always)]
    fn node_force(&self, i: usize) -> [f32; 3] {
        let mut f = [0.0f32; 3];
        for &k in &self.incidence[i] {
            let g = self.forces[(k / 4) as usize][(k % 4) as usize];
            for c in 0..3 {
                f[c] += g[c];
            }
        }
        f
    }
}

impl Blocks {
    /// Node `i`'s row (internal order), from the springs' row of the same node (the tet
    /// edges), each block oriented from `i` to its neighbour.
    fn row_of(
        tm: &crate::physics::TensorMass,
        graph: &Graph,
        order: &[u32],
        i: usize,
        damped: bool,
    ) -> Vec<(Slot, M3)> {
        let o = order[i];
        graph
            .springs
            .row(i)
            .filter_map(|(e, _)| {
                let q = order[e.other as usize];
                let t = tm.edge_tensor(o, q)?;
                let (k, c) = if o < q {
                    (t.stiffness, t.damping)
                } else {
                    (transposed(&t.stiffness), transposed(&t.damping))
                };
                Some((
                    Slot {
                        other: e.other,
                        k: to_m3(&k),
                    },
                    if damped { to_m3(&c) } else { [0.0; 9] },
                ))
            })
            .collect()
    }

    fn of(tm: &crate::physics::TensorMass, graph: &Graph, order: &[u32], damped: bool) -> Self {
        let n = order.len();
        let mut b = Blocks {
            rows: Vec::with_capacity(n),
            slots: Vec::with_capacity(graph.springs.live),
            damping: Vec::new(),
            holes: 0,
        };
        for i in 0..n {
            let row = Self::row_of(tm, graph, order, i, damped);
            let start = b.slots.len() as u32;
            b.slots.extend(row.iter().map(|r| r.0));
            if damped {
                b.damping.extend(row.iter().map(|r| r.1));
            }
            b.rows.push([start, b.slots.len() as u32]);
        }
        b
    }

    /// Rewrite node `i`'s row: where it is when it does not grow, else appended.
    fn rewrite(&mut self, i: usize, row: Vec<(Slot, M3)>, damped: bool) -> u64 {
        if i == self.rows.len() {
            let s = self.slots.len() as u32;
            self.rows.push([s, s]);
        }
        let [start, end] = self.rows[i];
        let (start, old) = (start as usize, (end - start) as usize);
        let at = if row.len() <= old {
            self.holes += old - row.len();
            start
        } else {
            self.holes += old;
            let at = self.slots.len();
            self.slots.resize(
                at + row.len(),
                Slot {
                    other: 0,
                    k: [0.0; 9],
                },
            );
            if damped {
                self.damping.resize(at + row.len(), [0.0; 9]);
            }
            at
        };
        for (k, (s, c)) in row.iter().enumerate() {
            self.slots[at + k] = *s;
            if damped {
                self.damping[at + k] = *c;
            }
        }
        self.rows[i] = [at as u32, (at + row.len()) as u32];
        (row.len() * std::mem::size_of::<Slot>() + if damped { row.len() * 36 } else { 0 }) as u64
    }

    #[inline(always)]
    fn node_force(&self, i: usize, x: &[P], w: &[P], w_scale: f32, damped: bool) -> [f32; 3] {
        let [start, end] = self.rows[i];
        let (ui, wi) = (x[i], w[i]);
        let mut f = [0.0f32; 3];
        for k in start as usize..end as usize {
            let s = &self.slots[k];
            let uj = x[s.other as usize];
            let p = mul(&s.k, [uj[0] - ui[0], uj[1] - ui[1], uj[2] - ui[2]]);
            for c in 0..3 {
                f[c] -= p[c];
            }
            if damped {
                let wj = w[s.other as usize];
                let q = mul(
                    &self.damping[k],
                    [0, 1, 2].map(|c| (wj[c] - wi[c]) * w_scale),
                );
                for c in 0..3 {
                    f[c] -= q[c];
                }
            }
        }
        f
    }
}

impl FastElements {
    /// The model `kind` of `model` in the engine's internal order (`order`, `rank`), its
    /// tensor-mass rows following the springs' rows of `graph`. `None` for springs.
    pub(super) fn new(
        kind: ForceModelKind,
        model: &PackedModel,
        graph: &Graph,
        order: &[u32],
        rank: &[u32],
    ) -> Result<Option<Self>> {
        let Some(reference) = ElementForces::new(kind, model)? else {
            return Ok(None);
        };
        let damped = reference.elements().iter().any(|e| e.beta != 0.0);
        let layout = match &reference {
            ElementForces::TensorMass(tm) => Layout::Blocks(Blocks::of(tm, graph, order, damped)),
            ElementForces::Corotational(c) => Layout::Tets(Tets::of(
                &c.elements().iter().collect::<Vec<_>>(),
                rank,
                order.len(),
                graph,
            )),
        };
        Ok(Some(FastElements {
            reference,
            layout,
            damped,
            rotated: Vec::new(),
        }))
    }

    /// The float64 model behind the engine's arrays (the energy is measured on it).
    pub(super) fn reference(&self) -> &ElementForces {
        &self.reference
    }

    /// Whether a diff that adds `added` tets would damp an undamped model (its arrays are
    /// then rebuilt, as the springs' are for their first damped spring).
    pub(super) fn needs_rebuild(&self, added: &[PackedTet]) -> bool {
        !self.damped
            && added.iter().any(|t| {
                matches!(
                    t.material.damping,
                    crate::model::SpringDamping::StiffnessProportional(b) if b != 0.0
                )
            })
    }

    /// Follow `diff` (applied to `model`; the springs' graph, order and rank already patched):
    /// the float64 shares, then the touched rows or tets. The bytes written.
    pub(super) fn patch(
        &mut self,
        model: &PackedModel,
        diff: &ModelDiff,
        nodes_before: usize,
        graph: &Graph,
        order: &[u32],
        rank: &[u32],
    ) -> Result<u64> {
        self.reference.patch(&model.rest, diff)?;
        let damped = self.damped;
        let mut written = 0u64;
        match (&mut self.layout, &self.reference) {
            (Layout::Blocks(b), ElementForces::TensorMass(tm)) => {
                let mut touched: Vec<usize> = diff
                    .touched_nodes(nodes_before)
                    .iter()
                    .map(|&o| rank[o as usize] as usize)
                    .collect();
                touched.sort_unstable();
                for i in touched {
                    let row = Blocks::row_of(tm, graph, order, i, damped);
                    written += b.rewrite(i, row, damped);
                }
                // Rows of new nodes no diff entry touched (none in a cut) are empty.
                while b.rows.len() < order.len() {
                    let s = b.slots.len() as u32;
                    b.rows.push([s, s]);
                }
                if b.holes > b.slots.len() / 2 {
                    *b = Blocks::of(tm, graph, order, damped);
                    written += (b.slots.len() * std::mem::size_of::<Slot>()) as u64;
                }
            }
            (Layout::Tets(t), ElementForces::Corotational(_)) => {
                t.incidence.resize(order.len(), Vec::new());
                for &c in &diff.removed_tets {
                    t.swap_remove(c);
                }
                for tet in &diff.added_tets {
                    let e = TetElement::new(&model.rest, tet, t.nodes.len())?;
                    t.push(&e, rank, graph);
                    written += (std::mem::size_of::<[M3; 16]>() + 160 + 24) as u64;
                }
                let touched: Vec<usize> = diff
                    .touched_nodes(nodes_before)
                    .iter()
                    .map(|&o| rank[o as usize] as usize)
                    .collect();
                t.reslot(&touched, graph);
            }
            _ => unreachable!("the layout is of the reference's kind"),
        }
        Ok(written)
    }

    /// How the patched arrays differ from a rebuild for `model` in the same internal order.
    pub(super) fn differences(
        &self,
        model: &PackedModel,
        graph: &Graph,
        order: &[u32],
        rank: &[u32],
    ) -> Result<Vec<String>> {
        let mut out = self.reference.differences_from_rebuild(model)?;
        let Some(fresh) = Self::new(self.reference.kind(), model, graph, order, rank)? else {
            return Ok(out);
        };
        match (&self.layout, &fresh.layout) {
            (Layout::Blocks(a), Layout::Blocks(b)) => {
                let scale = b
                    .slots
                    .iter()
                    .flat_map(|s| s.k)
                    .fold(0.0f32, |m, v| m.max(v.abs()));
                for (i, &node) in order.iter().enumerate() {
                    let row = |x: &Blocks| {
                        let [s, e] = x.rows[i];
                        x.slots[s as usize..e as usize].to_vec()
                    };
                    let (ra, rb) = (row(a), row(b));
                    // The float64 shares were added in another order: a block may round to
                    // the neighbouring float32.
                    let same = ra.len() == rb.len()
                        && ra.iter().zip(&rb).all(|(p, q)| {
                            p.other == q.other
                                && p.k
                                    .iter()
                                    .zip(&q.k)
                                    .all(|(u, v)| (u - v).abs() <= 1e-6 * scale)
                        });
                    if !same {
                        out.push(format!(
                            "fast engine: the tensor-mass row of node {node} differs from a rebuild"
                        ));
                        break;
                    }
                }
            }
            (Layout::Tets(a), Layout::Tets(b)) => {
                if a.nodes != b.nodes || a.stiffness != b.stiffness || a.beta != b.beta {
                    out.push("fast engine: the corotational tets differ from a rebuild".into());
                } else if a.slots != b.slots {
                    out.push(
                        "fast engine: a corotational tet's row slots differ from a rebuild's \
                         (backward Euler would search for its blocks)"
                            .into(),
                    );
                }
                let sorted = |t: &Tets| -> Vec<Vec<u32>> {
                    t.incidence
                        .iter()
                        .map(|l| {
                            let mut l = l.clone();
                            l.sort_unstable();
                            l
                        })
                        .collect()
                };
                if sorted(a) != sorted(b) {
                    out.push(
                        "fast engine: a node's list of tet corners differs from a rebuild".into(),
                    );
                }
            }
            _ => unreachable!("rebuilt as the same kind"),
        }
        Ok(out)
    }

    /// Bytes of the element arrays, by name.
    pub(super) fn buffers(&self) -> Vec<(String, u64)> {
        match &self.layout {
            Layout::Blocks(b) => vec![
                (
                    "tensor-mass blocks".into(),
                    (b.slots.len() * std::mem::size_of::<Slot>()) as u64,
                ),
                (
                    "tensor-mass damping blocks".into(),
                    (b.damping.len() * 36) as u64,
                ),
                ("tensor-mass row bounds".into(), (b.rows.len() * 8) as u64),
            ],
            Layout::Tets(t) => vec![
                (
                    "corotational tets".into(),
                    (t.nodes.len()
                        * (16 + 72 + 72 + std::mem::size_of::<[M3; 16]>() + 4 + 48 + 36 + 24))
                        as u64,
                ),
                (
                    "corotational corner lists".into(),
                    t.incidence.iter().map(|l| l.len() as u64 * 4 + 24).sum(),
                ),
            ],
        }
    }

    /// Bytes a step reads and writes of the element arrays.
    pub(super) fn bytes_per_step(&self) -> u64 {
        match &self.layout {
            Layout::Blocks(b) => {
                ((b.slots.len() - b.holes) * std::mem::size_of::<Slot>()
                    + if self.damped {
                        (b.slots.len() - b.holes) * 36
                    } else {
                        0
                    }
                    + b.rows.len() * 8) as u64
            }
            // The tets are read once and their forces written, then read by the gather.
            Layout::Tets(_) => {
                self.buffers().iter().map(|b| b.1).sum::<u64>() + 2 * self.tet_count() as u64 * 48
            }
        }
    }

    fn tet_count(&self) -> usize {
        match &self.layout {
            Layout::Blocks(_) => self.reference.elements().len(),
            Layout::Tets(t) => t.nodes.len(),
        }
    }

    /// Elastic energy at positions `x` (model order), J, of the float64 model.
    pub(super) fn energy(&self, x: &[[f64; 3]]) -> f64 {
        self.reference.potential_energy(x)
    }
}

impl FastEngine {
    /// One explicit step with the finite-element force; then swap old and new.
    pub(super) fn step_elements(&mut self) {
        let Some(fem) = self.elements.as_mut() else {
            return;
        };
        let (g, p) = (&self.graph, self.params);
        let (x, s) = (&self.x, &self.second);
        let integrator = self.integrator;
        let w_scale = match integrator {
            Integrator::Verlet => p.inv_h,
            _ => 1.0,
        };
        if let Layout::Tets(t) = &mut fem.layout {
            t.element_pass(x, s, w_scale, false);
        }
        let fem = &*fem;
        let damped = fem.damped;
        super::kernels::for_block_pairs(
            &mut self.x_next,
            &mut self.second_next,
            |start, xo, so| {
                let force = |i: usize| match &fem.layout {
                    Layout::Blocks(b) => b.node_force(i, x, s, w_scale, damped),
                    Layout::Tets(t) => t.node_force(i),
                };
                integrate_block(integrator, g, p, x, s, start, xo, so, force);
            },
        );
        std::mem::swap(&mut self.x, &mut self.x_next);
        std::mem::swap(&mut self.second, &mut self.second_next);
    }
}

/// Verlet or symplectic Euler for nodes `start..` with the force `force(i)`, as the springs'
/// blocks (`kernels::verlet_block`, `kernels::euler_block`) integrate.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn integrate_block(
    integrator: Integrator,
    g: &Graph,
    p: Params,
    x: &[P],
    second: &[P],
    start: usize,
    xo: &mut [P],
    so: &mut [P],
    force: impl Fn(usize) -> [f32; 3],
) {
    for ((xo, so), i) in xo.iter_mut().zip(so.iter_mut()).zip(start..) {
        let (xi, si) = (x[i], second[i]);
        if g.fixed[i] {
            *xo = xi;
            *so = [0.0; 4];
            continue;
        }
        let f = force(i);
        let m = g.inv_mass[i];
        let mut step = [0.0f32; 3];
        match integrator {
            Integrator::Verlet => {
                for c in 0..3 {
                    let a = f[c] * m + p.gravity[c] - p.alpha * si[c] * p.inv_h;
                    so[c] = si[c] + p.h2 * a;
                    step[c] = so[c];
                }
            }
            _ => {
                for c in 0..3 {
                    let a = f[c] * m + p.gravity[c] - p.alpha * si[c];
                    so[c] = si[c] + p.h * a;
                    step[c] = p.h * so[c];
                }
            }
        }
        super::kernels::advance(xi, si, step, xo, so);
    }
}
