//! The connectivity pass: pairs with `shaders/springs_connectivity.wgsl`. The pipeline and its
//! bind-group layout are made once; one bind group per phase of the state rotation is made
//! once too, so a step only records a dispatch.

use wgpu::util::DeviceExt;

use super::{buffers, GpuContext, NodeState};
use crate::error::Result;
use crate::layout::connectivity::ConnectivityLayout;

/// WGSL has no includes: the shared structs are prepended.
const SOURCE: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/springs_connectivity.wgsl")
);

/// The pass with its device data.
pub struct ConnectivityPass {
    pipeline: wgpu::ComputePipeline,
    /// One bind group per rotation phase of the node state.
    bind_groups: Vec<wgpu::BindGroup>,
    /// Kept alive for the bind groups.
    _slots: wgpu::Buffer,
    _inv_mass: wgpu::Buffer,
}

impl ConnectivityPass {
    /// Upload the layout and build the pipeline and bind groups.
    pub fn new(
        ctx: &GpuContext,
        layout: &ConnectivityLayout,
        uniform: &wgpu::Buffer,
        state: &NodeState,
    ) -> Result<Self> {
        let d = &ctx.device;
        buffers::check_binding(
            ctx,
            "slots",
            std::mem::size_of_val(&layout.slots[..]) as u64,
        )?;
        let slots = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("connectivity slots"),
            contents: bytemuck::cast_slice(&layout.slots),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        });
        let inv_mass = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("inverse masses"),
            contents: bytemuck::cast_slice(&layout.nodes.inv_mass),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        });
        let bgl = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("springs_connectivity"),
            entries: &[
                buffers::uniform_entry(0),
                buffers::storage_entry(1, true),
                buffers::storage_entry(2, true),
                buffers::storage_entry(3, true),
                buffers::storage_entry(4, true),
                buffers::storage_entry(5, false),
                buffers::storage_entry(6, false),
            ],
        });
        let pipeline = buffers::compute_pipeline(ctx, "springs_connectivity", SOURCE, &bgl)?;
        let bind_groups = (0..state.phases())
            .map(|phase| {
                let b = state.bindings(phase);
                d.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("springs_connectivity"),
                    layout: &bgl,
                    entries: &buffers::entries(&[
                        uniform,
                        &slots,
                        &inv_mass,
                        b.second_in,
                        b.cur,
                        b.next,
                        b.second_out,
                    ]),
                })
            })
            .collect();
        Ok(ConnectivityPass {
            pipeline,
            bind_groups,
            _slots: slots,
            _inv_mass: inv_mass,
        })
    }

    /// Record one step in phase `phase` of the state rotation.
    pub fn record(&self, pass: &mut wgpu::ComputePass<'_>, phase: usize, groups: (u32, u32)) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_groups[phase], &[]);
        pass.dispatch_workgroups(groups.0, groups.1, 1);
    }
}
