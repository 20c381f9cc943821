//! The fast engine's reads of the nodes in a box (a blade's sweep): a scan of its own arrays,
//! in parallel right after a step when the cut that follows asked for it ahead
//! ([`Engine::prefetch_near`](crate::engine::Engine::prefetch_near)), which the cut's own read
//! then narrows.

use super::FastEngine;

/// Nodes per task of a scan for the nodes near a blade made with a step.
#[cfg(feature = "parallel")]
const NEAR_BLOCK: usize = 8192;

/// Nodes found in a box after a step, in node order, with their positions.
pub(super) struct ReadAhead {
    lo: [f64; 3],
    hi: [f64; 3],
    found: Vec<(u32, [f64; 3])>,
}

impl FastEngine {
    /// The nodes among internal indices `range` whose position lies in the box `lo..=hi`, with
    /// their positions as [`Engine::positions`] gives them, in internal order.
    fn scan_near(
        &self,
        lo: [f64; 3],
        hi: [f64; 3],
        range: std::ops::Range<usize>,
    ) -> Vec<(u32, [f64; 3])> {
        // A scan of the engine's own arrays, in their order: no copy of every position. The box
        // is first tested in float32 (rest and displacement side by side), grown by the
        // rounding of that sum, which rejects most nodes without gathering their float64 rest.
        let (lo32, hi32) = crate::engine::reading::float32_box(lo, hi);
        let mut out = Vec::new();
        for i in range {
            let (r, u) = (self.rest_inner[i], self.x[i]);
            // Without short circuits: no branch per coordinate, and most nodes are outside.
            let x = [r[0] + u[0], r[1] + u[1], r[2] + u[2]];
            let maybe = (x[0] >= lo32[0])
                & (x[0] <= hi32[0])
                & (x[1] >= lo32[1])
                & (x[1] <= hi32[1])
                & (x[2] >= lo32[2])
                & (x[2] <= hi32[2]);
            if !maybe && !self.graph.fixed[i] {
                continue;
            }
            let x = self.position_at(i);
            if crate::engine::reading::inside(&x, &lo, &hi) {
                out.push((self.order[i], x));
            }
        }
        out
    }

    /// [`FastEngine::scan_near`] over every node, in node order: on the step's threads when
    /// `parallel` (they are awake right after a step; woken for a scan of their own, they
    /// would cost more than they save).
    fn scan_near_sorted(&self, lo: [f64; 3], hi: [f64; 3], parallel: bool) -> Vec<(u32, [f64; 3])> {
        let n = self.x.len();
        #[cfg(feature = "parallel")]
        let mut out: Vec<(u32, [f64; 3])> = if parallel {
            use rayon::prelude::*;
            let starts: Vec<usize> = (0..n).step_by(NEAR_BLOCK).collect();
            starts
                .into_par_iter()
                .flat_map_iter(|s| self.scan_near(lo, hi, s..(s + NEAR_BLOCK).min(n)))
                .collect()
        } else {
            self.scan_near(lo, hi, 0..n)
        };
        #[cfg(not(feature = "parallel"))]
        let mut out = {
            let _ = parallel;
            self.scan_near(lo, hi, 0..n)
        };
        crate::engine::reading::sort_by_node(&mut out);
        out
    }

    /// The nodes in the box `lo..=hi` in node order, with their positions: a narrowing of
    /// the read made ahead where it holds the box, else a scan of its own.
    pub(super) fn read_near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Vec<(u32, [f64; 3])> {
        if let Some(a) = &self.read_ahead {
            if (0..3).all(|c| a.lo[c] <= lo[c] && hi[c] <= a.hi[c]) {
                self.near_reads.ahead += 1;
                // Narrowed by the exact test a scan of its own makes last: the same list.
                return a
                    .found
                    .iter()
                    .filter(|(_, x)| crate::engine::reading::inside(x, &lo, &hi))
                    .copied()
                    .collect();
            }
        }
        self.near_reads.direct += 1;
        self.scan_near_sorted(lo, hi, false)
    }

    /// The read the cut after a step will make, made right after the step while the state is
    /// in cache and the threads are awake, where one was asked for.
    pub(super) fn read_near_ahead(&mut self) {
        if let Some((lo, hi)) = self.near_ahead.take() {
            let found = self.scan_near_sorted(lo, hi, true);
            self.read_ahead = Some(ReadAhead { lo, hi, found });
        }
    }
}
