//! The edge passes: pair with `shaders/springs_edges.wgsl` (one force per spring) and
//! `shaders/gather_edges.wgsl` (each node sums its springs' forces and integrates). Both
//! pipelines, their bind-group layouts and one bind group per rotation phase are made once.

use super::buffers::{self, Sizing};
use super::layout_buffers::{self, LayoutBuffers};
use super::{GpuContext, StateBuffers};
use crate::error::Result;
use crate::layout::edges::EdgeLayout;
use crate::layout::patch::LayoutArray;

const SPRINGS: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/edge_spring.wgsl"),
    include_str!("../../../shaders/springs_edges.wgsl")
);
const GATHER: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/gather_edges.wgsl")
);

/// The two passes with their device data.
pub struct EdgePasses {
    passes: SpringThenNode,
    buffers: EdgeBuffers,
    /// Bind-group layout of the spring pass.
    spring_layout: wgpu::BindGroupLayout,
    /// Bind-group layout of the gather.
    gather_layout: wgpu::BindGroupLayout,
}

/// The edge layout's device buffers, by name.
struct EdgeBuffers {
    /// The spring records ([`LayoutArray::EdgeSprings`]).
    springs: wgpu::Buffer,
    /// Each node's range in the incidence list ([`LayoutArray::IncidenceRows`]).
    rows: wgpu::Buffer,
    /// The incidence list ([`LayoutArray::Incidence`]).
    incidence: wgpu::Buffer,
    /// Inverse masses ([`LayoutArray::InvMass`]).
    inv_mass: wgpu::Buffer,
    /// Scratch: one force per spring record, written by the spring pass, read by the gather.
    forces: wgpu::Buffer,
}

impl EdgeBuffers {
    /// The buffer holding a layout array, if this layout has it.
    fn array_mut(&mut self, array: LayoutArray) -> Option<&mut wgpu::Buffer> {
        match array {
            LayoutArray::EdgeSprings => Some(&mut self.springs),
            LayoutArray::IncidenceRows => Some(&mut self.rows),
            LayoutArray::Incidence => Some(&mut self.incidence),
            LayoutArray::InvMass => Some(&mut self.inv_mass),
            _ => None,
        }
    }

    /// [`EdgeBuffers::array_mut`], shared.
    fn array(&self, array: LayoutArray) -> Option<&wgpu::Buffer> {
        match array {
            LayoutArray::EdgeSprings => Some(&self.springs),
            LayoutArray::IncidenceRows => Some(&self.rows),
            LayoutArray::Incidence => Some(&self.incidence),
            LayoutArray::InvMass => Some(&self.inv_mass),
            _ => None,
        }
    }
}

/// A pass over springs followed by a pass over nodes, each with one bind group per rotation
/// phase: the step shape of every edge variant (gather or atomics).
pub struct SpringThenNode {
    /// The pass over springs.
    pub springs: wgpu::ComputePipeline,
    /// The pass over nodes.
    pub nodes: wgpu::ComputePipeline,
    /// Per phase: (spring pass, node pass) bind groups.
    pub bind_groups: Vec<(wgpu::BindGroup, wgpu::BindGroup)>,
}

impl SpringThenNode {
    /// Record one step in phase `phase`.
    pub fn record(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        phase: usize,
        spring_groups: (u32, u32),
        node_groups: (u32, u32),
    ) {
        let (spring_bg, node_bg) = &self.bind_groups[phase];
        pass.set_pipeline(&self.springs);
        pass.set_bind_group(0, spring_bg, &[]);
        pass.dispatch_workgroups(spring_groups.0, spring_groups.1, 1);
        pass.set_pipeline(&self.nodes);
        pass.set_bind_group(0, node_bg, &[]);
        pass.dispatch_workgroups(node_groups.0, node_groups.1, 1);
    }
}

/// A storage buffer holding `data`, sized by `sizing`.
pub(crate) fn upload<T: bytemuck::Pod>(
    ctx: &GpuContext,
    label: &str,
    data: &[T],
    sizing: Sizing,
) -> Result<wgpu::Buffer> {
    buffers::storage_buffer(ctx, label, bytemuck::cast_slice(data), sizing)
}

