//! The implicit step's passes over the nodes, in blocks of [`BLOCK`] nodes: in parallel with
//! the `parallel` feature, their partial sums taken in block order, so that one thread and many
//! give the same bits.

use crate::engine::fast::{BLOCK, P};

/// Run `f(first node, block)` over blocks of [`BLOCK`] nodes of `out` (in parallel with the
/// `parallel` feature), each returning two partial sums; returns their sums taken in block
/// order, the same whatever the number of threads.
pub(super) fn over_blocks<T: Send>(
    out: &mut [T],
    partials: &mut [[f64; 2]],
    f: impl Fn(usize, &mut [T]) -> [f64; 2] + Sync + Send,
) -> [f64; 2] {
    let blocks = out.len().div_ceil(BLOCK);
    let partials = &mut partials[..blocks];
    #[cfg(feature = "parallel")]
    if !serial(blocks) {
        use rayon::prelude::*;
        out.par_chunks_mut(BLOCK)
            .zip(partials.par_iter_mut())
            .enumerate()
            .for_each(|(b, (chunk, part))| *part = f(b * BLOCK, chunk));
        return sum_partials(partials);
    }
    for (b, (chunk, part)) in out.chunks_mut(BLOCK).zip(partials.iter_mut()).enumerate() {
        *part = f(b * BLOCK, chunk);
    }
    sum_partials(partials)
}

/// The partial sums of [`over_blocks`] summed in block order.
fn sum_partials(partials: &[[f64; 2]]) -> [f64; 2] {
    partials
        .iter()
        .fold([0.0; 2], |acc, p| [acc[0] + p[0], acc[1] + p[1]])
}

/// Like [`over_blocks`] over two arrays of the same length, with nothing summed.
pub(super) fn for_pairs(
    a: &mut [P],
    b: &mut [P],
    f: impl Fn(usize, &mut [P], &mut [P]) + Sync + Send,
) {
    #[cfg(feature = "parallel")]
    if !serial(a.len().div_ceil(BLOCK)) {
        use rayon::prelude::*;
        a.par_chunks_mut(BLOCK)
            .zip(b.par_chunks_mut(BLOCK))
            .enumerate()
            .for_each(|(i, (ca, cb))| f(i * BLOCK, ca, cb));
        return;
    }
    for (i, (ca, cb)) in a.chunks_mut(BLOCK).zip(b.chunks_mut(BLOCK)).enumerate() {
        f(i * BLOCK, ca, cb);
    }
}

/// Whether a pass over `blocks` blocks of nodes runs on the calling thread: one block has
/// nothing to share, and on one thread handing the pass to the pool only adds a switch (the
/// solve makes three passes an iteration, so at a few thousand nodes the hand-overs are a
/// tenth of the time). The results are the same bits either way.
#[cfg(feature = "parallel")]
fn serial(blocks: usize) -> bool {
    blocks <= 1 || rayon::current_num_threads() <= 1
}
