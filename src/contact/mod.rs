//! Contact between the tools and the tissue, and of the tissue with itself: what happens once the
//! broad and narrow phases of [`crate::collide`] have found what touches. It sits above the
//! engines: each response reads the positions it needs from a [`crate::Simulation`] and moves
//! nodes through it, so the engines know nothing of contact.
//!
//! - `response.rs`: penetrating surface triangles pushed out of the tools by position
//!   correction, with friction, and the reaction force on each tool.
//! - `grasp.rs`: a closed grasper holds the surface nodes between its jaws and carries them.
//! - `self_response.rs`: self-contacts (surfaces closer than a thickness or a little inside
//!   each other) separated by equal and opposite, mass-weighted corrections.

pub mod grasp;
pub mod response;
pub mod self_response;
