//! The GPU engine on wgpu: the same physics as the float32 CPU engine (state stored as
//! displacements from rest, the same force law and integrators), with the springs packed in one
//! of the memory layouts of [`crate::layout`].
//!
//! A step records one dispatch per layout pass; `step(n)` records `n` steps into one compute
//! pass and submits once. Node state rotates through fixed buffers (three displacement buffers
//! for Verlet; two displacement and two velocity buffers for symplectic Euler), and every pass
//! holds one bind group per rotation phase, made at setup: stepping allocates nothing. Only
//! positions (and velocities) are read back, when asked for.

pub mod atomic_edges;
pub mod broad_self;
pub mod broad_tool;
pub mod buffers;
pub mod context;
pub mod health;
pub mod layout_buffers;
pub mod move_state;
pub mod node_gather;
pub mod nodes_near;
pub mod springs_connectivity;
pub mod springs_edges;
pub mod springs_valence;
pub mod surface_nodes;
pub mod time_step;
pub mod timing;
pub mod upload;

pub use upload::{merged_ranges, WRITE_GAP};

use bytemuck::{Pod, Zeroable};

pub use context::GpuContext;

use super::{Engine, EngineMemory, Health, Integrator, NearReads, PatchCost, SimConfig};
use crate::collide::broad::ToolBox;
use crate::error::Result;
use crate::layout::edges::{Accumulation, FixedPoint};
use crate::layout::patch::{Dirty, LayoutArray};
use crate::layout::{LayoutKind, NodeOrder, PackedLayout};
use crate::model::{ModelDiff, PackedModel};
use crate::physics::StepParams;
use buffers::{Growth, Sizing};
use layout_buffers::LayoutBuffers;

/// Per-step constants; mirrors `struct Params` in `shaders/common.wgsl` (64 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct StepUniform {
    h: f32,
    h2: f32,
    inv_h: f32,
    alpha: f32,
    gravity: [f32; 3],
    integrator: u32,
    n: u32,
    width: u32,
    damped: u32,
    row: u32,
    springs: u32,
    /// New h over old h at the last change of time step (read by `time_step.wgsl` only).
    rescale: f32,
    pad: [u32; 2],
}

const _: () = assert!(std::mem::size_of::<StepUniform>() == 64);

/// Node state read back from the device: current displacements and the second state.
type StatePair = (Vec<[f32; 4]>, Vec<[f32; 4]>);

/// Invocations per workgroup in every pass (`@workgroup_size(64)`).
pub const WORKGROUP: u32 = 64;

/// The node-state buffers and their rotation.
pub struct NodeState {
    integrator: Integrator,
    /// Displacements (three for Verlet, two for symplectic Euler).
    x: Vec<wgpu::Buffer>,
    /// Velocities (two for symplectic Euler; one unused placeholder for Verlet).
    v: Vec<wgpu::Buffer>,
}

/// The buffers a pass binds in one phase of the rotation.
pub struct PhaseBindings<'a> {
    /// Verlet: previous displacements; symplectic Euler: velocities.
    pub second_in: &'a wgpu::Buffer,
    /// Current displacements.
    pub cur: &'a wgpu::Buffer,
    /// Next displacements (written).
    pub next: &'a wgpu::Buffer,
    /// Symplectic Euler: next velocities (written); Verlet: unused.
    pub second_out: &'a wgpu::Buffer,
}

impl NodeState {
    fn new(ctx: &GpuContext, n: usize, integrator: Integrator, sizing: Sizing) -> Result<Self> {
        let bytes = sizing.size(ctx, (n.max(1) * 16) as u64);
        buffers::check_binding(ctx, "node state", bytes)?;
        let make = |label: &str, size: u64| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let (nx, nv, vbytes) = match integrator {
            Integrator::Verlet => (3, 1, 16),
            Integrator::SymplecticEuler => (2, 2, bytes),
        };
        Ok(NodeState {
            integrator,
            x: (0..nx).map(|_| make("displacements", bytes)).collect(),
            v: (0..nv).map(|_| make("velocities", vbytes)).collect(),
        })
    }

    /// Nodes the buffers have room for.
    pub fn capacity(&self) -> usize {
        (self.x[0].size() / 16) as usize
    }

    /// Every buffer that holds per-node state (the Verlet velocity placeholder excluded).
    fn buffers(&self) -> Vec<&wgpu::Buffer> {
        match self.integrator {
            Integrator::Verlet => self.x.iter().collect(),
            Integrator::SymplecticEuler => self.x.iter().chain(&self.v).collect(),
        }
    }

    /// New buffers with room for `n` nodes (a size class), holding this state.
    fn grown(&self, ctx: &GpuContext, n: usize) -> Result<Self> {
        let next = NodeState::new(ctx, n, self.integrator, Sizing::SizeClass)?;
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("grow node state"),
            });
        for (old, new) in self.buffers().into_iter().zip(next.buffers()) {
            enc.copy_buffer_to_buffer(old, 0, new, 0, old.size());
        }
        ctx.queue.submit([enc.finish()]);
        Ok(next)
    }

    /// Number of rotation phases.
    pub fn phases(&self) -> usize {
        self.x.len()
    }

    /// What a step in `phase` reads and writes.
    pub fn bindings(&self, phase: usize) -> PhaseBindings<'_> {
        match self.integrator {
            Integrator::Verlet => PhaseBindings {
                second_in: &self.x[phase],
                cur: &self.x[(phase + 1) % 3],
                next: &self.x[(phase + 2) % 3],
                second_out: &self.v[0],
            },
            Integrator::SymplecticEuler => PhaseBindings {
                second_in: &self.v[phase],
                cur: &self.x[phase],
                next: &self.x[1 - phase],
                second_out: &self.v[1 - phase],
            },
        }
    }
}

/// The passes of the chosen layout.
enum Passes {
    Connectivity(springs_connectivity::ConnectivityPass),
    Valence(springs_valence::ValencePass),
    Edges(springs_edges::EdgePasses),
    AtomicEdges(atomic_edges::AtomicEdgePasses),
}

impl Passes {
    /// The layout buffers of the chosen passes.
    fn layout_buffers(&self) -> &dyn LayoutBuffers {
        match self {
            Passes::Connectivity(p) => &p.gather,
            Passes::Valence(p) => &p.gather,
            Passes::Edges(p) => p,
            Passes::AtomicEdges(p) => p,
        }
    }

    /// The same, to grow.
    fn layout_buffers_mut(&mut self) -> &mut dyn LayoutBuffers {
        match self {
            Passes::Connectivity(p) => &mut p.gather,
            Passes::Valence(p) => &mut p.gather,
            Passes::Edges(p) => p,
            Passes::AtomicEdges(p) => p,
        }
    }

    /// The device buffer of a layout array.
    fn buffer(&self, array: LayoutArray) -> Option<&wgpu::Buffer> {
        self.layout_buffers().buffer(array)
    }
}

/// How dispatches cover the nodes and springs: invocations per row of the two-dimensional
/// grid, and the workgroup counts of the node and spring passes.
#[derive(Debug, Clone, Copy)]
struct Dispatch {
    row: u32,
    nodes: (u32, u32),
    springs: (u32, u32),
}

impl Dispatch {
    fn new(ctx: &GpuContext, n: u32, m: u32) -> Self {
        // One row width serves both the node and the spring dispatches.
        let groups = dispatch_size(ctx, n.max(m));
        let row = groups.0 * WORKGROUP;
        let fold = |count: u32| {
            (
                count.div_ceil(WORKGROUP).clamp(1, groups.0),
                count.div_ceil(row).max(1),
            )
        };
        Dispatch {
            row,
            nodes: fold(n),
            springs: fold(m),
        }
    }
}

