//! The edge passes: pair with `shaders/springs_edges.wgsl` (one force per spring) and
//! `shaders/gather_edges.wgsl` (each node sums its springs' forces and integrates). Both
//! pipelines, their bind-group layouts and one bind group per rotation phase are made once.

use wgpu::util::DeviceExt;

use super::{buffers, GpuContext, NodeState};
use crate::error::Result;
use crate::layout::edges::{EdgeLayout, EdgeSpring};

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
    _buffers: Vec<wgpu::Buffer>,
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

/// A read-only storage buffer holding `data` (at least one element, as empty bindings are
/// invalid).
pub(crate) fn upload<T: bytemuck::Pod + bytemuck::Zeroable>(
    ctx: &GpuContext,
    label: &str,
    data: &[T],
) -> Result<wgpu::Buffer> {
    buffers::check_binding(ctx, label, std::mem::size_of_val(data) as u64)?;
    let one = [T::zeroed()];
    let data = if data.is_empty() { &one[..] } else { data };
    Ok(ctx
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::cast_slice(data),
            usage: wgpu::BufferUsages::STORAGE,
        }))
}

impl EdgePasses {
    /// Upload the layout and build both pipelines and their bind groups.
    pub fn new(
        ctx: &GpuContext,
        layout: &EdgeLayout,
        uniform: &wgpu::Buffer,
        state: &NodeState,
    ) -> Result<Self> {
        let d = &ctx.device;
        let springs = upload::<EdgeSpring>(ctx, "edge springs", &layout.springs)?;
        let rows = upload(ctx, "incidence rows", &layout.incidence_rows)?;
        let incidence = upload(ctx, "incidence", &layout.incidence)?;
        let inv_mass = upload(ctx, "inverse masses", &layout.nodes.inv_mass)?;
        let force_bytes = (layout.springs.len().max(1) * 16) as u64;
        buffers::check_binding(ctx, "spring forces", force_bytes)?;
        let forces = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("spring forces"),
            size: force_bytes,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        // springs, second state, current (read); forces (written).
        let spring_layout = buffers::pass_layout(ctx, "springs_edges", &[true, true, true, false]);
        // rows, incidence, forces, masses, second state, current (read); next, second out.
        let gather_layout = buffers::pass_layout(
            ctx,
            "gather_edges",
            &[true, true, true, true, true, true, false, false],
        );
        let bind_groups = (0..state.phases())
            .map(|phase| {
                let b = state.bindings(phase);
                let spring = d.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("springs_edges"),
                    layout: &spring_layout,
                    entries: &buffers::entries(&[uniform, &springs, b.second_in, b.cur, &forces]),
                });
                let gather = d.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("gather_edges"),
                    layout: &gather_layout,
                    entries: &buffers::entries(&[
                        uniform,
                        &rows,
                        &incidence,
                        &forces,
                        &inv_mass,
                        b.second_in,
                        b.cur,
                        b.next,
                        b.second_out,
                    ]),
                });
                (spring, gather)
            })
            .collect();
        Ok(EdgePasses {
            passes: SpringThenNode {
                springs: buffers::compute_pipeline(
                    ctx,
                    "springs_edges",
                    SPRINGS,
                    &[&spring_layout],
                )?,
                nodes: buffers::compute_pipeline(ctx, "gather_edges", GATHER, &[&gather_layout])?,
                bind_groups,
            },
            _buffers: vec![springs, rows, incidence, inv_mass, forces],
        })
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
