//! Measurements users act on: benchmarks of engines and layouts against the memory-bandwidth
//! floor, and error against run time over a ladder of time steps.

pub mod accuracy;
pub mod bandwidth;
pub mod bench;
#[cfg(all(feature = "gpu", feature = "collide"))]
#[cfg(feature = "collide")]
pub mod collide_bench;
#[cfg(feature = "cut")]
pub mod cut_bench;
pub mod device_copy;
#[cfg(feature = "plot")]
mod labels;
#[cfg(feature = "scene")]
pub mod model_error;
#[cfg(feature = "plot")]
pub mod plot;

/// Whether a GPU engine can start here: `Err` with the reason (no adapter, no `gpu` feature).
/// The reports skip their GPU rows with that reason.
pub(crate) fn gpu_usable() -> std::result::Result<(), String> {
    #[cfg(feature = "gpu")]
    {
        crate::engine::gpu::GpuContext::new()
            .map(|_| ())
            .map_err(|e| e.to_string())
    }
    #[cfg(not(feature = "gpu"))]
    {
        Err("this build has no GPU engine (enable the `gpu` cargo feature)".into())
    }
}
