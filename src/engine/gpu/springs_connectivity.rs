//! The connectivity pass: pairs with `shaders/springs_connectivity.wgsl`. The pipeline and its
//! bind-group layout are made once, and one bind group per phase of the state rotation, so a
//! step only records a dispatch.

use super::buffers::{self, Sizing};
use super::node_gather::NodeGather;
use super::{GpuContext, StateBuffers};
use crate::error::Result;
use crate::layout::connectivity::ConnectivityLayout;

/// WGSL has no includes: the shared parts are prepended.
const SOURCE: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/node_gather.wgsl"),
    include_str!("../../../shaders/springs_connectivity.wgsl")
);

/// The pass with its device data.
pub struct ConnectivityPass {
    pipeline: wgpu::ComputePipeline,
    /// The slot and mass buffers with their bind groups.
    pub gather: NodeGather,
}

impl ConnectivityPass {
    /// Upload the layout and build the pipeline and bind groups.
    pub fn new(
        ctx: &GpuContext,
        layout: &ConnectivityLayout,
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
        sizing: Sizing,
    ) -> Result<Self> {
        let gather = NodeGather::new(
            ctx,
            "springs_connectivity",
            &layout.slots,
            &layout.nodes.inv_mass,
            uniform,
            state,
            sizing,
        )?;
        let pipeline =
            buffers::compute_pipeline(ctx, "springs_connectivity", SOURCE, &[&gather.layout])?;
        Ok(ConnectivityPass { pipeline, gather })
    }

    /// Record one step in phase `phase` of the state rotation.
    pub fn record(&self, pass: &mut wgpu::ComputePass<'_>, phase: usize, groups: (u32, u32)) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.gather.bind_groups[phase], &[]);
        pass.dispatch_workgroups(groups.0, groups.1, 1);
    }
}
