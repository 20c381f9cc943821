//! The tensor-mass passes: linear elasticity ([`TensorMass`]) stepped in the springs' layouts,
//! a 3x3 block per slot in a buffer beside the slot table (or the edge records), at the slot's
//! own index ([`TensorBlocks`]). The layout's own buffers (slots, masses, buckets, records,
//! incidence) are bound as they are: the tensor passes replace only the force the springs'
//! passes compute.
//!
//! - connectivity and valence: `shaders/tensor_gather.wgsl` with `tensor_connectivity.wgsl` or
//!   `tensor_valence.wgsl`, one invocation per node;
//! - edges (gather): `shaders/tensor_edges.wgsl`, both end forces of each record (a tensor's
//!   are not opposite, so two per record), then `tensor_gather_edges.wgsl`, each node summing
//!   its ends' forces in incidence order;
//! - edges (atomics): `shaders/tensor_accumulate_fixed.wgsl` or `tensor_accumulate_float.wgsl`,
//!   both end forces of each record added to their own ends' accumulators, then the springs'
//!   node pass ([`super::tensor_atomic`]).
//!
//! The twins are in `twin::tensor_mass`. A cut patches the float64 model by per-tet shares and
//! rewrites only the blocks of the slots the layout's patch moved or whose nodes the diff
//! touched ([`TensorMassPasses::patch`]).

use std::ops::Range;

use super::buffers;
use super::{GpuContext, Passes, StateBuffers};
use crate::error::{Error, Result};
use crate::layout::patch::{Dirty, LayoutArray};
use crate::layout::tensor_blocks::{slot_walk, TensorBlocks};
use crate::layout::PackedLayout;
use crate::model::{ModelDiff, PackedModel};
use crate::physics::{ElementForces, ForceModelKind, TensorMass};

const CONNECTIVITY: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/node_gather.wgsl"),
    include_str!("../../../shaders/tensor_gather.wgsl"),
    include_str!("../../../shaders/tensor_products.wgsl"),
    include_str!("../../../shaders/tensor_connectivity.wgsl")
);
const VALENCE: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/node_gather.wgsl"),
    include_str!("../../../shaders/valence_buckets.wgsl"),
    include_str!("../../../shaders/tensor_gather.wgsl"),
    include_str!("../../../shaders/tensor_products.wgsl"),
    include_str!("../../../shaders/tensor_valence.wgsl")
);
const EDGES: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/edge_spring.wgsl"),
    include_str!("../../../shaders/tensor_products.wgsl"),
    include_str!("../../../shaders/tensor_block.wgsl"),
    include_str!("../../../shaders/tensor_edges.wgsl")
);
const GATHER: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/tensor_gather_edges.wgsl")
);

/// Bytes of one layout record the blocks run beside (a slot or an edge record: 32 both).
const RECORD: u64 = 32;

/// The tensor-mass model of a GPU engine with its passes.
pub struct TensorMassPasses {
    /// The float64 model, patched by every cut: the source of the blocks.
    model: TensorMass,
    /// The blocks as uploaded.
    blocks: TensorBlocks,
    buffer: wgpu::Buffer,
    /// Edge layout: two forces per record (scratch).
    forces: Option<wgpu::Buffer>,
    /// The node pass (node-centric) or the record pass then the node pass (edges).
    pipelines: Vec<wgpu::ComputePipeline>,
    layouts: Vec<wgpu::BindGroupLayout>,
    /// Per phase, one group 0 per pipeline.
    bind_groups: Vec<Vec<wgpu::BindGroup>>,
}

/// Whether any tet of `tm` has Rayleigh damping.
fn damped(tm: &TensorMass) -> bool {
    tm.elements().any(|e| e.beta != 0.0)
}

/// Room for the blocks of every record the layout's buffer `beside` can hold.
fn blocks_buffer(ctx: &GpuContext, beside: u64, blocks: &TensorBlocks) -> Result<wgpu::Buffer> {
    let bytes = (beside / RECORD * blocks.slot_bytes())
        .max(blocks.bytes())
        .max(16);
    buffers::check_binding(ctx, "tensor-mass blocks", bytes)?;
    let b = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("tensor-mass blocks"),
        size: bytes,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    if !blocks.rows.is_empty() {
        ctx.queue
            .write_buffer(&b, 0, bytemuck::cast_slice(&blocks.rows));
    }
    Ok(b)
}

