//! The memory-bandwidth floor of this machine, measured in the same run as the benchmarks.
//!
//! A step of a mass-spring engine is memory-bound: it streams the spring data and the node state
//! once. Its time cannot beat `bytes moved / bandwidth`, so every timing is reported beside the
//! bandwidth it achieved and the ratio to what this machine can stream. The bandwidth is a
//! STREAM triad (`a[i] = b[i] + s * c[i]`, J. McCalpin's benchmark) over arrays far larger than
//! the caches, on all threads the engines use.

use std::time::Instant;

/// Result of the triad.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Bandwidth {
    /// Best bytes per second over the repetitions (STREAM counts 3 arrays of 8-byte values per
    /// element: two read, one written).
    pub bytes_per_s: f64,
    /// Elements per array.
    pub elements: usize,
    /// Threads used.
    pub threads: usize,
}

/// Measure the triad over arrays of `elements` f64 values, `reps` times; the best time counts
/// (as in STREAM), since slower runs measure interference, not the memory system.
pub fn stream_triad(elements: usize, reps: usize) -> Bandwidth {
    let b = vec![1.0f64; elements];
    let c = vec![2.0f64; elements];
    let mut a = vec![0.0f64; elements];
    let s = 3.0;
    let mut best = f64::INFINITY;
    for _ in 0..reps.max(1) {
        let t = Instant::now();
        triad(&mut a, &b, &c, s);
        best = best.min(t.elapsed().as_secs_f64());
    }
    // Keep the result observable so the loop is not optimised away.
    assert!(a[elements / 2] == 7.0, "triad computed a wrong value");
    Bandwidth {
        bytes_per_s: 3.0 * 8.0 * elements as f64 / best,
        elements,
        threads: threads(),
    }
}

#[cfg(feature = "parallel")]
fn triad(a: &mut [f64], b: &[f64], c: &[f64], s: f64) {
    use rayon::prelude::*;
    a.par_chunks_mut(1 << 16)
        .zip(b.par_chunks(1 << 16))
        .zip(c.par_chunks(1 << 16))
        .for_each(|((a, b), c)| {
            for i in 0..a.len() {
                a[i] = b[i] + s * c[i];
            }
        });
}

#[cfg(not(feature = "parallel"))]
fn triad(a: &mut [f64], b: &[f64], c: &[f64], s: f64) {
    for i in 0..a.len() {
        a[i] = b[i] + s * c[i];
    }
}

#[cfg(feature = "parallel")]
fn threads() -> usize {
    rayon::current_num_threads()
}

#[cfg(not(feature = "parallel"))]
fn threads() -> usize {
    1
}
