//! Nodes in a box on the device: pairs with `shaders/nodes_near.wgsl`. A cut needs the current
//! positions of the nodes near its blade only; this pass finds them where the state lives and
//! reads back just their displacements (16 bytes each, with the counter in the same buffer: one
//! round trip), instead of every node's state. Built with the surface culler, whose rest
//! positions it reads, so that a cut never waits for a pipeline to compile.

use bytemuck::{Pod, Zeroable};

use super::buffers::{self, Sizing};
use super::{dispatch_size, GpuContext, NodeState, WORKGROUP};
use crate::error::{Error, Result};

const SOURCE: &str = include_str!("../../../shaders/nodes_near.wgsl");

/// Mirrors `struct NearParams` in `shaders/nodes_near.wgsl` (48 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct NearParams {
    lo: [f32; 4],
    hi: [f32; 4],
    slots: u32,
    capacity: u32,
    row: u32,
    _pad: u32,
}

const _: () = assert!(std::mem::size_of::<NearParams>() == 48);

/// Bytes before the entries in the output buffer (the counter and its padding).
const HEADER: u64 = 16;

/// Entries the output holds at first: the nodes near a few-centimetre incision in centimetre
/// cells, with room; grown by size class when a cut finds more.
const FIRST_CAPACITY: u64 = 2048;

/// The pass and its output buffer.
pub struct NodesNear {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    found: wgpu::Buffer,
    /// Where `found` is copied for the host to read, kept from one cut to the next.
    staging: wgpu::Buffer,
    /// One bind group per rotation phase (the displacement buffer differs).
    bind_groups: Vec<wgpu::BindGroup>,
}

/// One node found: its layout slot and its displacement.
pub type Found = (u32, [f32; 3]);

impl NodesNear {
    /// Compile the pass and bind it to `rest` (positions in layout order) and the node state.
    pub fn new(ctx: &GpuContext, rest: &wgpu::Buffer, state: &NodeState) -> Result<Self> {
        let params = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("nodes near params"),
            size: std::mem::size_of::<NearParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // rest, displacements (read); found (written).
        let layout = buffers::pass_layout(ctx, "nodes near", &[true, true, false]);
        let pipeline = buffers::compute_pipeline(ctx, "nodes near", SOURCE, &[&layout])?;
        let found = found_buffer(ctx, FIRST_CAPACITY)?;
        let staging = buffers::staging_buffer(ctx, found.size());
        let mut pass = NodesNear {
            pipeline,
            layout,
            params,
            found,
            staging,
            bind_groups: Vec::new(),
        };
        pass.rebind(ctx, rest, state);
        Ok(pass)
    }

    /// Rebuild the bind groups (after the rest positions, the node state or the output buffer
    /// was reallocated).
    pub fn rebind(&mut self, ctx: &GpuContext, rest: &wgpu::Buffer, state: &NodeState) {
        self.bind_groups = (0..state.phases())
            .map(|phase| {
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("nodes near"),
                    layout: &self.layout,
                    entries: &buffers::entries(&[
                        &self.params,
                        rest,
                        state.bindings(phase).cur,
                        &self.found,
                    ]),
                })
            })
            .collect();
    }

    /// The node slots among the first `slots` whose current position (rest + displacement, in
    /// float32) lies in `lo..=hi`, with their displacements, at the state of `phase`. In slot
    /// order.
    #[allow(clippy::too_many_arguments)]
    pub fn find(
        &mut self,
        ctx: &GpuContext,
        rest: &wgpu::Buffer,
        state: &NodeState,
        phase: usize,
        slots: u32,
        lo: [f32; 3],
        hi: [f32; 3],
    ) -> Result<Vec<Found>> {
        let groups = dispatch_size(ctx, slots);
        loop {
            let capacity = (self.found.size() - HEADER) / 16;
            let params = NearParams {
                lo: [lo[0], lo[1], lo[2], 0.0],
                hi: [hi[0], hi[1], hi[2], 0.0],
                slots,
                capacity: capacity as u32,
                row: groups.0 * WORKGROUP,
                _pad: 0,
            };
            ctx.queue
                .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
            ctx.queue.write_buffer(&self.found, 0, &[0u8; 4]);
            // The pass and the copy of its output in one submission: one round trip.
            let mut enc = buffers::encode_dispatch(
                ctx,
                "nodes near",
                &self.pipeline,
                &self.bind_groups[phase],
                groups,
            );
            let size = self.found.size();
            enc.copy_buffer_to_buffer(&self.found, 0, &self.staging, 0, size);
            let raw = buffers::submit_and_read(ctx, enc, &self.staging, size)?;
            let count = u32::from_le_bytes(
                raw[..4]
                    .try_into()
                    .map_err(|_| Error::Gpu("nodes near: counter readback".into()))?,
            ) as u64;
            if count <= capacity {
                let entries: Vec<[u32; 4]> = bytemuck::pod_collect_to_vec(
                    &raw[HEADER as usize..(HEADER + 16 * count) as usize],
                );
                let mut out: Vec<Found> = entries
                    .iter()
                    .map(|e| (e[3], [0, 1, 2].map(|c| f32::from_bits(e[c]))))
                    .collect();
                out.sort_unstable_by_key(|f| f.0);
                return Ok(out);
            }
            // More nodes than room: grow to hold them all and run again.
            self.found = found_buffer(ctx, count)?;
            self.staging = buffers::staging_buffer(ctx, self.found.size());
            self.rebind(ctx, rest, state);
        }
    }
}

/// An output buffer with room for `capacity` entries (at least), by size class.
fn found_buffer(ctx: &GpuContext, capacity: u64) -> Result<wgpu::Buffer> {
    let bytes = vec![0u8; (HEADER + 16 * capacity) as usize];
    buffers::storage_buffer(ctx, "nodes near", &bytes, Sizing::SizeClass)
}