impl TensorMassPasses {
    /// The tensor-mass model of `model` beside `layout` (already uploaded by `passes`), with
    /// its pipelines (the edge layout's gather only). Under backward Euler only the blocks are
    /// used: the implicit solve reads them (`super::implicit`).
    pub(super) fn new(
        ctx: &GpuContext,
        model: &PackedModel,
        layout: &PackedLayout,
        passes: &Passes,
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
    ) -> Result<Self> {
        let tm = match ElementForces::new(ForceModelKind::TensorMass, model)? {
            Some(ElementForces::TensorMass(tm)) => tm,
            _ => unreachable!("a tensor-mass kind builds a tensor-mass model"),
        };
        let blocks = TensorBlocks::new(layout, &tm, damped(&tm));
        let read = |n: usize| vec![true; n];
        let (layouts, pipelines) = match passes {
            Passes::Connectivity(_) => {
                let mut ro = read(7);
                (ro[4], ro[5]) = (false, false);
                let l = buffers::pass_layout(ctx, "tensor_connectivity", &ro);
                let p = buffers::compute_pipeline(ctx, "tensor_connectivity", CONNECTIVITY, &[&l])?;
                (vec![l], vec![p])
            }
            Passes::Valence(v) => {
                let mut ro = read(7);
                (ro[4], ro[5]) = (false, false);
                let l = buffers::pass_layout(ctx, "tensor_valence", &ro);
                let p = buffers::compute_pipeline(
                    ctx,
                    "tensor_valence",
                    VALENCE,
                    &[&l, v.bucket_layout()],
                )?;
                (vec![l], vec![p])
            }
            Passes::Edges(_) => {
                // springs, second state, current (read); forces (written); blocks (read).
                let records =
                    buffers::pass_layout(ctx, "tensor_edges", &[true, true, true, false, true]);
                let mut ro = read(8);
                (ro[6], ro[7]) = (false, false);
                let gather = buffers::pass_layout(ctx, "tensor_gather_edges", &ro);
                let p1 = buffers::compute_pipeline(ctx, "tensor_edges", EDGES, &[&records])?;
                let p2 = buffers::compute_pipeline(ctx, "tensor_gather_edges", GATHER, &[&gather])?;
                (vec![records, gather], vec![p1, p2])
            }
            Passes::AtomicEdges(a) => {
                let (l, p) = super::tensor_atomic::record_pass(ctx, a)?;
                (vec![l], vec![p])
            }
        };
        let beside = passes
            .buffer(TensorBlocks::beside(layout))
            .map_or(0, |b| b.size());
        let buffer = blocks_buffer(ctx, beside, &blocks)?;
        let mut t = TensorMassPasses {
            model: tm,
            blocks,
            buffer,
            forces: None,
            pipelines,
            layouts,
            bind_groups: Vec::new(),
        };
        t.rebind(ctx, passes, uniform, state)?;
        Ok(t)
    }

    /// Whether any tet is damped (the step reads velocities; the blocks hold `C`).
    pub fn damped(&self) -> bool {
        self.blocks.damped
    }

    /// The blocks as uploaded (for the twins and the checks).
    pub fn blocks(&self) -> &TensorBlocks {
        &self.blocks
    }

    /// The float64 model behind the blocks.
    pub fn model(&self) -> &TensorMass {
        &self.model
    }

