//! The self-contact broad phase on the device: six dispatches in one submission (count, three
//! prefix-sum steps, scatter, pair tests) over the surface, reading back the overflow flag, the
//! pair count and the pairs. Built only when a program asks for self-contact. The twin is
//! `twin::broad_self::self_pairs_cpu`.
//!
//! The surface triangles and rest positions are the tool culler's ([`ToolCuller`]): one copy
//! on the device, which a cut's surface edit writes once for both broad phases. The culler
//! follows an edit by growing its hash table and entries when the surface grows and binding
//! afresh ([`SelfCuller::regrid`]); its pipelines are built once.

use super::broad_tool::ToolCuller;
use super::buffers::{self, Sizing};
use super::{dispatch_size, GpuContext, StateBuffers, WORKGROUP};
use crate::collide::self_broad::GridParams;
use crate::error::{Error, Result};

const GRID: &str = include_str!("../../../shaders/self_grid.wgsl");

fn source(pass: &str) -> String {
    let body = match pass {
        "self_count" => include_str!("../../../shaders/self_count.wgsl"),
        "scan_blocks" => include_str!("../../../shaders/scan_blocks.wgsl"),
        "scan_top" => include_str!("../../../shaders/scan_top.wgsl"),
        "scan_apply" => include_str!("../../../shaders/scan_apply.wgsl"),
        "self_scatter" => include_str!("../../../shaders/self_scatter.wgsl"),
        _ => include_str!("../../../shaders/self_pairs.wgsl"),
    };
    format!("{GRID}{body}")
}

/// What one self-contact cull found.
#[derive(Debug, Clone, PartialEq)]
pub struct SelfCullResult {
    /// Pairs of surface triangles (t < u), sorted.
    pub pairs: Vec<[u32; 2]>,
    /// The grid used (its cell may have grown for a stretched surface).
    pub grid: GridParams,
    /// Runs repeated to grow the cell or the pair buffer.
    pub reruns: u32,
}

/// A pipeline with its layout.
struct Pass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl Pass {
    fn new(ctx: &GpuContext, name: &str, read_only: &[bool]) -> Result<Self> {
        let layout = buffers::pass_layout(ctx, name, read_only);
        let pipeline = buffers::compute_pipeline(ctx, name, &source(name), &[&layout])?;
        Ok(Pass { pipeline, layout })
    }
}

/// One value per pass of the self broad phase, by name; [`Stages::in_order`] gives them in
/// dispatch order.
struct Stages<T> {
    /// Count the triangles per grid cell.
    count: T,
    /// Prefix sums within blocks of cells.
    scan_blocks: T,
    /// Prefix sum of the block totals.
    scan_top: T,
    /// Add the block offsets to the cells.
    scan_apply: T,
    /// Write each triangle into its cells' buckets.
    scatter: T,
    /// Test the pairs sharing a bucket.
    pairs: T,
}

impl<T> Stages<T> {
    /// The six values in dispatch order.
    fn in_order(&self) -> [&T; 6] {
        [
            &self.count,
            &self.scan_blocks,
            &self.scan_top,
            &self.scan_apply,
            &self.scatter,
            &self.pairs,
        ]
    }
}

/// The passes and their buffers.
pub struct SelfCuller {
    passes: Stages<Pass>,
    params: wgpu::Buffer,
    counts: wgpu::Buffer,
    block_sums: wgpu::Buffer,
    offsets: wgpu::Buffer,
    cursors: wgpu::Buffer,
    entries: wgpu::Buffer,
    pairs: wgpu::Buffer,
    count: wgpu::Buffer,
    overflow: wgpu::Buffer,
    grid: GridParams,
    /// Per rotation phase: the bind groups of the six passes.
    bind_groups: Vec<Stages<wgpu::BindGroup>>,
}

