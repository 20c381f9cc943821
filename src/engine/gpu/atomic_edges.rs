//! The edge passes with atomic accumulation: pair with `shaders/accumulate_fixed.wgsl` +
//! `shaders/integrate_fixed.wgsl` (fixed point in `atomic<i32>`) and
//! `shaders/accumulate_float.wgsl` + `shaders/integrate_float.wgsl` (`atomic<f32>`). The spring
//! pass adds each force to both ends' accumulators; the node pass reads, clears and integrates.
//! Pipelines, bind-group layouts and one bind group pair per rotation phase are made once.

use wgpu::util::DeviceExt;

use super::buffers::{self, Sizing};
use super::layout_buffers::{self, LayoutBuffers};
use super::springs_edges::upload;
use super::{GpuContext, StateBuffers};
use crate::error::{Error, Result};
use crate::layout::edges::{Accumulation, EdgeLayout, FixedPoint};
use crate::layout::patch::LayoutArray;

const ACCUMULATE_FIXED: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/fixed_point.wgsl"),
    include_str!("../../../shaders/edge_spring.wgsl"),
    include_str!("../../../shaders/accumulate_fixed.wgsl")
);
const INTEGRATE_FIXED: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/fixed_point.wgsl"),
    include_str!("../../../shaders/integrate_fixed.wgsl")
);
const ACCUMULATE_FLOAT: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/edge_spring.wgsl"),
    include_str!("../../../shaders/accumulate_float.wgsl")
);
const INTEGRATE_FLOAT: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/integrate_float.wgsl")
);

/// The two passes of an atomic variant with their device data.
pub struct AtomicEdgePasses {
    /// Accumulating spring pass, then the integrating node pass.
    passes: super::springs_edges::SpringThenNode,
    /// The overflow flag of the fixed-point variant (16 bytes; nonzero once a force saturated).
    overflow: Option<wgpu::Buffer>,
    buffers: AtomicBuffers,
    /// Bind-group layout of the accumulating pass.
    accumulate_layout: wgpu::BindGroupLayout,
    /// Bind-group layout of the integrating pass.
    integrate_layout: wgpu::BindGroupLayout,
    /// The fixed-point variant (binds the constants and the overflow flag).
    fixed: bool,
}

/// The atomic variants' device buffers, by name.
struct AtomicBuffers {
    /// The spring records ([`LayoutArray::EdgeSprings`]).
    springs: wgpu::Buffer,
    /// Inverse masses ([`LayoutArray::InvMass`]).
    inv_mass: wgpu::Buffer,
    /// Three accumulators per node the mass buffer has room for.
    accumulators: wgpu::Buffer,
    /// The fixed-point constants (uniform; bound by the fixed-point variant only).
    fixed_point: wgpu::Buffer,
    /// The overflow flag (bound by the fixed-point variant only).
    overflow: wgpu::Buffer,
}

impl AtomicBuffers {
    /// The buffer holding a layout array, if these passes have it.
    fn array(&self, array: LayoutArray) -> Option<&wgpu::Buffer> {
        match array {
            LayoutArray::EdgeSprings => Some(&self.springs),
            LayoutArray::InvMass => Some(&self.inv_mass),
            _ => None,
        }
    }

    /// [`AtomicBuffers::array`], mutably.
    fn array_mut(&mut self, array: LayoutArray) -> Option<&mut wgpu::Buffer> {
        match array {
            LayoutArray::EdgeSprings => Some(&mut self.springs),
            LayoutArray::InvMass => Some(&mut self.inv_mass),
            _ => None,
        }
    }
}

