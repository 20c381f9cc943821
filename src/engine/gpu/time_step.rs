//! A change of time step on the device: pairs with `shaders/time_step.wgsl`. The step
//! parameters (h, h², 1/h) are one uniform the passes read every step, so a new step writes it
//! and nothing else; Verlet, which keeps its last step `d = u - u_prev` (h times the velocity),
//! also needs it scaled by h'/h so that its velocity stays what it was, which this pass does in place
//! without a readback or an upload. Its twin is [`crate::twin::time_step`].

use super::buffers;
use super::{GpuContext, PhaseBindings};
use crate::error::Result;

const SOURCE: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/time_step.wgsl")
);

/// The Verlet rescale pass: its pipeline and bind-group layout. Bind groups are made at each
/// use: a change of time step is rare, and the state buffers it binds change at patches.
pub struct RescalePass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl RescalePass {
    /// Compile the pass.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let layout = buffers::pass_layout(ctx, "time step", &[true, false]);
        let pipeline = buffers::compute_pipeline(ctx, "time step", SOURCE, &[&layout])?;
        Ok(RescalePass { pipeline, layout })
    }

    /// Record the rescale of `state`'s last steps (`second_in`) by the uniform's
    /// `rescale` into `enc`, over `groups` workgroups of nodes.
    pub fn record(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        uniform: &wgpu::Buffer,
        state: &PhaseBindings<'_>,
        groups: (u32, u32),
    ) {
        let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("time step"),
            layout: &self.layout,
            entries: &buffers::entries(&[uniform, state.cur, state.second_in]),
        });
        buffers::record_dispatch(enc, "time step", &self.pipeline, &group, groups);
    }
}
