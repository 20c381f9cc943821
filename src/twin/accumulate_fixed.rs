//! Twin of `shaders/accumulate_fixed.wgsl` (pass 1 of the edge layout's fixed-point variant,
//! `engine::gpu::atomic_edges`): each spring's force, quantized, added to its ends' integer
//! accumulators.

use crate::layout::edges::{EdgeLayout, FixedPoint};

impl EdgeLayout {
    /// The fixed-point spring pass on the CPU, as `shaders/accumulate_fixed.wgsl` computes it:
    /// the integer accumulators of every node (wrapping adds, as `atomicAdd` on `i32`) and
    /// whether any spring force saturated. `forces` are the springs' forces on their `a` ends
    /// ([`EdgeLayout::spring_forces_cpu`]).
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
}
