//! The render surface on the device: pairs with `shaders/embed_surface.wgsl`. After a step the
//! pass forms every render vertex from the current displacements, where the state lives, into
//! a buffer a host binds as its vertex buffer (`VERTEX | STORAGE`, 16 bytes per vertex: xyz
//! and w = 1), so that drawing the deformed organ needs no readback.
//!
//! The engine holds the pass ([`GpuEngine::set_render_surface`]); it keeps a bind group per
//! state buffer it has seen, so that it always binds the state buffer of the current phase,
//! whatever a patch reallocated. After a cut only the bound vertices that changed (rebound, or
//! bound to nodes a patch moved) and those it added (the crossings and caps of
//! [`crate::surface::cap`], appended) are written: the buffers have room for a first few cuts'
//! vertices, and grow to the next size class when a cut outgrows them.

use bytemuck::{Pod, Zeroable};

use super::buffers::{self, Sizing};
use super::{dispatch_size, GpuContext, GpuEngine, WORKGROUP};
use crate::error::{Error, Result};
use crate::surface::Embedding;
use crate::twin::embed_surface::BoundVertex;

const SOURCE: &str = include_str!("../../../shaders/embed_surface.wgsl");

/// Mirrors `struct EmbedParams` in `shaders/embed_surface.wgsl` (16 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct EmbedParams {
    count: u32,
    row: u32,
    _pad: [u32; 2],
}

/// The pass, its input (the bound vertices) and its output (the vertex buffer).
pub struct EmbedPass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    bound: wgpu::Buffer,
    vertices: wgpu::Buffer,
    count: u32,
    /// Vertices the buffers have room for.
    capacity: usize,
    /// What the device's bound vertices hold: a change writes only the vertices that differ.
    host: Vec<BoundVertex>,
    /// Bind groups made for the displacement buffers seen so far (the state alternates between
    /// two), so that evaluating a frame makes none; emptied when the pass's own buffers change.
    bind_groups: Vec<(wgpu::Buffer, wgpu::BindGroup)>,
}

impl EmbedPass {
    /// Compile the pass and upload `bound` (node slots in layout order).
    pub fn new(ctx: &GpuContext, bound: &[BoundVertex]) -> Result<Self> {
        let layout = buffers::pass_layout(ctx, "embed surface", &[true, true, false]);
        let pipeline = buffers::compute_pipeline(ctx, "embed surface", SOURCE, &[&layout])?;
        let params = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("embed surface params"),
            size: std::mem::size_of::<EmbedParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let (bound_buf, vertices, capacity) = Self::buffers(ctx, bound, Sizing::Headroom)?;
        let mut pass = EmbedPass {
            pipeline,
            layout,
            params,
            bound: bound_buf,
            vertices,
            count: 0,
            capacity,
            host: bound.to_vec(),
            bind_groups: Vec::new(),
        };
        pass.write(ctx, bound);
        Ok(pass)
    }

