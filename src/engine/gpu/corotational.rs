//! The corotational passes: finite elements whose stiffness turns with each tet, stepped on the
//! GPU by one layout-independent element path whatever `--layout` says (the tets are not in
//! the spring layouts; the node state, masses and node order are the layout's):
//!
//! 1. `shaders/corotational_tets.wgsl`, one invocation per tet: the tet's rotation by a float32
//!    polar decomposition (Müller et al. 2016's quaternion iteration, warm-started from the
//!    tet's rotation of the last step, kept in a per-tet buffer), then its four corner forces
//!    `-R K_e (R^T x - X)` (with Rayleigh's `beta R K_e R^T v`) into per-tet force records;
//! 2. `shaders/corotational_gather.wgsl`, one invocation per node: the node's records summed
//!    through its (tet, corner) list in a fixed order, then the node update every layout shares
//!    (`integrate` in `common.wgsl`: gravity, mass damping, compensated summation with
//!    `Params.one`).
//!
//! Why this decomposition: it needs only arithmetic and square roots (bit-exact twins on
//! lavapipe), it returns a rotation for every matrix (inverted and flat tets included: no
//! inverse, no determinant sign to get wrong), and warm-started it converges in one or two
//! iterations per step; a cold start (a new tet after a cut, a state set from outside) takes
//! more iterations within the same step, up to `ROTATION_ITERATIONS`. The twins are in
//! `twin::corotational`. A cut patches the float64 model by per-tet shares and patches the tet
//! table where it changed ([`TetTable::patch`]): the records of the tets it moved (the last
//! tet into each removed one's place, as the model moves them) and added, and the record lists
//! of their corners, are written; the rotations of the tets that moved are copied on the
//! device and new tets start from the identity, so nothing is read back and the bytes a cut
//! uploads follow the cut, not the mesh. The few nodes a valence patch moves to another
//! bucket take their record lists along and their tets' corners are renumbered. Where the
//! layout renumbered many nodes (a valence regroup, a repack) or a buffer must grow, the
//! table is rebuilt whole and the rotations are read back to follow it.

use super::buffers::{self, Sizing};
use super::{dispatch_size, GpuContext, Passes, StateBuffers, WORKGROUP};
use crate::error::{Error, Result};
use crate::layout::patch::LayoutArray;
use crate::layout::tet_table::{corner_sets, TablePatch, TetTable, IDENTITY};
use crate::layout::PackedLayout;
use crate::model::{corner_set, ModelDiff, PackedModel};
use crate::physics::{ElementForces, ForceModelKind, TetElement};

const TETS: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/corotational_tets.wgsl")
);
const GATHER: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/corotational_gather.wgsl")
);

/// The tet pass's own constants; mirrors `TetParams` in `corotational_tets.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct TetUniform {
    tets: u32,
    row: u32,
    pad: [u32; 2],
}

/// The table's device buffers.
struct TableBuffers {
    uniform: wgpu::Buffer,
    corners: wgpu::Buffer,
    shape: wgpu::Buffer,
    rotations: wgpu::Buffer,
    forces: wgpu::Buffer,
    rows: wgpu::Buffer,
    incidence: wgpu::Buffer,
}

/// The table's device buffers the implicit step binds ([`CorotationalPasses::device_table`]).
pub(super) struct DeviceTable<'a> {
    pub shape: &'a wgpu::Buffer,
    pub rotations: &'a wgpu::Buffer,
    pub rows: &'a wgpu::Buffer,
    pub incidence: &'a wgpu::Buffer,
    pub forces: &'a wgpu::Buffer,
}

