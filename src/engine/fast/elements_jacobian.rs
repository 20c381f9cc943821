//! Backward Euler's rows of the system from the finite-element arrays of the fast engine: for
//! each node `i` and each entry `j` of its row (the springs' row: the tet edges), the block
//! `B_ij = -(h D_ij + h^2 K_ij)` of the force's derivatives, with `A_ij = -B_ij` the system's
//! off-diagonal block (so that `A_ii = (1 + h alpha) m_i I + sum_j B_ij`, every element's block
//! rows summing to zero), and the node's force and `K v` at the same state.
//!
//! **Tensor-mass.** `K` is constant: `B_ij = -(h^2 K_ij + h C_ij)` straight from the slots
//! (`K_ij` the tensor of `elements.rs`, whose force is `-K_ij (u_j - u_i)`).
//!
//! **Corotational.** `K` is the corotated `-R K_e R^T` of each tet, its rotation `R` that of
//! the state the system is linearised at and frozen over the solve (the derivative of `R` is
//! neglected, as the float64 model and SOFA neglect it: symmetric and negative semi-definite,
//! so conjugate gradients always apply). Rayleigh's damping is `beta` times the same block.
//! The rotations come from the element pass that also forms the force; a pass over the tets
//! then forms each tet's six blocks `R K_ab R^T`, `a < b` (`K_ba = K_ab^T`, so the pair `b, a`
//! reads the transpose: half the products of forming the twelve, and rows `i, j` and `j, i`
//! hold exact transposes), and node `i` reads those of its own corners, so rows are written by
//! the task that owns the node. Each block goes to the entry of the row that the tet's slot
//! table names (`Tets::slots`, written with the layout and patched at cuts), not searched for.

use super::{FastElements, Layout, Tets, M3};
use crate::engine::fast::implicit::FullBlock;
use crate::engine::fast::{Graph, P};

impl FastElements {
    /// Before forming rows at displacements `x` and velocities `v`: the corotational tets'
    /// corner forces (with their damping at `v`) and rotations.
    pub(in crate::engine::fast) fn linearize(&mut self, x: &[P], v: &[P]) {
        if let Layout::Tets(t) = &mut self.layout {
            t.element_pass(x, v, 1.0, true);
            t.corotate_pass(&mut self.rotated);
        }
    }

    /// Node `i`'s row of the system at `(x, v)` for the step `h`, written into `row` in the
    /// order of the springs' row of `i` (every entry's `other` set, zero where no tet joins the
    /// two nodes); returns the node's element force (elastic and damping) and `K v`. For a
    /// corotational model, after [`FastElements::linearize`] at the same state.
    pub(in crate::engine::fast) fn implicit_row(
        &self,
        i: usize,
        g: &Graph,
        x: &[P],
        v: &[P],
        h: f32,
        row: &mut [FullBlock],
    ) -> ([f32; 3], [f32; 3]) {
        for (out, (e, _)) in row.iter_mut().zip(g.springs.row(i)) {
            *out = FullBlock {
                m: [0.0; 9],
                other: e.other,
            };
        }
        match &self.layout {
            Layout::Blocks(b) => {
                let (f, kv) = (b.node_force(i, x, v, 1.0, self.damped), {
                    // `K v` is the elastic force's formula on velocities.
                    b.node_force(i, v, v, 0.0, false)
                });
                let [start, end] = b.rows[i];
                let slots = start as usize..end as usize;
                let mut next = slots.start;
                for out in row.iter_mut() {
                    // The slots follow the springs' row, those without a tensor left out.
                    let k = if next < slots.end && b.slots[next].other == out.other {
                        next += 1;
                        next - 1
                    } else {
                        match slots.clone().find(|&k| b.slots[k].other == out.other) {
                            Some(k) => k,
                            None => continue,
                        }
                    };
                    let c = if self.damped { b.damping[k] } else { [0.0; 9] };
                    let kk = &b.slots[k].k;
                    out.m = std::array::from_fn(|n| -(h * h * kk[n] + h * c[n]));
                }
                (f, kv)
            }
            Layout::Tets(t) => (
                t.node_force(i),
                t.corotated_row(&self.rotated, i, v, h, row),
            ),
        }
    }
}