/// Mass-spring engine on a wgpu device.
pub struct GpuEngine {
    ctx: GpuContext,
    config: SimConfig,
    layout: PackedLayout,
    rest: Vec<[f64; 3]>,
    fixed: Vec<bool>,
    state: NodeState,
    passes: Passes,
    health: health::HealthPass,
    uniform: wgpu::Buffer,
    uniform_data: StepUniform,
    phase: usize,
    dispatch: Dispatch,
    /// Fixed-point constants (used by the atomic fixed-point variant only).
    fixed_point: FixedPoint,
    /// Device timing of the step pass, where the adapter has timestamp queries.
    timer: Option<timing::PassTimer>,
    /// What patches changed under the surface since the culler last saw it.
    surface_sync: SurfaceSync,
    /// The tissue surface and its cullers, built only once a program culls.
    surface: Option<SurfaceCulling>,
    /// The pass that moves node state within the layout at a patch. Built with the engine:
    /// compiling it at the first cut would stall that cut (about 10 ms on lavapipe).
    mover: move_state::MovePass,
    /// The pass that keeps Verlet's velocity through a change of time step (Verlet only;
    /// built with the engine for the same reason as `mover`).
    rescale: Option<time_step::RescalePass>,
    /// Staging buffers of patches' uploads, reused.
    staging: upload::StagingPool,
    /// A box whose nodes the next step finds as its last pass ([`Engine::prefetch_near`]).
    near_ahead: Option<([f64; 3], [f64; 3])>,
    /// How reads of the nodes near a blade were served.
    near_reads: NearReads,
    /// The last step's submission, which `wait` waits for.
    last_submission: Option<wgpu::SubmissionIndex>,
}

/// What changed under the surface culler since it last saw the layout. A patch moves a node
/// to another layout index only with a state move to it (its state must follow it: a
/// connectivity repack or an edge compaction packs the same order anew, a valence regroup
/// moves every node of the buckets it packs anew), so the moves name every slot whose
/// triangles and rest position may be stale.
enum SurfaceSync {
    /// Nothing: its triangles and rest positions match the layout.
    Current,
    /// The nodes at these layout slots moved there or were added (from patches' state moves);
    /// `rebind` when the node state moved to new buffers, which the culler's passes read.
    Moved { slots: Vec<u32>, rebind: bool },
}

/// The tissue surface on the device and the broad phases over it.
struct SurfaceCulling {
    /// Boundary triangles, model order.
    triangles: Vec<[u32; 3]>,
    /// The triangles at each model node.
    at_nodes: surface_nodes::TrianglesAtNodes,
    tool: broad_tool::ToolCuller,
    /// Nodes near a blade, over the culler's rest positions (built with it: a cut that reads
    /// them never waits for a pipeline).
    near: nodes_near::NodesNear,
    /// The self-contact broad phase and the margin it was built for, once asked for.
    self_contact: Option<(f64, broad_self::SelfCuller)>,
}

impl GpuEngine {
    /// Open the preferred adapter and upload `model` in `layout`.
    pub fn new(model: &PackedModel, config: SimConfig, layout: LayoutKind) -> Result<Self> {
        Self::with_context(GpuContext::new()?, model, config, layout)
    }

    /// Upload `model` in `layout` on an open device, nodes in locality (RCM) order.
    pub fn with_context(
        ctx: GpuContext,
        model: &PackedModel,
        config: SimConfig,
        layout: LayoutKind,
    ) -> Result<Self> {
        let packed = PackedLayout::pack(model, layout, config.node_order.order(model))?;
        Self::with_layout(ctx, model, config, packed)
    }

    /// Upload `model` packed as `layout` (which must be a packing of `model`) on an open
    /// device: for programs that arrange the layout themselves.
    pub fn with_layout(
        ctx: GpuContext,
        model: &PackedModel,
        config: SimConfig,
        mut layout: PackedLayout,
    ) -> Result<Self> {
        // Patches append to the host's arrays: room now, not a reallocation at the first cut.
        layout.reserve_room();
        let params = step_params(model, config);
        let uniform_data = StepUniform {
            h: params.h,
            h2: params.h * params.h,
            inv_h: 1.0 / params.h,
            alpha: params.alpha,
            gravity: params.gravity,
            integrator: (config.integrator == Integrator::SymplecticEuler) as u32,
            n: 0,
            width: 0,
            damped: params.damped as u32,
            row: 0,
            springs: 0,
            rescale: 1.0,
            pad: [0; 2],
        };
        let uniform = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("step constants"),
            size: std::mem::size_of::<StepUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let state = NodeState::new(
            &ctx,
            layout.node_slots(),
            config.integrator,
            Sizing::Headroom,
        )?;
        let fixed_point = match &layout {
            PackedLayout::Edges(e) => e.fixed_point(model),
            _ => FixedPoint::new(1.0, 1),
        };
        let dispatch = Dispatch::new(&ctx, layout.node_slots() as u32, spring_records(&layout));
        let uniform_data = constants(uniform_data, &layout, dispatch);
        ctx.queue
            .write_buffer(&uniform, 0, bytemuck::bytes_of(&uniform_data));
        let passes = build_passes(
            &ctx,
            &layout,
            config,
            &uniform,
            &state,
            fixed_point,
            Sizing::Headroom,
        )?;
        let health = health_pass(&ctx, &passes, &uniform, &state, dispatch)?;
        let timer = timing::PassTimer::new(&ctx);
        let mover = move_state::MovePass::new(&ctx)?;
        let rescale = match config.integrator {
            Integrator::Verlet => Some(time_step::RescalePass::new(&ctx)?),
            Integrator::SymplecticEuler => None,
        };
        Ok(GpuEngine {
            rescale,
            timer,
            surface_sync: SurfaceSync::Current,
            surface: None,
            mover,
            staging: upload::StagingPool::default(),
            near_ahead: None,
            near_reads: NearReads::default(),
            last_submission: None,
            ctx,
            config,
            layout,
            rest: crate::model::room::copy_with_room(&model.rest),
            fixed: crate::model::room::copy_with_room(&model.fixed),
            state,
            passes,
            health,
            uniform,
            uniform_data,
            phase: 0,
            dispatch,
            fixed_point,
        })
    }

    /// Bytes of the device buffer holding `array` (the room it has), where the passes hold one.
    pub fn buffer_size(&self, array: LayoutArray) -> Option<u64> {
        self.passes.buffer(array).map(|b| b.size())
    }

    /// Node states the state buffers have room for.
    pub fn state_capacity(&self) -> usize {
        self.state.capacity()
    }

    /// Where the device's copy of the layout differs from the layout on the CPU (each array
    /// read back whole): empty when every uploaded byte is what the layout holds.
    pub fn device_differences(&self) -> Result<Vec<String>> {
        let mut out = Vec::new();
        for a in LayoutArray::ALL {
            let (Some(buf), host) = (self.passes.buffer(a), self.layout.array(a)) else {
                continue;
            };
            if host.is_empty() {
                continue;
            }
            if buf.size() < host.len() as u64 {
                out.push(format!(
                    "device {a:?} buffer holds {} bytes, the layout {}",
                    buf.size(),
                    host.len()
                ));
                continue;
            }
            let device = buffers::read_bytes(&self.ctx, buf, host.len() as u64)?;
            if let Some(i) = device.iter().zip(host).position(|(d, h)| d != h) {
                out.push(format!(
                    "device {a:?} buffer differs from the layout at byte {i} of {}",
                    host.len()
                ));
            }
        }
        out.extend(self.surface_differences()?);
        // The bucket table, after the count of buckets it holds.
        if let (Passes::Valence(p), PackedLayout::Valence(v)) = (&self.passes, &self.layout) {
            let (held, device) = p.read_buckets(&self.ctx, v.buckets.len())?;
            if held as usize != v.buckets.len() {
                out.push(format!(
                    "the device's bucket table holds {held} buckets, the layout {}",
                    v.buckets.len()
                ));
            }
            if let Some(i) = (0..v.buckets.len()).find(|&i| device.get(i) != Some(&v.buckets[i])) {
                out.push(format!("device bucket {i} differs from the layout"));
            }
        }
        Ok(out)
    }