/// The corotational model of a GPU engine with its passes.
pub struct CorotationalPasses {
    /// The float64 model, patched by every cut: the source of the table.
    model: ElementForces,
    table: TetTable,
    /// Each tet's corners (model indices) as a set, in table order, and where each is.
    keys: Vec<[u32; 4]>,
    at: rustc_hash::FxHashMap<[u32; 4], usize>,
    /// The layout's rank (model index to layout index) the table's corners are numbered by.
    rank: Vec<u32>,
    /// Bytes the last patch uploaded, and whether it rebuilt the table whole.
    last_patch: (u64, bool),
    /// What the last patch changed where it patched the table in place (`None` where it
    /// rebuilt it): the implicit step's pair lists follow it.
    last_table: Option<TablePatch>,
    buffers: TableBuffers,
    /// Workgroups of the tet pass (x, y).
    groups: (u32, u32),
    pipelines: [wgpu::ComputePipeline; 2],
    layouts: [wgpu::BindGroupLayout; 2],
    /// Per phase, the tet pass's group and the node pass's.
    bind_groups: Vec<[wgpu::BindGroup; 2]>,
}

fn elements(model: &ElementForces) -> &[TetElement] {
    match model {
        ElementForces::Corotational(c) => c.elements(),
        _ => unreachable!("the corotational passes hold a corotational model"),
    }
}

