//! Buffers a host renders from without reading anything back: the node positions (16 bytes
//! per node: xyz and w = 1, in the model's node order), an index buffer of the tissue's
//! boundary triangles over them, and the render surface's vertices
//! ([`GpuEngine::set_render_surface`]).
//!
//! The node positions are the render-surface pass ([`EmbedPass`]) run over one "vertex" per
//! node bound to that node alone with weight one: the same shader, the same twin, so the host
//! sees exactly what the surface pass would give at the nodes. A patch (a cut) moves node
//! slots and adds nodes, so each accessor binds again when the engine was patched since it
//! last bound; between patches a call costs one dispatch.
//!
//! The buffers belong to the engine: a host holds the reference for the frame it draws and asks
//! again for the next one (a patch may replace a buffer that had to grow, and a change of time
//! step may build a new engine).

use super::embed_surface::EmbedPass;
use super::GpuEngine;
use crate::error::{Error, Result};
use crate::surface::Embedding;
use crate::twin::embed_surface::BoundVertex;

/// Vertices on the device, ready to bind as a vertex buffer.
#[derive(Debug, Clone, Copy)]
pub struct DeviceVertices<'a> {
    /// The buffer (`VERTEX | STORAGE | COPY_SRC`): 16 bytes per vertex, `x, y, z` as `f32`
    /// and `w = 1` (bind as `Float32x3` at offset 0 with a stride of 16, or as `Float32x4`).
    pub buffer: &'a wgpu::Buffer,
    /// Vertices written (the buffer may be larger).
    pub count: u32,
}

/// Triangle indices on the device, ready to bind as an index buffer.
#[derive(Debug, Clone, Copy)]
pub struct DeviceIndices<'a> {
    /// The buffer (`INDEX | COPY_DST | COPY_SRC`): three `u32` per triangle.
    pub buffer: &'a wgpu::Buffer,
    /// Indices in it (three per triangle).
    pub count: u32,
}

/// What the engine keeps for hosts; everything is made at the first call that needs it.
#[derive(Default)]
pub(super) struct HostBuffers {
    /// The node-positions pass and the patch count it was bound at.
    nodes: Option<(EmbedPass, u64)>,
    /// The boundary triangles' index buffer, its index count and the generation of the
    /// triangles it holds.
    indices: Option<(wgpu::Buffer, u32, u64)>,
    /// The render surface's embedding (model node indices) and the patch count its pass was
    /// bound at, so that a patch re-binds it.
    pub(super) render: Option<(Embedding, u64)>,
}

impl GpuEngine {
    /// Bound vertices placing one vertex on each node of the model (weight one on that node's
    /// slot), at its rest position.
    fn node_vertices(&self) -> Result<Vec<BoundVertex>> {
        let rank = &self.layout.order().rank;
        if rank.len() < self.rest.len() {
            return Err(Error::Model(format!(
                "the layout orders {} nodes but the model has {}",
                rank.len(),
                self.rest.len()
            )));
        }
        Ok(self
            .rest
            .iter()
            .zip(rank)
            .map(|(r, &slot)| BoundVertex {
                nodes: [slot; 4],
                weights: [1.0, 0.0, 0.0, 0.0],
                rest: [r[0] as f32, r[1] as f32, r[2] as f32, 0.0],
            })
            .collect())
    }

    /// The current node positions on the device, in the model's node order (what
    /// [`crate::engine::Engine::positions`] reads back, in float32), evaluated now from the
    /// state of the last step submitted. Nothing is read back.
    pub fn node_positions(&mut self) -> Result<DeviceVertices<'_>> {
        let patches = self.patches;
        let stale = !matches!(&self.host.nodes, Some((_, at)) if *at == patches);
        if stale {
            let bound = self.node_vertices()?;
            match &mut self.host.nodes {
                Some((pass, at)) => {
                    pass.set_bound(&self.ctx, &bound)?;
                    *at = patches;
                }
                None => self.host.nodes = Some((EmbedPass::new(&self.ctx, &bound)?, patches)),
            }
        }
        let (pass, _) = self.host.nodes.as_mut().expect("bound above");
        pass.run(&self.ctx, self.state.bindings(self.phase).cur);
        Ok(DeviceVertices {
            buffer: pass.vertices(),
            count: pass.count(),
        })
    }

    /// An index buffer of `triangles` (model node indices, e.g. the tissue's boundary) over
    /// [`GpuEngine::node_positions`]. `generation` names the triangles: the buffer is written
    /// again only when it changes (or the count outgrows the buffer).
    pub fn triangle_indices(
        &mut self,
        triangles: &[[u32; 3]],
        generation: u64,
    ) -> Result<DeviceIndices<'_>> {
        let n = self.rest.len() as u32;
        if let Some((t, c)) = triangles
            .iter()
            .enumerate()
            .find_map(|(t, tri)| tri.iter().find(|&&c| c >= n).map(|&c| (t, c)))
        {
            return Err(Error::Model(format!(
                "surface triangle {t} names node {c} but the model has {n} nodes"
            )));
        }
        let count = (triangles.len() * 3) as u32;
        let fresh =
            matches!(&self.host.indices, Some((_, c, g)) if *g == generation && *c == count);
        if !fresh {
            let bytes = (u64::from(count) * 4).max(4);
            let fits = matches!(&self.host.indices, Some((b, ..)) if b.size() >= bytes);
            if !fits {
                // Room to grow by a quarter: cuts open new faces a few at a time.
                let size = (bytes + bytes / 4).next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT);
                let buffer = self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("surface indices"),
                    size,
                    usage: wgpu::BufferUsages::INDEX
                        | wgpu::BufferUsages::COPY_DST
                        | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                self.host.indices = Some((buffer, 0, 0));
            }
            let (buffer, c, g) = self.host.indices.as_mut().expect("made above");
            if count > 0 {
                self.ctx
                    .queue
                    .write_buffer(buffer, 0, bytemuck::cast_slice(triangles));
            }
            (*c, *g) = (count, generation);
        }
        let (buffer, count, _) = self.host.indices.as_ref().expect("made above");
        Ok(DeviceIndices {
            buffer,
            count: *count,
        })
    }

    /// The render surface ([`GpuEngine::set_render_surface`]) evaluated now, bound again first
    /// if a patch moved node slots since it was bound; `None` when none is set.
    pub fn render_vertices(&mut self) -> Result<Option<DeviceVertices<'_>>> {
        let patches = self.patches;
        match &self.host.render {
            Some((e, at)) if *at != patches => {
                // Bound again from the kept embedding, without copying it.
                let bound = self.bound_vertices(e)?;
                if let Some(pass) = self.render.as_mut() {
                    pass.set_bound(&self.ctx, &bound)?;
                }
                if let Some((_, at)) = self.host.render.as_mut() {
                    *at = patches;
                }
            }
            Some(_) => {}
            None => return Ok(None),
        }
        if self.render_surface().is_none() {
            return Ok(None);
        }
        let pass = self.render.as_ref().expect("evaluated above");
        Ok(Some(DeviceVertices {
            buffer: pass.vertices(),
            count: pass.count(),
        }))
    }
}