impl AtomicEdgePasses {
    /// Upload the layout and build both passes of `accumulation` (an atomic variant) with the
    /// fixed-point constants `fp` (used by [`Accumulation::AtomicFixed`] only). Float atomics
    /// without `SHADER_FLOAT32_ATOMIC` on the device are an [`Error::Unsupported`].
    pub fn new(
        ctx: &GpuContext,
        layout: &EdgeLayout,
        accumulation: Accumulation,
        fp: FixedPoint,
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
        sizing: Sizing,
    ) -> Result<Self> {
        let fixed = match accumulation {
            Accumulation::AtomicFixed => true,
            Accumulation::AtomicFloat => {
                if !ctx
                    .device
                    .features()
                    .contains(wgpu::Features::SHADER_FLOAT32_ATOMIC)
                {
                    return Err(Error::Unsupported(format!(
                        "the AtomicFloat accumulation needs float32 atomics \
                         (SHADER_FLOAT32_ATOMIC), which {} does not have; use AtomicFixed or \
                         Gather (--accumulation atomic-fixed or gather)",
                        ctx.describe()
                    )));
                }
                false
            }
            Accumulation::Gather => {
                return Err(Error::Gpu(
                    "the gather variant runs in springs_edges, not with atomics".into(),
                ))
            }
        };
        let d = &ctx.device;
        let label = |a| layout_buffers::label(a);
        let springs = upload(
            ctx,
            label(LayoutArray::EdgeSprings),
            &layout.springs,
            sizing,
        )?;
        let inv_mass = upload(
            ctx,
            label(LayoutArray::InvMass),
            &layout.nodes.inv_mass,
            sizing,
        )?;
        let acc = accumulators(ctx, &inv_mass)?;
        let fx = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("fixed-point constants"),
            contents: bytemuck::bytes_of(&fp),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let overflow = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("overflow flag"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let storage = buffers::storage_entry;
        let (accumulate_entries, integrate_entries) = if fixed {
            (
                vec![
                    buffers::uniform_entry(0),
                    storage(1, true),
                    storage(2, true),
                    storage(3, true),
                    storage(4, false),
                    buffers::uniform_entry(5),
                    storage(6, false),
                ],
                vec![
                    buffers::uniform_entry(0),
                    buffers::uniform_entry(1),
                    storage(2, false),
                    storage(3, true),
                    storage(4, true),
                    storage(5, true),
                    storage(6, false),
                    storage(7, false),
                ],
            )
        } else {
            (
                vec![
                    buffers::uniform_entry(0),
                    storage(1, true),
                    storage(2, true),
                    storage(3, true),
                    storage(4, false),
                ],
                vec![
                    buffers::uniform_entry(0),
                    storage(1, false),
                    storage(2, true),
                    storage(3, true),
                    storage(4, true),
                    storage(5, false),
                    storage(6, false),
                ],
            )
        };
        let accumulate_layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("accumulate_edges"),
            entries: &accumulate_entries,
        });
        let integrate_layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("integrate_edges"),
            entries: &integrate_entries,
        });
        let (a_src, i_src, a_name, i_name) = if fixed {
            (
                ACCUMULATE_FIXED,
                INTEGRATE_FIXED,
                "accumulate_fixed",
                "integrate_fixed",
            )
        } else {
            (
                ACCUMULATE_FLOAT,
                INTEGRATE_FLOAT,
                "accumulate_float",
                "integrate_float",
            )
        };
        let mut passes = AtomicEdgePasses {
            passes: super::springs_edges::SpringThenNode {
                springs: buffers::compute_pipeline(ctx, a_name, a_src, &[&accumulate_layout])?,
                nodes: buffers::compute_pipeline(ctx, i_name, i_src, &[&integrate_layout])?,
                bind_groups: Vec::new(),
            },
            overflow: fixed.then(|| overflow.clone()),
            buffers: AtomicBuffers {
                springs,
                inv_mass,
                accumulators: acc,
                fixed_point: fx,
                overflow,
            },
            accumulate_layout,
            integrate_layout,
            fixed,
        };
        passes.rebind(ctx, uniform, state)?;
        Ok(passes)
    }

    /// Replace the fixed-point constants (after a patch raised the largest valence past what
    /// they were made for).
    pub fn set_fixed_point(&self, ctx: &GpuContext, fp: &FixedPoint) {
        ctx.queue
            .write_buffer(&self.buffers.fixed_point, 0, bytemuck::bytes_of(fp));
    }

    /// Record one step in phase `phase`: the accumulating spring pass, then the node pass.
    pub fn record(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        phase: usize,
        spring_groups: (u32, u32),
        node_groups: (u32, u32),
    ) {
        self.passes.record(pass, phase, spring_groups, node_groups);
    }

    /// Record only the node pass in phase `phase` (read, clear and integrate the
    /// accumulators): the step's second half after another model's accumulating record pass
    /// (`super::tensor_atomic`).
    pub(super) fn record_nodes(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        phase: usize,
        node_groups: (u32, u32),
    ) {
        let (_, node_bg) = &self.passes.bind_groups[phase];
        pass.set_pipeline(&self.passes.nodes);
        pass.set_bind_group(0, node_bg, &[]);
        pass.dispatch_workgroups(node_groups.0, node_groups.1, 1);
    }

    /// Whether these are the fixed-point passes (else float atomics).
    pub fn is_fixed(&self) -> bool {
        self.fixed
    }

    /// The accumulators, and for the fixed-point variant its constants and overflow flag:
    /// what another model's accumulating pass binds (`super::tensor_atomic`).
    pub(super) fn accumulation_buffers(&self) -> (&wgpu::Buffer, Option<[&wgpu::Buffer; 2]>) {
        let b = &self.buffers;
        (
            &b.accumulators,
            self.fixed.then_some([&b.fixed_point, &b.overflow]),
        )
    }

    /// Whether a spring force has saturated the fixed-point range since setup (always false
    /// for float atomics).
    pub fn overflowed(&self, ctx: &GpuContext) -> Result<bool> {
        match &self.overflow {
            None => Ok(false),
            Some(b) => Ok(buffers::read_vec4(ctx, b)?
                .iter()
                .any(|v| v.iter().any(|x| x.to_bits() != 0))),
        }
    }
}

