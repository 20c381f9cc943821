//! Building a [`World`]: the mesh and its model, the step settings and the engine.

use super::World;
use crate::engine::{EngineKind, GpuOptions, SimConfig, Simulation};
use crate::error::{Error, Result};
use crate::mesh::TetMesh;
use crate::model::{ModelConfig, PackedModel, SpringModel, StabilityBound};

/// What a [`World`] is built from: the mesh, its model (built and packed), the step settings,
/// the engine and the GPU options.
pub struct WorldBuilder {
    pub(super) mesh: TetMesh,
    pub(super) model: SpringModel,
    pub(super) packed: PackedModel,
    pub(super) config: SimConfig,
    pub(super) engine: EngineKind,
    pub(super) gpu: GpuOptions,
}

impl WorldBuilder {
    /// Build the model of `mesh` under `model` and pack it, to step under `config` on the
    /// reference engine (see [`WorldBuilder::engine`]).
    pub fn new(mesh: TetMesh, model: &ModelConfig, config: SimConfig) -> Result<Self> {
        let spring = SpringModel::build(&mesh, model)?;
        let packed = spring.pack(&mesh)?;
        Ok(WorldBuilder {
            mesh,
            model: spring,
            packed,
            config,
            engine: EngineKind::Reference,
            gpu: GpuOptions::default(),
        })
    }

    /// Step on `engine`.
    pub fn engine(mut self, engine: EngineKind) -> Self {
        self.engine = engine;
        self
    }

    /// Run the GPU engine with `gpu` (layout, accumulation); the CPU engines ignore it.
    pub fn gpu(mut self, gpu: GpuOptions) -> Self {
        self.gpu = gpu;
        self
    }

    /// Step at `fraction` of the stable bound of the explicit schemes for the configured force
    /// model (`0 < fraction`, typically 0.5 to 0.9).
    pub fn bound_fraction(mut self, fraction: f64) -> Result<Self> {
        let bound = self.bound()?;
        if !(fraction > 0.0 && fraction.is_finite() && bound.dt.is_finite()) {
            return Err(Error::Options(format!(
                "a time step of {fraction} of the stable bound ({:e} s) is not a positive \
                 finite step; give a positive fraction, or a step in seconds",
                bound.dt
            )));
        }
        self.config.dt = fraction * bound.dt;
        Ok(self)
    }

    /// The stable bound of the explicit schemes for the configured force model.
    pub fn bound(&self) -> Result<StabilityBound> {
        self.config.force_model.stable_time_step(&self.packed)
    }

    /// The mesh.
    pub fn mesh(&self) -> &TetMesh {
        &self.mesh
    }

    /// The packed model.
    pub fn packed(&self) -> &PackedModel {
        &self.packed
    }

    /// The step settings.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// The simulation this builds (refused, as [`Simulation::with_gpu`] refuses, for a step
    /// above the stable bound of an explicit scheme). [`WorldBuilder::build`] makes one; a
    /// caller that reports a refusal with the model still at hand makes it here and hands it
    /// to [`WorldBuilder::build_with`].
    pub fn simulation(&self) -> Result<Simulation> {
        let mut sim =
            Simulation::with_gpu(self.packed.clone(), self.engine, self.config, self.gpu)?;
        sim.watch_mesh(&self.mesh)?;
        Ok(sim)
    }

    /// The world, with the simulation [`WorldBuilder::simulation`] made.
    pub fn build_with(self, sim: Simulation) -> World {
        World::from_parts(self.mesh, self.model, sim)
    }

    /// The world: no tools, no cutting, the mesh's tets watched for inversion.
    pub fn build(self) -> Result<World> {
        let sim = self.simulation()?;
        Ok(self.build_with(sim))
    }
}
