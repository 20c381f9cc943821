//! The GPU engine on wgpu: the same physics as the float32 CPU engine (state stored as
//! displacements from rest, the same force law and integrators), with the springs packed in one
//! of the memory layouts of [`crate::layout`].
//!
//! A step records one dispatch per layout pass; `step(n)` records `n` steps into one compute
//! pass and submits once. Node state swaps between fixed buffers (two displacement buffers and
//! two of the second state: Verlet's last step, symplectic Euler's velocity), and every pass
//! holds one bind group per rotation phase, made at setup: stepping allocates nothing. Only
//! positions (and velocities) are read back, when asked for.

pub mod atomic_edges;
#[cfg(feature = "collide")]
pub mod broad_self;
pub mod broad_tool;
pub mod buffers;
pub mod context;
pub mod corotational;
pub mod corotational_implicit;
pub mod embed_surface;
pub mod health;
pub mod host_buffers;
pub mod implicit;
mod implicit_atomic;
mod implicit_engine;
pub mod layout_buffers;
pub mod move_state;
pub mod node_gather;
pub mod nodes_near;
pub mod springs_connectivity;
pub mod springs_edges;
pub mod springs_valence;
pub mod surface_nodes;
pub mod tensor_atomic;
pub mod tensor_mass;
pub mod time_step;
pub mod timing;
pub mod upload;

mod device;
mod patching;
mod state;
mod stepping;
mod surface;

pub use upload::{merged_ranges, WRITE_GAP};

use bytemuck::{Pod, Zeroable};

pub use context::GpuContext;
pub use state::{PhaseBindings, StateBuffers};
use surface::{SurfaceCulling, SurfaceSync};

use super::{
    DeviceEngine, Engine, EngineMemory, GpuOptions, Health, Integrator, NearReads, PatchCost,
    SimConfig,
};
use crate::collide::broad::ToolBox;
use crate::error::Result;
use crate::layout::edges::{Accumulation, FixedPoint};
use crate::layout::patch::{Dirty, LayoutArray};
use crate::layout::{NodeOrder, PackedLayout};
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
    /// Always 1.0: the shaders' `two_sum` multiplies by it so that the compiler cannot fold
    /// compensated summation's exact-residual arithmetic away (see `shaders/common.wgsl`).
    one: f32,
    pad: u32,
}

const _: () = assert!(std::mem::size_of::<StepUniform>() == 64);

/// Invocations per workgroup in every pass (`@workgroup_size(64)`).
pub const WORKGROUP: u32 = 64;

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
    /// How the edge layout sums spring forces (the layout kind is `layout`'s).
    accumulation: Accumulation,
    rest: Vec<[f64; 3]>,
    fixed: Vec<bool>,
    state: StateBuffers,
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
    /// The implicit integrator's solver (backward Euler only).
    implicit: Option<implicit::ImplicitSolver>,
    /// The render surface's pass, once one is set ([`GpuEngine::set_render_surface`]).
    render: Option<embed_surface::EmbedPass>,
    /// What hosts render from without readback ([`GpuEngine::node_positions`]).
    host: host_buffers::HostBuffers,
    /// Patches applied so far: the host buffers bind again when it moved.
    patches: u64,
    /// The tensor-mass model and its passes, which replace the springs' force
    /// (`config.force_model` TensorMass); `None` for springs.
    tensor: Option<tensor_mass::TensorMassPasses>,
    /// The corotational model and its passes, which replace the springs' force
    /// (`config.force_model` Corotational); `None` otherwise.
    corot: Option<corotational::CorotationalPasses>,
    /// The corotational model's block pass under backward Euler (the blocks its solve reads);
    /// `None` otherwise.
    corot_blocks: Option<corotational_implicit::CorotationalBlocks>,
}

impl GpuEngine {
    /// Open the preferred adapter and upload `model` with the layout and accumulation of
    /// `options` (a [`crate::layout::LayoutKind`] alone gives the default accumulation).
    pub fn new(
        model: &PackedModel,
        config: SimConfig,
        options: impl Into<GpuOptions>,
    ) -> Result<Self> {
        Self::with_context(GpuContext::new()?, model, config, options)
    }

    /// Upload `model` as `options` say on an open device, nodes in the order of
    /// `config.node_order`.
    pub fn with_context(
        ctx: GpuContext,
        model: &PackedModel,
        config: SimConfig,
        options: impl Into<GpuOptions>,
    ) -> Result<Self> {
        let options = options.into();
        let packed = PackedLayout::pack(model, options.layout, config.node_order.order(model))?;
        Self::with_layout(ctx, model, config, packed, options.accumulation)
    }

