//! Two explicit steps in one sweep of the nodes (temporal blocking): the step is memory
//! bound, and most of what it reads is the springs (`sliced.rs`), read once per step. In the
//! engine's locality order every spring joins nodes at most [`Sliced::reach`] apart, so the
//! second step of a slice of nodes can be made as soon as the first step has gone past its
//! last neighbour ([`Sliced::bounds`], mostly well short of the reach), while its springs are
//! still in cache: the springs then come from memory once per two steps.
//!
//! The first step reads the state `A` and writes `B` (the output buffers), the second reads
//! `B` and writes `A` again, so no buffer is added: a node's second step overwrites its `A`
//! only once every first step that reads it (its neighbours', `reach` either way) is made.
//! Every node's arithmetic is the one-step kernel's, on the same inputs: the result is the
//! same bits as two single steps.
//!
//! Threads: the nodes are split into one range per thread, even ranges swept upwards, odd ones
//! downwards, so that two neighbouring ranges end their sweeps at their shared boundary. A
//! range makes the second step of its nodes further than `reach` from its ends while it sweeps
//! (their first-step neighbours are all its own); the nodes within `reach` of another range
//! wait until every range has made its first step, and are then stepped a second time in a
//! pass of their own, while the ones just swept are still in cache.

use super::kernels::{step_block, Simd};
use super::sliced::{Sliced, LANES};
use super::{FastEngine, Graph, Params, P};

/// Nodes per window of the first step's sweep: small against the reach of a mesh of 100k
/// nodes (a few thousand), so the second step trails the first closely. On the peer box of
/// 100k nodes a cache of 1 MB (callgrind's model, one thread) misses 24% fewer lines per step
/// at 64 nodes, 23.5% at 128 and 22% at 256 than single steps, at 0.6%, 0.3% and 0.1% more
/// instructions; timed, 256 did best of the three.
const WINDOW: usize = 256;

/// Ranges are used only where each is at least this many times the reach: otherwise most of
/// their nodes would wait for the second pass, read twice from memory as unfused steps do.
const MIN_SPAN_PER_REACH: usize = 4;

/// The state arrays of a pair of steps, shared by the threads as raw pointers: each thread
/// writes disjoint nodes, and no node is read while another thread writes it (the module's
/// rule), which references to whole arrays could not express.
#[derive(Clone, Copy)]
struct State {
    /// Displacements and second states the pair starts from and ends in (`A`).
    x: *mut P,
    s: *mut P,
    /// The first step's output (`B`).
    xn: *mut P,
    sn: *mut P,
    /// Nodes.
    n: usize,
}

// SAFETY: the pointers are only dereferenced under the module's rule: disjoint writes, no read
// of a node while it is written.
unsafe impl Send for State {}
unsafe impl Sync for State {}

/// What a step of a block needs besides the state: the model, the constants, the kernel.
#[derive(Clone, Copy)]
struct Kernel<'a> {
    g: &'a Graph,
    sl: &'a Sliced,
    p: Params,
    damped: bool,
    uniform: bool,
    simd: Simd,
}

impl Kernel<'_> {
    /// Step nodes `start..end` (`start` a multiple of [`LANES`], `end` too or the node count)
    /// from `A` into `B` (`first`) or from `B` into `A`.
    ///
    /// # Safety
    /// `simd` at most what the CPU has; no other thread reads the nodes written or
    /// writes any node within `reach` of them (the nodes read) while this runs.
    unsafe fn run<const VERLET: bool>(&self, st: State, first: bool, start: usize, end: usize) {
        if start >= end {
            return;
        }
        let (src, dst) = if first {
            ((st.x, st.s), (st.xn, st.sn))
        } else {
            ((st.xn, st.sn), (st.x, st.s))
        };
        // SAFETY: the arrays hold `n` nodes; the caller's rule keeps these views free of
        // concurrent writes where they are read and of any other access where they are written.
        let (x, s, xo, so) = unsafe {
            (
                std::slice::from_raw_parts(src.0 as *const P, st.n),
                std::slice::from_raw_parts(src.1 as *const P, st.n),
                std::slice::from_raw_parts_mut(dst.0.add(start), end - start),
                std::slice::from_raw_parts_mut(dst.1.add(start), end - start),
            )
        };
        let (g, sl, p, w) = (self.g, self.sl, self.p, self.simd);
        // SAFETY: the caller's (`simd`).
        unsafe {
            match (self.damped, self.uniform) {
                (true, true) => step_block::<true, true, VERLET>(w, g, sl, p, x, s, start, xo, so),
                (true, false) => {
                    step_block::<true, false, VERLET>(w, g, sl, p, x, s, start, xo, so)
                }
                (false, true) => {
                    step_block::<false, true, VERLET>(w, g, sl, p, x, s, start, xo, so)
                }
                (false, false) => {
                    step_block::<false, false, VERLET>(w, g, sl, p, x, s, start, xo, so)
                }
            }
        }
    }
}

