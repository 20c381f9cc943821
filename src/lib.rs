//! # lancet
//!
//! Soft-tissue simulation with cutting, for surgical simulators: unstructured tetrahedral
//! meshes ([`mesh`]), a mass-spring model ([`model`]) stepped by a float64 reference engine, a
//! fast float32 CPU engine or a wgpu engine in three memory layouts ([`engine`], [`layout`]),
//! surgical tools with GPU broad phase and parry3d narrow phase ([`collide`]) and contact
//! response ([`contact`]), incisions that edit the mesh and patch the engine ([`cut`]), scenes with
//! checked expectations and reports.
//!
//! ```
//! use lancet::mesh::generate::BoxGrid;
//! let mesh = BoxGrid::cube_cells([2, 2, 2], 0.01).build().unwrap();
//! assert_eq!(mesh.tet_count(), 2 * 2 * 2 * 6);
//! ```

#![warn(missing_docs)]

pub mod collide;
#[cfg(feature = "collide")]
pub mod contact;
pub mod error;
pub mod mesh;

pub use error::{BadStep, Error, IdKind, Location, ParseError, Result};
pub use mesh::{NodeKey, TetKey, TetMesh};
pub mod engine;
pub mod layout;
pub mod model;
pub mod physics;
#[cfg(feature = "render")]
pub mod render;
pub mod report;
pub mod surface;
pub mod twin;

pub use engine::{EngineKind, GpuOptions, Integrator, SimConfig, Simulation};
pub use model::{Material, ModelConfig, PackedModel, SpringModel};
#[cfg(feature = "scene")]
pub mod scene;

// The README's Rust example runs as a doctest, so it cannot drift from the API.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctest;
#[cfg(feature = "cut")]
pub mod cut;
pub mod world;