    /// Where the surface culler's device buffers (triangles in layout order, rest positions of
    /// every node slot) differ from the surface and layout, once it is up to date (after a
    /// patch it catches up at its next use). Empty without a surface.
    pub fn surface_differences(&self) -> Result<Vec<String>> {
        let Some(s) = &self.surface else {
            return Ok(Vec::new());
        };
        if !matches!(self.surface_sync, SurfaceSync::Current) {
            return Ok(Vec::new());
        }
        let mut out = Vec::new();
        let want: Vec<[u32; 4]> = self
            .in_layout_order(&s.triangles)
            .into_iter()
            .map(|t| [t[0], t[1], t[2], 0])
            .collect();
        let (tris, rest) = s
            .tool
            .read_surface(&self.ctx, want.len(), self.layout.node_slots())?;
        if let Some(i) = (0..want.len()).find(|&i| tris[i] != want[i]) {
            out.push(format!(
                "device surface triangle {i} is {:?}, the surface's {:?}",
                tris[i], want[i]
            ));
        }
        let order = &self.layout.order().order;
        let rest_want = self.rest_f32();
        // Holes hold no node: whatever they hold is never read.
        if let Some(i) = (0..rest_want.len())
            .find(|&i| order[i] != crate::layout::NodeOrder::HOLE && rest[i] != rest_want[i])
        {
            out.push(format!(
                "device rest position of slot {i} is {:?}, the layout's {:?}",
                rest[i], rest_want[i]
            ));
        }
        Ok(out)
    }

