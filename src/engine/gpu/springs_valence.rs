//! The valence pass: pairs with `shaders/springs_valence.wgsl`. Group 0 is the node gather;
//! group 1 holds the bucket table in a uniform buffer, one entry per dynamic offset, so each
//! bucket is one dispatch with nothing rebuilt per step.

use super::buffers::{self, Sizing};
use super::node_gather::NodeGather;
use super::{GpuContext, NodeState, WORKGROUP};
use crate::error::Result;
use crate::layout::valence::{Bucket, ValenceLayout};

/// WGSL has no includes: the shared parts are prepended.
const SOURCE: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/node_gather.wgsl"),
    include_str!("../../../shaders/springs_valence.wgsl")
);

/// The pass with its device data.
pub struct ValencePass {
    pipeline: wgpu::ComputePipeline,
    /// The slot and mass buffers with their bind groups.
    pub gather: NodeGather,
    /// Layout of group 1, for rebinding a grown table.
    bucket_layout: wgpu::BindGroupLayout,
    buckets: wgpu::BindGroup,
    table: wgpu::Buffer,
    /// Per bucket: its dynamic offset and its workgroup counts.
    dispatches: Vec<(u32, (u32, u32))>,
}

/// Bytes between bucket entries: the device's uniform offset alignment.
pub fn bucket_stride(ctx: &GpuContext) -> u64 {
    (ctx.limits.min_uniform_buffer_offset_alignment as u64).max(16)
}

impl ValencePass {
    /// Upload the layout and build the pipeline and bind groups. `row` is the invocations per
    /// dispatch row of the step constants.
    pub fn new(
        ctx: &GpuContext,
        layout: &ValenceLayout,
        uniform: &wgpu::Buffer,
        state: &NodeState,
        row: u32,
        sizing: Sizing,
    ) -> Result<Self> {
        let d = &ctx.device;
        let gather = NodeGather::new(
            ctx,
            "springs_valence",
            &layout.slots,
            &layout.nodes.inv_mass,
            uniform,
            state,
            sizing,
        )?;
        let entries = match sizing {
            Sizing::Exact => layout.buckets.len().max(1),
            // Room for the buckets the first cuts append.
            Sizing::Headroom => layout.buckets.len() + 16,
            Sizing::SizeClass => layout.buckets.len().max(1).next_power_of_two(),
        };
        let bucket_layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("valence bucket"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: true,
                    min_binding_size: wgpu::BufferSize::new(std::mem::size_of::<Bucket>() as u64),
                },
                count: None,
            }],
        });
        let (table, buckets) = bucket_table(ctx, &bucket_layout, entries);
        let pipeline = buffers::compute_pipeline(
            ctx,
            "springs_valence",
            SOURCE,
            &[&gather.layout, &bucket_layout],
        )?;
        let mut pass = ValencePass {
            pipeline,
            gather,
            bucket_layout,
            buckets,
            table,
            dispatches: Vec::new(),
        };
        pass.set_buckets(ctx, &layout.buckets, row, |table, bytes| {
            ctx.queue.write_buffer(table, 0, bytes)
        });
        Ok(pass)
    }

    /// The bucket table as the device holds it, one entry per bucket of `count` (read back:
    /// for checks).
    pub fn read_buckets(&self, ctx: &GpuContext, count: usize) -> Result<Vec<Bucket>> {
        let stride = bucket_stride(ctx);
        let bytes = (count as u64 * stride).min(self.table.size());
        if bytes == 0 {
            return Ok(Vec::new());
        }
        let raw = buffers::read_bytes(ctx, &self.table, bytes)?;
        Ok(raw
            .chunks(stride as usize)
            .filter(|c| c.len() >= 16)
            .map(|c| bytemuck::pod_read_unaligned::<Bucket>(&c[..16]))
            .collect())
    }

    /// Write the bucket table with `write` (given the table's buffer and its bytes from offset
    /// 0: a patch stages it with its other writes, so that the device makes no staging buffer
    /// of its own for it) and recompute the dispatches (after a patch moved nodes between
    /// buckets). A table without room for that many buckets is first replaced by one of the
    /// next size class, rebound in place (the pipeline is kept). Returns whether it was.
    pub fn set_buckets(
        &mut self,
        ctx: &GpuContext,
        buckets: &[Bucket],
        row: u32,
        write: impl FnOnce(&wgpu::Buffer, &[u8]),
    ) -> bool {
        let stride = bucket_stride(ctx);
        let grow = buckets.len() as u64 * stride > self.table.size();
        if grow {
            let entries = buckets.len().next_power_of_two();
            (self.table, self.buckets) = bucket_table(ctx, &self.bucket_layout, entries);
        }
        let mut table = vec![0u8; (buckets.len() as u64 * stride) as usize];
        for (b, bucket) in buckets.iter().enumerate() {
            let at = b * stride as usize;
            table[at..at + 16].copy_from_slice(bytemuck::bytes_of(bucket));
        }
        if !table.is_empty() {
            write(&self.table, &table);
        }
        let per_row = (row / WORKGROUP).max(1);
        self.dispatches = buckets
            .iter()
            .enumerate()
            .filter(|(_, b)| b.count > 0)
            .map(|(i, b)| {
                let groups = b.count.div_ceil(WORKGROUP);
                let size = (groups.min(per_row), b.count.div_ceil(row.max(1)));
                ((i as u64 * stride) as u32, size)
            })
            .collect();
        grow
    }

    /// Record one step in phase `phase` of the state rotation: one dispatch per bucket.
    pub fn record(&self, pass: &mut wgpu::ComputePass<'_>, phase: usize) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.gather.bind_groups[phase], &[]);
        for &(offset, (x, y)) in &self.dispatches {
            pass.set_bind_group(1, &self.buckets, &[offset]);
            pass.dispatch_workgroups(x, y, 1);
        }
    }
}

/// A bucket table with room for `entries` buckets (uninitialised: [`ValencePass::set_buckets`]
/// writes it) and its bind group: one bucket at a dynamic offset.
fn bucket_table(
    ctx: &GpuContext,
    layout: &wgpu::BindGroupLayout,
    entries: usize,
) -> (wgpu::Buffer, wgpu::BindGroup) {
    let table = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("valence buckets"),
        size: entries.max(1) as u64 * bucket_stride(ctx),
        // Read back by checks (`read_buckets`).
        usage: wgpu::BufferUsages::UNIFORM
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("valence bucket"),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &table,
                offset: 0,
                size: wgpu::BufferSize::new(std::mem::size_of::<Bucket>() as u64),
            }),
        }],
    });
    (table, group)
}
