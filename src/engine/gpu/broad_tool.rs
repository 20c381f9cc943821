//! The tool broad phase on the device: pairs with `shaders/broad_tool.wgsl`. Built only when a
//! program asks for culling (no tool, no pass). The surface (triangles in layout order and the
//! rest positions) is uploaded once, then only what a cut or patch changed is written; each
//! cull uploads the tool boxes, runs one dispatch over the triangles and reads back the counter
//! and the candidates, nothing else, in the same submission.

use bytemuck::{Pod, Zeroable};

use super::buffers::{self, Sizing};
use super::{dispatch_size, GpuContext, StateBuffers, WORKGROUP};
use crate::collide::broad::{Candidate, ToolBox};
use crate::error::{Error, Result};

const SOURCE: &str = include_str!("../../../shaders/broad_tool.wgsl");

/// Mirrors `struct CullParams` in `shaders/broad_tool.wgsl` (16 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct CullParams {
    triangles: u32,
    tools: u32,
    capacity: u32,
    row: u32,
}

const _: () = assert!(std::mem::size_of::<CullParams>() == 16);

/// What one cull found, and what it cost.
#[derive(Debug, Clone, PartialEq)]
pub struct CullResult {
    /// (triangle, tool) pairs, sorted.
    pub candidates: Vec<Candidate>,
    /// Times the candidate buffer was too small and the pass ran again after growing it.
    pub regrown: u32,
}

/// What the device holds of a surface: triangles (layout-order corners, padded to four) and
/// rest positions of every node slot.
pub type DeviceSurface = (Vec<[u32; 4]>, Vec<[f32; 4]>);

/// The pass, its surface and its output buffers.
pub struct ToolCuller {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    triangles: wgpu::Buffer,
    rest: wgpu::Buffer,
    /// What `triangles` and `rest` hold, so that an update writes only what changed.
    triangles_host: Vec<[u32; 4]>,
    rest_host: Vec<[f32; 4]>,
    triangle_count: u32,
    boxes: wgpu::Buffer,
    candidates: wgpu::Buffer,
    count: wgpu::Buffer,
    /// Where the counter (first 16 bytes) and the candidates are copied for the host to read:
    /// one submission and one map per cull, kept from one cull to the next.
    staging: wgpu::Buffer,
    /// One bind group per rotation phase (the displacement buffer differs).
    bind_groups: Vec<wgpu::BindGroup>,
}

/// Write the elements `indices` of `host` (what `buffer` should hold) to `buffer`, or, where
/// `host` outgrew it, replace it by a grown copy ([`buffers::grown`]: the elements written
/// and those past the old buffer go up, the rest is copied on the device). Returns whether the
/// buffer was replaced.
fn write_or_grow<T: bytemuck::Pod>(
    ctx: &GpuContext,
    label: &str,
    buffer: &mut wgpu::Buffer,
    host: &[T],
    indices: &mut Vec<u32>,
) -> Result<bool> {
    let bytes: &[u8] = bytemuck::cast_slice(host);
    if bytes.len() as u64 <= buffer.size() {
        buffers::write_slots(ctx, buffer, host, indices);
        return Ok(false);
    }
    indices.sort_unstable();
    indices.dedup();
    let elem = std::mem::size_of::<T>() as u64;
    let dirty: Vec<std::ops::Range<u64>> = indices
        .iter()
        .map(|&i| i as u64 * elem..(i as u64 + 1) * elem)
        .collect();
    *buffer = buffers::grown(ctx, label, buffer, bytes, &dirty)?.0;
    Ok(true)
}