    /// Upload `model` packed as `layout` (which must be a packing of `model`) on an open
    /// device, the edge layout summing its forces by `accumulation` (ignored by the other
    /// layouts): for programs that arrange the layout themselves.
    pub fn with_layout(
        ctx: GpuContext,
        model: &PackedModel,
        config: SimConfig,
        mut layout: PackedLayout,
        accumulation: Accumulation,
    ) -> Result<Self> {
        implicit_atomic::check_layout(config.integrator, layout.kind(), accumulation)?;
        // Patches append to the host's arrays: room now, not a reallocation at the first cut.
        layout.reserve_room();
        let params = step_params(model, config);
        let uniform_data = StepUniform {
            h: params.h,
            h2: params.h * params.h,
            inv_h: 1.0 / params.h,
            alpha: params.alpha,
            gravity: params.gravity,
            integrator: (config.integrator.keeps_velocity()) as u32,
            n: 0,
            width: 0,
            damped: params.damped as u32,
            row: 0,
            springs: 0,
            rescale: 1.0,
            one: 1.0,
            pad: 0,
        };
        let uniform = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("step constants"),
            size: std::mem::size_of::<StepUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let state = StateBuffers::new(
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
            accumulation,
            &uniform,
            &state,
            fixed_point,
            Sizing::Headroom,
        )?;
        let tensor = tensor_passes(&ctx, model, config, &layout, &passes, &uniform, &state)?;
        let corot = corotational_passes(&ctx, model, config, &layout, &passes, &uniform, &state)?;
        // Fixed point sized for the tensors' end forces too, where they are accumulated.
        let fixed_point = match (&tensor, &passes) {
            (Some(t), Passes::AtomicEdges(p)) => {
                let fp = tensor_atomic::fixed_point(&layout, model, t, fixed_point);
                p.set_fixed_point(&ctx, &fp);
                fp
            }
            _ => fixed_point,
        };
        let mut uniform_data = uniform_data;
        // The element passes read velocities where the tets are damped, not the springs.
        let element_damping = tensor
            .as_ref()
            .map(|t| t.damped())
            .or(corot.as_ref().map(|c| c.damped()));
        if let Some(damped) = element_damping {
            uniform_data.damped = damped as u32;
            ctx.queue
                .write_buffer(&uniform, 0, bytemuck::bytes_of(&uniform_data));
        }
        let health = health_pass(&ctx, &passes, &uniform, &state, dispatch)?;
        let timer = timing::PassTimer::new(&ctx);
        let mover = move_state::MovePass::new(&ctx)?;
        let rescale = match config.integrator {
            Integrator::Verlet => Some(time_step::RescalePass::new(&ctx)?),
            Integrator::SymplecticEuler | Integrator::BackwardEuler => None,
        };
        let solve_model = match (&tensor, &corot) {
            (Some(_), _) => implicit::SolveModel::TensorMass,
            (_, Some(_)) => implicit::SolveModel::Corotational,
            _ => implicit::SolveModel::Springs,
        };
        let implicit = match config.integrator.is_implicit() {
            true => Some(implicit::ImplicitSolver::new(
                &ctx,
                config.solver,
                &params,
                &state,
                layout.kind(),
                solve_model,
                accumulation != Accumulation::Gather,
            )?),
            false => None,
        };
        let corot_blocks = match (&corot, config.integrator.is_implicit()) {
            (Some(c), true) => Some(corotational_implicit::CorotationalBlocks::new(
                &ctx, c, &layout,
            )?),
            _ => None,
        };
        let mut engine = GpuEngine {
            implicit,
            rescale,
            timer,
            surface_sync: SurfaceSync::Current,
            surface: None,
            mover,
            staging: upload::StagingPool::default(),
            near_ahead: None,
            near_reads: NearReads::default(),
            last_submission: None,
            render: None,
            host: host_buffers::HostBuffers::default(),
            patches: 0,
            tensor,
            corot,
            corot_blocks,
            ctx,
            config,
            layout,
            accumulation,
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
        };
        engine.rebind_implicit()?;
        Ok(engine)
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
    /// layout index), for comparing with its twin [`crate::twin::health::health_cpu`].
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

    /// The layout and accumulation this engine runs (what it was built with).
    pub fn options(&self) -> GpuOptions {
        GpuOptions {
            layout: self.layout.kind(),
            accumulation: self.accumulation,
        }
    }

    /// `"gpu-connectivity on <adapter>"`; the edge layout with atomics names its variant
    /// ("gpu-edges-atomicfixed on ...").
    pub fn describe(&self) -> String {
        let variant = match (&self.passes, self.accumulation) {
            (Passes::AtomicEdges(..), a) => format!("-{a:?}").to_lowercase(),
            _ => String::new(),
        };
        format!(
            "gpu-{}{variant} on {}",
            format!("{:?}", self.layout.kind()).to_lowercase(),
            self.ctx.describe()
        )
    }

    /// The tensor-mass model and its passes, when the engine runs that force model.
    pub fn tensor_mass(&self) -> Option<&tensor_mass::TensorMassPasses> {
        self.tensor.as_ref()
    }

    /// The corotational model and its passes, when the engine runs that force model.
    pub fn corotational(&self) -> Option<&corotational::CorotationalPasses> {
        self.corot.as_ref()
    }

    /// The corotational block pass, when the engine runs that force model under backward
    /// Euler.
    pub fn corotational_blocks(&self) -> Option<&corotational_implicit::CorotationalBlocks> {
        self.corot_blocks.as_ref()
    }

    /// The blocks the corotational implicit solve read at the last step (`R K R^T` per slot,
    /// layout order), read back; `None` for every other engine.
    pub fn corotational_block_values(
        &self,
    ) -> Result<Option<crate::layout::tensor_blocks::TensorBlocks>> {
        self.corot_blocks
            .as_ref()
            .map(|b| b.read_blocks(&self.ctx))
            .transpose()
    }

    /// The device's per-tet rotations of a corotational engine (unit quaternions, in the
    /// model's tet order); empty for every other force model.
    pub fn tet_rotations(&self) -> Result<Vec<[f32; 4]>> {
        self.corot
            .as_ref()
            .map_or(Ok(Vec::new()), |c| c.rotations(&self.ctx))
    }

    /// Whether a spring force has saturated the fixed-point accumulators (edge layout with
    /// [`Accumulation::AtomicFixed`]) since setup; false for every other layout and variant.
    pub fn fixed_point_overflowed(&self) -> Result<bool> {
        match &self.passes {
            Passes::AtomicEdges(p) => p.overflowed(&self.ctx),
            _ => Ok(false),
        }
    }
}

/// The tensor-mass passes where `config` asks for that force model (the implicit solve reads
/// their blocks too); `None` for the other force models.
fn tensor_passes(
    ctx: &GpuContext,
    model: &PackedModel,
    config: SimConfig,
    layout: &PackedLayout,
    passes: &Passes,
    uniform: &wgpu::Buffer,
    state: &StateBuffers,
) -> Result<Option<tensor_mass::TensorMassPasses>> {
    use crate::physics::ForceModelKind;
    match config.force_model {
        ForceModelKind::Springs | ForceModelKind::Corotational => Ok(None),
        ForceModelKind::TensorMass => Ok(Some(tensor_mass::TensorMassPasses::new(
            ctx, model, layout, passes, uniform, state,
        )?)),
    }
}

/// The corotational passes where `config` asks for that force model (any layout: the element
/// path is the same for all; under backward Euler its tet pass runs before the block pass and
/// the solve); `None` for the others.
fn corotational_passes(
    ctx: &GpuContext,
    model: &PackedModel,
    config: SimConfig,
    layout: &PackedLayout,
    passes: &Passes,
    uniform: &wgpu::Buffer,
    state: &StateBuffers,
) -> Result<Option<corotational::CorotationalPasses>> {
    if config.force_model != crate::physics::ForceModelKind::Corotational {
        return Ok(None);
    }
    Ok(Some(corotational::CorotationalPasses::new(
        ctx, model, layout, passes, uniform, state,
    )?))
}

/// The divergence probe over the inverse masses of `passes` and `state`.
fn health_pass(
    ctx: &GpuContext,
    passes: &Passes,
    uniform: &wgpu::Buffer,
    state: &StateBuffers,
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
fn layout_memory(
    layout: &PackedLayout,
    config: SimConfig,
    accumulation: Accumulation,
) -> EngineMemory {
    let (stats, bytes_per_step) = match layout {
        PackedLayout::Connectivity(c) => c.memory(config.integrator),
        PackedLayout::Valence(v) => v.memory(config.integrator),
        PackedLayout::Edges(e) => e.memory(config.integrator, accumulation),
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
    accumulation: Accumulation,
    uniform: &wgpu::Buffer,
    state: &StateBuffers,
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
        PackedLayout::Edges(e) => match accumulation {
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
