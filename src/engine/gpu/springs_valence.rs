//! The valence pass: pairs with `shaders/springs_valence.wgsl`. Group 0 is the node gather;
//! group 1 holds the bucket table (a count, then the buckets) in a storage buffer. One dispatch
//! over every node slot steps all buckets: each invocation finds its node's bucket by a binary
//! search of the table. One dispatch per bucket, as the valence textures of the literature
//! were drawn, made the step cost 4-8 µs a bucket on an H100 (the 104,544-tet box's step 0.044
//! ms of device time with 11 buckets, 0.19-0.22 ms with the 27 that 40 incisions leave; 0.014
//! ms in one dispatch), more than the step's own work.

use super::buffers::{self, Sizing};
use super::node_gather::NodeGather;
use super::{GpuContext, StateBuffers};
use crate::error::Result;
use crate::layout::valence::{table_bytes, Bucket, ValenceLayout, TABLE_HEADER};

/// WGSL has no includes: the shared parts are prepended.
const SOURCE: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/node_gather.wgsl"),
    include_str!("../../../shaders/valence_buckets.wgsl"),
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
}

impl ValencePass {
    /// Upload the layout and build the pipeline and bind groups.
    pub fn new(
        ctx: &GpuContext,
        layout: &ValenceLayout,
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
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
            // A runtime-sized array binds at least one element.
            Sizing::Exact => layout.buckets.len().max(1),
            // Room for the buckets the first cuts append.
            Sizing::Headroom => layout.buckets.len() + 16,
            Sizing::SizeClass => layout.buckets.len().max(1).next_power_of_two(),
        };
        let bucket_layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("valence buckets"),
            entries: &[buffers::storage_entry(0, true)],
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
        };
        pass.set_buckets(ctx, &layout.buckets, |table, bytes| {
            ctx.queue.write_buffer(table, 0, bytes)
        });
        Ok(pass)
    }

    /// The bucket table as the device holds it, `count` buckets (read back: for checks), and
    /// the count it says it holds.
    pub fn read_buckets(&self, ctx: &GpuContext, count: usize) -> Result<(u32, Vec<Bucket>)> {
        let bytes = table_bytes(count).min(self.table.size());
        let raw = buffers::read_bytes(ctx, &self.table, bytes)?;
        let held = bytemuck::pod_read_unaligned::<u32>(&raw[..4]);
        let buckets = raw[TABLE_HEADER as usize..]
            .chunks_exact(16)
            .map(bytemuck::pod_read_unaligned::<Bucket>)
            .collect();
        Ok((held, buckets))
    }

    /// Write the bucket table with `write` (given the table's buffer and its bytes from offset
    /// 0: a patch stages it with its other writes, so that the device makes no staging buffer
    /// of its own for it). A table without room for that many buckets is first replaced by one
    /// of the next size class, rebound in place (the pipeline is kept). Returns whether it was.
    pub fn set_buckets(
        &mut self,
        ctx: &GpuContext,
        buckets: &[Bucket],
        write: impl FnOnce(&wgpu::Buffer, &[u8]),
    ) -> bool {
        let bytes = table_bytes(buckets.len());
        let grow = bytes > self.table.size();
        if grow {
            let entries = buckets.len().next_power_of_two();
            (self.table, self.buckets) = bucket_table(ctx, &self.bucket_layout, entries);
        }
        let mut table = Vec::with_capacity(bytes as usize);
        table.extend_from_slice(bytemuck::bytes_of(&[buckets.len() as u32, 0, 0, 0]));
        table.extend_from_slice(bytemuck::cast_slice(buckets));
        write(&self.table, &table);
        grow
    }

    /// Layout of group 1 (the bucket table), for passes that walk the buckets too.
    pub fn bucket_layout(&self) -> &wgpu::BindGroupLayout {
        &self.bucket_layout
    }

    /// Group 1 (the bucket table) as bound now: a table that grew binds anew.
    pub fn bucket_group(&self) -> &wgpu::BindGroup {
        &self.buckets
    }

    /// The bucket table's buffer (the implicit solve binds it too).
    pub fn table(&self) -> &wgpu::Buffer {
        &self.table
    }

    /// Record one step in phase `phase` of the state rotation over the node dispatch `groups`.
    pub fn record(&self, pass: &mut wgpu::ComputePass<'_>, phase: usize, groups: (u32, u32)) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.gather.bind_groups[phase], &[]);
        pass.set_bind_group(1, &self.buckets, &[]);
        pass.dispatch_workgroups(groups.0, groups.1, 1);
    }
}

/// A bucket table with room for `entries` buckets after its header (zeroed: an empty table
/// until [`ValencePass::set_buckets`] writes it) and its bind group. A few hundred bytes: no
/// binding limit to check.
fn bucket_table(
    ctx: &GpuContext,
    layout: &wgpu::BindGroupLayout,
    entries: usize,
) -> (wgpu::Buffer, wgpu::BindGroup) {
    let table = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("valence buckets"),
        size: table_bytes(entries),
        // Read back by checks (`read_buckets`).
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("valence buckets"),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: table.as_entire_binding(),
        }],
    });
    (table, group)
}
