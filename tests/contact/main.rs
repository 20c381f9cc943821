//! Tools and contact: broad and narrow phases, response, friction, grasping.
//!
//! One test binary per area (linking each binary costs more than its tests on a 2-core
//! machine); each module is one behaviour, named as the file it was.

#[path = "../common/mod.rs"]
mod common;
#[path = "../common/splitmix.rs"]
mod splitmix;
#[path = "../common/tissue.rs"]
mod tissue;

mod collide_narrow;
mod collide_self_narrow;
mod collide_tools;
mod contact_energy_reference;
mod contact_flat_tools;
mod contact_friction;
mod contact_held;
mod contact_implicit;
mod contact_probe;
mod grasp_flap;
mod scene_grasp;
mod self_contact_response;
