//! Twins of the tensor-mass passes (`engine::gpu::tensor_mass`): on the node-centric layouts
//! `shaders/tensor_gather.wgsl` with `tensor_connectivity.wgsl` or `tensor_valence.wgsl` (each
//! node sums `-K_ij (u_j - u_i) - C_ij (v_j - v_i)` over its slots and integrates); on the edge
//! layout `tensor_edges.wgsl` (each record's two end forces), then `tensor_gather_edges.wgsl`
//! (each node sums its ends' forces in incidence order and integrates).

use crate::layout::edges::{EdgeLayout, B_END};
use crate::layout::tensor_blocks::{slot_walk, Row, TensorBlocks};
use crate::layout::PackedLayout;
use crate::physics::{integrate, velocity, StepParams};

/// `a . b` over the first three lanes, in the order WGSL's `dot` is lowered.
fn dot3(a: &Row, b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl TensorBlocks {
    /// `K du + C dv` of slot `slot` (`C` only when damped), as `tensor_force` computes it.
    pub fn force_cpu(&self, slot: usize, du: [f32; 3], dv: [f32; 3]) -> [f32; 3] {
        let b = &self.rows[slot * self.stride()..];
        let mut f = [dot3(&b[0], du), dot3(&b[1], du), dot3(&b[2], du)];
        if self.damped {
            let g = [dot3(&b[3], dv), dot3(&b[4], dv), dot3(&b[5], dv)];
            f = [f[0] + g[0], f[1] + g[1], f[2] + g[2]];
        }
        f
    }

    /// `K^T du + C^T dv` of slot `slot`, as `tensor_force_t` computes it (row by row, scaled).
    pub fn force_t_cpu(&self, slot: usize, du: [f32; 3], dv: [f32; 3]) -> [f32; 3] {
        let b = &self.rows[slot * self.stride()..];
        let t = |r: &[Row], d: [f32; 3]| -> [f32; 3] {
            std::array::from_fn(|c| r[0][c] * d[0] + r[1][c] * d[1] + r[2][c] * d[2])
        };
        let mut f = t(&b[0..3], du);
        if self.damped {
            let g = t(&b[3..6], dv);
            f = [f[0] + g[0], f[1] + g[1], f[2] + g[2]];
        }
        f
    }

    /// The elastic and damping force on every node of a node-centric `layout` (connectivity,
    /// valence), summed over its slots in the order its pass sums them.
    pub fn node_forces_cpu(
        &self,
        p: &StepParams,
        layout: &PackedLayout,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> Vec<[f32; 3]> {
        let mut f = vec![[0.0f32; 3]; cur.len()];
        for (i, slot, j) in slot_walk(layout) {
            let (i, j) = (i as usize, j as usize);
            let du = [0, 1, 2].map(|c| cur[j][c] - cur[i][c]);
            let dv = if p.damped {
                let (vi, vj) = (
                    velocity(p, cur[i], second[i]),
                    velocity(p, cur[j], second[j]),
                );
                [0, 1, 2].map(|c| vj[c] - vi[c])
            } else {
                [0.0; 3]
            };
            let g = self.force_cpu(slot, du, dv);
            for c in 0..3 {
                f[i][c] -= g[c];
            }
        }
        f
    }

    /// The record pass of the edge layout: per record `(a, b)`, the force on `a`,
    /// `-(K du + C dv)`, at `2 r` and on `b`, `K^T du + C^T dv`, at `2 r + 1`, with
    /// `du = u_b - u_a`.
    pub fn record_forces_cpu(
        &self,
        p: &StepParams,
        edges: &EdgeLayout,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> Vec<[f32; 4]> {
        let mut out = vec![[0.0f32; 4]; 2 * edges.springs.len()];
        for (r, s) in edges.springs.iter().enumerate() {
            let (a, b) = (s.a as usize, s.b as usize);
            let du = [0, 1, 2].map(|c| cur[b][c] - cur[a][c]);
            let dv = if p.damped {
                let (va, vb) = (
                    velocity(p, cur[a], second[a]),
                    velocity(p, cur[b], second[b]),
                );
                [0, 1, 2].map(|c| vb[c] - va[c])
            } else {
                [0.0; 3]
            };
            let fa = self.force_cpu(r, du, dv);
            let fb = self.force_t_cpu(r, du, dv);
            out[2 * r] = [-fa[0], -fa[1], -fa[2], 0.0];
            out[2 * r + 1] = [fb[0], fb[1], fb[2], 0.0];
        }
        out
    }

    /// The node pass of the edge layout: each node sums its ends' forces in incidence order.
    pub fn gather_edges_cpu(&self, edges: &EdgeLayout, forces: &[[f32; 4]]) -> Vec<[f32; 3]> {
        (0..edges.node_count())
            .map(|i| {
                let mut f = [0.0f32; 3];
                for &e in edges.row(i) {
                    let end = usize::from(e & B_END != 0);
                    let g = forces[2 * (e & !B_END) as usize + end];
                    for c in 0..3 {
                        f[c] += g[c];
                    }
                }
                f
            })
            .collect()
    }

    /// One tensor-mass step of `layout` on the CPU, exactly as its passes take it: the node
    /// forces (gathered over slots, or over the edge records' end forces), then every free
    /// node integrated. Fixed nodes (and holes) stay at rest.
    pub fn step_cpu(
        &self,
        p: &StepParams,
        layout: &PackedLayout,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let (f, inv_mass) = match layout {
            PackedLayout::Edges(e) => {
                let forces = self.record_forces_cpu(p, e, cur, second);
                (self.gather_edges_cpu(e, &forces), &e.nodes.inv_mass)
            }
            PackedLayout::Connectivity(c) => (
                self.node_forces_cpu(p, layout, cur, second),
                &c.nodes.inv_mass,
            ),
            PackedLayout::Valence(v) => (
                self.node_forces_cpu(p, layout, cur, second),
                &v.nodes.inv_mass,
            ),
        };
        let n = cur.len();
        let mut next = vec![[0.0f32; 4]; n];
        let mut second_next = vec![[0.0f32; 4]; n];
        for i in 0..n {
            let m_inv = inv_mass.get(i).copied().unwrap_or(0.0);
            if m_inv == 0.0 {
                continue;
            }
            let vi = velocity(p, cur[i], second[i]);
            (next[i], second_next[i]) = integrate(p, cur[i], second[i], vi, f[i], m_inv);
        }
        (next, second_next)
    }
}
