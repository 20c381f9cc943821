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

use super::buffers::Sizing;
use super::embed_surface::EmbedPass;
use super::{GpuContext, GpuEngine};
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
    /// Bytes written to this index buffer (and the smaller ones it replaced) since the engine
    /// was built: what keeping it up to date has cost, for a host that counts its uploads.
    pub uploaded: u64,
}

/// An index buffer kept for a host: rewritten only when the triangles it holds change, and
/// then only the triangles that differ from what it holds and those past its count; grown
/// like the layout's buffers (room by [`Sizing::Headroom`] at first, then the next size class).
struct IndexBuffer {
    buffer: wgpu::Buffer,
    /// The generation of the triangles it holds.
    generation: u64,
    /// What it holds.
    held: Vec<[u32; 3]>,
    /// Bytes written since it was first made.
    uploaded: u64,
}

impl IndexBuffer {
    /// Hold `triangles` (of `generation`) in `slot`, writing only what changed.
    fn update<'a>(
        slot: &'a mut Option<IndexBuffer>,
        ctx: &GpuContext,
        label: &str,
        triangles: &[[u32; 3]],
        generation: u64,
    ) -> DeviceIndices<'a> {
        let bytes = std::mem::size_of_val(triangles) as u64;
        let fresh = matches!(slot, Some(b) if b.generation == generation);
        if !fresh {
            let fits = matches!(slot, Some(b) if b.buffer.size() >= bytes);
            if !fits {
                let sizing = if slot.is_some() {
                    Sizing::SizeClass
                } else {
                    Sizing::Headroom
                };
                let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: sizing.size(ctx, bytes).next_multiple_of(4),
                    usage: wgpu::BufferUsages::INDEX
                        | wgpu::BufferUsages::COPY_DST
                        | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                let uploaded = slot.as_ref().map_or(0, |b| b.uploaded);
                *slot = Some(IndexBuffer {
                    buffer,
                    generation,
                    held: Vec::new(),
                    uploaded,
                });
            }
            let b = slot.as_mut().expect("made above");
            b.uploaded += write_changed(ctx, &b.buffer, &b.held, triangles);
            b.held.clear();
            b.held.extend_from_slice(triangles);
            b.generation = generation;
        }
        let b = slot.as_ref().expect("made above");
        DeviceIndices {
            buffer: &b.buffer,
            count: (b.held.len() * 3) as u32,
            uploaded: b.uploaded,
        }
    }
}

/// Write the runs of `new` that differ from `old` (what `buffer` holds) and the part past it
/// into `buffer`; returns the bytes written.
fn write_changed(
    ctx: &GpuContext,
    buffer: &wgpu::Buffer,
    old: &[[u32; 3]],
    new: &[[u32; 3]],
) -> u64 {
    let size = std::mem::size_of::<[u32; 3]>();
    let mut written = 0;
    let mut write = |from: usize, to: usize| {
        ctx.queue.write_buffer(
            buffer,
            (from * size) as u64,
            bytemuck::cast_slice(&new[from..to]),
        );
        written += ((to - from) * size) as u64;
    };
    let common = old.len().min(new.len());
    let mut t = 0;
    while t < common {
        if new[t] == old[t] {
            t += 1;
            continue;
        }
        let run = t;
        while t < common && new[t] != old[t] {
            t += 1;
        }
        write(run, t);
    }
    if new.len() > common {
        write(common, new.len());
    }
    written
}

/// What the engine keeps for hosts; everything is made at the first call that needs it.
#[derive(Default)]
pub(super) struct HostBuffers {
    /// The node-positions pass and the patch count it was bound at.
    nodes: Option<(EmbedPass, u64)>,
    /// The boundary triangles' index buffer.
    indices: Option<IndexBuffer>,
    /// The render surface's index buffer ([`GpuEngine::render_indices`]).
    render_indices: Option<IndexBuffer>,
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
        Ok(IndexBuffer::update(
            &mut self.host.indices,
            &self.ctx,
            "surface indices",
            triangles,
            generation,
        ))
    }

    /// An index buffer of `triangles` over the render surface's vertices
    /// ([`GpuEngine::render_vertices`]): the surface as drawn, split and capped after cuts
    /// ([`crate::surface::Capper`]). `generation` names the triangles: the buffer is written
    /// again only when it changes, and then only the triangles that differ. An error when no
    /// render surface is set or a triangle names a vertex it does not have.
    pub fn render_indices(
        &mut self,
        triangles: &[[u32; 3]],
        generation: u64,
    ) -> Result<DeviceIndices<'_>> {
        let Some((e, _)) = &self.host.render else {
            return Err(Error::Model(
                "render triangles need a render surface: set one first (set_render_surface)".into(),
            ));
        };
        let n = e.len() as u32;
        if let Some((t, c)) = triangles
            .iter()
            .enumerate()
            .find_map(|(t, tri)| tri.iter().find(|&&c| c >= n).map(|&c| (t, c)))
        {
            return Err(Error::Model(format!(
                "render triangle {t} names vertex {c} but the render surface has {n} vertices; \
                 set the embedding the triangles were made with (set_render_surface) first"
            )));
        }
        Ok(IndexBuffer::update(
            &mut self.host.render_indices,
            &self.ctx,
            "render surface indices",
            triangles,
            generation,
        ))
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