impl ToolCuller {
    /// Upload the surface (`triangles` in layout order, `rest` positions in layout order) and
    /// build the pass over the node state.
    pub fn new(
        ctx: &GpuContext,
        triangles: &[[u32; 3]],
        rest: &[[f32; 4]],
        state: &StateBuffers,
    ) -> Result<Self> {
        let d = &ctx.device;
        let tris: Vec<[u32; 4]> = triangles.iter().map(|t| [t[0], t[1], t[2], 0]).collect();
        let triangles_buf = buffers::storage_buffer(
            ctx,
            "surface triangles",
            bytemuck::cast_slice(&tris),
            Sizing::Headroom,
        )?;
        let rest_buf = buffers::storage_buffer(
            ctx,
            "rest positions",
            bytemuck::cast_slice(rest),
            Sizing::Headroom,
        )?;
        let params = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("cull params"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // triangles, rest, displacements, boxes (read); candidates, count (written).
        let layout =
            buffers::pass_layout(ctx, "broad_tool", &[true, true, true, true, false, false]);
        let pipeline = buffers::compute_pipeline(ctx, "broad_tool", SOURCE, &[&layout])?;
        let boxes = buffers::storage_buffer(ctx, "tool boxes", &[0u8; 32], Sizing::Exact)?;
        // Room for a few candidates per triangle touched by a millimetre tool; grown on demand.
        let candidates =
            buffers::storage_buffer(ctx, "candidates", &[0u8; 8 * 1024], Sizing::Exact)?;
        let count = buffers::storage_buffer(ctx, "candidate count", &[0u8; 4], Sizing::Exact)?;
        let staging = buffers::staging_buffer(ctx, 16 + candidates.size());
        let mut culler = ToolCuller {
            pipeline,
            layout,
            params,
            triangles: triangles_buf,
            rest: rest_buf,
            triangles_host: crate::model::room::with_room(tris),
            rest_host: crate::model::room::copy_with_room(rest),
            triangle_count: triangles.len() as u32,
            boxes,
            candidates,
            count,
            staging,
            bind_groups: Vec::new(),
        };
        culler.rebind(ctx, state);
        Ok(culler)
    }

    /// Bring the surface up to date (after a cut changed it, or a patch renumbered nodes or
    /// reallocated the node state), keeping the pipeline and output buffers: only triangles and
    /// rest positions that differ from what the device holds are written.
    pub fn set_surface(
        &mut self,
        ctx: &GpuContext,
        triangles: &[[u32; 3]],
        rest: &[[f32; 4]],
        state: &StateBuffers,
    ) -> Result<()> {
        let tris: Vec<[u32; 4]> = triangles.iter().map(|t| [t[0], t[1], t[2], 0]).collect();
        buffers::write_changed(
            ctx,
            "surface triangles",
            &mut self.triangles,
            &mut self.triangles_host,
            &tris,
        )?;
        buffers::write_changed(
            ctx,
            "rest positions",
            &mut self.rest,
            &mut self.rest_host,
            rest,
        )?;
        self.triangle_count = triangles.len() as u32;
        // The state buffers may have been reallocated by a patch: bind afresh (cheap).
        self.rebind(ctx, state);
        Ok(())
    }

    /// Write only what an edit changed: the surface has `count` triangles, of which those in
    /// `triangles` (slot, layout-order corners) are new, and the layout `slots` node slots, of
    /// which those in `rest` (slot, position) are new. A buffer too small is replaced by one of
    /// the next size class holding the old contents (copied on the device) and the new (see
    /// [`buffers::grown`]), and the pass bound to `state` anew: a surface that carving grows
    /// past the first upload's room is not compared and uploaded whole. Returns whether the
    /// rest positions moved to a new buffer (passes sharing them must bind it). An edit that
    /// would take either buffer past the device's binding limit is refused before anything
    /// changes, on the host or the device.
    pub fn edit(
        &mut self,
        ctx: &GpuContext,
        count: usize,
        triangles: &[(u32, [u32; 3])],
        slots: usize,
        rest: &[(u32, [f32; 4])],
        state: &StateBuffers,
    ) -> Result<bool> {
        // Checked first: the triangles are written before the rest positions, and a refusal
        // of the second left the first edited.
        let entry = std::mem::size_of::<[u32; 4]>() as u64;
        buffers::check_binding(ctx, "surface triangles", count as u64 * entry)?;
        buffers::check_binding(ctx, "rest positions", slots as u64 * entry)?;
        // Slots past the last count go up whatever the caller names: a grown buffer keeps the
        // old one's bytes there (a longer surface's, before it shrank), and they become live.
        let known = self.triangles_host.len().min(count) as u32;
        self.triangles_host.resize(count, [0; 4]);
        let mut written: Vec<u32> = (known..count as u32).collect();
        for &(i, t) in triangles {
            self.triangles_host[i as usize] = [t[0], t[1], t[2], 0];
            written.push(i);
        }
        let tris_moved = write_or_grow(
            ctx,
            "surface triangles",
            &mut self.triangles,
            &self.triangles_host,
            &mut written,
        )?;
        // Only named slots go up: a slot a node takes is named (its state moves there), and
        // nothing reads a hole's rest position, so new holes (valence appends whole buckets
        // of them) may keep whatever the device holds there (zeros, or an older layout's
        // positions after the slots shrank), however the host copy pads them.
        self.rest_host.resize(slots, [0.0; 4]);
        written.clear();
        for &(i, r) in rest {
            self.rest_host[i as usize] = r;
            written.push(i);
        }
        let rest_moved = write_or_grow(
            ctx,
            "rest positions",
            &mut self.rest,
            &self.rest_host,
            &mut written,
        )?;
        self.triangle_count = count as u32;
        if tris_moved || rest_moved {
            self.rebind(ctx, state);
        }
        Ok(rest_moved)
    }

    /// Read back the first `count` triangles and `slots` rest positions (a check).
    pub fn read_surface(
        &self,
        ctx: &GpuContext,
        count: usize,
        slots: usize,
    ) -> Result<DeviceSurface> {
        let tris = buffers::read_bytes(ctx, &self.triangles, (count.max(1) * 16) as u64)?;
        let rest = buffers::read_bytes(ctx, &self.rest, (slots.max(1) * 16) as u64)?;
        Ok((
            bytemuck::pod_collect_to_vec(&tris),
            bytemuck::pod_collect_to_vec(&rest),
        ))
    }

    /// The surface triangles, layout order, `[a, b, c, 0]` each (for passes that share them;
    /// the first `count` of the last edit are live).
    pub fn triangles(&self) -> &wgpu::Buffer {
        &self.triangles
    }

    /// The rest positions of every node slot, layout order (for passes that share them).
    pub fn rest(&self) -> &wgpu::Buffer {
        &self.rest
    }

    /// Rebuild the bind groups (after the node state or an output buffer was reallocated).
    pub fn rebind(&mut self, ctx: &GpuContext, state: &StateBuffers) {
        self.bind_groups = (0..state.phases())
            .map(|phase| {
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("broad_tool"),
                    layout: &self.layout,
                    entries: &buffers::entries(&[
                        &self.params,
                        &self.triangles,
                        &self.rest,
                        state.bindings(phase).cur,
                        &self.boxes,
                        &self.candidates,
                        &self.count,
                    ]),
                })
            })
            .collect();
    }

    /// Cull the surface against `boxes` at the state of `phase`.
    pub fn cull(
        &mut self,
        ctx: &GpuContext,
        state: &StateBuffers,
        phase: usize,
        boxes: &[ToolBox],
    ) -> Result<CullResult> {
        if boxes.is_empty() || self.triangle_count == 0 {
            return Ok(CullResult {
                candidates: Vec::new(),
                regrown: 0,
            });
        }
        let box_bytes: &[u8] = bytemuck::cast_slice(boxes);
        if box_bytes.len() as u64 > self.boxes.size() {
            self.boxes = buffers::storage_buffer(ctx, "tool boxes", box_bytes, Sizing::SizeClass)?;
            self.rebind(ctx, state);
        } else {
            ctx.queue.write_buffer(&self.boxes, 0, box_bytes);
        }
        let groups = dispatch_size(ctx, self.triangle_count);
        let row = groups.0 * WORKGROUP;
        let mut regrown = 0;
        loop {
            let capacity = (self.candidates.size() / 8) as u32;
            let params = CullParams {
                triangles: self.triangle_count,
                tools: boxes.len() as u32,
                capacity,
                row,
            };
            ctx.queue
                .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
            ctx.queue.write_buffer(&self.count, 0, &0u32.to_le_bytes());
            // The pass and the copies of its counter and output in one submission.
            let mut enc = buffers::encode_dispatch(
                ctx,
                "broad_tool",
                &self.pipeline,
                &self.bind_groups[phase],
                groups,
            );
            let size = self.candidates.size();
            enc.copy_buffer_to_buffer(&self.count, 0, &self.staging, 0, 4);
            enc.copy_buffer_to_buffer(&self.candidates, 0, &self.staging, 16, size);
            let raw = buffers::submit_and_read(ctx, enc, &self.staging, 16 + size)?;
            let n = u32::from_le_bytes(
                raw[..4]
                    .try_into()
                    .map_err(|_| Error::Gpu("candidate count readback".into()))?,
            );
            if n <= capacity {
                let mut candidates: Vec<Candidate> =
                    bytemuck::pod_collect_to_vec(&raw[16..16 + 8 * n as usize]);
                candidates.sort_unstable();
                return Ok(CullResult {
                    candidates,
                    regrown,
                });
            }
            // Too many survivors: grow by size class to hold them all and run again.
            self.candidates = buffers::storage_buffer(
                ctx,
                "candidates",
                &vec![0u8; n as usize * 8],
                Sizing::SizeClass,
            )?;
            self.staging = buffers::staging_buffer(ctx, 16 + self.candidates.size());
            self.rebind(ctx, state);
            regrown += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::Integrator;

    /// The device, or `None` (the test skipped, saying why) where none opens; a failure where
    /// `LANCET_REQUIRE_GPU=1`.
    fn opened(ctx: Result<GpuContext>) -> Option<GpuContext> {
        match ctx {
            Ok(ctx) => Some(ctx),
            Err(e) if std::env::var("LANCET_REQUIRE_GPU").as_deref() == Ok("1") => {
                panic!("LANCET_REQUIRE_GPU=1 but no GPU is usable: {e}")
            }
            Err(e) => {
                eprintln!("skipped: no GPU adapter ({e})");
                None
            }
        }
    }

    /// A surface that shrank, then grows past its buffer's room by an edit that names only
    /// some of the slots it makes live: the device holds what the host copy holds there
    /// (zeros where nothing was named), not the longer surface's old triangles.
    #[test]
    fn growing_after_shrinking_writes_every_slot_it_makes_live() {
        let Some(ctx) = opened(GpuContext::new()) else {
            return;
        };
        let state = StateBuffers::new(&ctx, 8, Integrator::Verlet, Sizing::Headroom).unwrap();
        let tris: Vec<[u32; 3]> = (0..1000u32).map(|i| [i % 8, (i + 1) % 8, 7]).collect();
        let rest = vec![[0.5f32; 4]; 8];
        let mut culler = ToolCuller::new(&ctx, &tris, &rest, &state).unwrap();
        // 16,000 bytes and 16 KiB of room: 2,024 triangles.
        let room = (culler.triangles.size() / 16) as usize;
        culler.edit(&ctx, 500, &[], 8, &[], &state).unwrap();
        let count = room + 100;
        let named: Vec<(u32, [u32; 3])> = (1100..count as u32).map(|i| (i, [1, 2, 3])).collect();
        culler.edit(&ctx, count, &named, 8, &[], &state).unwrap();
        assert!(
            culler.triangles.size() as usize > room * 16,
            "the buffer grew"
        );
        let (device, _) = culler.read_surface(&ctx, count, 8).unwrap();
        assert_eq!(device.len(), count);
        for (i, (d, h)) in device.iter().zip(&culler.triangles_host).enumerate() {
            assert_eq!(
                d, h,
                "slot {i}: the device holds {d:?}, the host copy {h:?}"
            );
        }
        assert_eq!(device[700], [0; 4]);
        assert_eq!(device[1100], [1, 2, 3, 0]);
    }

    /// An edit whose rest positions would pass the device's binding limit is refused before
    /// anything changes: the triangles it names are written neither on the host nor on the
    /// device, and the culler keeps its count.
    #[test]
    fn an_edit_past_the_binding_limit_changes_nothing() {
        // 64 KiB a binding: 4,096 rest positions or triangles.
        let lower = |l: &mut wgpu::Limits| l.max_storage_buffer_binding_size = 64 << 10;
        let Some(ctx) = opened(GpuContext::with_limits(lower)) else {
            return;
        };
        let state = StateBuffers::new(&ctx, 8, Integrator::Verlet, Sizing::Headroom).unwrap();
        let tris: Vec<[u32; 3]> = (0..100u32).map(|i| [i % 8, (i + 1) % 8, 7]).collect();
        let rest = vec![[0.5f32; 4]; 8];
        let mut culler = ToolCuller::new(&ctx, &tris, &rest, &state).unwrap();
        let before_host = culler.triangles_host.clone();
        let err = culler
            .edit(&ctx, 120, &[(0, [5, 6, 7])], 5000, &[], &state)
            .unwrap_err();
        assert!(err.to_string().contains("rest positions"), "{err}");
        assert_eq!(culler.triangle_count, 100);
        assert_eq!(culler.triangles_host, before_host);
        let (device, _) = culler.read_surface(&ctx, 100, 8).unwrap();
        for (i, (d, t)) in device.iter().zip(&tris).enumerate() {
            assert_eq!(*d, [t[0], t[1], t[2], 0], "slot {i}");
        }
    }
}