impl SelfCuller {
    /// Build the passes for `grid` over the surface the tool culler `tool` holds (layout
    /// order).
    pub fn new(
        ctx: &GpuContext,
        grid: GridParams,
        tool: &ToolCuller,
        state: &StateBuffers,
    ) -> Result<Self> {
        let d = &ctx.device;
        let storage =
            |label: &str, bytes: u64| buffers::zeroed_storage(ctx, label, bytes, Sizing::Exact);
        let table = grid.table as u64;
        let passes = Stages {
            count: Pass::new(ctx, "self_count", &[true, true, true, false, false])?,
            scan_blocks: Pass::new(ctx, "scan_blocks", &[true, false])?,
            scan_top: Pass::new(ctx, "scan_top", &[false])?,
            scan_apply: Pass::new(ctx, "scan_apply", &[true, true, false, false])?,
            scatter: Pass::new(ctx, "self_scatter", &[true, true, true, false, false])?,
            pairs: Pass::new(
                ctx,
                "self_pairs",
                &[true, true, true, true, true, true, false, false],
            )?,
        };
        let mut culler = SelfCuller {
            passes,
            params: d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("grid params"),
                size: 32,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            counts: storage("bucket counts", table * 4)?,
            block_sums: storage("block sums", table / 256 * 4)?,
            offsets: storage("bucket offsets", table * 4)?,
            cursors: storage("bucket cursors", table * 4)?,
            // Each triangle lands in at most MAX_SPAN^3 = 8 cells.
            entries: storage("bucket entries", grid.triangles.max(1) as u64 * 8 * 4)?,
            pairs: storage("self pairs", 8 * 1024)?,
            count: storage("self pair count", 4)?,
            overflow: storage("grid overflow", 4)?,
            grid,
            bind_groups: Vec::new(),
        };
        culler.rebind(ctx, tool, state);
        Ok(culler)
    }

    /// Go on with `grid` (a surface edited to `grid.triangles` triangles, or a new margin)
    /// over the tool culler's surface, keeping the pipelines: the hash table and the entries
    /// grow where the grid needs more (scratch the passes fill, nothing uploaded), and the
    /// passes are bound afresh (the tool culler's buffers may have moved with the edit).
    pub fn regrid(
        &mut self,
        ctx: &GpuContext,
        grid: GridParams,
        tool: &ToolCuller,
        state: &StateBuffers,
    ) -> Result<()> {
        let storage =
            |label: &str, bytes: u64| buffers::zeroed_storage(ctx, label, bytes, Sizing::SizeClass);
        let table = grid.table as u64;
        if self.counts.size() < table * 4 {
            self.counts = storage("bucket counts", table * 4)?;
            self.block_sums = storage("block sums", table / 256 * 4)?;
            self.offsets = storage("bucket offsets", table * 4)?;
            self.cursors = storage("bucket cursors", table * 4)?;
        }
        let entries = grid.triangles.max(1) as u64 * 8 * 4;
        if self.entries.size() < entries {
            self.entries = storage("bucket entries", entries)?;
        }
        self.grid = grid;
        self.rebind(ctx, tool, state);
        Ok(())
    }

    /// The grid the culler uses (its cell grown where a stretched surface needed it).
    pub fn grid(&self) -> GridParams {
        self.grid
    }

