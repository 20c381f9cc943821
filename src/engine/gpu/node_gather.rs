//! What the node-centric passes (connectivity, valence) share: the slot and mass buffers and the
//! group-0 bindings of `shaders/node_gather.wgsl`, one bind group per rotation phase.

use super::buffers::{self, Sizing};
use super::layout_buffers::{self, LayoutBuffers};
use super::{GpuContext, StateBuffers};
use crate::error::Result;
use crate::layout::patch::LayoutArray;
use crate::layout::Slot;

/// Group 0 of a node-centric pass.
pub struct NodeGather {
    /// Its layout, for building the pipeline.
    pub layout: wgpu::BindGroupLayout,
    /// One bind group per rotation phase of the node state.
    pub bind_groups: Vec<wgpu::BindGroup>,
    label: &'static str,
    slots: wgpu::Buffer,
    inv_mass: wgpu::Buffer,
}

impl NodeGather {
    /// Upload `slots` and `inv_mass` and bind them with the step constants and node state.
    pub fn new(
        ctx: &GpuContext,
        label: &'static str,
        slots: &[Slot],
        inv_mass: &[f32],
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
        sizing: Sizing,
    ) -> Result<Self> {
        let slots = buffers::storage_buffer(
            ctx,
            layout_buffers::label(LayoutArray::Slots),
            bytemuck::cast_slice(slots),
            sizing,
        )?;
        let inv_mass = buffers::storage_buffer(
            ctx,
            layout_buffers::label(LayoutArray::InvMass),
            bytemuck::cast_slice(inv_mass),
            sizing,
        )?;
        // slots, masses, second state, current (read); next, second out (written).
        let layout = buffers::pass_layout(ctx, label, &[true, true, true, true, false, false]);
        let mut gather = NodeGather {
            layout,
            bind_groups: Vec::new(),
            label,
            slots,
            inv_mass,
        };
        gather.rebind(ctx, uniform, state)?;
        Ok(gather)
    }
}

impl LayoutBuffers for NodeGather {
    fn buffer(&self, array: LayoutArray) -> Option<&wgpu::Buffer> {
        match array {
            LayoutArray::Slots => Some(&self.slots),
            LayoutArray::InvMass => Some(&self.inv_mass),
            _ => None,
        }
    }

    fn buffer_mut(&mut self, array: LayoutArray) -> Option<&mut wgpu::Buffer> {
        match array {
            LayoutArray::Slots => Some(&mut self.slots),
            LayoutArray::InvMass => Some(&mut self.inv_mass),
            _ => None,
        }
    }

    fn rebind(
        &mut self,
        ctx: &GpuContext,
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
    ) -> Result<()> {
        self.bind_groups = (0..state.phases())
            .map(|phase| {
                let b = state.bindings(phase);
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some(self.label),
                    layout: &self.layout,
                    entries: &buffers::entries(&[
                        uniform,
                        &self.slots,
                        &self.inv_mass,
                        b.second_in,
                        b.cur,
                        b.next,
                        b.second_out,
                    ]),
                })
            })
            .collect();
        Ok(())
    }
}
