//! Twin of `shaders/springs_valence.wgsl` (pass `engine::gpu::springs_valence`): every node of
//! every valence bucket gathers its row, exactly as wide as its valence, and integrates.

use super::node_gather::node_update;
use crate::layout::valence::ValenceLayout;
use crate::physics::StepParams;

impl ValenceLayout {
    /// One step on the CPU exactly as `shaders/springs_valence.wgsl` does it (the GPU pass's
    /// twin); see [`ConnectivityLayout::step_cpu`](crate::layout::connectivity::ConnectivityLayout::step_cpu)
    /// for the arguments. Holes (room left in a bucket) stay at zero.
    pub fn step_cpu(
        &self,
        p: &StepParams,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let mut next = vec![[0.0f32; 4]; cur.len()];
        let mut second_next = vec![[0.0f32; 4]; cur.len()];
        for b in &self.buckets {
            for local in 0..b.count {
                let i = (b.first + local) as usize;
                let base = (b.offset + local * b.valence) as usize;
                let row = &self.slots[base..base + b.valence as usize];
                let (u, s) = node_update(p, row, self.nodes.inv_mass[i], cur, second, i);
                next[i] = u;
                second_next[i] = s;
            }
        }
        (next, second_next)
    }
}