/// One thread's nodes `a..b` (`a` a multiple of [`LANES`], `b` too or the node count), swept
/// upwards where `up`.
#[derive(Clone, Copy, Debug)]
struct Range {
    a: usize,
    b: usize,
    up: bool,
}

fn down8(i: usize) -> usize {
    i / LANES * LANES
}

fn up8(i: usize) -> usize {
    i.div_ceil(LANES) * LANES
}

impl Range {
    /// The nodes whose second step may overwrite `A` during the sweep: those whose
    /// neighbours (within `reach`) are all in this range.
    fn inner(&self, n: usize, reach: usize) -> (usize, usize) {
        let lo = if self.a == 0 { 0 } else { up8(self.a + reach) };
        let hi = if self.b == n {
            n
        } else {
            down8(self.b.saturating_sub(reach))
        };
        (lo.min(self.b), hi.max(lo.min(self.b)))
    }

    /// Sweep the range: the first step window by window, the second step of the inner nodes
    /// slice by slice as soon as the first has gone past their neighbours. Returns the nodes whose second step
    /// was made (the rest wait for [`Range::finish`]).
    ///
    /// # Safety
    /// As [`Kernel::run`]; the ranges of the other threads are disjoint from this one and
    /// swept under the same rule.
    unsafe fn sweep<const VERLET: bool>(
        &self,
        k: &Kernel,
        st: State,
        reach: usize,
    ) -> (usize, usize) {
        let n = st.n;
        let (lo, hi) = self.inner(n, reach);
        if self.up {
            let (mut f1, mut f2) = (self.a, lo);
            while f1 < self.b {
                let e = (f1 + WINDOW).min(self.b);
                // SAFETY: the caller's.
                unsafe { k.run::<VERLET>(st, true, f1, e) };
                f1 = e;
                // The slices whose every neighbour lies below `f1`: every first step they
                // read is made, and so is every first step that reads them (a neighbour's).
                let mut lim = f2;
                while lim < hi && (k.sl.bounds[lim / LANES][1] as usize) < f1 {
                    lim = (lim + LANES).min(hi);
                }
                if lim > f2 {
                    unsafe { k.run::<VERLET>(st, false, f2, lim) };
                    f2 = lim;
                }
            }
            (lo, f2.max(lo))
        } else {
            let (mut f1, mut f2) = (self.b, hi);
            while f1 > self.a {
                let s = down8(f1.saturating_sub(WINDOW)).max(self.a);
                unsafe { k.run::<VERLET>(st, true, s, f1) };
                f1 = s;
                // The slices whose every neighbour lies at or above `f1`, as above.
                let mut lim = f2;
                while lim > lo && (k.sl.bounds[(lim - 1) / LANES][0] as usize) >= f1 {
                    lim = down8(lim - 1).max(lo);
                }
                if lim < f2 {
                    unsafe { k.run::<VERLET>(st, false, lim, f2) };
                    f2 = lim;
                }
            }
            (f2.min(hi), hi)
        }
    }

