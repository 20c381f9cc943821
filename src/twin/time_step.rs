//! Twin of `shaders/time_step.wgsl` (pass `engine::gpu::time_step`): a change of time step for
//! Verlet's state. The arithmetic is the integrator's own and stays with it
//! ([`crate::physics::integrator`]); this names it as the pass's twin.

pub use crate::physics::rescale_previous;
