//! Measurements users act on: benchmarks of engines and layouts against the memory-bandwidth
//! floor (and, to come, error against run time).

pub mod bandwidth;
pub mod bench;