impl EdgePasses {
    /// Upload the layout and build both pipelines and their bind groups.
    pub fn new(
        ctx: &GpuContext,
        layout: &EdgeLayout,
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
        sizing: Sizing,
    ) -> Result<Self> {
        let label = |a| layout_buffers::label(a);
        let springs = upload(
            ctx,
            label(LayoutArray::EdgeSprings),
            &layout.springs,
            sizing,
        )?;
        let rows = upload(
            ctx,
            label(LayoutArray::IncidenceRows),
            &layout.incidence_rows,
            sizing,
        )?;
        let incidence = upload(
            ctx,
            label(LayoutArray::Incidence),
            &layout.incidence,
            sizing,
        )?;
        let inv_mass = upload(
            ctx,
            label(LayoutArray::InvMass),
            &layout.nodes.inv_mass,
            sizing,
        )?;
        let forces = force_buffer(ctx, &springs)?;
        // springs, second state, current (read); forces (written).
        let spring_layout = buffers::pass_layout(ctx, "springs_edges", &[true, true, true, false]);
        // rows, incidence, forces, masses, second state, current (read); next, second out.
        let gather_layout = buffers::pass_layout(
            ctx,
            "gather_edges",
            &[true, true, true, true, true, true, false, false],
        );
        let mut passes = EdgePasses {
            passes: SpringThenNode {
                springs: buffers::compute_pipeline(
                    ctx,
                    "springs_edges",
                    SPRINGS,
                    &[&spring_layout],
                )?,
                nodes: buffers::compute_pipeline(ctx, "gather_edges", GATHER, &[&gather_layout])?,
                bind_groups: Vec::new(),
            },
            buffers: EdgeBuffers {
                springs,
                rows,
                incidence,
                inv_mass,
                forces,
            },
            spring_layout,
            gather_layout,
        };
        passes.rebind(ctx, uniform, state)?;
        Ok(passes)
    }

    /// Record one step in phase `phase`: the spring pass, then the node gather.
    pub fn record(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        phase: usize,
        spring_groups: (u32, u32),
        node_groups: (u32, u32),
    ) {
        self.passes.record(pass, phase, spring_groups, node_groups);
    }
}

/// One force per record the spring buffer can hold, so patches that fill its room need no new
/// force buffer. Scratch: the spring pass writes every force before the gather reads it.
fn force_buffer(ctx: &GpuContext, springs: &wgpu::Buffer) -> Result<wgpu::Buffer> {
    let force_bytes = springs.size() / 32 * 16;
    buffers::check_binding(ctx, "spring forces", force_bytes)?;
    Ok(ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("spring forces"),
        size: force_bytes,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    }))
}

impl LayoutBuffers for EdgePasses {
    fn buffer(&self, array: LayoutArray) -> Option<&wgpu::Buffer> {
        self.buffers.array(array)
    }

    fn buffer_mut(&mut self, array: LayoutArray) -> Option<&mut wgpu::Buffer> {
        self.buffers.array_mut(array)
    }

    fn rebind(
        &mut self,
        ctx: &GpuContext,
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
    ) -> Result<()> {
        let d = &ctx.device;
        // Grown springs: forces for all the records they have room for.
        if self.buffers.forces.size() < self.buffers.springs.size() / 32 * 16 {
            self.buffers.forces = force_buffer(ctx, &self.buffers.springs)?;
        }
        let EdgeBuffers {
            springs,
            rows,
            incidence,
            inv_mass,
            forces,
        } = &self.buffers;
        let (spring_layout, gather_layout) = (&self.spring_layout, &self.gather_layout);
        self.passes.bind_groups = (0..state.phases())
            .map(|phase| {
                let b = state.bindings(phase);
                let spring = d.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("springs_edges"),
                    layout: spring_layout,
                    entries: &buffers::entries(&[uniform, springs, b.second_in, b.cur, forces]),
                });
                let gather = d.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("gather_edges"),
                    layout: gather_layout,
                    entries: &buffers::entries(&[
                        uniform,
                        rows,
                        incidence,
                        forces,
                        inv_mass,
                        b.second_in,
                        b.cur,
                        b.next,
                        b.second_out,
                    ]),
                });
                (spring, gather)
            })
            .collect();
        Ok(())
    }
}
