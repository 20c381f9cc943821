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
//! A cut patches the tet table (`super::corotational`) and the pair lists after it
//! ([`TetPairs::patch`]): the lists of the slots the layout's patch rewrote and of the slots
//! between two corners of a tet the table's patch removed, moved or added are rewritten, and
//! only their rows and pairs are uploaded (a cut's bytes follow the cut, not the mesh). The
//! blocks are never uploaded: the pass writes every block each step. Where the tet table or
//! the layout was rebuilt, a buffer is too small, the blocks' stride changed or holes fill
//! half the pairs, the lists are built again and uploaded whole. Twin:
//! [`crate::twin::corotational_implicit`].

use std::ops::Range;

use rustc_hash::FxHashSet;

use super::buffers::{self, Sizing};
use super::corotational::CorotationalPasses;
use super::{dispatch_size, GpuContext, WORKGROUP};
use crate::error::Result;
use crate::layout::patch::Dirty;
use crate::layout::tensor_blocks::TensorBlocks;
use crate::layout::tet_pairs::{PairsPatch, TetPairs};
use crate::layout::tet_table::{TablePatch, TetTable};
use crate::layout::PackedLayout;

const BLOCKS: &str = include_str!("../../../shaders/corotational_blocks.wgsl");

/// How a patch brought the pair lists up to date ([`CorotationalBlocks::last_patch`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PairsUpload {
    /// Only the rows and pairs of the slots the cut reached were written.
    Patched,
    /// Uploaded whole: the layout was repacked or its passes rebuilt.
    LayoutRebuilt,
    /// Uploaded whole: the tet table was rebuilt (its tets may all have moved).
    TableRebuilt,
    /// Uploaded whole: the first damped tet (or the last) changed the blocks' stride.
    StrideChanged,
    /// Uploaded whole: a buffer had to grow (to the next size class).
    Outgrown,
    /// Uploaded whole: the holes rewritten lists left filled half the pairs, or the lists
    /// outgrew a buffer with their holes and fit it without.
    Compacted,
}

