//! Scene files: what to simulate, how, what to write and what to check.

pub mod cut_settings;
pub mod cuts;
pub mod driver;
pub mod expect;
pub mod placement;
pub mod runner;
pub mod schema;
pub mod surface;
pub mod validate;

pub use expect::ExpectationResult;
pub use runner::{run_scene, RunOptions, RunSummary};
pub use schema::{Expectation, GraspWindow, MeshSource, Scene, SceneTool, TimeStep};
