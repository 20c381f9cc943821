//! Twin of `shaders/integrate_float.wgsl` (pass 2 of the edge layout's float-atomic variant,
//! `engine::gpu::atomic_edges`): each node integrates under its accumulated force; and the
//! whole float-atomic step.

use crate::layout::edges::EdgeLayout;
use crate::physics::StepParams;

impl EdgeLayout {
    /// One float-atomic step on the CPU, summing in record order (spring pass, then the node
    /// pass, whose integration is [`EdgeLayout::integrate_cpu`]).
    pub fn step_float_cpu(
        &self,
        p: &StepParams,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let forces = self.spring_forces_cpu(p, cur, second);
        self.integrate_cpu(p, &self.accumulate_float_cpu(&forces), cur, second)
    }
}