    /// Rebuild the bind groups (after the node state, the tool culler's surface or the pair
    /// buffer was reallocated).
    pub fn rebind(&mut self, ctx: &GpuContext, tool: &ToolCuller, state: &StateBuffers) {
        let (triangles, rest) = (tool.triangles(), tool.rest());
        let group = |pass: &Pass, buffers: &[&wgpu::Buffer]| {
            ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("self broad phase"),
                layout: &pass.layout,
                entries: &buffers::entries(buffers),
            })
        };
        let p = &self.passes;
        self.bind_groups = (0..state.phases())
            .map(|phase| {
                let disp = state.bindings(phase).cur;
                Stages {
                    count: group(
                        &p.count,
                        &[
                            &self.params,
                            triangles,
                            rest,
                            disp,
                            &self.counts,
                            &self.overflow,
                        ],
                    ),
                    scan_blocks: group(
                        &p.scan_blocks,
                        &[&self.params, &self.counts, &self.block_sums],
                    ),
                    scan_top: group(&p.scan_top, &[&self.params, &self.block_sums]),
                    scan_apply: group(
                        &p.scan_apply,
                        &[
                            &self.params,
                            &self.counts,
                            &self.block_sums,
                            &self.offsets,
                            &self.cursors,
                        ],
                    ),
                    scatter: group(
                        &p.scatter,
                        &[
                            &self.params,
                            triangles,
                            rest,
                            disp,
                            &self.cursors,
                            &self.entries,
                        ],
                    ),
                    pairs: group(
                        &p.pairs,
                        &[
                            &self.params,
                            triangles,
                            rest,
                            disp,
                            &self.counts,
                            &self.offsets,
                            &self.entries,
                            &self.pairs,
                            &self.count,
                        ],
                    ),
                }
            })
            .collect();
    }

    /// Find the self-contact pairs at the state of `phase`. A surface stretched so far that a
    /// box spans more than two cells doubles the cell and runs again; a full pair buffer grows
    /// by size class and runs again.
    pub fn cull(
        &mut self,
        ctx: &GpuContext,
        tool: &ToolCuller,
        state: &StateBuffers,
        phase: usize,
    ) -> Result<SelfCullResult> {
        let tri_groups = dispatch_size(ctx, self.grid.triangles.max(1));
        let row = tri_groups.0 * WORKGROUP;
        let block_groups = self.grid.blocks.div_ceil(WORKGROUP).max(1);
        let mut reruns = 0;
        loop {
            let grid = GridParams {
                capacity: (self.pairs.size() / 8) as u32,
                row,
                ..self.grid
            };
            ctx.queue
                .write_buffer(&self.params, 0, bytemuck::bytes_of(&grid));
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("self broad phase"),
                });
            enc.clear_buffer(&self.counts, 0, None);
            enc.clear_buffer(&self.count, 0, None);
            enc.clear_buffer(&self.overflow, 0, None);
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("self broad phase"),
                    timestamp_writes: None,
                });
                let groups = &self.bind_groups[phase];
                let sizes = Stages {
                    count: tri_groups,
                    scan_blocks: (block_groups, 1),
                    scan_top: (1, 1),
                    scan_apply: (block_groups, 1),
                    scatter: tri_groups,
                    pairs: tri_groups,
                };
                let stages = self.passes.in_order().into_iter();
                for ((p, group), size) in stages.zip(groups.in_order()).zip(sizes.in_order()) {
                    pass.set_pipeline(&p.pipeline);
                    pass.set_bind_group(0, group, &[]);
                    pass.dispatch_workgroups(size.0, size.1, 1);
                }
            }
            ctx.queue.submit([enc.finish()]);
            let word = |b: &wgpu::Buffer| -> Result<u32> {
                let v = buffers::read_bytes(ctx, b, 4)?;
                Ok(u32::from_le_bytes(v.try_into().map_err(|_| {
                    Error::Gpu("a four-byte readback came back another size".into())
                })?))
            };
            if word(&self.overflow)? != 0 {
                // The surface stretched past the grid: coarser cells, then again.
                self.grid.inv_cell *= 0.5;
                reruns += 1;
                if reruns > 40 {
                    return Err(Error::Diverged {
                        step: 0,
                        node: 0,
                        reason: "the tissue surface stretched beyond any grid cell (non-finite \
                                 or enormous positions)"
                            .into(),
                        found: None,
                    });
                }
                continue;
            }
            let n = word(&self.count)?;
            if n > grid.capacity {
                self.pairs = buffers::storage_buffer(
                    ctx,
                    "self pairs",
                    &vec![0u8; n as usize * 8],
                    Sizing::SizeClass,
                )?;
                self.rebind(ctx, tool, state);
                reruns += 1;
                continue;
            }
            let raw = buffers::read_bytes(ctx, &self.pairs, n.max(1) as u64 * 8)?;
            let mut pairs: Vec<[u32; 2]> = bytemuck::pod_collect_to_vec(&raw);
            pairs.truncate(n as usize);
            pairs.sort_unstable();
            return Ok(SelfCullResult {
                pairs,
                grid: GridParams {
                    capacity: 0,
                    row: 0,
                    ..self.grid
                },
                reruns,
            });
        }
    }
}
