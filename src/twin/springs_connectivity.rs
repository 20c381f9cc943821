//! Twin of `shaders/springs_connectivity.wgsl` (pass `engine::gpu::springs_connectivity`): every
//! node gathers its row of fixed slots, continuing in overflow rows, and integrates.

use super::node_gather::node_update;
use crate::layout::connectivity::ConnectivityLayout;
use crate::physics::StepParams;

impl ConnectivityLayout {
    /// One step on the CPU, exactly as `shaders/springs_connectivity.wgsl` does it: the twin the
    /// GPU pass is tested against. `second` is the last step (Verlet) or the
    /// velocity (symplectic Euler); returns the next displacement and the next second state.
    pub fn step_cpu(
        &self,
        p: &StepParams,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
        let mut next = vec![[0.0f32; 4]; cur.len()];
        let mut second_next = vec![[0.0f32; 4]; cur.len()];
        for i in 0..cur.len() {
            let row = self.row(i);
            let (u, s) = node_update(p, &row, self.nodes.inv_mass[i], cur, second, i);
            next[i] = u;
            second_next[i] = s;
        }
        (next, second_next)
    }
}
