//! What the node-centric passes (connectivity, valence) share: the slot and mass buffers and the
//! group-0 bindings of `shaders/node_gather.wgsl`, one bind group per rotation phase.

use super::buffers::{self, Sizing};
use super::{GpuContext, NodeState};
use crate::error::Result;
use crate::layout::patch::LayoutArray;
use crate::layout::Slot;

/// Group 0 of a node-centric pass.
pub struct NodeGather {
    /// Its layout, for building the pipeline.
    pub layout: wgpu::BindGroupLayout,
    /// One bind group per rotation phase of the node state.
    pub bind_groups: Vec<wgpu::BindGroup>,
    slots: wgpu::Buffer,
    inv_mass: wgpu::Buffer,
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
        sizing: Sizing,
    ) -> Result<Self> {
        let d = &ctx.device;
        let slots = buffers::storage_buffer(ctx, "slots", bytemuck::cast_slice(slots), sizing)?;
        let inv_mass = buffers::storage_buffer(
            ctx,
            "inverse masses",
            bytemuck::cast_slice(inv_mass),
            sizing,
        )?;
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
            slots,
            inv_mass,
        })
    }

    /// The device buffer of a layout array, if this pass holds it.
    pub fn buffer(&self, array: LayoutArray) -> Option<&wgpu::Buffer> {
        match array {
            LayoutArray::Slots => Some(&self.slots),
            LayoutArray::InvMass => Some(&self.inv_mass),
            _ => None,
        }
    }
}
