//! Surgical tools and finding what they touch: shapes and poses, the broad phases and the
//! narrow phases. Below the engines (which run the broad phases on the device); what contact
//! does to the tissue is [`crate::contact`], above them.
//!
//! A [`Tool`] is a rigid [`ToolShape`] (probe or needle, sphere, blade, grasper) with a pose in
//! the scene frame (metres, `nalgebra::Isometry3<f64>`). Where the pose comes from is up to the
//! caller: a scene gives each tool a [`Trajectory`] (keyframes or a scripted velocity) and
//! evaluates [`Trajectory::pose_at`] each step; an embedding program driven by a haptic device
//! calls [`Tool::set_pose`] every step with the device's pose. Either way the tool remembers the
//! pose of the previous step, so that [`Tool::step_bounds`] covers the whole motion of the step
//! (the broad phase tests triangle bounds against it, so a fast tool cannot jump over a thin
//! layer of tissue between two steps).
//!
//! The pipeline, one stage per file (see issue 4):
//!
//! - `tool.rs`: shapes, poses, trajectories, and conservative float64 bounds
//!   ([`ToolShape::aabb`], [`ToolShape::swept_aabb`]).
//! - `broad.rs`: boundary triangles whose bounds meet a tool's swept bounds become candidates
//!   (GPU pass `shaders/broad_tool.wgsl` with its CPU twin and a float64 brute force).
//! - `self_broad.rs`: pairs of boundary triangles that come near each other (a spatial hash on
//!   the GPU, `shaders/self_*.wgsl` and `shaders/scan_*.wgsl`, with its CPU twin).
//! - `tool_mesh.rs`: the shapes as closed triangle surfaces, for pictures and per-frame output.
//! - `narrow.rs` (feature `collide`): parry3d contact queries on the candidates, tool against
//!   triangle or tetrahedron, computed in a local frame centred on the tool part and scaled to
//!   unit size so that parry's float32 arithmetic stays accurate for millimetre tools in scenes
//!   measured in metres.
//! - `self_narrow.rs` (feature `collide`): triangle against triangle through parry3d (in a
//!   unit frame centred on the pair), and the float64 node–triangle and edge–edge proximity
//!   primitives.

pub mod broad;
#[cfg(feature = "collide")]
pub mod narrow;
#[cfg(feature = "collide")]
pub mod self_broad;
#[cfg(feature = "collide")]
pub mod self_narrow;
pub mod tool;
pub mod tool_mesh;

pub use tool::{Aabb, Keyframe, Tool, ToolPart, ToolShape, Trajectory};
