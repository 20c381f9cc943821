//! The GPU engine on a real device (lavapipe in CI): every pass against its CPU twin.
//!
//! One test binary per area (linking each binary costs more than its tests on a 2-core
//! machine); each module is one behaviour, named as the file it was.

#[path = "../common/mod.rs"]
mod common;
#[path = "../common/cut_box.rs"]
mod cut_box;
#[path = "../common/fem_cut.rs"]
mod fem_cut;
#[path = "../common/models.rs"]
mod models;
#[path = "../common/read_ahead.rs"]
mod read_ahead;

mod fem_gpu_checks;
mod gpu_broad_phase;
mod gpu_corotational;
mod gpu_corotational_pairs;
mod gpu_edges;
mod gpu_embed_surface;
mod gpu_health;
mod gpu_host_device;
mod gpu_implicit;
mod gpu_implicit_atomic;
mod gpu_implicit_atomic_fem;
mod gpu_implicit_corotational;
mod gpu_implicit_tensor;
mod gpu_layouts;
mod gpu_limits;
mod gpu_nodes_near;
mod gpu_patch;
mod gpu_read_ahead;
mod gpu_self_contact;
mod gpu_tensor_atomic;
mod gpu_tensor_mass;
mod gpu_valence;
mod twin_tolerance;
