//! The implicit solve's product `A p` in the sliced layout of the springs (`sliced.rs`): each
//! spring end's 3x3 block is kept a second time lane by lane beside its group, so that one
//! SIMD lane forms one node's product and the eight lanes of a group are eight nodes' k-th
//! blocks, as the explicit step forms eight nodes' forces.
//!
//! Why: the product is most of each conjugate-gradient iteration, and read row by row it runs
//! a scalar chain of nine multiply-adds per spring end into one node's sum (about 3 ns an end
//! on this machine's cores, three times what the blocks' bytes need). Lane by lane the nine
//! multiply-adds are eight-wide (AVX2 and FMA where the CPU has them, chosen at run time like
//! the explicit kernels), and only the neighbours' values are gathered. The row-wise blocks stay
//! for the Gauss-Seidel sweep, which runs node after node within a block and cannot be laned.
//!
//! Each lane sums its node's blocks in row order, a fixed order: the same bits on any number
//! of threads. Padding lanes (rows shorter than their slice's longest) hold zero blocks.

use super::sliced::{Sliced, LANES};
use super::{dot64, sym_mul, Graph, NodeSystem, Sym, P};

/// The blocks of one group of the sliced layout, component by component: `[xx, yy, zz, xy,
/// xz, yz]`, eight lanes each.
pub(super) type Lanes = [[f32; LANES]; 6];

/// The lane-by-lane blocks, written by the assembly.
#[derive(Clone, Copy)]
pub(super) struct SharedLanes(pub(super) *mut Lanes, pub(super) usize);

// SAFETY: only used to write the lanes of the nodes a task owns (see `SharedLanes::node`), while
// the `Vec` it points into is borrowed mutably by the assembly and not otherwise touched.
unsafe impl Send for SharedLanes {}
unsafe impl Sync for SharedLanes {}

/// Writes node `i`'s blocks into its lane, in row order, and zeroes its padding.
pub(super) struct LaneWriter {
    lanes: SharedLanes,
    lane: usize,
    next: usize,
    end: usize,
}

impl SharedLanes {
    /// A writer for node `i`'s lane over its slice's groups.
    ///
    /// # Safety
    /// No other live writer may be for the same node, and the slices must be those of `sl`,
    /// which the array was sized for.
    pub(super) unsafe fn node(&self, sl: &Sliced, i: usize) -> LaneWriter {
        let [start, end] = sl.slices[i / LANES];
        assert!(end as usize <= self.1, "a group past the blocks");
        LaneWriter {
            lanes: *self,
            lane: i % LANES,
            next: start as usize,
            end: end as usize,
        }
    }
}

impl LaneWriter {
    /// The row's next block.
    #[inline(always)]
    pub(super) fn push(&mut self, s: &Sym) {
        assert!(self.next < self.end, "a row longer than its slice");
        // SAFETY: `next < end <= len` (checked), and the lane is this writer's own.
        let group = unsafe { &mut *self.lanes.0.add(self.next) };
        for (c, v) in s.iter().enumerate() {
            group[c][self.lane] = *v;
        }
        self.next += 1;
    }

    /// Zero the rest of the lane (the row's padding).
    #[inline(always)]
    pub(super) fn finish(mut self) {
        while self.next < self.end {
            self.push(&[0.0; 6]);
        }
    }
}

/// `Ap` for the nodes `start..start + out.len()` (`start` a multiple of [`LANES`]): zero on
/// fixed nodes; returns `p . Ap` over them, summed in float64 in node order.
#[inline(always)]
pub(super) fn product_slices(
    g: &Graph,
    lanes: &[Lanes],
    nodes: &[NodeSystem],
    p: &[P],
    start: usize,
    out: &mut [P],
) -> f64 {
    let sl = &g.springs;
    let mut sum = 0.0f64;
    for (s, chunk) in out.chunks_mut(LANES).enumerate() {
        let b = start / LANES + s;
        let mut acc = [[0.0f32; LANES]; 3];
        let [first, end] = sl.slices[b];
        let range = first as usize..end as usize;
        for (grp, blk) in sl.groups[range.clone()].iter().zip(&lanes[range]) {
            let mut q = [[0.0f32; LANES]; 3];
            for l in 0..LANES {
                let pj = p[grp.node(l)];
                for a in 0..3 {
                    q[a][l] = pj[a];
                }
            }
            for l in 0..LANES {
                acc[0][l] += blk[0][l] * q[0][l] + blk[3][l] * q[1][l] + blk[4][l] * q[2][l];
                acc[1][l] += blk[3][l] * q[0][l] + blk[1][l] * q[1][l] + blk[5][l] * q[2][l];
                acc[2][l] += blk[4][l] * q[0][l] + blk[5][l] * q[1][l] + blk[2][l] * q[2][l];
            }
        }
        for (l, o) in chunk.iter_mut().enumerate() {
            let i = b * LANES + l;
            if g.fixed[i] {
                *o = [0.0; 4];
                continue;
            }
            let d = sym_mul(&nodes[i].diag, p[i]);
            *o = [d[0] - acc[0][l], d[1] - acc[1][l], d[2] - acc[2][l], 0.0];
            sum += dot64(p[i], *o);
        }
    }
    sum
}

/// [`product_slices`] compiled for AVX2 and FMA.
///
/// # Safety
/// The CPU must have AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn product_slices_wide(
    g: &Graph,
    lanes: &[Lanes],
    nodes: &[NodeSystem],
    p: &[P],
    start: usize,
    out: &mut [P],
) -> f64 {
    product_slices(g, lanes, nodes, p, start, out)
}
