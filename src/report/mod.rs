//! Measurements users act on: benchmarks of engines and layouts against the memory-bandwidth
//! floor, and error against run time over a ladder of time steps.

pub mod accuracy;
pub mod bandwidth;
pub mod bench;
#[cfg(all(feature = "gpu", feature = "collide"))]
pub mod collide_bench;
pub mod cut_bench;
pub mod device_copy;
#[cfg(feature = "plot")]
pub mod plot;
