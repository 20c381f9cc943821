//! Incisions: sweeps, classification, topology edits, patches, fixtures and time-step policies.
//!
//! One test binary per area (linking each binary costs more than its tests on a 2-core
//! machine); each module is one behaviour, named as the file it was.

#[path = "../common/mod.rs"]
mod common;
#[path = "../common/fem_cut.rs"]
mod fem_cut;
#[path = "../common/models.rs"]
mod models;
#[path = "../common/splitmix.rs"]
mod splitmix;

mod cut_blade_defects;
mod cut_fem;
mod cut_implicit;
mod cut_per_node_models;
mod cut_planar;
mod cut_properties;
mod cut_reading;
mod cut_scenes;
mod cut_snap;
mod cut_state;
mod cut_surface;
mod cut_topology_errors;
mod incisions;