impl CorotationalPasses {
    /// The corotational model of `model` beside `layout` (already uploaded by `passes`), with
    /// its pipelines. Under backward Euler the tet pass runs alone, before the block pass
    /// (`super::corotational_implicit`) and the solve, which read its rotations and forces.
    pub(super) fn new(
        ctx: &GpuContext,
        model: &PackedModel,
        layout: &PackedLayout,
        passes: &Passes,
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
    ) -> Result<Self> {
        let forces = ElementForces::new(ForceModelKind::Corotational, model)?
            .expect("a corotational kind builds a model");
        let table = TetTable::new(elements(&forces), &layout.order().rank, layout.node_slots());
        let rotations = vec![IDENTITY; table.len()];
        let (buffers, groups) = upload(ctx, &table, &rotations, Sizing::Headroom)?;
        let keys = corner_sets(elements(&forces));
        let tets = {
            let mut e = vec![buffers::uniform_entry(0), buffers::uniform_entry(1)];
            for (b, read_only) in [(2, true), (3, true), (4, false), (5, true), (6, true)] {
                e.push(buffers::storage_entry(b, read_only));
            }
            e.push(buffers::storage_entry(7, false));
            ctx.device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("corotational_tets"),
                    entries: &e,
                })
        };
        let mut ro = vec![true; 8];
        (ro[6], ro[7]) = (false, false);
        let gather = buffers::pass_layout(ctx, "corotational_gather", &ro);
        let p1 = buffers::compute_pipeline(ctx, "corotational_tets", TETS, &[&tets])?;
        let p2 = buffers::compute_pipeline(ctx, "corotational_gather", GATHER, &[&gather])?;
        let mut c = CorotationalPasses {
            model: forces,
            table,
            at: keys.iter().enumerate().map(|(i, &k)| (k, i)).collect(),
            keys,
            rank: layout.order().rank.clone(),
            last_patch: (0, false),
            last_table: None,
            buffers,
            groups,
            pipelines: [p1, p2],
            layouts: [tets, gather],
            bind_groups: Vec::new(),
        };
        c.rebind(ctx, passes, uniform, state)?;
        Ok(c)
    }

    /// Whether any tet is damped (the tet pass reads velocities).
    pub fn damped(&self) -> bool {
        self.table.damped
    }

    /// The tet table as uploaded (for the twins and the checks).
    pub fn table(&self) -> &TetTable {
        &self.table
    }

    /// The float64 model behind the table.
    pub fn model(&self) -> &ElementForces {
        &self.model
    }

    /// The device's per-tet rotations (unit quaternions `(x, y, z, w)`), read back.
    pub fn rotations(&self, ctx: &GpuContext) -> Result<Vec<[f32; 4]>> {
        let bytes =
            buffers::read_bytes(ctx, &self.buffers.rotations, 16 * self.table.len() as u64)?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }

    /// Rebuild the bind groups over the layout's masses and the state held now.
    pub(super) fn rebind(
        &mut self,
        ctx: &GpuContext,
        passes: &Passes,
        uniform: &wgpu::Buffer,
        state: &StateBuffers,
    ) -> Result<()> {
        let inv_mass = passes.buffer(LayoutArray::InvMass).ok_or_else(|| {
            Error::Gpu("the layout's passes hold no inverse-mass buffer to bind".into())
        })?;
        let t = &self.buffers;
        let d = &ctx.device;
        let group = |layout: &wgpu::BindGroupLayout, label: &str, list: &[&wgpu::Buffer]| {
            d.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout,
                entries: &buffers::entries(list),
            })
        };
        self.bind_groups = (0..state.phases())
            .map(|phase| {
                let b = state.bindings(phase);
                [
                    group(
                        &self.layouts[0],
                        "corotational tets",
                        &[
                            uniform,
                            &t.uniform,
                            &t.corners,
                            &t.shape,
                            &t.rotations,
                            b.second_in,
                            b.cur,
                            &t.forces,
                        ],
                    ),
                    group(
                        &self.layouts[1],
                        "corotational gather",
                        &[
                            uniform,
                            &t.rows,
                            &t.incidence,
                            &t.forces,
                            inv_mass,
                            b.second_in,
                            b.cur,
                            b.next,
                            b.second_out,
                        ],
                    ),
                ]
            })
            .collect();
        Ok(())
    }

    /// Record one step in phase `phase`: the tet pass, then the node pass over `nodes`
    /// workgroups.
    pub(super) fn record(&self, pass: &mut wgpu::ComputePass<'_>, phase: usize, nodes: (u32, u32)) {
        self.record_tets(pass, phase);
        let g = &self.bind_groups[phase];
        pass.set_pipeline(&self.pipelines[1]);
        pass.set_bind_group(0, &g[1], &[]);
        pass.dispatch_workgroups(nodes.0, nodes.1, 1);
    }

    /// Record the tet pass alone in phase `phase` (rotations and corner forces): the implicit
    /// step's first pass, before its blocks and its solve.
    pub(super) fn record_tets(&self, pass: &mut wgpu::ComputePass<'_>, phase: usize) {
        if !self.table.is_empty() {
            pass.set_pipeline(&self.pipelines[0]);
            pass.set_bind_group(0, &self.bind_groups[phase][0], &[]);
            pass.dispatch_workgroups(self.groups.0, self.groups.1, 1);
        }
    }

    /// The device buffers the implicit step reads beside the table: the tets' shapes and
    /// rotations (the block pass), the node rows, records and corner forces (the solve's
    /// force).
    pub(super) fn device_table(&self) -> DeviceTable<'_> {
        let t = &self.buffers;
        DeviceTable {
            shape: &t.shape,
            rotations: &t.rotations,
            rows: &t.rows,
            incidence: &t.incidence,
            forces: &t.forces,
        }
    }

    /// Follow `diff` (applied to `model`; `layout` already patched): the float64 model's
    /// elements removed and added, and the table patched where they changed (see the module
    /// documentation), or rebuilt whole where the layout renumbered old nodes or a buffer is
    /// too small. The bind groups must be rebuilt after (`rebind`). Returns the bytes
    /// uploaded.
    pub fn patch(
        &mut self,
        ctx: &GpuContext,
        model: &PackedModel,
        diff: &ModelDiff,
        layout: &PackedLayout,
    ) -> Result<u64> {
        let rank = &layout.order().rank;
        // Old nodes the layout moved (a valence patch moves a node whose valence changed):
        // followed in place while they are few; a regroup or repack that moves many rebuilds.
        let moved: Vec<(u32, u32)> = match self.rank.len() <= rank.len() {
            true => self
                .rank
                .iter()
                .zip(rank)
                .filter(|(a, b)| a != b)
                .map(|(&a, &b)| (a, b))
                .collect(),
            false => Vec::new(),
        };
        let kept_order = self.rank.len() <= rank.len()
            && moved.len() <= 64.max(self.rank.len() / 16)
            && layout.node_slots() >= self.table.rows.len();
        self.last_table = None;
        if !kept_order {
            let bytes = self.rebuild(ctx, model, diff, layout)?;
            self.last_patch = (bytes, true);
            return Ok(bytes);
        }
        let before = self.table.clone();
        let (keys, at) = (self.keys.clone(), self.at.clone());
        self.model.patch(&model.rest, diff)?;
        let Some(patch) = self.table.patch(
            &diff.removed_tets,
            elements(&self.model),
            &mut self.keys,
            &mut self.at,
            rank,
            &moved,
            layout.node_slots(),
        ) else {
            unreachable!("the model's patch checked every removed tet");
        };
        self.rank.clone_from(rank);
        let fits = |b: &wgpu::Buffer, bytes: usize| b.size() >= bytes as u64;
        let t = &self.table;
        let b = &self.buffers;
        if !(fits(&b.corners, 16 * t.len())
            && fits(&b.shape, 48 * t.len())
            && fits(&b.rotations, 16 * t.len())
            && fits(&b.forces, 64 * t.len())
            && fits(&b.rows, 8 * t.rows.len())
            && fits(&b.incidence, 4 * t.incidence.len()))
            || t.holes() > t.incidence.len() / 2
        {
            // Rebuilt from where it was before this patch, so that the rotations follow.
            (self.table, self.keys, self.at) = (before, keys, at);
            let bytes = self.regrow(ctx, diff, layout)?;
            self.last_patch = (bytes, true);
            return Ok(bytes);
        }
        let bytes = self.write_patch(ctx, &patch);
        self.last_patch = (bytes, false);
        self.last_table = Some(patch);
        Ok(bytes)
    }

    /// What the last patch changed in the table where it patched it in place; `None` where it
    /// rebuilt the table whole (every tet may have moved).
    pub fn last_table_patch(&self) -> Option<&TablePatch> {
        self.last_table.as_ref()
    }

    /// The bytes the last patch uploaded, and whether it rebuilt the table whole (see
    /// [`CorotationalPasses::patch`]).
    pub fn last_patch(&self) -> (u64, bool) {
        self.last_patch
    }

    /// Write what `patch` changed in the table to the device: the moved tets' rotations copied
    /// (through a scratch buffer: a copy may not read and write one buffer), then the written
    /// records, rows and incidence ranges, the new tets' identity rotations and the tet count.
    /// The bytes uploaded.
    fn write_patch(&mut self, ctx: &GpuContext, patch: &TablePatch) -> u64 {
        let (t, b) = (&self.table, &self.buffers);
        let q = &ctx.queue;
        if !patch.moved.is_empty() {
            let scratch = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("corotational moved rotations"),
                size: 16 * patch.moved.len() as u64,
                usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("corotational rotations moved"),
                });
            for (k, &(from, _)) in patch.moved.iter().enumerate() {
                enc.copy_buffer_to_buffer(
                    &b.rotations,
                    16 * from as u64,
                    &scratch,
                    16 * k as u64,
                    16,
                );
            }
            for (k, &(_, to)) in patch.moved.iter().enumerate() {
                enc.copy_buffer_to_buffer(
                    &scratch,
                    16 * k as u64,
                    &b.rotations,
                    16 * to as u64,
                    16,
                );
            }
            // Submitted before the writes below, which a queue runs at its next submission.
            q.submit([enc.finish()]);
        }
        let mut bytes = 0u64;
        let mut write = |buffer: &wgpu::Buffer, offset: u64, data: &[u8]| {
            if !data.is_empty() {
                q.write_buffer(buffer, offset, data);
                bytes += data.len() as u64;
            }
        };
        for &i in &patch.tets {
            let i = i as usize;
            write(&b.corners, 16 * i as u64, bytemuck::bytes_of(&t.corners[i]));
            write(&b.shape, 48 * i as u64, bytemuck::cast_slice(&t.shape[i]));
        }
        let new = t.len() - patch.first_new as usize;
        write(
            &b.rotations,
            16 * patch.first_new as u64,
            bytemuck::cast_slice(&vec![IDENTITY; new]),
        );
        for &n in &patch.nodes {
            let n = n as usize;
            write(&b.rows, 8 * n as u64, bytemuck::bytes_of(&t.rows[n]));
        }
        for r in &patch.incidence {
            let r = r.start as usize..r.end as usize;
            write(
                &b.incidence,
                4 * r.start as u64,
                bytemuck::cast_slice(&t.incidence[r]),
            );
        }
        self.groups = dispatch_size(ctx, t.len() as u32);
        let constants = TetUniform {
            tets: t.len() as u32,
            row: self.groups.0 * WORKGROUP,
            pad: [0; 2],
        };
        write(&b.uniform, 0, bytemuck::bytes_of(&constants));
        bytes
    }

    /// [`CorotationalPasses::patch`] where a buffer must grow: the rotations read back and the
    /// table rebuilt whole into buffers with room for the next cuts.
    fn regrow(&mut self, ctx: &GpuContext, diff: &ModelDiff, layout: &PackedLayout) -> Result<u64> {
        let rotations = self.rotations(ctx)?;
        self.relayout(ctx, layout, rotations, diff, Sizing::SizeClass)
    }

    /// [`CorotationalPasses::patch`] where the layout renumbered old nodes: the float64 model
    /// patched, the rotations read back and the table rebuilt whole.
    fn rebuild(
        &mut self,
        ctx: &GpuContext,
        model: &PackedModel,
        diff: &ModelDiff,
        layout: &PackedLayout,
    ) -> Result<u64> {
        let rotations = self.rotations(ctx)?;
        self.model.patch(&model.rest, diff)?;
        self.relayout(ctx, layout, rotations, diff, Sizing::Headroom)
    }

    /// The table rebuilt from the (patched) float64 model in `layout`'s order, with the
    /// rotations `rotations` (the table's before `diff`) moved as the model moved its tets.
    fn relayout(
        &mut self,
        ctx: &GpuContext,
        layout: &PackedLayout,
        mut rotations: Vec<[f32; 4]>,
        diff: &ModelDiff,
        sizing: Sizing,
    ) -> Result<u64> {
        let mut keys = std::mem::take(&mut self.keys);
        let mut at = std::mem::take(&mut self.at);
        for &t in &diff.removed_tets {
            let i = at
                .remove(&corner_set(t))
                .expect("the model's patch checked every removed tet");
            keys.swap_remove(i);
            rotations.swap_remove(i);
            if let Some(&moved) = keys.get(i) {
                at.insert(moved, i);
            }
        }
        rotations.resize(elements(&self.model).len(), IDENTITY);
        self.keys = corner_sets(elements(&self.model));
        self.at = self.keys.iter().enumerate().map(|(i, &k)| (k, i)).collect();
        self.rank.clone_from(&layout.order().rank);
        self.table = TetTable::new(
            elements(&self.model),
            &layout.order().rank,
            layout.node_slots(),
        );
        let (b, groups) = upload(ctx, &self.table, &rotations, sizing)?;
        self.buffers = b;
        self.groups = groups;
        Ok(self.table.bytes() + 16 * rotations.len() as u64)
    }

    /// Device buffers beside the layout's, by name, with their sizes.
    pub fn buffers(&self) -> Vec<(String, u64)> {
        let t = &self.buffers;
        [
            ("corotational tet corners", &t.corners),
            ("corotational tet shapes", &t.shape),
            ("corotational rotations", &t.rotations),
            ("corotational force records", &t.forces),
            ("corotational node rows", &t.rows),
            ("corotational incidence", &t.incidence),
        ]
        .into_iter()
        .map(|(n, b)| (n.to_string(), b.size()))
        .collect()
    }

    /// Bytes a step moves: per tet its corners, shape and rotation (read and written), its
    /// corners' displacements (and second states when damped) and its four force records
    /// written; per node its row, state and mass read, its next state written; per record its
    /// incidence entry and force read.
    pub fn bytes_per_step(&self, nodes: u64) -> u64 {
        let tets = self.table.len() as u64;
        let corner_reads = if self.table.damped { 4 * 32 } else { 4 * 16 };
        let tet = 16 + 48 + 32 + corner_reads + 64;
        let node = 8 + 4 + 2 * 16 + 2 * 16;
        let record = 4 + 16;
        tets * tet + nodes * node + 4 * tets * record
    }

    /// How the engine's model and table differ from a fresh build of `model` beside `layout`:
    /// empty when a patched engine holds what a rebuilt one would.
    pub fn differences(
        &self,
        ctx: &GpuContext,
        model: &PackedModel,
        layout: &PackedLayout,
    ) -> Result<Vec<String>> {
        let mut out = self.model.differences_from_rebuild(model)?;
        let fresh = ElementForces::new(ForceModelKind::Corotational, model)?
            .expect("a corotational kind builds a model");
        let want = TetTable::new(elements(&fresh), &layout.order().rank, layout.node_slots());
        if self.table.differs_from(&want) {
            out.push(format!(
                "the corotational tet table ({} tets, {} records) differs from a rebuild's \
                 ({} tets, {} records)",
                self.table.len(),
                self.table.incidence.len(),
                want.len(),
                want.incidence.len()
            ));
        }
        let t = &self.buffers;
        let same = |b: &wgpu::Buffer, host: &[u8]| -> Result<bool> {
            Ok(host.is_empty() || buffers::read_bytes(ctx, b, host.len() as u64)? == host)
        };
        if !same(&t.corners, bytemuck::cast_slice(&self.table.corners))?
            || !same(&t.shape, bytemuck::cast_slice(&self.table.shape))?
            || !same(&t.rows, bytemuck::cast_slice(&self.table.rows))?
            || !same(&t.incidence, bytemuck::cast_slice(&self.table.incidence))?
        {
            out.push("the device's corotational tet table differs from the host's".into());
        }
        Ok(out)
    }
}

