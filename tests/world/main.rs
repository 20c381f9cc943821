//! The world step: one object for the tissue, tools, cuts and contacts, the scene runner on top
//! of it, and haptic-rate force through a virtual coupling.
//!
//! One test binary per area (linking each binary costs more than its tests on a 2-core
//! machine); each module is one behaviour.

mod haptic;
mod world_order;
mod world_scene;
