//! Twin of `shaders/integrate_fixed.wgsl` (pass 2 of the edge layout's fixed-point variant,
//! `engine::gpu::atomic_edges`): each node converts its integer accumulators to a force and
//! integrates; and the whole fixed-point step.

use crate::layout::edges::{EdgeLayout, FixedPoint};
use crate::physics::StepParams;

impl EdgeLayout {
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
}
