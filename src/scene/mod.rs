//! Scene files: what to simulate, how, what to write and what to check.

pub mod cut_settings;
pub mod cuts;
pub mod driver;
pub mod expect;
pub mod frames;
pub mod placement;
pub mod runner;
pub mod schema;
pub mod surface;
pub mod validate;

pub use expect::ExpectationResult;
pub use frames::{Frame, FrameMesh, FrameSink};
pub use runner::{run_scene, run_scene_with, RunOptions, RunSummary};
pub use schema::{Expectation, GraspWindow, MeshSource, Scene, SceneTool, TimeStep};