/// The buffers of `table` with the rotations `rotations`, and the tet pass's workgroups.
fn upload(
    ctx: &GpuContext,
    table: &TetTable,
    rotations: &[[f32; 4]],
    sizing: Sizing,
) -> Result<(TableBuffers, (u32, u32))> {
    let groups = dispatch_size(ctx, table.len() as u32);
    let constants = TetUniform {
        tets: table.len() as u32,
        row: groups.0 * WORKGROUP,
        pad: [0; 2],
    };
    let uniform = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("corotational constants"),
        size: std::mem::size_of::<TetUniform>() as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    ctx.queue
        .write_buffer(&uniform, 0, bytemuck::bytes_of(&constants));
    let store = |label: &str, data: &[u8]| buffers::storage_buffer(ctx, label, data, sizing);
    Ok((
        TableBuffers {
            uniform,
            corners: store(
                "corotational tet corners",
                bytemuck::cast_slice(&table.corners),
            )?,
            shape: store(
                "corotational tet shapes",
                bytemuck::cast_slice(&table.shape),
            )?,
            rotations: store("corotational rotations", bytemuck::cast_slice(rotations))?,
            forces: buffers::zeroed_storage(
                ctx,
                "corotational force records",
                64 * table.len() as u64,
                sizing,
            )?,
            rows: store("corotational node rows", bytemuck::cast_slice(&table.rows))?,
            incidence: store(
                "corotational incidence",
                bytemuck::cast_slice(&table.incidence),
            )?,
        },
        groups,
    ))
}
