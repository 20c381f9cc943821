//! Twin of `shaders/springs_edges.wgsl` (pass 1 of the edge layout's gather variant,
//! `engine::gpu::springs_edges`): one force per spring, stored for its `a` end.

use super::edge_spring::edge_force;
use crate::layout::edges::EdgeLayout;
use crate::physics::StepParams;

impl EdgeLayout {
    /// The spring pass on the CPU, as `shaders/springs_edges.wgsl` computes it: the force each
    /// spring puts on its `a` end, in record order.
    pub fn spring_forces_cpu(
        &self,
        p: &StepParams,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> Vec<[f32; 4]> {
        self.springs
            .iter()
            .map(|s| edge_force(p, s, cur, second))
            .collect()
    }
}
