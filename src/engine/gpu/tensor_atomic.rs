//! Tensor-mass on the edge layout's atomic variants: pairs with
//! `shaders/tensor_accumulate_fixed.wgsl` (fixed point in `atomic<i32>`, the springs'
//! [`crate::layout::edges::FixedPoint`] constants and overflow flag) and
//! `shaders/tensor_accumulate_float.wgsl` (`atomic<f32>`, where the device has
//! `SHADER_FLOAT32_ATOMIC`). One invocation per edge record computes its two end forces (a
//! tensor's are not opposite, unlike a spring's) and adds each to its own end's accumulators;
//! the node pass that reads, clears and integrates them is the springs' own
//! (`AtomicEdgePasses::record_nodes`), bound to the same accumulators. The diagonal tensor
//! `K_aa` needs no term: the blocks act on displacement differences
//! (`crate::layout::tensor_blocks`). Twin: `twin::tensor_atomic`.

use super::atomic_edges::AtomicEdgePasses;
use super::buffers;
use super::GpuContext;
use crate::error::Result;
use crate::layout::edges::FixedPoint;

const FIXED: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/fixed_point.wgsl"),
    include_str!("../../../shaders/edge_spring.wgsl"),
    include_str!("../../../shaders/tensor_products.wgsl"),
    include_str!("../../../shaders/tensor_block.wgsl"),
    include_str!("../../../shaders/tensor_accumulate_fixed.wgsl")
);
const FLOAT: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/edge_spring.wgsl"),
    include_str!("../../../shaders/tensor_products.wgsl"),
    include_str!("../../../shaders/tensor_block.wgsl"),
    include_str!("../../../shaders/tensor_accumulate_float.wgsl")
);

/// The accumulating record pass's bind-group layout and pipeline for the variant of `atomic`.
pub(super) fn record_pass(
    ctx: &GpuContext,
    atomic: &AtomicEdgePasses,
) -> Result<(wgpu::BindGroupLayout, wgpu::ComputePipeline)> {
    let storage = buffers::storage_entry;
    // Uniform; records, second state, current (read); accumulators (written); blocks (read);
    // fixed point: its constants (uniform) and the overflow flag (written).
    let mut entries = vec![
        buffers::uniform_entry(0),
        storage(1, true),
        storage(2, true),
        storage(3, true),
        storage(4, false),
        storage(5, true),
    ];
    let fixed = atomic.is_fixed();
    if fixed {
        entries.extend([buffers::uniform_entry(6), storage(7, false)]);
    }
    let (name, source) = if fixed {
        ("tensor_accumulate_fixed", FIXED)
    } else {
        ("tensor_accumulate_float", FLOAT)
    };
    let layout = ctx
        .device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(name),
            entries: &entries,
        });
    let pipeline = buffers::compute_pipeline(ctx, name, source, &[&layout])?;
    Ok((layout, pipeline))
}

/// The record pass's buffers in binding order: the step constants, the records, the state
/// read (second, current), the accumulators of `atomic`, the blocks, and for fixed point its
/// constants and overflow flag.
pub(super) fn bindings<'a>(
    atomic: &'a AtomicEdgePasses,
    uniform: &'a wgpu::Buffer,
    records: &'a wgpu::Buffer,
    second_in: &'a wgpu::Buffer,
    cur: &'a wgpu::Buffer,
    blocks: &'a wgpu::Buffer,
) -> Vec<&'a wgpu::Buffer> {
    let (acc, fixed) = atomic.accumulation_buffers();
    let mut list = vec![uniform, records, second_in, cur, acc, blocks];
    list.extend(fixed.into_iter().flatten());
    list
}

/// Record one step in `phase`: the accumulating record pass over `records` workgroups, then
/// the atomic variant's node pass over `nodes`.
pub(super) fn record(
    pass: &mut wgpu::ComputePass<'_>,
    atomic: &AtomicEdgePasses,
    pipeline: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    phase: usize,
    records: (u32, u32),
    nodes: (u32, u32),
) {
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, group, &[]);
    pass.dispatch_workgroups(records.0, records.1, 1);
    atomic.record_nodes(pass, phase, nodes);
}

/// The fixed-point constants of a tensor-mass model on the edge layout: sized for the larger
/// of the layout's plausible force (springs, weights) and the blocks' plausible end force
/// ([`crate::layout::tensor_blocks::TensorBlocks::plausible_end_force`]), so that the
/// tensors' forces saturate no sooner than the springs' would. Other layouts keep `fallback`.
pub(super) fn fixed_point(
    layout: &crate::layout::PackedLayout,
    model: &crate::model::PackedModel,
    tensor: &super::tensor_mass::TensorMassPasses,
    fallback: FixedPoint,
) -> FixedPoint {
    match layout {
        crate::layout::PackedLayout::Edges(e) => FixedPoint::new(
            e.plausible_force(model)
                .max(tensor.blocks().plausible_end_force(e)),
            e.max_valence(),
        ),
        _ => fallback,
    }
}
