//! Corotational finite elements under backward Euler on the GPU, in every layout: the
//! tensor-mass solve (`super::implicit`, `shaders/implicit_tensor.wgsl`) run on blocks that
//! turn with the tets. A step records
//!
//! 1. the corotational tet pass (`shaders/corotational_tets.wgsl`): each tet's rotation at the
//!    step's start, warm-started, and its corner forces `-R K_e (R^T x - X) - beta R K_e R^T v`;
//! 2. the block pass (`shaders/corotational_blocks.wgsl`, here): per slot (or edge record)
//!    `K'_ij = sum_t R_t K_t,ab R_t^T` over the tets holding both nodes, through a per-slot list
//!    of `(tet, corner, corner)` pairs in a fixed order ([`TetPairs`]), and `C'_ij` with each
//!    tet's Rayleigh `beta` where any tet is damped, into a blocks buffer laid out as the
//!    tensor-mass blocks ([`crate::layout::tensor_blocks`]);
//! 3. the tensor-mass solve, unchanged but for its force: its setup sums each node's corner
//!    records (`shaders/implicit_corotational.wgsl`) where the linear model takes the blocks'
//!    own product, so the right-hand side holds the rotated rest state's term.
//!
//! The rotations are frozen over the solve and `R K R^T` is the Jacobian, as on the float64
//! reference engine ([`crate::physics::Corotational`]). Why the blocks rather than a
//! matrix-free product per tet inside the conjugate gradients: the product then reads one
//! block per slot as the tensor-mass solve does, with the solve, its twin and its
//! preconditioner (whose diagonal blocks are `-sum_j K'_ij`: a rotated element's block rows
//! still sum to zero) unchanged; a per-tet product would add a tet pass and a gather to every
//! iteration. The blocks cost one pass per step.
//!
//! A cut patches the tet table (`super::corotational`); the pair lists follow slots, which a
//! layout's patch moves, so they are built again from the patched table and layout and
//! uploaded whole (a cut's bytes here follow the mesh, not the cut). Twin:
//! [`crate::twin::corotational_implicit`].

use super::buffers::{self, Sizing};
use super::corotational::CorotationalPasses;
use super::{dispatch_size, GpuContext, WORKGROUP};
use crate::error::Result;
use crate::layout::tensor_blocks::TensorBlocks;
use crate::layout::tet_pairs::TetPairs;
use crate::layout::PackedLayout;

const BLOCKS: &str = include_str!("../../../shaders/corotational_blocks.wgsl");

/// The block pass's constants; mirrors `BlockParams` in `corotational_blocks.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct BlockUniform {
    records: u32,
    row: u32,
    stride: u32,
    pad: u32,
}

/// The block pass of a corotational implicit engine: the pair lists, the blocks it writes
/// each step, its pipeline and bind group.
pub struct CorotationalBlocks {
    pairs: TetPairs,
    /// Rows per slot: 3, or 6 where any tet is damped.
    stride: u32,
    uniform: wgpu::Buffer,
    pair_rows: wgpu::Buffer,
    pair_list: wgpu::Buffer,
    blocks: wgpu::Buffer,
    groups: (u32, u32),
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
}

