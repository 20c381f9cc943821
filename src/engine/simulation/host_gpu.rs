//! Sharing the GPU with a host: a simulation on the host's own wgpu device
//! ([`Simulation::with_gpu_context`]), and the buffers the host draws from without reading the
//! state back: node positions, the boundary's index buffer, the render surface's vertices.
//!
//! ```no_run
//! # fn demo(device: wgpu::Device, queue: wgpu::Queue, info: wgpu::AdapterInfo,
//! #         model: lancet::model::PackedModel) -> lancet::Result<()> {
//! use lancet::engine::gpu::GpuContext;
//! use lancet::{SimConfig, Simulation};
//! // The host's device and queue (its renderer made them).
//! let ctx = GpuContext::from_device(device, queue, info)?;
//! let mut sim = Simulation::with_gpu_context(model, ctx, SimConfig::new(1e-4), Default::default())?;
//! sim.run(10)?;
//! if let Some(v) = sim.gpu_node_positions()? {
//!     // Bind `v.buffer` as a vertex buffer (stride 16, Float32x3 at offset 0) and draw.
//!     let _ = (v.buffer, v.count);
//! }
//! # Ok(()) }
//! ```

use super::*;
use crate::engine::gpu::host_buffers::{DeviceIndices, DeviceVertices};
use crate::engine::gpu::GpuContext;
use crate::surface::Embedding;

/// What a simulation keeps for a host sharing its GPU.
#[derive(Clone, Default)]
pub(crate) struct HostDevice {
    /// The host's device, used for every GPU engine this simulation builds (a change of time
    /// step builds a new one).
    pub(crate) context: Option<GpuContext>,
    /// The render surface bound with [`Simulation::set_render_surface`], bound again on an
    /// engine this simulation builds anew.
    pub(crate) render: Option<Embedding>,
    /// The render surface's triangles as drawn ([`Simulation::set_render_triangles`]) and
    /// their generation, counted up each time they change.
    pub(crate) render_triangles: Option<(Vec<[u32; 3]>, u64)>,
}

impl Simulation {
    /// [`Simulation::with_gpu`] on the host's device `ctx` (see
    /// [`GpuContext::from_device`]): the GPU engine, with the layout and accumulation of `gpu`,
    /// and every engine this simulation builds later, run on it. A host that draws with the same
    /// device binds the buffers of [`Simulation::gpu_node_positions`] without any readback.
    pub fn with_gpu_context(
        model: PackedModel,
        ctx: GpuContext,
        config: SimConfig,
        gpu: GpuOptions,
    ) -> Result<Self> {
        Self::build(
            model,
            EngineKind::Gpu,
            config,
            gpu,
            HostDevice {
                context: Some(ctx),
                ..HostDevice::default()
            },
        )
    }

    /// The device the GPU engine runs on; `None` on a CPU engine.
    pub fn gpu_context(&mut self) -> Option<GpuContext> {
        self.engine.gpu_mut().map(|g| g.context().clone())
    }

    /// The node positions on the device, evaluated now from the last step submitted (float32,
    /// 16 bytes per node, the model's node order: [`Simulation::positions`] without the
    /// readback). `None` on a CPU engine. Ask again each frame: a cut or a new time step may
    /// replace the buffer.
    pub fn gpu_node_positions(&mut self) -> Result<Option<DeviceVertices<'_>>> {
        match self.engine.gpu_mut() {
            Some(g) => g.node_positions().map(Some),
            None => Ok(None),
        }
    }

    /// The boundary triangles given to [`Simulation::set_surface`] (and edited by cuts) as an
    /// index buffer over [`Simulation::gpu_node_positions`]: `None` on a CPU engine or before a
    /// surface is set. Written again only after the surface changed.
    pub fn gpu_surface_indices(&mut self) -> Result<Option<DeviceIndices<'_>>> {
        let generation = self.surface_generation;
        match (self.engine.gpu_mut(), &self.surface) {
            (Some(g), Some(t)) => g.triangle_indices(t, generation).map(Some),
            _ => Ok(None),
        }
    }

    /// Bind a render surface (its embedding in this model) for
    /// [`Simulation::gpu_render_vertices`]; kept through cuts and rebuilds of the engine.
    /// Call it again with the new embedding when the surface itself changes. Does nothing on a
    /// CPU engine but keep it (evaluate [`Embedding`] on [`Simulation::positions`] there).
    pub fn set_render_surface(&mut self, embedding: &Embedding) -> Result<()> {
        if let Some(g) = self.engine.gpu_mut() {
            g.set_render_surface(embedding)?;
        }
        self.host.render = Some(embedding.clone());
        Ok(())
    }

    /// The triangles to draw the render surface with, as indices into its vertices (those of
    /// the embedding given to [`Simulation::set_render_surface`]): the surface as read, or as
    /// split and capped after cuts ([`crate::surface::Capped::triangles`]). Call it after each
    /// cut the surface followed (or every frame): triangles equal to those held change nothing,
    /// so [`Simulation::gpu_render_indices`] rewrites its buffer only when the caps changed.
    /// An error when a triangle names a vertex the bound surface does not have.
    pub fn set_render_triangles(&mut self, triangles: &[[u32; 3]]) -> Result<()> {
        let n = self.host.render.as_ref().map_or(0, Embedding::len) as u32;
        if let Some((t, c)) = triangles
            .iter()
            .enumerate()
            .find_map(|(t, tri)| tri.iter().find(|&&c| c >= n).map(|&c| (t, c)))
        {
            return Err(Error::Model(format!(
                "render triangle {t} names vertex {c} but the render surface bound has {n} \
                 vertices; call set_render_surface with the embedding the triangles were made \
                 with first"
            )));
        }
        match &mut self.host.render_triangles {
            Some((held, _)) if held.as_slice() == triangles => {}
            Some((held, generation)) => {
                held.clear();
                held.extend_from_slice(triangles);
                *generation += 1;
            }
            None => self.host.render_triangles = Some((triangles.to_vec(), 0)),
        }
        Ok(())
    }

    /// The render surface's triangles ([`Simulation::set_render_triangles`]) as an index buffer
    /// over [`Simulation::gpu_render_vertices`], to draw the surface (split and capped after
    /// cuts) without readback: `None` on a CPU engine or before both are set. Written again
    /// only after the triangles changed, and then only the triangles that differ; it grows like
    /// the vertex buffer. [`DeviceIndices::uploaded`] counts the bytes written. Ask again each
    /// frame: a cut may replace the buffer.
    pub fn gpu_render_indices(&mut self) -> Result<Option<DeviceIndices<'_>>> {
        match (self.engine.gpu_mut(), &self.host.render_triangles) {
            (Some(g), Some((t, generation))) => g.render_indices(t, *generation).map(Some),
            _ => Ok(None),
        }
    }

    /// The render surface's vertices on the device, evaluated now (16 bytes per vertex);
    /// `None` on a CPU engine or before [`Simulation::set_render_surface`].
    pub fn gpu_render_vertices(&mut self) -> Result<Option<DeviceVertices<'_>>> {
        match self.engine.gpu_mut() {
            Some(g) => g.render_vertices(),
            None => Ok(None),
        }
    }

    /// Give a newly built engine what the host bound on the old one.
    pub(super) fn rebind_host(&mut self) -> Result<()> {
        if let (Some(e), Some(g)) = (&self.host.render, self.engine.gpu_mut()) {
            g.set_render_surface(e)?;
        }
        Ok(())
    }
}