    /// The second step of the nodes the sweep left (outside `done`), once every range's first
    /// step is made.
    ///
    /// # Safety
    /// As [`Kernel::run`]; every range has finished its sweep.
    unsafe fn finish<const VERLET: bool>(&self, k: &Kernel, st: State, done: (usize, usize)) {
        unsafe {
            k.run::<VERLET>(st, false, self.a, done.0);
            k.run::<VERLET>(st, false, done.1, self.b);
        }
    }
}

/// The ranges of `threads` threads over `n` nodes, or `None` where one would be too short
/// against `reach` to gain anything.
fn ranges(n: usize, threads: usize, reach: usize) -> Option<Vec<Range>> {
    let threads = threads.max(1);
    let span = up8(n.div_ceil(threads));
    if threads > 1 && span < MIN_SPAN_PER_REACH * reach.max(1) {
        return None;
    }
    let out: Vec<Range> = (0..threads)
        .map(|t| Range {
            a: (t * span).min(n),
            b: ((t + 1) * span).min(n),
            up: t % 2 == 0,
        })
        .filter(|r| r.a < r.b)
        .collect();
    Some(out)
}

impl FastEngine {
    /// Two explicit steps in one sweep (Verlet's where `VERLET`, else symplectic Euler's), the
    /// same bits as two calls of `step_explicit`. Returns false, having done nothing, where the
    /// layout's reach is too long for the threads' ranges.
    pub(super) fn step_pair<const VERLET: bool>(&mut self) -> bool {
        let sl = &self.graph.springs;
        let n = self.x.len();
        assert!(
            sl.nodes() == n
                && self.second.len() == n
                && self.x_next.len() == n
                && self.second_next.len() == n
        );
        #[cfg(feature = "parallel")]
        let threads = rayon::current_num_threads();
        #[cfg(not(feature = "parallel"))]
        let threads = 1;
        let Some(ranges) = ranges(n, threads, sl.reach) else {
            return false;
        };
        let k = Kernel {
            g: &self.graph,
            sl,
            p: self.params,
            damped: self.damped,
            uniform: sl.uniform.is_some(),
            simd: self.simd,
        };
        let st = State {
            x: self.x.as_mut_ptr(),
            s: self.second.as_mut_ptr(),
            xn: self.x_next.as_mut_ptr(),
            sn: self.second_next.as_mut_ptr(),
            n,
        };
        let reach = sl.reach;
        // SAFETY: `simd` at most what the CPU has (`Simd::best`, which `set_wide_simd` and
        // `set_avx512` never exceed); the
        // ranges are disjoint, a sweep writes `A` only for nodes whose readers are all its
        // own and done, and `finish` runs after every sweep (see the module's rule).
        let sweep = |r: &Range| unsafe { r.sweep::<VERLET>(&k, st, reach) };
        let finish =
            |(r, done): (&Range, (usize, usize))| unsafe { r.finish::<VERLET>(&k, st, done) };
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            let done: Vec<(usize, usize)> = ranges.par_iter().map(sweep).collect();
            ranges.par_iter().zip(done).for_each(finish);
        }
        #[cfg(not(feature = "parallel"))]
        {
            let done: Vec<(usize, usize)> = ranges.iter().map(sweep).collect();
            ranges.iter().zip(done).for_each(finish);
        }
        self.fused_pairs += 1;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every node's second step is made once: in its range's sweep or in its finish.
    #[test]
    fn ranges_cover_every_node_once() {
        for (n, threads, reach) in [(1000, 2, 100), (1001, 3, 40), (77, 1, 500), (4096, 4, 9)] {
            let rs = ranges(n, threads, reach).unwrap();
            let mut seen = vec![0u8; n];
            for r in &rs {
                let (lo, hi) = r.inner(n, reach);
                assert!(r.a <= lo && lo <= hi && hi <= r.b, "{r:?}: {lo}..{hi}");
                for s in &mut seen[r.a..r.b] {
                    *s += 1;
                }
            }
            assert!(seen.iter().all(|&s| s == 1), "{n} {threads} {reach}");
        }
        assert!(ranges(1000, 2, 200).is_none());
    }
}
