//! Render surfaces: reading them (OBJ, STL, PLY, hostile input) and embedding them in the
//! simulation mesh (barycentric inside, offset from the nearest boundary face outside).
//!
//! One test binary per area (linking each binary costs more than its tests on a 2-core
//! machine); each module is one behaviour.

#[path = "../common/cut_box.rs"]
mod cut_box;
#[path = "../common/splitmix.rs"]
mod splitmix;

mod surface_cap;
mod surface_cut;
mod surface_embed;
mod surface_follow;
mod surface_last_strokes;
mod surface_on_sweep;
mod surface_read;
mod surface_scene;
mod surface_turning;
