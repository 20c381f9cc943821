//! The CPU twins of the edge layout's passes, in the order the shaders compute: the spring pass
//! (`shaders/springs_edges.wgsl`), the gather and integration (`gather_edges.wgsl`), the
//! fixed-point and float atomic accumulations (`accumulate_*.wgsl`, `integrate_*.wgsl`), and a
//! whole step in each variant.

use super::*;

impl EdgeLayout {
    /// The spring pass on the CPU, as `shaders/springs_edges.wgsl` computes it: the force each
    /// spring puts on its `a` end.
    pub fn spring_forces_cpu(
        &self,
        p: &StepParams,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> Vec<[f32; 4]> {
        self.springs
            .iter()
            .map(|s| {
                let (a, b) = (s.a as usize, s.b as usize);
                let d = [
                    s.edge[0] + (cur[b][0] - cur[a][0]),
                    s.edge[1] + (cur[b][1] - cur[a][1]),
                    s.edge[2] + (cur[b][2] - cur[a][2]),
                ];
                let dv = if p.damped {
                    let (va, vb) = (
                        velocity(p, cur[a], second[a]),
                        velocity(p, cur[b], second[b]),
                    );
                    [vb[0] - va[0], vb[1] - va[1], vb[2] - va[2]]
                } else {
                    [0.0; 3]
                };
                let f = spring_force(p, s.k, s.rest, s.c, d, dv);
                [f[0], f[1], f[2], 0.0]
            })
            .collect()
    }

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

    /// The fixed-point spring pass on the CPU, as `shaders/accumulate_fixed.wgsl` computes it:
    /// the integer accumulators of every node (wrapping adds, as `atomicAdd` on `i32`) and
    /// whether any spring force saturated.
    pub fn accumulate_fixed_cpu(
        &self,
        fp: &FixedPoint,
        forces: &[[f32; 4]],
    ) -> (Vec<[i32; 3]>, bool) {
        let mut acc = vec![[0i32; 3]; self.node_count()];
        let mut overflow = false;
        for (s, f) in self.springs.iter().zip(forces) {
            for c in 0..3 {
                let (q, o) = fp.quantize(f[c]);
                overflow |= o;
                acc[s.a as usize][c] = acc[s.a as usize][c].wrapping_add(q);
                acc[s.b as usize][c] = acc[s.b as usize][c].wrapping_sub(q);
            }
        }
        (acc, overflow)
    }

    /// Node forces from fixed-point accumulators, as `shaders/integrate_fixed.wgsl` converts
    /// them: `f32(sum) * inv_scale`.
    pub fn fixed_forces(fp: &FixedPoint, acc: &[[i32; 3]]) -> Vec<[f32; 3]> {
        acc.iter()
            .map(|q| [0, 1, 2].map(|c| q[c] as f32 * fp.inv_scale))
            .collect()
    }

    /// One fixed-point step on the CPU (spring pass, then integration), and whether any force
    /// saturated. Bitwise independent of the spring order.
    pub fn step_fixed_cpu(
        &self,
        p: &StepParams,
        fp: &FixedPoint,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>, bool) {
        let forces = self.spring_forces_cpu(p, cur, second);
        let (acc, overflow) = self.accumulate_fixed_cpu(fp, &forces);
        let (next, second_next) = self.integrate_cpu(p, &Self::fixed_forces(fp, &acc), cur, second);
        (next, second_next, overflow)
    }

    /// The float-atomic spring pass on the CPU in one of the orders a device may take: springs
    /// in record order, `a` end before `b` end (`shaders/accumulate_float.wgsl`).
    pub fn accumulate_float_cpu(&self, forces: &[[f32; 4]]) -> Vec<[f32; 3]> {
        let mut acc = vec![[0.0f32; 3]; self.node_count()];
        for (s, f) in self.springs.iter().zip(forces) {
            for c in 0..3 {
                acc[s.a as usize][c] += f[c];
                acc[s.b as usize][c] += -f[c];
            }
        }
        acc
    }

    /// One float-atomic step on the CPU, summing in record order.
    pub fn step_float_cpu(
        &self,
        p: &StepParams,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let forces = self.spring_forces_cpu(p, cur, second);
        self.integrate_cpu(p, &self.accumulate_float_cpu(&forces), cur, second)
    }

    /// One step of `accumulation` on the CPU (fixed point with [`EdgeLayout::fixed_point`]
    /// constants supplied as `fp`; the overflow flag is dropped).
    pub fn step_variant_cpu(
        &self,
        accumulation: Accumulation,
        p: &StepParams,
        fp: &FixedPoint,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        match accumulation {
            Accumulation::Gather => self.step_cpu(p, cur, second),
            Accumulation::AtomicFixed => {
                let (u, s, _) = self.step_fixed_cpu(p, fp, cur, second);
                (u, s)
            }
            Accumulation::AtomicFloat => self.step_float_cpu(p, cur, second),
        }
    }

    /// Both passes: one step on the CPU.
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
