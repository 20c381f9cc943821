//! Per-frame output and pictures: the `.glb` frames written beside the VTU frames (the
//! tissue's surface and the tools, read back and compared with the VTU and VTP frames of the
//! same run), and `lancet render`'s PNG pictures (coverage against the projected outline,
//! colours against the displacement the physics gives).
//!
//! One test binary per area (linking each binary costs more than its tests on a 2-core
//! machine); each module is one behaviour.

#[path = "../common/mod.rs"]
mod common;

mod render_glb;
mod render_png;
mod render_shapes;
