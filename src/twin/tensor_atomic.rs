//! Twins of the tensor-mass record passes on the edge layout's atomic variants
//! (`engine::gpu::tensor_atomic`): `shaders/tensor_accumulate_fixed.wgsl` (each record's two
//! end forces, quantized, added to their own ends' integer accumulators) and
//! `shaders/tensor_accumulate_float.wgsl` (added as floats, in one of the orders a device may
//! take); the node passes are the springs' (`twin::integrate_fixed`, `twin::integrate_float`).

use crate::layout::edges::{Accumulation, EdgeLayout, FixedPoint};
use crate::layout::tensor_blocks::TensorBlocks;
use crate::physics::StepParams;

use super::State;

impl TensorBlocks {
    /// The fixed-point record pass on the CPU: the integer accumulators of every node
    /// (wrapping adds, as `atomicAdd` on `i32`) and whether any end force saturated. `forces`
    /// are the records' end forces ([`TensorBlocks::record_forces_cpu`]: `a` at `2 r`, `b` at
    /// `2 r + 1`).
    pub fn accumulate_fixed_cpu(
        edges: &EdgeLayout,
        fp: &FixedPoint,
        forces: &[[f32; 4]],
    ) -> (Vec<[i32; 3]>, bool) {
        let mut acc = vec![[0i32; 3]; edges.node_count()];
        let mut overflow = false;
        for (r, s) in edges.springs.iter().enumerate() {
            for (end, node) in [(0, s.a), (1, s.b)] {
                let f = forces[2 * r + end];
                for c in 0..3 {
                    let (q, o) = fp.quantize(f[c]);
                    overflow |= o;
                    let a = &mut acc[node as usize][c];
                    *a = a.wrapping_add(q);
                }
            }
        }
        (acc, overflow)
    }

    /// The float-atomic record pass on the CPU in one of the orders a device may take:
    /// records in order, the `a` end before the `b` end.
    pub fn accumulate_float_cpu(edges: &EdgeLayout, forces: &[[f32; 4]]) -> Vec<[f32; 3]> {
        let mut acc = vec![[0.0f32; 3]; edges.node_count()];
        for (r, s) in edges.springs.iter().enumerate() {
            for (end, node) in [(0, s.a), (1, s.b)] {
                let f = forces[2 * r + end];
                for c in 0..3 {
                    acc[node as usize][c] += f[c];
                }
            }
        }
        acc
    }

    /// One tensor-mass step of the edge layout's `accumulation` on the CPU, as its passes take
    /// it: the record pass, then the node pass (fixed point with the constants `fp`; the
    /// overflow flag is dropped). The gather is [`TensorBlocks::step_cpu`]'s.
    pub fn step_atomic_cpu(
        &self,
        accumulation: Accumulation,
        p: &StepParams,
        edges: &EdgeLayout,
        fp: &FixedPoint,
        cur: &[[f32; 4]],
        second: &[[f32; 4]],
    ) -> State {
        let forces = self.record_forces_cpu(p, edges, cur, second);
        let f = match accumulation {
            Accumulation::AtomicFixed => {
                EdgeLayout::fixed_forces(fp, &Self::accumulate_fixed_cpu(edges, fp, &forces).0)
            }
            Accumulation::AtomicFloat => Self::accumulate_float_cpu(edges, &forces),
            Accumulation::Gather => self.gather_edges_cpu(edges, &forces),
        };
        edges.integrate_cpu(p, &f, cur, second)
    }
}
