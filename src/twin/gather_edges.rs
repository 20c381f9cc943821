//! Twin of `shaders/gather_edges.wgsl` (pass 2 of the edge layout's gather variant,
//! `engine::gpu::springs_edges`): each node sums its incident springs' forces in the incidence
//! table's order and integrates. The integration alone ([`EdgeLayout::integrate_cpu`]) is also
//! the node half of the atomic variants ([`super::integrate_fixed`], [`super::integrate_float`]).

use crate::layout::edges::{EdgeLayout, B_END};
use crate::physics::{integrate, velocity, StepParams};

impl EdgeLayout {
    /// The node forces of the gather pass: each node sums its incident forces in table order
    /// (as `shaders/gather_edges.wgsl` does).
    pub fn gather_forces_cpu(&self, forces: &[[f32; 4]]) -> Vec<[f32; 3]> {
        (0..self.node_count())
            .map(|i| {
                let mut f = [0.0f32; 3];
                for &e in self.row(i) {
                    let fs = forces[(e & !B_END) as usize];
                    if e & B_END != 0 {
                        for c in 0..3 {
                            f[c] -= fs[c];
                        }
                    } else {
                        for c in 0..3 {
                            f[c] += fs[c];
                        }
                    }
                }
                f
            })
            .collect()
    }

    /// The node pass on the CPU, as `shaders/gather_edges.wgsl` computes it: each node sums its
    /// incident forces in table order and integrates.
    pub fn gather_cpu(
        &self,
        p: &StepParams,
        forces: &[[f32; 4]],
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let f = self.gather_forces_cpu(forces);
        self.integrate_cpu(p, &f, cur, second)
    }

    /// Integrate every node under its spring force `f` (fixed nodes stay at rest), as the node
    /// passes of every variant do.
    pub fn integrate_cpu(
        &self,
        p: &StepParams,
        f: &[[f32; 3]],
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let n = cur.len();
        let mut next = vec![[0.0f32; 4]; n];
        let mut second_next = vec![[0.0f32; 4]; n];
        for i in 0..n {
            let m_inv = self.nodes.inv_mass[i];
            if m_inv == 0.0 {
                continue;
            }
            let vi = velocity(p, cur[i], second[i]);
            (next[i], second_next[i]) = integrate(p, cur[i], second[i], vi, f[i], m_inv);
        }
        (next, second_next)
    }

    /// Both passes of the gather variant: one step on the CPU.
    pub fn step_cpu(
        &self,
        p: &StepParams,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let forces = self.spring_forces_cpu(p, cur, second);
        self.gather_cpu(p, &forces, cur, second)
    }
}
