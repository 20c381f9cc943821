//! Twin of `shaders/accumulate_float.wgsl` (pass 1 of the edge layout's float-atomic variant,
//! `engine::gpu::atomic_edges`): each spring's force added to its ends' float accumulators, in
//! one of the orders a device may take.

use crate::layout::edges::EdgeLayout;

impl EdgeLayout {
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
}