/// Three accumulators for every node the mass buffer has room for, created zeroed (the node pass
/// leaves them zero after every step).
fn accumulators(ctx: &GpuContext, inv_mass: &wgpu::Buffer) -> Result<wgpu::Buffer> {
    let acc_bytes = inv_mass.size() / 4 * 12;
    buffers::check_binding(ctx, "accumulators", acc_bytes)?;
    Ok(ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("accumulators"),
        size: acc_bytes,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    }))
}

impl LayoutBuffers for AtomicEdgePasses {
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
        // Grown masses: accumulators for all the nodes they have room for.
        if self.buffers.accumulators.size() < self.buffers.inv_mass.size() / 4 * 12 {
            self.buffers.accumulators = accumulators(ctx, &self.buffers.inv_mass)?;
        }
        let AtomicBuffers {
            springs,
            inv_mass,
            accumulators: acc,
            fixed_point: fx,
            overflow,
        } = &self.buffers;
        let (accumulate_layout, integrate_layout) =
            (&self.accumulate_layout, &self.integrate_layout);
        self.passes.bind_groups = (0..state.phases())
            .map(|phase| {
                let b = state.bindings(phase);
                // Fixed point adds the scale and the overflow flag to accumulating, and the
                // scale (second) to integrating.
                let mut a = vec![uniform, springs, b.second_in, b.cur, acc];
                let mut i = vec![
                    uniform,
                    acc,
                    inv_mass,
                    b.second_in,
                    b.cur,
                    b.next,
                    b.second_out,
                ];
                if self.fixed {
                    a.extend([fx, overflow]);
                    i.insert(1, fx);
                }
                let accumulate = d.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("accumulate_edges"),
                    layout: accumulate_layout,
                    entries: &buffers::entries(&a),
                });
                let integrate = d.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("integrate_edges"),
                    layout: integrate_layout,
                    entries: &buffers::entries(&i),
                });
                (accumulate, integrate)
            })
            .collect();
        Ok(())
    }
}
