//! The fast engine's parallel passes on a chosen number of threads.

/// Run `f` with the fast engine's parallel passes (made inside it) on a pool of `threads`
/// threads of its own, leaving the global pool alone: to compare timings, or results, across
/// thread counts. Without the `parallel` feature everything runs on the calling thread anyway
/// and `threads` is only checked.
pub fn on_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> crate::Result<R> {
    if threads == 0 {
        return Err(crate::Error::InvalidParameter {
            name: "threads".into(),
            value: 0.0,
            requirement: "be at least 1".into(),
        });
    }
    #[cfg(feature = "parallel")]
    {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| crate::Error::Unsupported(format!("a pool of {threads} threads: {e}")))?;
        Ok(pool.install(f))
    }
    #[cfg(not(feature = "parallel"))]
    Ok(f())
}