    /// Apply a change to the model between steps: `diff` has already been applied to `model`
    /// (the model after it, see [`PackedModel::apply`]). The layout is patched on the CPU and
    /// only its dirty byte ranges are written to the device; node state moves on the device
    /// (new nodes start from the state of the node they copy, or at rest). A buffer that
    /// outgrows its room is replaced by one of the next size class, its old contents copied on
    /// the device, and rebound; the passes keep their pipelines. Only a repack of a
    /// node-centric layout or node state outgrowing its buffers rebuilds the passes and
    /// uploads the layout whole.
    ///
    /// On an error (a diff that does not match the model) the engine is left inconsistent:
    /// build a new one.
    pub fn patch(&mut self, model: &PackedModel, diff: &ModelDiff) -> Result<PatchCost> {
        self.forget_ahead();
        let patch = self.layout.patch(model, diff)?;
        if patch.repacked {
            // A repack (or an edge compaction) made new arrays: room again for the next cuts.
            self.layout.reserve_room();
        }
        // A diff only appends nodes and changes the fixed flags it names: copy just those, not
        // the whole arrays (a local cut on a large mesh).
        let before = self.rest.len();
        self.rest.extend_from_slice(&model.rest[before..]);
        self.fixed.extend_from_slice(&model.fixed[before..]);
        for c in &diff.changed_nodes {
            self.fixed[c.node as usize] = model.fixed[c.node as usize];
        }
        debug_assert_eq!(self.fixed, model.fixed);
        let slots = self.layout.node_slots();
        // An edge-layout compaction rewrites only its two incidence arrays, both marked dirty
        // whole: written in place like any dirty range (or grown like any array), it keeps the
        // passes and their pipelines. A connectivity repack rebuilds them (its whole table is new;
        // a valence regroup packs only the buckets patches appended, written like any patch).
        let mut rebuild = patch.repacked && !matches!(self.layout, PackedLayout::Edges(_));
        let state_moved = slots > self.state.capacity();
        if state_moved {
            self.state = self.state.grown(&self.ctx, slots)?;
            self.mover.forget_state();
            rebuild = true;
        }
        self.update_fixed_point(model);
        self.dispatch = Dispatch::new(&self.ctx, slots as u32, spring_records(&self.layout));
        let uniform_before = self.uniform_data;
        self.uniform_data = constants(self.uniform_data, &self.layout, self.dispatch);
        // The first damped spring of an undamped model turns the damped step on (it reads the
        // neighbours' velocities); springs that lose their damping leave zeros, which the
        // damped step handles, so it stays on.
        if diff
            .added_springs
            .iter()
            .chain(&diff.changed_springs)
            .any(|s| s.damping != 0.0)
        {
            self.uniform_data.damped = 1;
        }
        let layout_bytes = self.layout.upload_bytes();
        let mut cost = PatchCost {
            uploaded_bytes: layout_bytes,
            copied_bytes: 0,
            buffers_grown: 0,
            layout_bytes,
            state_moves: patch.moves.len(),
            reallocated: rebuild,
        };
        // The dirty ranges and the state moves go up together: one staging buffer, one
        // submission.
        // Room for the dirty ranges, the move records (16 bytes each and a header) and the step
        // constants; ranges joined across small gaps may still grow it.
        let mut upload = upload::Upload::with_capacity(
            (patch.dirty_bytes() + 16 * patch.moves.len() as u64 + 256) as usize,
        );
        // With the patch's other writes (a queue write stages through a buffer of its own),
        // and only when the dispatch sizes changed.
        if bytemuck::bytes_of(&uniform_before) != bytemuck::bytes_of(&self.uniform_data) {
            upload.write(&self.uniform, 0, bytemuck::bytes_of(&self.uniform_data));
        }
        if rebuild {
            self.passes = build_passes(
                &self.ctx,
                &self.layout,
                self.config,
                &self.uniform,
                &self.state,
                self.fixed_point,
                Sizing::SizeClass,
            )?;
        } else {
            let grown = self.outgrown();
            let growth = self.grow(&grown, &patch.dirty)?;
            let (written, tables) = self.write_dirty(&patch.dirty, &grown, &mut upload);
            cost.uploaded_bytes = growth.uploaded + written;
            cost.copied_bytes = growth.copied;
            cost.buffers_grown = grown.len() + tables;
        }
        // Submitted before anything else can fail: the host layout is patched already, and
        // the device must follow it even if the moves cannot be staged (the error says so).
        debug_assert!(
            patch
                .moves
                .iter()
                .all(|m| (m.to as usize) < self.state.capacity()),
            "a state move past the state buffers"
        );
        let state_buffers = self.state.buffers();
        let moves = self
            .mover
            .stage(&self.ctx, &mut upload, &patch.moves, state_buffers.len());
        // Nothing to write and no moves (the records are written too): nothing to submit.
        if upload.bytes() > 0 {
            let mut enc = self
                .ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("patch"),
                });
            let staging = upload.record(&self.ctx, &mut self.staging, &mut enc)?;
            if let Ok(staged) = moves {
                self.mover
                    .record(&self.ctx, &mut enc, &state_buffers, staged);
            }
            self.ctx.queue.submit([enc.finish()]);
            if let Some(b) = staging {
                self.staging.submitted(b);
            }
        }
        moves?;
        if rebuild || !self.health.fits(self.dispatch.nodes) {
            // Bound to new buffers, or grown with the node dispatch.
            self.health = health_pass(
                &self.ctx,
                &self.passes,
                &self.uniform,
                &self.state,
                self.dispatch,
            )?;
        } else if cost.buffers_grown > 0 {
            // The mass buffer may be a new one: the probe keeps its pipeline.
            let inv_mass = self
                .passes
                .buffer(LayoutArray::InvMass)
                .expect("every layout uploads inverse masses");
            self.health
                .rebind(&self.ctx, inv_mass, &self.uniform, &self.state);
        }
        // Node indices and state buffers may have changed under the surface: the culler is
        // brought up to date when next used (a cut usually edits the surface right after).
        // Only the moved slots are stale, after a repack too (see `SurfaceSync`).
        self.note_surface_moves(&patch.moves, state_moved);
        Ok(cost)
    }

    /// The staging buffers patches upload through: how many are kept for reuse, and how many
    /// were made so far.
    pub fn staging_buffers(&self) -> (usize, usize) {
        (self.staging.kept(), self.staging.made())
    }

    /// Re-quantize the fixed-point accumulation (edge layout, atomic fixed point) only when the
    /// patched model's larger valence could wrap an accumulator: keeping the constants keeps
    /// the step bit-identical to before the patch otherwise.
    fn update_fixed_point(&mut self, model: &PackedModel) {
        if let (PackedLayout::Edges(e), Accumulation::AtomicFixed) =
            (&self.layout, self.config.accumulation)
        {
            let fp = e.fixed_point(model);
            if fp.limit < self.fixed_point.limit {
                self.fixed_point = fp;
                if let Passes::AtomicEdges(p) = &self.passes {
                    p.set_fixed_point(&self.ctx, &fp);
                }
            }
        }
    }

    /// The layout arrays that outgrew their device buffers.
    fn outgrown(&self) -> Vec<LayoutArray> {
        LayoutArray::ALL
            .into_iter()
            .filter(|&a| {
                self.passes
                    .buffer(a)
                    .is_some_and(|b| self.layout.array(a).len() as u64 > b.size())
            })
            .collect()
    }

    /// Replace the buffers of `arrays` by larger ones holding the patched arrays (`dirty`: the
    /// patch's ranges), rebinding the passes that use them.
    fn grow(&mut self, arrays: &[LayoutArray], dirty: &[Dirty]) -> Result<Growth> {
        let grown: Vec<_> = arrays
            .iter()
            .map(|&array| layout_buffers::Outgrown {
                array,
                data: self.layout.array(array),
                dirty: dirty
                    .iter()
                    .filter(|d| d.array == array)
                    .map(|d| d.bytes.clone())
                    .collect(),
            })
            .collect();
        self.passes
            .layout_buffers_mut()
            .grow(&self.ctx, &grown, &self.uniform, &self.state)
    }

    /// Write the dirty ranges of every array but those in `skip` (grown: already written) in
    /// place through `upload`, and the valence bucket table when it changed. Returns the bytes
    /// written and how many tables outgrew their buffers on the way (the bucket table grows as
    /// it is written).
    fn write_dirty(
        &mut self,
        dirty: &[Dirty],
        skip: &[LayoutArray],
        upload: &mut upload::Upload,
    ) -> (u64, usize) {
        let mut written = 0u64;
        for (array, bytes) in merged_ranges(dirty, WRITE_GAP) {
            if skip.contains(&array) {
                continue;
            }
            let Some(buf) = self.passes.buffer(array) else {
                continue;
            };
            let data = &self.layout.array(array)[bytes.start as usize..bytes.end as usize];
            upload.write(buf, bytes.start, data);
            written += data.len() as u64;
        }
        let mut grown = 0;
        if let (Passes::Valence(p), PackedLayout::Valence(v)) = (&mut self.passes, &self.layout) {
            if dirty.iter().any(|d| d.array == LayoutArray::Buckets) {
                let stage = |table: &wgpu::Buffer, bytes: &[u8]| upload.write(table, 0, bytes);
                grown += p.set_buckets(&self.ctx, &v.buckets, stage) as usize;
                written += crate::layout::valence::table_bytes(v.buckets.len());
            }
        }
        (written, grown)
    }

    /// Give the engine the tissue's boundary triangles (dense model indices, as
    /// `collide::broad::Surface` makes them) for [`GpuEngine::cull_tools`]. The first call
    /// uploads them and the rest positions; later calls (a cut edited the surface, a patch
    /// renumbered or appended nodes) write only the triangles and positions that changed.
    pub fn set_surface(&mut self, triangles: &[[u32; 3]]) -> Result<()> {
        let n = self.rest.len();
        if let Some(t) = triangles
            .iter()
            .find(|t| t.iter().any(|&i| i as usize >= n))
        {
            return Err(crate::Error::Model(format!(
                "surface triangle {t:?} names a node past the model's {n} nodes"
            )));
        }
        let (tris, rest) = (self.in_layout_order(triangles), self.rest_f32());
        // A culler that exists keeps its pipeline: only what changed is written. On error the
        // old surface stays.
        match &mut self.surface {
            Some(s) => {
                s.tool.set_surface(&self.ctx, &tris, &rest, &self.state)?;
                s.near.rebind(&self.ctx, s.tool.rest(), &self.state);
                s.triangles = triangles.to_vec();
                s.at_nodes = surface_nodes::TrianglesAtNodes::of(triangles, n);
                s.self_contact = None;
            }
            None => {
                let tool = broad_tool::ToolCuller::new(&self.ctx, &tris, &rest, &self.state)?;
                let near = nodes_near::NodesNear::new(&self.ctx, tool.rest(), &self.state)?;
                self.surface = Some(SurfaceCulling {
                    triangles: triangles.to_vec(),
                    at_nodes: surface_nodes::TrianglesAtNodes::of(triangles, n),
                    tool,
                    near,
                    self_contact: None,
                });
            }
        }
        self.surface_sync = SurfaceSync::Current;
        Ok(())
    }

    /// The surface after an edit: `triangles` is the whole new list (dense model indices), of
    /// which only the slots `changed` differ from the last one given (a cut swapped out the
    /// triangles it removed and appended those it added, as [`crate::Simulation::edit_surface`]
    /// does). Writes only those triangles, those at nodes a patch moved in the layout, and the
    /// rest positions of the moved and added nodes: a cut costs what it changed, not a pass
    /// over the surface and every node (a buffer the edit outgrows is grown by a copy on the
    /// device). A patch that moved the node state to new buffers costs a rebinding more.
    pub fn edit_surface(&mut self, triangles: &[[u32; 3]], changed: &[u32]) -> Result<()> {
        let (moved, rebind) = match &self.surface_sync {
            SurfaceSync::Moved { slots, rebind } => (slots.clone(), *rebind),
            SurfaceSync::Current => (Vec::new(), false),
        };
        let Some(surface) = self.surface.as_ref() else {
            return self.set_surface(triangles);
        };
        let known = surface.triangles.len();
        let n = self.rest.len();
        let mut slots: Vec<u32> = changed
            .iter()
            .copied()
            .filter(|&c| (c as usize) < triangles.len())
            .collect();
        // Appended slots are always written, named or not.
        slots.extend(known as u32..triangles.len() as u32);
        if let Some(t) = slots
            .iter()
            .map(|&c| &triangles[c as usize])
            .find(|t| t.iter().any(|&i| i as usize >= n))
        {
            return Err(crate::Error::Model(format!(
                "surface triangle {t:?} names a node past the model's {n} nodes"
            )));
        }
        let order = &self.layout.order();
        // The model node at a layout slot (none at a hole).
        let node_at = |slot: u32| {
            order
                .order
                .get(slot as usize)
                .copied()
                .filter(|&o| o != crate::layout::NodeOrder::HOLE)
        };
        // Triangles at a node whose layout index changed hold stale indices. Those of the new
        // list are the ones at the node before the edit (the index is of the last list) that
        // the edit left alone, and changed ones, which are written anyway.
        for node in moved.iter().filter_map(|&slot| node_at(slot)) {
            slots.extend(
                surface
                    .at_nodes
                    .at(node)
                    .iter()
                    .copied()
                    .filter(|&i| (i as usize) < triangles.len()),
            );
        }
        slots.sort_unstable();
        slots.dedup();
        let tris: Vec<(u32, [u32; 3])> = slots
            .iter()
            .map(|&i| (i, triangles[i as usize].map(|k| order.rank[k as usize])))
            .collect();
        let slots_total = self.layout.node_slots();
        // Slots a shrinking patch dropped are no node's: nothing to write there.
        let rest: Vec<(u32, [f32; 4])> = moved
            .iter()
            .filter(|&&slot| (slot as usize) < slots_total)
            .map(|&slot| {
                let r = node_at(slot).map_or([0.0; 4], |old| {
                    let r = self.rest[old as usize];
                    [r[0] as f32, r[1] as f32, r[2] as f32, 0.0]
                });
                (slot, r)
            })
            .collect();
        let s = self.surface.as_mut().expect("checked above");
        let rest_moved = s.tool.edit(
            &self.ctx,
            triangles.len(),
            &tris,
            slots_total,
            &rest,
            &self.state,
        )?;
        if rebind {
            s.tool.rebind(&self.ctx, &self.state);
        }
        if rest_moved || rebind {
            s.near.rebind(&self.ctx, s.tool.rest(), &self.state);
        }
        // Dropped slots leave the index; changed and appended ones are put in it anew.
        for (i, t) in s.triangles.iter().enumerate().skip(triangles.len()) {
            s.at_nodes.remove(i as u32, t);
        }
        s.triangles.resize(triangles.len(), [u32::MAX; 3]);
        s.at_nodes.grow(n);
        for &i in &slots {
            let (old, new) = (s.triangles[i as usize], triangles[i as usize]);
            if old != new {
                s.at_nodes.remove(i, &old);
                s.at_nodes.add(i, &new);
                s.triangles[i as usize] = new;
            }
        }
        debug_assert_eq!(s.triangles, triangles, "the edit named every changed slot");
        debug_assert!(
            s.at_nodes
                .same_as(&surface_nodes::TrianglesAtNodes::of(triangles, n)),
            "the triangles at the nodes follow the edits"
        );
        s.self_contact = None;
        self.surface_sync = SurfaceSync::Current;
        Ok(())
    }

    /// Remember what a patch's `moves` changed under the surface, and whether it moved the node
    /// state to new buffers (`state_moved`).
    fn note_surface_moves(&mut self, moves: &[crate::layout::patch::StateMove], state_moved: bool) {
        if self.surface.is_none() {
            return;
        }
        let (mut slots, rebind) =
            match std::mem::replace(&mut self.surface_sync, SurfaceSync::Current) {
                SurfaceSync::Current => (Vec::new(), false),
                SurfaceSync::Moved { slots, rebind } => (slots, rebind),
            };
        slots.extend(moves.iter().map(|m| m.to));
        self.surface_sync = SurfaceSync::Moved {
            slots,
            rebind: rebind || state_moved,
        };
    }

    /// Bring the culler up to date after a patch (nodes appended or renumbered, state
    /// reallocated), before it is used.
    fn refresh_surface(&mut self) -> Result<()> {
        if matches!(self.surface_sync, SurfaceSync::Current) {
            return Ok(());
        }
        if let Some(triangles) = self.surface.as_ref().map(|s| s.triangles.clone()) {
            self.edit_surface(&triangles, &[])?;
        }
        self.surface_sync = SurfaceSync::Current;
        Ok(())
    }

    /// Triangles of model nodes renumbered to layout indices.
    fn in_layout_order(&self, triangles: &[[u32; 3]]) -> Vec<[u32; 3]> {
        let rank = &self.layout.order().rank;
        triangles
            .iter()
            .map(|t| t.map(|i| rank[i as usize]))
            .collect()
    }

    /// Rest positions in layout order as the passes see them (zero at holes).
    pub fn rest_f32(&self) -> Vec<[f32; 4]> {
        let mut rest = vec![[0.0f32; 4]; self.layout.node_slots()];
        for (new, old) in self.layout.order().pairs() {
            let r = self.rest[old];
            rest[new] = [r[0] as f32, r[1] as f32, r[2] as f32, 0.0];
        }
        rest
    }

    /// The surface triangles in layout order, as the culler holds them.
    pub fn surface_layout_order(&self) -> Option<Vec<[u32; 3]>> {
        self.surface
            .as_ref()
            .map(|s| self.in_layout_order(&s.triangles))
    }

    /// Broad phase against tool boxes on the device: the (triangle, tool) pairs whose boxes
    /// overlap at the current state, triangle indices into the surface given to
    /// [`GpuEngine::set_surface`]. Reads back only the candidate list.
    pub fn cull_tools(&mut self, boxes: &[ToolBox]) -> Result<broad_tool::CullResult> {
        self.refresh_surface()?;
        let Some(surface) = &mut self.surface else {
            return Err(no_surface());
        };
        surface.tool.cull(&self.ctx, &self.state, self.phase, boxes)
    }

    /// The nodes (model indices, ascending) whose current position lies in `lo..=hi` (m), with
    /// their positions as [`Engine::positions`] gives them, found on the device with one pass
    /// over the nodes; only those nodes are read back (16 bytes each). A few just outside the
    /// box may come too. Before a surface is given ([`GpuEngine::set_surface`]; the pass
    /// shares its rest positions) every position is read back and scanned instead.
    pub fn nodes_near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Result<Vec<(u32, [f64; 3])>> {
        self.refresh_surface()?;
        let Some(surface) = &mut self.surface else {
            let x = self.state_f64().0;
            return crate::cut::PositionSource::near(&mut crate::cut::AllPositions(&x), lo, hi);
        };
        let (lo32, hi32) = crate::cut::reading::float32_box(lo, hi);
        let (order, rest, fixed) = (&self.layout.order().order, &self.rest, &self.fixed);
        // The model node at a slot and its position as `state_f64` gives it (a cut reads what
        // a full readback gives), with its rest position; none at a hole.
        let node = |slot: u32, u: &[f32; 3]| {
            let old = *order.get(slot as usize)?;
            let r = *rest.get(old as usize)?;
            let x = if fixed[old as usize] {
                r
            } else {
                [0, 1, 2].map(|c| r[c] + u[c] as f64)
            };
            Some((old, x, r))
        };
        let mut out: Vec<(u32, [f64; 3])> = match surface.near.take_ahead(&self.ctx, lo32, hi32)? {
            Some(all) => {
                self.near_reads.ahead += 1;
                // In node order first (sorting 8-byte keys), so that the rest positions and
                // fixed flags are then read in ascending order, not at random, and the list
                // comes out sorted.
                let mut keys: Vec<u64> = all
                    .iter()
                    .enumerate()
                    .filter_map(|(i, (slot, _))| {
                        let old = *order.get(*slot as usize)?;
                        Some((u64::from(old) << 32) | i as u64)
                    })
                    .collect();
                keys.sort_unstable();
                // Narrowed to this box by the pass's own test (rest and displacement added
                // in float32), so the list is the one a read of its own would give.
                keys.iter()
                    .map(|k| &all[(k & 0xffff_ffff) as usize])
                    .filter_map(|(slot, u)| {
                        let (old, x, r) = node(*slot, u)?;
                        let x32 = [0, 1, 2].map(|c| r[c] as f32 + u[c]);
                        (0..3)
                            .all(|c| lo32[c] <= x32[c] && x32[c] <= hi32[c])
                            .then_some((old, x))
                    })
                    .collect()
            }
            None => {
                self.near_reads.direct += 1;
                surface
                    .near
                    .find(
                        &self.ctx,
                        surface.tool.rest(),
                        &self.state,
                        self.phase,
                        self.layout.node_slots() as u32,
                        lo32,
                        hi32,
                    )?
                    .iter()
                    .filter_map(|(slot, u)| node(*slot, u).map(|(old, x, _)| (old, x)))
                    .collect()
            }
        };
        crate::cut::reading::sort_by_node(&mut out);
        Ok(out)
    }

    /// Drop a read of nodes near a blade made ahead with a step: the state it saw is changing.
    fn forget_ahead(&mut self) {
        if let Some(s) = &mut self.surface {
            s.near.forget_ahead();
        }
    }

    /// Broad phase of the tissue against itself on the device: pairs of surface triangles that
    /// share no node and whose boxes, widened by `margin / 2` (m), overlap at the current
    /// state. The passes are built at the first call (and again when the margin changes).
    pub fn cull_self(&mut self, margin: f64) -> Result<broad_self::SelfCullResult> {
        self.refresh_surface()?;
        let Some(surface) = &self.surface else {
            return Err(no_surface());
        };
        // Built at the first call and when the margin changes; otherwise nothing is made here.
        if surface
            .self_contact
            .as_ref()
            .is_none_or(|(m, _)| *m != margin)
        {
            let tris = self.in_layout_order(&surface.triangles);
            let grid = crate::collide::self_broad::GridParams::for_surface(
                &self.rest,
                &surface.triangles,
                margin,
            );
            let culler =
                broad_self::SelfCuller::new(&self.ctx, &tris, &self.rest_f32(), grid, &self.state)?;
            if let Some(s) = &mut self.surface {
                s.self_contact = Some((margin, culler));
            }
        }
        let (_, culler) = self
            .surface
            .as_mut()
            .and_then(|s| s.self_contact.as_mut())
            .expect("built above");
        culler.cull(&self.ctx, &self.state, self.phase)
    }

    /// The packed layout as it is on the device.
    pub fn layout(&self) -> &PackedLayout {
        &self.layout
    }

    /// The step constants the shaders see.
    pub fn step_params(&self) -> StepParams {
        let u = &self.uniform_data;
        StepParams {
            h: u.h,
            gravity: u.gravity,
            alpha: u.alpha,
            integrator: self.config.integrator,
            damped: u.damped != 0,
        }
    }

    /// The device's divergence probe as read back (per-workgroup energies, first non-finite
    /// layout index), for comparing with its twin [`health::health_cpu`].
    pub fn health_partials(&self) -> Result<health::HealthPartials> {
        self.health.run(&self.ctx, self.phase, self.dispatch.nodes)
    }

    /// Inverse masses in layout order, as uploaded.
    pub fn inv_mass(&self) -> &[f32] {
        bytemuck::cast_slice(self.layout.array(LayoutArray::InvMass))
    }

    /// The fixed-point constants of the atomic fixed-point edge variant.
    pub fn fixed_point(&self) -> FixedPoint {
        self.fixed_point
    }

    /// `"gpu-connectivity on <adapter>"`; the edge layout with atomics names its variant
    /// ("gpu-edges-atomicfixed on ...").
    pub fn describe(&self) -> String {
        let variant = match (&self.passes, self.config.accumulation) {
            (Passes::AtomicEdges(..), a) => format!("-{a:?}").to_lowercase(),
            _ => String::new(),
        };
        format!(
            "gpu-{}{variant} on {}",
            format!("{:?}", self.layout.kind()).to_lowercase(),
            self.ctx.describe()
        )
    }

    /// Whether a spring force has saturated the fixed-point accumulators (edge layout with
    /// [`Accumulation::AtomicFixed`]) since setup; false for every other layout and variant.
    pub fn fixed_point_overflowed(&self) -> Result<bool> {
        match &self.passes {
            Passes::AtomicEdges(p) => p.overflowed(&self.ctx),
            _ => Ok(false),
        }
    }

    /// The raw device state in layout order (holes included): current displacements and the
    /// second state (previous displacements for Verlet, velocities for symplectic Euler).
    pub fn raw_state(&self) -> Result<StatePair> {
        let b = self.state.bindings(self.phase);
        let n = self.layout.node_slots();
        let mut cur = buffers::read_vec4(&self.ctx, b.cur)?;
        let mut second = buffers::read_vec4(&self.ctx, b.second_in)?;
        cur.truncate(n);
        second.truncate(n);
        Ok((cur, second))
    }

    /// Overwrite the raw device state (layout order, as [`GpuEngine::raw_state`] gives it).
    pub fn set_raw_state(&mut self, cur: &[[f32; 4]], second: &[[f32; 4]]) -> Result<()> {
        self.forget_ahead();
        let n = self.layout.node_slots();
        if cur.len() != n || second.len() != n {
            return Err(crate::Error::Model(format!(
                "raw state of {} and {} entries for a layout of {n} node slots",
                cur.len(),
                second.len()
            )));
        }
        let b = self.state.bindings(self.phase);
        self.ctx
            .queue
            .write_buffer(b.cur, 0, bytemuck::cast_slice(cur));
        self.ctx
            .queue
            .write_buffer(b.second_in, 0, bytemuck::cast_slice(second));
        Ok(())
    }

    /// Model-order positions and velocities from the device state; NaN if the device failed,
    /// which the simulation's divergence check then reports.
    fn state_f64(&self) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let n = self.rest.len();
        let (cur, second) = match self.raw_state() {
            Ok(s) => s,
            Err(e) => {
                eprintln!("lancet: reading the GPU state failed: {e}");
                return (vec![[f64::NAN; 3]; n], vec![[f64::NAN; 3]; n]);
            }
        };
        let dt = self.config.dt;
        let mut x = vec![[0.0; 3]; n];
        let mut v = vec![[0.0; 3]; n];
        for (new, old) in self.layout.order().pairs() {
            for c in 0..3 {
                x[old][c] = self.rest[old][c] + cur[new][c] as f64;
                v[old][c] = match self.state.integrator {
                    Integrator::Verlet => (cur[new][c] as f64 - second[new][c] as f64) / dt,
                    Integrator::SymplecticEuler => second[new][c] as f64,
                };
            }
            if self.fixed[old] {
                x[old] = self.rest[old];
            }
        }
        (x, v)
    }
}