/// Index of the pair `a < b` among a tet's six.
#[inline(always)]
fn upper_pair(a: usize, b: usize) -> usize {
    debug_assert!(a < b);
    match a {
        0 => b - 1,
        1 => b + 1,
        _ => 5,
    }
}

impl Tets {
    /// Every tet's six blocks `R K_ab R^T`, `a < b`, at the rotations of the last element
    /// pass, into `rotated` ([`FastElements::rotated`]).
    fn corotate_pass(&self, rotated: &mut Vec<[M3; 6]>) {
        rotated.resize(self.rotations.len(), [[0.0; 9]; 6]);
        let this = self;
        let run = |start: usize, chunk: &mut [[M3; 6]]| {
            for (k, out) in chunk.iter_mut().enumerate() {
                let t = start + k;
                let r = &this.rotations[t];
                for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                    out[upper_pair(a, b)] = corotate(r, &this.stiffness[t][4 * a + b]);
                }
            }
        };
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            rotated
                .par_chunks_mut(super::BLOCK)
                .enumerate()
                .for_each(|(b, chunk)| run(b * super::BLOCK, chunk));
        }
        #[cfg(not(feature = "parallel"))]
        for (b, chunk) in rotated.chunks_mut(super::BLOCK).enumerate() {
            run(b * super::BLOCK, chunk);
        }
    }

    /// Node `i`'s blocks `-(h beta + h^2) R K_ab R^T` (read from `rotated`, the last
    /// [`Tets::corotate_pass`]) added into `row` (found by the other corner), and
    /// `K v = -sum R K_ab R^T (v_b - v_a)` over the tets at `i` returned.
    fn corotated_row(
        &self,
        rotated: &[[M3; 6]],
        i: usize,
        v: &[P],
        h: f32,
        row: &mut [FullBlock],
    ) -> [f32; 3] {
        let mut kv = [0.0f32; 3];
        let vi = v[i];
        for &corner in &self.incidence[i] {
            let (t, a) = ((corner / 4) as usize, (corner % 4) as usize);
            let rotated = &rotated[t];
            let scale = -(h * self.beta[t] + h * h);
            for b in (0..4).filter(|&b| b != a) {
                let block = if a < b {
                    rotated[upper_pair(a, b)]
                } else {
                    let m = &rotated[upper_pair(b, a)];
                    [m[0], m[3], m[6], m[1], m[4], m[7], m[2], m[5], m[8]]
                };
                let j = self.nodes[t][b];
                let slot = self.slots[t][super::pair_index(a, b)] as usize;
                let dv = [0, 1, 2].map(|c| v[j as usize][c] - vi[c]);
                let q = super::mul(&block, dv);
                for c in 0..3 {
                    kv[c] -= q[c];
                }
                // The slot written with the tet; checked, so that a stale one (which the
                // rebuild comparison reports) costs a scan of the row, never a wrong block.
                let entry = match row.get_mut(slot) {
                    Some(e) if e.other == j => Some(e),
                    _ => row.iter_mut().find(|e| e.other == j),
                };
                match entry {
                    Some(e) => {
                        for (m, b) in e.m.iter_mut().zip(block) {
                            *m += scale * b;
                        }
                    }
                    None => debug_assert!(false, "a tet edge with no spring"),
                }
            }
        }
        kv
    }
}

/// `R K R^T` in float32.
#[inline(always)]
fn corotate(r: &M3, k: &M3) -> M3 {
    // `RK = R K`, then `(R K) R^T`.
    let rk: M3 = std::array::from_fn(|n| {
        let (row, col) = (n / 3, n % 3);
        (0..3).map(|l| r[3 * row + l] * k[3 * l + col]).sum()
    });
    std::array::from_fn(|n| {
        let (row, col) = (n / 3, n % 3);
        (0..3).map(|l| rk[3 * row + l] * r[3 * col + l]).sum()
    })
}