/// The block pass's constants; mirrors `BlockParams` in `corotational_blocks.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
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
    /// The constants as last written.
    constants: BlockUniform,
    /// Bytes the last patch uploaded, and how.
    last_patch: (u64, PairsUpload),
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
        let (pair_rows, pair_list, blocks, stride, groups, constants) =
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
            constants,
            last_patch: (0, PairsUpload::Patched),
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

    /// Follow a patch (`corot` and `layout` already patched; `dirty` the layout's changed
    /// ranges, `whole` where it repacked; `removed` the diff's removed tets, model indices):
    /// the lists patched where the cut reached them and those written, or built again and
    /// uploaded whole (see the module documentation); the bind group rebuilt over `corot`'s
    /// buffers of now. Returns the bytes uploaded.
    pub(super) fn patch(
        &mut self,
        ctx: &GpuContext,
        corot: &CorotationalPasses,
        layout: &PackedLayout,
        dirty: &[Dirty],
        whole: bool,
        removed: &[[u32; 4]],
    ) -> Result<u64> {
        let stride = if corot.damped() { 6 } else { 3 };
        let how = match corot.last_table_patch() {
            _ if whole => PairsUpload::LayoutRebuilt,
            None => PairsUpload::TableRebuilt,
            Some(_) if stride != self.stride => PairsUpload::StrideChanged,
            Some(t) => {
                let changed = changed_records(layout, dirty);
                let p = self.patch_lists(corot.table(), t, layout, &changed, removed);
                if self.outgrown() {
                    PairsUpload::Outgrown
                } else if self.pairs.holes() > self.pairs.pairs.len() / 2 {
                    PairsUpload::Compacted
                } else {
                    let bytes = self.write_lists(ctx, &p);
                    self.last_patch = (bytes, PairsUpload::Patched);
                    PairsUpload::Patched
                }
            }
        };
        if how != PairsUpload::Patched {
            self.last_patch = {
                self.pairs = TetPairs::new(corot.table(), layout);
                let held = (&self.pair_rows, &self.pair_list, &self.blocks);
                let (rows, list, blocks, stride, groups, constants) =
                    upload(ctx, &self.uniform, &self.pairs, corot.damped(), Some(held))?;
                (self.stride, self.groups, self.constants) = (stride, groups, constants);
                // Lists that outgrew a buffer with their holes may fit it compacted.
                let sizes = |b: &Self| [b.pair_rows.size(), b.pair_list.size(), b.blocks.size()];
                let before = sizes(self);
                (self.pair_rows, self.pair_list, self.blocks) = (rows, list, blocks);
                let how = match how {
                    PairsUpload::Outgrown if sizes(self) == before => PairsUpload::Compacted,
                    how => how,
                };
                (self.pairs.bytes() + 16, how)
            };
        }
        self.bind_group = bind(
            ctx,
            &self.layout,
            corot,
            &self.uniform,
            [&self.pair_rows, &self.pair_list, &self.blocks],
        );
        Ok(self.last_patch.0)
    }

    /// The bytes the last patch uploaded, and how (see `CorotationalBlocks::patch`).
    pub fn last_patch(&self) -> (u64, PairsUpload) {
        self.last_patch
    }

    /// The host lists patched after the tet table's patch `t` of `table` and the layout's
    /// rewritten records `changed`: the slots between two corners of the tets `removed`
    /// (model indices) and of those `t` wrote (moved or added).
    fn patch_lists(
        &mut self,
        table: &TetTable,
        t: &TablePatch,
        layout: &PackedLayout,
        changed: &[Range<usize>],
        removed: &[[u32; 4]],
    ) -> PairsPatch {
        let rank = &layout.order().rank;
        let mut coupled = FxHashSet::default();
        let mut couple = |c: [u32; 4]| {
            for a in c {
                for b in c {
                    if a != b {
                        coupled.insert((a, b));
                    }
                }
            }
        };
        for r in removed {
            couple(r.map(|n| rank[n as usize]));
        }
        for &i in &t.tets {
            couple(table.corners[i as usize]);
        }
        self.pairs.patch(table, layout, changed, &coupled)
    }

    /// Whether the patched lists outgrew a buffer held.
    fn outgrown(&self) -> bool {
        let (rows, pairs) = (self.pairs.rows.len() as u64, self.pairs.pairs.len() as u64);
        self.pair_rows.size() < 8 * rows
            || self.pair_list.size() < 4 * pairs
            || self.blocks.size() < 16 * self.stride as u64 * rows
    }

    /// Write what `p` changed in the lists to the device (runs of rows and pairs joined across
    /// gaps of a few entries), and the constants where the records changed. The bytes written.
    fn write_lists(&mut self, ctx: &GpuContext, p: &PairsPatch) -> u64 {
        let q = &ctx.queue;
        let mut bytes = 0u64;
        let slots = p.slots.iter().map(|&s| s..s + 1);
        for r in joined(slots, 8) {
            let r = r.start as usize..r.end as usize;
            let data: &[u8] = bytemuck::cast_slice(&self.pairs.rows[r.clone()]);
            q.write_buffer(&self.pair_rows, 8 * r.start as u64, data);
            bytes += data.len() as u64;
        }
        for r in joined(p.pairs.iter().cloned(), 16) {
            let r = r.start as usize..r.end as usize;
            let data: &[u8] = bytemuck::cast_slice(&self.pairs.pairs[r.clone()]);
            q.write_buffer(&self.pair_list, 4 * r.start as u64, data);
            bytes += data.len() as u64;
        }
        let n = self.pairs.rows.len() as u32;
        let groups = dispatch_size(ctx, n);
        let constants = BlockUniform {
            records: n,
            row: groups.0 * WORKGROUP,
            stride: self.stride,
            pad: 0,
        };
        if constants != self.constants {
            q.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&constants));
            bytes += 16;
            (self.groups, self.constants) = (groups, constants);
        }
        bytes
    }

    /// How the lists differ from a rebuild's beside `corot`'s table and `layout`, and the
    /// device's lists from the host's: empty when a patched engine holds what a rebuilt one
    /// would.
    pub fn differences(
        &self,
        ctx: &GpuContext,
        corot: &CorotationalPasses,
        layout: &PackedLayout,
    ) -> Result<Vec<String>> {
        let mut out = Vec::new();
        let want = TetPairs::new(corot.table(), layout);
        if self.pairs.differs_from(&want) {
            out.push(format!(
                "the corotational pair lists ({} slots, {} pairs) differ from a rebuild's \
                 ({} slots, {} pairs)",
                self.pairs.rows.len(),
                self.pairs.pairs.len(),
                want.rows.len(),
                want.pairs.len()
            ));
        }
        let same = |b: &wgpu::Buffer, host: &[u8]| -> Result<bool> {
            Ok(host.is_empty() || buffers::read_bytes(ctx, b, host.len() as u64)? == host)
        };
        if !same(&self.pair_rows, bytemuck::cast_slice(&self.pairs.rows))?
            || !same(&self.pair_list, bytemuck::cast_slice(&self.pairs.pairs))?
        {
            out.push("the device's corotational pair lists differ from the host's".into());
        }
        let stride = if corot.damped() { 6 } else { 3 };
        if self.constants.records as usize != self.pairs.rows.len() || self.stride != stride {
            out.push(format!(
                "the corotational block pass runs over {} records of stride {}, the layout has \
                 {} (stride {stride})",
                self.constants.records,
                self.stride,
                self.pairs.rows.len()
            ));
        }
        Ok(out)
    }

    /// Bytes of one record's blocks (`K`, and `C` when damped).
    pub fn slot_bytes(&self) -> u64 {
        16 * self.stride as u64
    }

    /// Bytes the block pass moves a step: per record its range read and its blocks written,
    /// per pair the pair, its tet's shape and rotation read.
    pub fn bytes_per_step(&self) -> u64 {
        let records = self.pairs.rows.len() as u64;
        let pairs = (self.pairs.pairs.len() - self.pairs.holes()) as u64;
        records * (8 + 16 * self.stride as u64) + pairs * (4 + 48 + 16)
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

type Uploaded = (
    wgpu::Buffer,
    wgpu::Buffer,
    wgpu::Buffer,
    u32,
    (u32, u32),
    BlockUniform,
);

/// The records (slots, or edge records) of `dirty`'s ranges of the array the blocks run beside.
fn changed_records(layout: &PackedLayout, dirty: &[Dirty]) -> Vec<Range<usize>> {
    const RECORD: u64 = 32;
    let beside = TensorBlocks::beside(layout);
    dirty
        .iter()
        .filter(|d| d.array == beside)
        .map(|d| (d.bytes.start / RECORD) as usize..d.bytes.end.div_ceil(RECORD) as usize)
        .collect()
}

/// `ranges` (ascending by start) joined where fewer than `gap` entries lie between them.
fn joined(ranges: impl Iterator<Item = Range<u32>>, gap: u32) -> Vec<Range<u32>> {
    let mut out: Vec<Range<u32>> = Vec::new();
    for r in ranges {
        match out.last_mut() {
            Some(last) if r.start <= last.end + gap => last.end = last.end.max(r.end),
            _ => out.push(r),
        }
    }
    out
}

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
    // A buffer a patch outgrew gets the next size class: room for the next cuts.
    let sizing = match held {
        Some(_) => Sizing::SizeClass,
        None => Sizing::Headroom,
    };
    let put = |label: &str, data: &[u8], old: Option<&wgpu::Buffer>| -> Result<wgpu::Buffer> {
        match old {
            Some(b) if b.size() >= data.len() as u64 => {
                if !data.is_empty() {
                    ctx.queue.write_buffer(b, 0, data);
                }
                Ok(b.clone())
            }
            _ => buffers::storage_buffer(ctx, label, data, sizing),
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
            buffers::zeroed_storage(ctx, "corotational blocks", want, sizing)?
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
    Ok((rows, list, blocks, stride, groups, constants))
}