/// The error for culling before a surface was given.
fn no_surface() -> crate::Error {
    crate::Error::Model(
        "no surface to cull: call set_surface with the boundary triangles first".into(),
    )
}

/// The divergence probe over the inverse masses of `passes` and `state`.
fn health_pass(
    ctx: &GpuContext,
    passes: &Passes,
    uniform: &wgpu::Buffer,
    state: &NodeState,
    dispatch: Dispatch,
) -> Result<health::HealthPass> {
    let inv_mass = passes
        .buffer(LayoutArray::InvMass)
        .expect("every layout uploads inverse masses");
    let groups = dispatch.nodes.0 * dispatch.nodes.1;
    health::HealthPass::new(ctx, inv_mass, uniform, state, groups)
}

/// Records the spring passes cover (edge layout; 0 for the node-centric layouts).
fn spring_records(layout: &PackedLayout) -> u32 {
    match layout {
        PackedLayout::Edges(e) => e.springs.len() as u32,
        _ => 0,
    }
}

/// `base` with the sizes of `layout` and `dispatch` filled in.
fn constants(base: StepUniform, layout: &PackedLayout, dispatch: Dispatch) -> StepUniform {
    StepUniform {
        n: layout.node_slots() as u32,
        width: match layout {
            PackedLayout::Connectivity(c) => c.capacity,
            _ => 0,
        },
        row: dispatch.row,
        springs: spring_records(layout),
        ..base
    }
}

