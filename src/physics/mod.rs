//! The step in one place: what one step of the model computes, apart from where its data lives.
//!
//! Two seams carry the physics. The reference engine steps through them; the float32 kernels of
//! the fast engine and of every GPU layout are their twins, in their own precision and order:
//! - the **force model** ([`ForceModel`], in [`force_model`]): the force of the elements on
//!   their nodes from the current state, and its Jacobian-vector products. Springs today
//!   ([`SpringForces`], [`springs`]): a scalar stiffness and damping along each tet edge.
//!   Beside them, the finite-element models on constant-strain tets ([`linear_tet`]):
//!   [`TensorMass`] (linear elasticity as per-node and per-edge 3x3 tensors, the springs'
//!   connectivity, in [`tensor_mass`]) and [`Corotational`] (each tet's stiffness in its
//!   rotated frame, in [`corotational`]); [`ForceModelKind`] chooses one ([`model_kind`]);
//! - the **integrator** ([`TimeIntegrator`], in [`time_integrator`]; the schemes in
//!   [`integrator`]): how a node's state advances from the force on it (Verlet and symplectic
//!   Euler, explicit), what state it keeps, and how that state follows a change of time step.
//!   The implicit one, [`BackwardEuler`] (linearised backward Euler with matrix-free
//!   preconditioned conjugate gradients), plugs in beside [`Explicit`], solving with the force
//!   model's products.
//!
//! [`StepParams`] are the constants of one step: a parameter written per step, never a reason
//! to rebuild an engine (`Engine::set_time_step` writes them and nothing else).
//!
//! The traits are stated in float64: they are the reference engine's step and the reference
//! of every kernel. The free functions ([`spring_force`], [`velocity`], [`integrate`],
//! [`rescale_previous`]) are the float32 arithmetic of the GPU kernels, in the order
//! `shaders/common.wgsl` computes it: the CPU twins of the passes (`crate::twin`) are
//! built from them, so a twin and its pass agree bit for bit on a device that rounds like the
//! CPU. This module imports only the model's data (`model::PackedSpring`, `model::PackedTet`,
//! the stability bound's type): the layouts, engines and shaders depend on it, never the other
//! way.

pub mod backward_euler;
pub mod contact_constraint;
pub mod corotational;
pub mod element_forces;
pub mod force_model;
pub mod integrator;
pub mod linear_tet;
pub mod model_kind;
pub mod runge_kutta;
pub mod springs;
pub mod tensor_mass;
pub mod time_integrator;

#[cfg(test)]
mod corotational_tests;
#[cfg(test)]
mod force_model_tests;
#[cfg(test)]
mod tensor_mass_tests;

pub use backward_euler::{BackwardEuler, Preconditioner, SolverSettings, SolverStats};
pub use contact_constraint::NodeConstraint;
pub use corotational::Corotational;
pub use element_forces::{element_energy, ElementForces};
pub use force_model::{ForceModel, Linearization, Mat3, Vec3};
pub use integrator::{
    integrate, rescale_previous, state_buffers, state_traffic, velocity, Compensation, Integrator,
    StepParams,
};
pub use linear_tet::TetElement;
pub use model_kind::ForceModelKind;
pub use runge_kutta::RungeKutta4;
pub use springs::{spring_force, spring_stiffness_block, SpringForces};
pub use tensor_mass::{EdgeTensor, TensorMass};
pub use time_integrator::{integrator_for, Explicit, NodeState, Nodes, TimeIntegrator};
