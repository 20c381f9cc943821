//! Blended state moves on the device: pairs with `shaders/blend_state.wgsl`. A node a cut puts
//! on an edge starts with the state interpolated between the edge's ends; the mix is computed
//! where the state lives, so a cut reads nothing back for it.

use bytemuck::{Pod, Zeroable};

use super::buffers::{self, Sizing};
use super::GpuContext;
use crate::error::Result;

const SOURCE: &str = include_str!("../../../shaders/blend_state.wgsl");

/// One blended move: indices into the staging buffer of the two sources, the destination in
/// the state buffer and the weight of the second source.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct BlendRecord {
    /// Destination index; [`BlendRecord::PAD`] for a padding record.
    pub to: u32,
    /// First source, index into the staging buffer.
    pub first: u32,
    /// Second source, index into the staging buffer.
    pub second: u32,
    /// Weight of the second source.
    pub t: f32,
}

impl BlendRecord {
    /// Marks a record that only pads the list to the smallest binding (32 bytes).
    pub const PAD: u32 = u32::MAX;
}

/// The blend pipeline, built the first time a patch blends.
pub struct BlendPass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl BlendPass {
    /// Compile the pass.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let layout = ctx
            .device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("blend state"),
                entries: &[
                    buffers::storage_entry(0, true),
                    buffers::storage_entry(1, true),
                    buffers::storage_entry(2, false),
                ],
            });
        let pipeline = buffers::compute_pipeline(ctx, "blend state", SOURCE, &[&layout])?;
        Ok(BlendPass { pipeline, layout })
    }

    /// Record into `enc` the blends `records` from `temp` (the staged sources) into `state`.
    pub fn record(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        temp: &wgpu::Buffer,
        state: &wgpu::Buffer,
        records: &[BlendRecord],
    ) -> Result<()> {
        if records.is_empty() {
            return Ok(());
        }
        // At least two records (32 bytes, the smallest buffer made here), so the buffer holds
        // exactly the records and the shader's `arrayLength` counts them.
        let mut list = records.to_vec();
        if list.len() < 2 {
            list.push(BlendRecord {
                to: BlendRecord::PAD,
                ..list[0]
            });
        }
        let blends = buffers::storage_buffer(
            ctx,
            "blend records",
            bytemuck::cast_slice(&list),
            Sizing::Exact,
        )?;
        let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("blend state"),
            layout: &self.layout,
            entries: &buffers::entries(&[&blends, temp, state]),
        });
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("blend state"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups((list.len() as u32).div_ceil(64), 1, 1);
        Ok(())
    }
}