/// Device memory of `layout` with its node state, and the bytes a step moves.
fn layout_memory(layout: &PackedLayout, config: SimConfig) -> EngineMemory {
    let (stats, bytes_per_step) = match layout {
        PackedLayout::Connectivity(c) => c.memory(config.integrator),
        PackedLayout::Valence(v) => v.memory(config.integrator),
        PackedLayout::Edges(e) => e.memory(config.integrator, config.accumulation),
    };
    EngineMemory {
        stats,
        bytes_per_step,
    }
}

/// Upload `layout` and build its passes.
#[allow(clippy::too_many_arguments)]
fn build_passes(
    ctx: &GpuContext,
    layout: &PackedLayout,
    config: SimConfig,
    uniform: &wgpu::Buffer,
    state: &NodeState,
    fixed_point: FixedPoint,
    sizing: Sizing,
) -> Result<Passes> {
    Ok(match layout {
        PackedLayout::Connectivity(c) => Passes::Connectivity(
            springs_connectivity::ConnectivityPass::new(ctx, c, uniform, state, sizing)?,
        ),
        PackedLayout::Valence(v) => Passes::Valence(springs_valence::ValencePass::new(
            ctx, v, uniform, state, sizing,
        )?),
        PackedLayout::Edges(e) => match config.accumulation {
            Accumulation::Gather => Passes::Edges(springs_edges::EdgePasses::new(
                ctx, e, uniform, state, sizing,
            )?),
            atomic => Passes::AtomicEdges(atomic_edges::AtomicEdgePasses::new(
                ctx,
                e,
                atomic,
                fixed_point,
                uniform,
                state,
                sizing,
            )?),
        },
    })
}

