//! What the node-centric passes (connectivity, valence) share: the slot and mass buffers and the
//! group-0 bindings of `shaders/node_gather.wgsl`, one bind group per rotation phase.

use wgpu::util::DeviceExt;

use super::{buffers, GpuContext, NodeState};
use crate::error::Result;
use crate::layout::Slot;

/// Group 0 of a node-centric pass.
pub struct NodeGather {
    /// Its layout, for building the pipeline.
    pub layout: wgpu::BindGroupLayout,
    /// One bind group per rotation phase of the node state.
    pub bind_groups: Vec<wgpu::BindGroup>,
    _slots: wgpu::Buffer,
    _inv_mass: wgpu::Buffer,
}

impl NodeGather {
    /// Upload `slots` and `inv_mass` and bind them with the step constants and node state.
    pub fn new(
        ctx: &GpuContext,
        label: &str,
        slots: &[Slot],
        inv_mass: &[f32],
        uniform: &wgpu::Buffer,
        state: &NodeState,
    ) -> Result<Self> {
        let d = &ctx.device;
        buffers::check_binding(ctx, "slots", std::mem::size_of_val(slots) as u64)?;
        // An empty binding is invalid; a mesh without springs still gets one (unused) slot.
        let one = [Slot::empty()];
        let slot_data = if slots.is_empty() { &one[..] } else { slots };
        let slots = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::cast_slice(slot_data),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        });
        let inv_mass = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("inverse masses"),
            contents: bytemuck::cast_slice(inv_mass),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        });
        // slots, masses, second state, current (read); next, second out (written).
        let layout = buffers::pass_layout(ctx, label, &[true, true, true, true, false, false]);
        let bind_groups = (0..state.phases())
            .map(|phase| {
                let b = state.bindings(phase);
                d.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some(label),
                    layout: &layout,
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
        Ok(NodeGather {
            layout,
            bind_groups,
            _slots: slots,
            _inv_mass: inv_mass,
        })
    }
}
