//! The CPU engines and the layouts: packing, patching, node order, float32 against float64.
//!
//! One test binary per area (linking each binary costs more than its tests on a 2-core
//! machine); each module is one behaviour, named as the file it was.

#[path = "../common/mod.rs"]
mod common;
#[path = "../common/models.rs"]
mod models;
#[path = "../common/read_ahead.rs"]
mod read_ahead;

mod bench_preset;
mod engine_agreement;
mod engine_api;
mod engine_correction;
mod engine_patch;
mod fast_fem;
mod fast_fused;
mod fast_implicit;
mod fast_probe;
mod fast_read_ahead;
mod fast_simd;
mod fast_sliced;
mod float32_precision;
mod layout_edges;
mod layout_patch;
mod layout_regroup;
mod layout_valence;
mod node_order;