/// Workgroups of [`WORKGROUP`] covering `n` invocations, folded into as few rows as the
/// device's limit per dimension allows, of equal width (65,536 workgroups fold into two rows of
/// 32,768; the limit's width, 65,535, would leave almost a row idle). The shaders find their
/// index as `row * y + x` with `row` = the width times [`WORKGROUP`].
pub fn dispatch_size(ctx: &GpuContext, n: u32) -> (u32, u32) {
    let groups = n.div_ceil(WORKGROUP).max(1);
    let max = ctx.limits.max_compute_workgroups_per_dimension.max(1);
    let rows = groups.div_ceil(max);
    (groups.div_ceil(rows), rows)
}

/// The step constants of a model and configuration, in float32.
pub fn step_params(model: &PackedModel, config: SimConfig) -> StepParams {
    let g = model.gravity;
    StepParams {
        h: config.dt as f32,
        gravity: [g[0] as f32, g[1] as f32, g[2] as f32],
        alpha: model.mass_damping as f32,
        integrator: config.integrator,
        damped: model.springs().iter().any(|s| s.damping != 0.0),
    }
}

impl Engine for GpuEngine {
    fn step(&mut self, steps: u32) {
        // Whatever was read ahead saw the state this step replaces.
        self.forget_ahead();
        let ahead = self.near_ahead.take();
        // A culler behind a patch is brought up to date before the pass reads its rest
        // positions; where that fails the read is not made ahead (a direct read will report it).
        let ahead = ahead.filter(|_| self.refresh_surface().is_ok());
        let mut enc = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("steps"),
            });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("springs"),
                timestamp_writes: self.timer.as_ref().map(|t| t.writes()),
            });
            for _ in 0..steps {
                let d = self.dispatch;
                match &self.passes {
                    Passes::Connectivity(p) => p.record(&mut pass, self.phase, d.nodes),
                    Passes::Valence(p) => p.record(&mut pass, self.phase, d.nodes),
                    Passes::Edges(p) => p.record(&mut pass, self.phase, d.springs, d.nodes),
                    Passes::AtomicEdges(p) => p.record(&mut pass, self.phase, d.springs, d.nodes),
                }
                self.phase = (self.phase + 1) % self.state.phases();
            }
        }
        if let Some(t) = &self.timer {
            t.resolve(&mut enc);
        }
        let slots = self.layout.node_slots() as u32;
        let near = match (ahead, self.surface.as_mut()) {
            (Some((lo, hi)), Some(s)) => {
                let (lo32, hi32) = crate::cut::reading::float32_box(lo, hi);
                s.near
                    .record_ahead(&self.ctx, &mut enc, self.phase, slots, lo32, hi32);
                Some(&mut s.near)
            }
            _ => None,
        };
        let submitted = self.ctx.queue.submit([enc.finish()]);
        if let Some(near) = near {
            near.map_ahead(submitted.clone());
        }
        self.last_submission = Some(submitted);
    }

    fn prefetch_near(&mut self, lo: [f64; 3], hi: [f64; 3]) {
        self.near_ahead = Some((lo, hi));
    }

    fn near_reads(&self) -> NearReads {
        self.near_reads
    }

    fn last_device_seconds(&self) -> Option<f64> {
        // A failed readback only loses the timing; the step itself is unaffected.
        self.timer.as_ref()?.last_seconds(&self.ctx).ok().flatten()
    }

    fn wait(&mut self) {
        // This engine's last step only: the device is shared (`GpuContext::new`), and waiting
        // for all of it would wait for other engines' work too.
        let _ = self.ctx.device.poll(wgpu::PollType::Wait {
            submission_index: self.last_submission.clone(),
            timeout: None,
        });
    }

    fn positions(&self) -> Vec<[f64; 3]> {
        self.state_f64().0
    }

    fn velocities(&self) -> Vec<[f64; 3]> {
        self.state_f64().1
    }

    fn state(&self) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        self.state_f64()
    }

    fn set_time_step(&mut self, dt: f64) -> Result<PatchCost> {
        let h = dt as f32;
        let u = &mut self.uniform_data;
        u.rescale = (dt / self.config.dt) as f32;
        (u.h, u.h2, u.inv_h) = (h, h * h, 1.0 / h);
        self.config.dt = dt;
        let bytes = bytemuck::bytes_of(&self.uniform_data);
        self.ctx.queue.write_buffer(&self.uniform, 0, bytes);
        if let Some(pass) = &self.rescale {
            let mut enc = self
                .ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("time step"),
                });
            let b = self.state.bindings(self.phase);
            pass.record(&self.ctx, &mut enc, &self.uniform, &b, self.dispatch.nodes);
            self.last_submission = Some(self.ctx.queue.submit([enc.finish()]));
        }
        Ok(PatchCost::parameters_only(
            bytes.len() as u64,
            self.layout.upload_bytes(),
        ))
    }

    fn set_state(&mut self, positions: &[[f64; 3]], velocities: &[[f64; 3]]) {
        self.forget_ahead();
        let n = self.layout.node_slots();
        let dt = self.config.dt;
        let mut cur = vec![[0.0f32; 4]; n];
        let mut second = vec![[0.0f32; 4]; n];
        for (new, old) in self.layout.order().pairs() {
            if self.fixed[old] {
                continue;
            }
            for c in 0..3 {
                let u = positions[old][c] - self.rest[old][c];
                cur[new][c] = u as f32;
                second[new][c] = match self.state.integrator {
                    Integrator::Verlet => (u - velocities[old][c] * dt) as f32,
                    Integrator::SymplecticEuler => velocities[old][c] as f32,
                };
            }
        }
        let b = self.state.bindings(self.phase);
        self.ctx
            .queue
            .write_buffer(b.cur, 0, bytemuck::cast_slice(&cur));
        self.ctx
            .queue
            .write_buffer(b.second_in, 0, bytemuck::cast_slice(&second));
    }

    fn differences_from_rebuild(&self, model: &PackedModel) -> Result<Vec<String>> {
        let mut out = self.layout.differences_from_rebuild(model)?;
        out.extend(self.device_differences()?);
        Ok(out)
    }

    fn memory(&self) -> EngineMemory {
        // Counted when asked (a pass over the slot table), not at every patch.
        layout_memory(&self.layout, self.config)
    }

    fn name(&self) -> String {
        self.describe()
    }

    fn patch(&mut self, model: &PackedModel, diff: &ModelDiff) -> Result<Option<PatchCost>> {
        GpuEngine::patch(self, model, diff).map(Some)
    }

    fn node_positions(&self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        let n = self.rest.len();
        if let Some(&i) = nodes.iter().find(|&&i| i as usize >= n) {
            return Err(super::bad_node(i, n));
        }
        let rank = &self.layout.order().rank;
        let idx: Vec<u32> = nodes.iter().map(|&i| rank[i as usize]).collect();
        let cur = buffers::read_entries(&self.ctx, self.state.bindings(self.phase).cur, &idx)?;
        Ok(nodes
            .iter()
            .zip(cur)
            .map(|(&i, u)| {
                let r = self.rest[i as usize];
                if self.fixed[i as usize] {
                    r
                } else {
                    [0, 1, 2].map(|c| r[c] + u[c] as f64)
                }
            })
            .collect())
    }

    fn node_start_positions(&self, nodes: &[u32], dt: f64) -> Result<Vec<[f64; 3]>> {
        let n = self.rest.len();
        if let Some(&i) = nodes.iter().find(|&&i| i as usize >= n) {
            return Err(super::bad_node(i, n));
        }
        let rank = &self.layout.order().rank;
        let idx: Vec<u32> = nodes.iter().map(|&i| rank[i as usize]).collect();
        let b = self.state.bindings(self.phase);
        // Verlet keeps the previous displacements: the start of the step, read as they are.
        // Symplectic Euler: the current displacement less dt times the velocity.
        let second = buffers::read_entries(&self.ctx, b.second_in, &idx)?;
        let euler = self.state.integrator == Integrator::SymplecticEuler;
        let cur = if euler {
            buffers::read_entries(&self.ctx, b.cur, &idx)?
        } else {
            Vec::new()
        };
        Ok(nodes
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                let r = self.rest[i as usize];
                if self.fixed[i as usize] {
                    return r;
                }
                [0, 1, 2].map(|c| {
                    let u = if euler {
                        cur[k][c] as f64 - dt * second[k][c] as f64
                    } else {
                        second[k][c] as f64
                    };
                    r[c] + u
                })
            })
            .collect())
    }

    fn node_velocities(&self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        if nodes.is_empty() {
            return Ok(Vec::new());
        }
        let n = self.rest.len();
        if let Some(&i) = nodes.iter().find(|&&i| i as usize >= n) {
            return Err(super::bad_node(i, n));
        }
        let rank = &self.layout.order().rank;
        let idx: Vec<u32> = nodes.iter().map(|&i| rank[i as usize]).collect();
        let b = self.state.bindings(self.phase);
        let second = buffers::read_entries(&self.ctx, b.second_in, &idx)?;
        let cur = match self.state.integrator {
            Integrator::Verlet => buffers::read_entries(&self.ctx, b.cur, &idx)?,
            Integrator::SymplecticEuler => Vec::new(),
        };
        let dt = self.config.dt;
        Ok(nodes
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                if self.fixed[i as usize] {
                    return [0.0; 3];
                }
                [0, 1, 2].map(|c| match self.state.integrator {
                    Integrator::Verlet => (cur[k][c] as f64 - second[k][c] as f64) / dt,
                    Integrator::SymplecticEuler => second[k][c] as f64,
                })
            })
            .collect())
    }

    fn correct_positions(&mut self, nodes: &[u32], positions: &[[f64; 3]]) -> Result<()> {
        self.forget_ahead();
        super::check_correction(nodes, positions, self.rest.len())?;
        let rank = &self.layout.order().rank;
        let b = self.state.bindings(self.phase);
        // Symplectic Euler adds the move over dt to the velocity: read the few old states.
        let moving: Vec<(u32, [f64; 3])> = nodes
            .iter()
            .zip(positions)
            .filter(|(&i, _)| !self.fixed[i as usize])
            .map(|(&i, &p)| (i, p))
            .collect();
        let idx: Vec<u32> = moving.iter().map(|&(i, _)| rank[i as usize]).collect();
        let euler = self.config.integrator == Integrator::SymplecticEuler;
        let (old, vel) = if euler {
            (
                buffers::read_entries(&self.ctx, b.cur, &idx)?,
                buffers::read_entries(&self.ctx, b.second_in, &idx)?,
            )
        } else {
            (Vec::new(), Vec::new())
        };
        let inv_h = 1.0 / self.config.dt;
        for (k, &(i, p)) in moving.iter().enumerate() {
            let r = self.rest[i as usize];
            let u = [0, 1, 2].map(|c| p[c] - r[c]);
            let at = idx[k] as u64 * 16;
            let cur = [u[0] as f32, u[1] as f32, u[2] as f32, 0.0];
            self.ctx
                .queue
                .write_buffer(b.cur, at, bytemuck::bytes_of(&cur));
            if euler {
                let v = [0, 1, 2]
                    .map(|c| (vel[k][c] as f64 + (u[c] - old[k][c] as f64) * inv_h) as f32);
                let v = [v[0], v[1], v[2], 0.0];
                self.ctx
                    .queue
                    .write_buffer(b.second_in, at, bytemuck::bytes_of(&v));
            }
        }
        Ok(())
    }

    fn set_surface(&mut self, triangles: &[[u32; 3]]) -> Result<()> {
        GpuEngine::set_surface(self, triangles)
    }

    fn edit_surface(&mut self, triangles: &[[u32; 3]], changed: &[u32]) -> Result<()> {
        GpuEngine::edit_surface(self, triangles, changed)
    }

    fn nodes_near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Result<Vec<(u32, [f64; 3])>> {
        GpuEngine::nodes_near(self, lo, hi)
    }

    fn cull_tools(&mut self, boxes: &[ToolBox]) -> Result<Option<Vec<[u32; 2]>>> {
        GpuEngine::cull_tools(self, boxes).map(|r| Some(r.candidates))
    }

    fn cull_self(&mut self, margin: f64) -> Result<Option<Vec<[u32; 2]>>> {
        GpuEngine::cull_self(self, margin).map(|r| Some(r.pairs))
    }

    fn health(&self) -> Result<Option<Health>> {
        let h = self
            .health
            .run(&self.ctx, self.phase, self.dispatch.nodes)?;
        let (kinetic, gravity) = h.totals();
        let order = &self.layout.order().order;
        Ok(Some(Health {
            non_finite: h
                .first_bad
                .map(|i| order[i as usize])
                .filter(|&m| m != NodeOrder::HOLE)
                .map(|m| m as usize),
            kinetic,
            gravity,
        }))
    }
}