    /// The device's blocks buffer.
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// Rebuild the bind groups over the layout's buffers held by `passes` now and the state
    /// (after a patch grew either); the edge layout's force scratch follows its records.
    pub(super) fn rebind(
        &mut self,
        ctx: &GpuContext,
        passes: &Passes,
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
    ) -> Result<()> {
        let get = |a: LayoutArray| {
            passes.buffer(a).ok_or_else(|| {
                Error::Gpu(format!("the layout's passes hold no {a:?} buffer to bind"))
            })
        };
        if let Passes::Edges(_) = passes {
            let want = get(LayoutArray::EdgeSprings)?.size() / RECORD * 32;
            if self.forces.as_ref().is_none_or(|f| f.size() < want) {
                buffers::check_binding(ctx, "tensor-mass end forces", want)?;
                self.forces = Some(ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("tensor-mass end forces"),
                    size: want.max(32),
                    usage: wgpu::BufferUsages::STORAGE,
                    mapped_at_creation: false,
                }));
            }
        }
        let d = &ctx.device;
        let mut groups = Vec::with_capacity(state.phases());
        for phase in 0..state.phases() {
            let b = state.bindings(phase);
            let group = |layout: &wgpu::BindGroupLayout, label: &str, list: &[&wgpu::Buffer]| {
                d.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some(label),
                    layout,
                    entries: &buffers::entries(list),
                })
            };
            let g = match passes {
                Passes::Connectivity(_) | Passes::Valence(_) => vec![group(
                    &self.layouts[0],
                    "tensor-mass nodes",
                    &[
                        uniform,
                        get(LayoutArray::Slots)?,
                        get(LayoutArray::InvMass)?,
                        b.second_in,
                        b.cur,
                        b.next,
                        b.second_out,
                        &self.buffer,
                    ],
                )],
                Passes::AtomicEdges(a) => vec![group(
                    &self.layouts[0],
                    "tensor-mass accumulate",
                    &super::tensor_atomic::bindings(
                        a,
                        uniform,
                        get(LayoutArray::EdgeSprings)?,
                        b.second_in,
                        b.cur,
                        &self.buffer,
                    ),
                )],
                Passes::Edges(_) => {
                    let forces = self
                        .forces
                        .as_ref()
                        .expect("made above for the edge layout");
                    vec![
                        group(
                            &self.layouts[0],
                            "tensor-mass records",
                            &[
                                uniform,
                                get(LayoutArray::EdgeSprings)?,
                                b.second_in,
                                b.cur,
                                forces,
                                &self.buffer,
                            ],
                        ),
                        group(
                            &self.layouts[1],
                            "tensor-mass gather",
                            &[
                                uniform,
                                get(LayoutArray::IncidenceRows)?,
                                get(LayoutArray::Incidence)?,
                                forces,
                                get(LayoutArray::InvMass)?,
                                b.second_in,
                                b.cur,
                                b.next,
                                b.second_out,
                            ],
                        ),
                    ]
                }
            };
            groups.push(g);
        }
        self.bind_groups = groups;
        Ok(())
    }

    /// Record one step in phase `phase`: the node pass over `nodes` workgroups (after the
    /// record pass over `records` on the edge layout).
    pub(super) fn record(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        passes: &Passes,
        phase: usize,
        records: (u32, u32),
        nodes: (u32, u32),
    ) {
        let g = &self.bind_groups[phase];
        if let Passes::AtomicEdges(a) = passes {
            let p = &self.pipelines[0];
            return super::tensor_atomic::record(pass, a, p, &g[0], phase, records, nodes);
        }
        if self.pipelines.len() == 2 {
            pass.set_pipeline(&self.pipelines[0]);
            pass.set_bind_group(0, &g[0], &[]);
            pass.dispatch_workgroups(records.0, records.1, 1);
            pass.set_pipeline(&self.pipelines[1]);
            pass.set_bind_group(0, &g[1], &[]);
        } else {
            pass.set_pipeline(&self.pipelines[0]);
            pass.set_bind_group(0, &g[0], &[]);
            if let Passes::Valence(v) = passes {
                pass.set_bind_group(1, v.bucket_group(), &[]);
            }
        }
        pass.dispatch_workgroups(nodes.0, nodes.1, 1);
    }

    /// Follow `diff` (applied to `model`; `layout` already patched, its changes `dirty`, or
    /// repacked whole when `whole`): the float64 model's shares subtracted and added, then the
    /// blocks of the slots the layout's patch rewrote or moved and of every slot of a node the
    /// diff touched (a tensor changes only between two corners of a removed or added tet, both
    /// touched) computed again and written to the device; nothing else. Returns the bytes
    /// written.
    pub fn patch(
        &mut self,
        ctx: &GpuContext,
        model: &PackedModel,
        diff: &ModelDiff,
        layout: &PackedLayout,
        dirty: &[Dirty],
        whole: bool,
    ) -> Result<u64> {
        let nodes_before = self.model.node_tensors().len();
        self.model.patch(&model.rest, diff)?;
        let damped = self.blocks.damped || damped(&self.model);
        if whole || damped != self.blocks.damped {
            self.blocks = TensorBlocks::new(layout, &self.model, damped);
            return self.upload_all(ctx);
        }
        let beside = TensorBlocks::beside(layout);
        let records = match layout {
            PackedLayout::Connectivity(c) => c.slots.len(),
            PackedLayout::Valence(v) => v.slots.len(),
            PackedLayout::Edges(e) => e.springs.len(),
        };
        let stride = self.blocks.stride();
        self.blocks.rows.resize(records * stride, [0.0; 4]);
        // Records the layout's patch changed: zeroed first (a row that shrank leaves empty
        // slots, which a fresh packing holds as zeros), then written where in use.
        let changed: Vec<Range<usize>> = dirty
            .iter()
            .filter(|d| d.array == beside)
            .map(|d| {
                let end = (d.bytes.end.div_ceil(RECORD) as usize).min(records);
                (d.bytes.start / RECORD) as usize..end
            })
            .filter(|r| r.start < r.end)
            .collect();
        for r in &changed {
            self.blocks.rows[r.start * stride..r.end * stride].fill([0.0; 4]);
        }
        let mut touched = vec![false; layout.node_slots()];
        let rank = &layout.order().rank;
        for o in diff.touched_nodes(nodes_before) {
            if let Some(&r) = rank.get(o as usize) {
                touched[r as usize] = true;
            }
        }
        let mut moved = vec![false; records];
        for r in &changed {
            moved[r.clone()].fill(true);
        }
        let order = &layout.order().order;
        for (i, slot, j) in slot_walk(layout) {
            if touched[i as usize] || touched[j as usize] || moved[slot] {
                self.blocks
                    .write_pair(slot, order[i as usize], order[j as usize], &self.model);
                moved[slot] = true;
            }
        }
        if self.blocks.bytes() > self.buffer.size() {
            return self.upload_all(ctx);
        }
        let slot_bytes = self.blocks.slot_bytes();
        // Runs of rewritten slots, ascending.
        let mut dirty: Vec<Dirty> = Vec::new();
        for (s, _) in moved.iter().enumerate().filter(|(_, &m)| m) {
            let bytes = s as u64 * slot_bytes..(s as u64 + 1) * slot_bytes;
            match dirty.last_mut() {
                Some(d) if d.bytes.end == bytes.start => d.bytes.end = bytes.end,
                _ => dirty.push(Dirty {
                    array: beside,
                    bytes,
                }),
            }
        }
        let data: &[u8] = bytemuck::cast_slice(&self.blocks.rows);
        let mut written = 0;
        for (_, bytes) in super::merged_ranges(&dirty, super::WRITE_GAP) {
            let part = &data[bytes.start as usize..bytes.end as usize];
            ctx.queue.write_buffer(&self.buffer, bytes.start, part);
            written += part.len() as u64;
        }
        Ok(written)
    }

    /// A new blocks buffer (with room as the layout's) holding every block.
    fn upload_all(&mut self, ctx: &GpuContext) -> Result<u64> {
        let room = self.blocks.bytes() + self.blocks.bytes() / 4;
        if room > self.buffer.size() {
            self.buffer =
                blocks_buffer(ctx, room / self.blocks.slot_bytes() * RECORD, &self.blocks)?;
        } else if !self.blocks.rows.is_empty() {
            ctx.queue
                .write_buffer(&self.buffer, 0, bytemuck::cast_slice(&self.blocks.rows));
        }
        Ok(self.blocks.bytes())
    }

    /// Device buffers beside the layout's, by name, with their sizes.
    pub fn buffers(&self) -> Vec<(String, u64)> {
        let mut out = vec![("tensor-mass blocks".to_string(), self.blocks.bytes())];
        if let Some(f) = &self.forces {
            out.push(("tensor-mass end forces".to_string(), f.size()));
        }
        out
    }

    /// Bytes a step moves beyond the springs' layout traffic: the blocks of every slot in use
    /// read once, and on the edge layout's gather the second end force written and read.
    pub fn extra_bytes_per_step(&self, layout: &PackedLayout) -> u64 {
        let used = slot_walk(layout).len() as u64;
        // The atomic variants add both end forces to the accumulators instead, which the
        // layout's own traffic counts (two ends per record, as for a spring).
        let forces = match layout {
            PackedLayout::Edges(e) if self.forces.is_some() => 2 * e.springs.len() as u64 * 16,
            _ => 0,
        };
        used * self.blocks.slot_bytes() + forces
    }

    /// How the blocks differ from a fresh assembly of `model` beside `layout` (each block
    /// within float32 rounding of the largest): empty when a patched engine holds what a
    /// rebuilt one would.
    pub fn differences(
        &self,
        ctx: &GpuContext,
        model: &PackedModel,
        layout: &PackedLayout,
    ) -> Result<Vec<String>> {
        let mut out =
            ElementForces::TensorMass(self.model.clone()).differences_from_rebuild(model)?;
        let device = buffers::read_bytes(ctx, &self.buffer, self.blocks.bytes())?;
        if device.as_slice() != bytemuck::cast_slice::<_, u8>(&self.blocks.rows) {
            out.push("the device's tensor-mass blocks differ from the host's".into());
        }
        let fresh = match ElementForces::new(ForceModelKind::TensorMass, model)? {
            Some(ElementForces::TensorMass(tm)) => tm,
            _ => unreachable!("a tensor-mass kind builds a tensor-mass model"),
        };
        let want = TensorBlocks::new(layout, &fresh, self.blocks.damped);
        if want.rows.len() != self.blocks.rows.len() {
            out.push(format!(
                "tensor-mass blocks: {} rows, a rebuild {}",
                self.blocks.rows.len(),
                want.rows.len()
            ));
            return Ok(out);
        }
        let scale = want
            .rows
            .iter()
            .flatten()
            .fold(0.0f32, |m, v| m.max(v.abs()));
        if let Some(k) = (0..want.rows.len()).find(|&k| {
            (0..4).any(|c| (want.rows[k][c] - self.blocks.rows[k][c]).abs() > 1e-6 * scale)
        }) {
            out.push(format!(
                "tensor-mass block row {k} (slot {}) is {:?}, a rebuild's {:?}",
                k / self.blocks.stride(),
                self.blocks.rows[k],
                want.rows[k]
            ));
        }
        Ok(out)
    }
}
