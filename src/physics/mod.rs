//! The step in one place: what one step of the model computes, apart from where its data lives.
//!
//! Two seams carry the physics, and every engine and layout goes through them:
//! - the **force model** ([`springs`]): the force of one element on its nodes from their
//!   current state. Springs today: a scalar stiffness and damping along each tet edge. A
//!   finite-element model plugs in beside it, contributing per-node and per-edge terms through
//!   the same layouts;
//! - the **integrator** ([`integrator`]): how a node's state advances from the force on it
//!   (Verlet and symplectic Euler), what state it keeps, and how that state follows a change of
//!   time step.
//!
//! [`StepParams`] are the constants of one step: a parameter written per step, never a reason
//! to rebuild an engine (`Engine::set_time_step` writes them and nothing else).
//!
//! The functions here are the float32 arithmetic of the GPU kernels, in the order
//! `shaders/common.wgsl` computes it: the CPU twins of the layouts (`layout::*::step_cpu`) are
//! built from them, so a twin and its pass agree bit for bit on a device that rounds like the
//! CPU. This module imports nothing of the crate: the layouts, engines and shaders depend on
//! it, never the other way.

pub mod integrator;
pub mod springs;

pub use integrator::{
    integrate, rescale_previous, state_buffers, state_traffic, velocity, Integrator, StepParams,
};
pub use springs::spring_force;