    /// The bound vertices' buffer holding `bound` with room by `sizing`, the vertex buffer for
    /// as many, and how many that is.
    fn buffers(
        ctx: &GpuContext,
        bound: &[BoundVertex],
        sizing: Sizing,
    ) -> Result<(wgpu::Buffer, wgpu::Buffer, usize)> {
        let bound_buf = buffers::storage_buffer(
            ctx,
            "render surface bindings",
            bytemuck::cast_slice(bound),
            sizing,
        )?;
        let capacity = bound_buf.size() as usize / std::mem::size_of::<BoundVertex>();
        let bytes = (capacity.max(1) * 16) as u64;
        buffers::check_binding(ctx, "render surface vertices", bytes)?;
        let vertices = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("render surface vertices"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::VERTEX
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        Ok((bound_buf, vertices, capacity))
    }

    /// Replace the bound vertices (a new surface, a cut's rebinding and caps, or the same after
    /// a patch moved node slots): within the buffers' room, only the runs of vertices that
    /// differ from what the device holds, and those past its count, are written; new buffers
    /// (the next size class) otherwise. Returns the bytes written.
    pub fn set_bound(&mut self, ctx: &GpuContext, bound: &[BoundVertex]) -> Result<u64> {
        let size = std::mem::size_of::<BoundVertex>();
        let written;
        if bound.len() > self.capacity {
            (self.bound, self.vertices, self.capacity) =
                Self::buffers(ctx, bound, Sizing::SizeClass)?;
            self.bind_groups.clear();
            written = std::mem::size_of_val(bound) as u64;
        } else {
            let mut total = 0;
            let common = bound.len().min(self.host.len());
            if bound.len() > common {
                ctx.queue.write_buffer(
                    &self.bound,
                    (common * size) as u64,
                    bytemuck::cast_slice(&bound[common..]),
                );
                total += (bound.len() - common) * size;
            }
            let head = &bound[..common];
            let mut v = 0;
            while v < head.len() {
                if bound[v] == self.host[v] {
                    v += 1;
                    continue;
                }
                let run = v;
                while v < head.len() && bound[v] != self.host[v] {
                    v += 1;
                }
                ctx.queue.write_buffer(
                    &self.bound,
                    (run * size) as u64,
                    bytemuck::cast_slice(&bound[run..v]),
                );
                total += (v - run) * size;
            }
            written = total as u64;
        }
        self.host.clear();
        self.host.extend_from_slice(bound);
        self.write(ctx, bound);
        Ok(written)
    }

    fn write(&mut self, ctx: &GpuContext, bound: &[BoundVertex]) {
        self.count = bound.len() as u32;
        let row = dispatch_size(ctx, self.count).0 * WORKGROUP;
        let params = EmbedParams {
            count: self.count,
            row,
            _pad: [0; 2],
        };
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
    }

    /// The vertex buffer (16 bytes per vertex: xyz, w = 1), valid after [`EmbedPass::run`].
    pub fn vertices(&self) -> &wgpu::Buffer {
        &self.vertices
    }

    /// Number of render vertices.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// Evaluate the surface from the displacements in `disp` (layout order) and submit.
    pub fn run(&mut self, ctx: &GpuContext, disp: &wgpu::Buffer) {
        if self.count == 0 {
            return;
        }
        let at = match self.bind_groups.iter().position(|(b, _)| b == disp) {
            Some(at) => at,
            None => {
                // The state's two displacement buffers, and those of a state that grew: keep
                // the two latest.
                if self.bind_groups.len() == 2 {
                    self.bind_groups.remove(0);
                }
                let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("embed surface"),
                    layout: &self.layout,
                    entries: &buffers::entries(&[&self.params, disp, &self.bound, &self.vertices]),
                });
                self.bind_groups.push((disp.clone(), group));
                self.bind_groups.len() - 1
            }
        };
        let groups = dispatch_size(ctx, self.count);
        let enc = buffers::encode_dispatch(
            ctx,
            "embed surface",
            &self.pipeline,
            &self.bind_groups[at].1,
            groups,
        );
        ctx.queue.submit([enc.finish()]);
    }

    /// Read the vertex buffer back (tests, output files).
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<[f32; 4]>> {
        let mut v = buffers::read_vec4(ctx, &self.vertices)?;
        v.truncate(self.count as usize);
        Ok(v)
    }
}

impl GpuEngine {
    /// The device this engine runs on (a host renders the surface's vertex buffer with it).
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// `embedding`'s vertices as the pass reads them: node slots in this engine's layout order,
    /// weights and rest positions in float32.
    pub fn bound_vertices(&self, embedding: &Embedding) -> Result<Vec<BoundVertex>> {
        let rank = &self.layout.order().rank;
        let mut out = Vec::with_capacity(embedding.len());
        for (v, (n, w)) in embedding.nodes.iter().zip(&embedding.weights).enumerate() {
            let mut nodes = [0u32; 4];
            for k in 0..4 {
                nodes[k] = *rank.get(n[k] as usize).ok_or_else(|| {
                    Error::Model(format!(
                        "render vertex {v} is bound to node {} but the model has {}",
                        n[k],
                        rank.len()
                    ))
                })?;
            }
            let r = embedding.rest[v];
            out.push(BoundVertex {
                nodes,
                weights: w.map(|w| w as f32),
                rest: [r[0] as f32, r[1] as f32, r[2] as f32, 0.0],
            });
        }
        Ok(out)
    }

    /// Bind a render surface: from now on [`GpuEngine::render_surface`] evaluates it. Call it
    /// again after a patch (a cut moves node slots and adds nodes) and after a cut rebinds
    /// vertices ([`crate::surface::Rebinder`]): only the vertices whose nodes, slots or weights
    /// changed are uploaded. Returns the bytes of bound vertices written.
    pub fn set_render_surface(&mut self, embedding: &Embedding) -> Result<u64> {
        let bound = self.bound_vertices(embedding)?;
        self.host.render = Some((embedding.clone(), self.patches));
        match &mut self.render {
            Some(pass) => pass.set_bound(&self.ctx, &bound),
            None => {
                self.render = Some(EmbedPass::new(&self.ctx, &bound)?);
                Ok(std::mem::size_of_val(bound.as_slice()) as u64)
            }
        }
    }

    /// Evaluate the render surface at the current state on the device and return its vertex
    /// buffer (16 bytes per vertex: xyz, w = 1), `None` before
    /// [`GpuEngine::set_render_surface`]. Nothing is read back.
    pub fn render_surface(&mut self) -> Option<&wgpu::Buffer> {
        let pass = self.render.as_mut()?;
        pass.run(&self.ctx, self.state.bindings(self.phase).cur);
        Some(pass.vertices())
    }

    /// [`GpuEngine::render_surface`] read back (tests, output files).
    pub fn read_render_surface(&mut self) -> Result<Vec<[f32; 4]>> {
        self.render_surface()
            .ok_or_else(|| Error::Model("no render surface is set on this engine".into()))?;
        self.render.as_ref().expect("checked above").read(&self.ctx)
    }
}