impl CorotationalBlocks {
    /// The block pass of `corot` beside `layout`.
    pub(super) fn new(
        ctx: &GpuContext,
        corot: &CorotationalPasses,
        layout: &PackedLayout,
    ) -> Result<Self> {
        // Pair rows, pairs, shapes, rotations (read); the blocks (written).
        let ro = [true, true, true, true, false];
        let entries: Vec<_> = std::iter::once(buffers::uniform_entry(0))
            .chain(
                ro.iter()
                    .enumerate()
                    .map(|(k, &r)| buffers::storage_entry(k as u32 + 1, r)),
            )
            .collect();
        let bind_layout = ctx
            .device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("corotational_blocks"),
                entries: &entries,
            });
        let pipeline =
            buffers::compute_pipeline(ctx, "corotational_blocks", BLOCKS, &[&bind_layout])?;
        let uniform = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("corotational block constants"),
            size: std::mem::size_of::<BlockUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let pairs = TetPairs::new(corot.table(), layout);
        let (pair_rows, pair_list, blocks, stride, groups) =
            upload(ctx, &uniform, &pairs, corot.damped(), None)?;
        let bind_group = bind(
            ctx,
            &bind_layout,
            corot,
            &uniform,
            [&pair_rows, &pair_list, &blocks],
        );
        Ok(CorotationalBlocks {
            pairs,
            stride,
            uniform,
            pair_rows,
            pair_list,
            blocks,
            groups,
            pipeline,
            layout: bind_layout,
            bind_group,
        })
    }

    /// The blocks buffer the solve reads (group 1, binding 0).
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.blocks
    }

    /// The pair lists as uploaded (for the twin).
    pub fn pairs(&self) -> &TetPairs {
        &self.pairs
    }

    /// The blocks the last step wrote, read back (layout order, [`TensorBlocks`]).
    pub fn read_blocks(&self, ctx: &GpuContext) -> Result<TensorBlocks> {
        let n = self.pairs.rows.len() as u64 * self.stride as u64 * 16;
        let bytes = buffers::read_bytes(ctx, &self.blocks, n)?;
        Ok(TensorBlocks {
            damped: self.stride == 6,
            rows: bytemuck::pod_collect_to_vec(&bytes),
        })
    }

    /// Record the block pass (after the tet pass has written this step's rotations).
    pub(super) fn record(&self, pass: &mut wgpu::ComputePass<'_>) {
        if self.pairs.rows.is_empty() {
            return;
        }
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.dispatch_workgroups(self.groups.0, self.groups.1, 1);
    }

    /// Follow a patch: the pair lists built again from `corot`'s patched table and the
    /// patched `layout`, uploaded whole (into the buffers held where they fit), and the bind
    /// group rebuilt over `corot`'s buffers of now. Returns the bytes uploaded.
    pub(super) fn patch(
        &mut self,
        ctx: &GpuContext,
        corot: &CorotationalPasses,
        layout: &PackedLayout,
    ) -> Result<u64> {
        self.pairs = TetPairs::new(corot.table(), layout);
        let held = (&self.pair_rows, &self.pair_list, &self.blocks);
        let (rows, list, blocks, stride, groups) =
            upload(ctx, &self.uniform, &self.pairs, corot.damped(), Some(held))?;
        (self.pair_rows, self.pair_list, self.blocks) = (rows, list, blocks);
        (self.stride, self.groups) = (stride, groups);
        self.bind_group = bind(
            ctx,
            &self.layout,
            corot,
            &self.uniform,
            [&self.pair_rows, &self.pair_list, &self.blocks],
        );
        Ok(self.pairs.bytes() + 16)
    }

    /// Device buffers beside the layout's, by name, with their sizes.
    pub fn buffers(&self) -> Vec<(String, u64)> {
        [
            ("corotational pair rows", &self.pair_rows),
            ("corotational pairs", &self.pair_list),
            ("corotational blocks", &self.blocks),
        ]
        .into_iter()
        .map(|(n, b)| (n.to_string(), b.size()))
        .collect()
    }
}

/// The block pass's bind group over `corot`'s shapes and rotations and the pass's own buffers.
fn bind(
    ctx: &GpuContext,
    layout: &wgpu::BindGroupLayout,
    corot: &CorotationalPasses,
    uniform: &wgpu::Buffer,
    [rows, list, blocks]: [&wgpu::Buffer; 3],
) -> wgpu::BindGroup {
    let t = corot.device_table();
    ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("corotational blocks"),
        layout,
        entries: &buffers::entries(&[uniform, rows, list, t.shape, t.rotations, blocks]),
    })
}

type Uploaded = (wgpu::Buffer, wgpu::Buffer, wgpu::Buffer, u32, (u32, u32));

/// The pair lists of `pairs` written to the device (into `held`'s buffers where they fit,
/// else new ones with room), a blocks buffer for them (`held`'s where it fits: the pass
/// writes every block each step, so its contents are never uploaded), the constants written;
/// with the stride and the dispatch size.
fn upload(
    ctx: &GpuContext,
    uniform: &wgpu::Buffer,
    pairs: &TetPairs,
    damped: bool,
    held: Option<(&wgpu::Buffer, &wgpu::Buffer, &wgpu::Buffer)>,
) -> Result<Uploaded> {
    let stride = if damped { 6u32 } else { 3 };
    let n = pairs.rows.len() as u64;
    let put = |label: &str, data: &[u8], old: Option<&wgpu::Buffer>| -> Result<wgpu::Buffer> {
        match old {
            Some(b) if b.size() >= data.len() as u64 => {
                if !data.is_empty() {
                    ctx.queue.write_buffer(b, 0, data);
                }
                Ok(b.clone())
            }
            _ => buffers::storage_buffer(ctx, label, data, Sizing::Headroom),
        }
    };
    let rows = put(
        "corotational pair rows",
        bytemuck::cast_slice(&pairs.rows),
        held.map(|h| h.0),
    )?;
    let list = put(
        "corotational pairs",
        bytemuck::cast_slice(&pairs.pairs),
        held.map(|h| h.1),
    )?;
    let want = (n * stride as u64 * 16).max(16);
    let blocks = match held.map(|h| h.2) {
        Some(b) if b.size() >= want => b.clone(),
        _ => {
            buffers::check_binding(ctx, "corotational blocks", want)?;
            buffers::zeroed_storage(ctx, "corotational blocks", want, Sizing::Headroom)?
        }
    };
    let groups = dispatch_size(ctx, n as u32);
    let constants = BlockUniform {
        records: n as u32,
        row: groups.0 * WORKGROUP,
        stride,
        pad: 0,
    };
    ctx.queue
        .write_buffer(uniform, 0, bytemuck::bytes_of(&constants));
    Ok((rows, list, blocks, stride, groups))
}
