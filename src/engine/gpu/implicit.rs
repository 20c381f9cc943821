//! Linearised backward Euler on the device: pairs with `shaders/implicit_solve.wgsl`, twin
//! [`crate::twin::implicit_solve`]. A step records the right-hand side and preconditioner
//! pass, then conjugate-gradient iterations in batches of [`ITERATIONS_PER_SUBMISSION`], each
//! batch ending with the pass that writes the next state once the solve has ended; after each
//! batch only the 32-byte scalar block (status, iterations, residual) is read back. The
//! iteration count is the shader's own, exact, not rounded to the batch size.
//!
//! The product gathers over the connectivity table or the valence buckets (the layout's
//! `row_of` joined to the shader), or, on the edge layout, runs as the edge layout's gather
//! variant: a pass over the springs stores each spring's block product, a pass over the nodes
//! gathers them in incidence order (`shaders/implicit_edges.wgsl`). The edge layout's
//! float-atomic variant, which has no incidence table, runs the springs' solve with a record
//! pass that adds each spring's setup terms to its ends before `setup`, and a product that
//! adds each record's block product to its ends (`shaders/implicit_atomic.wgsl`, twin
//! [`crate::twin::implicit_atomic`]; the sums' rounding follows the order of the adds); the
//! finite elements' solve there adds each record's tensor terms per end
//! (`implicit_atomic.rs`). The fixed-point variant is refused (the products shrink by
//! orders of magnitude within a solve, below any one scale).
//!
//! With the tensor-mass force model the system's stiffness and damping are the constant 3x3
//! blocks of [`super::tensor_mass::TensorMassPasses`] (bound as group 1), read where the
//! springs' solve computes each spring's Jacobian block from its geometry
//! (`shaders/implicit_tensor.wgsl`); the conjugate gradients and the block-Jacobi
//! preconditioner are the same passes. Twin: [`crate::twin::implicit_tensor`].
//!
//! With the corotational force model the solve is the tensor-mass one on blocks the
//! corotational block pass writes each step (`R K R^T` per slot,
//! [`super::corotational_implicit`]), bound in group 1 with the tet table's node rows, records
//! and corner forces: the setup's force is those corner forces gathered
//! (`shaders/implicit_corotational.wgsl`), the rest unchanged. The engine records the tet and
//! block passes before the setup (`ImplicitSolver::step`'s prelude). Twin:
//! [`crate::twin::corotational_implicit`].

use bytemuck::{Pod, Zeroable};

use super::buffers;
use super::{GpuContext, StateBuffers};
use crate::error::{Error, Result};
use crate::layout::LayoutKind;
use crate::physics::{Linearization, SolverSettings, SolverStats, StepParams};
use crate::twin::implicit_solve::{status, Scalars, SolveParams, SolveVectors};

/// Conjugate-gradient iterations recorded per submission between reads of the status word.
pub const ITERATIONS_PER_SUBMISSION: u32 = 16;

/// The springs' solve over the connectivity table (WGSL has no includes: the parts are
/// joined).
const CONNECTIVITY: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/implicit_solve.wgsl"),
    include_str!("../../../shaders/implicit_spring_block.wgsl"),
    include_str!("../../../shaders/implicit_springs.wgsl"),
    include_str!("../../../shaders/implicit_slots.wgsl"),
    include_str!("../../../shaders/implicit_slots_springs.wgsl"),
    include_str!("../../../shaders/implicit_connectivity.wgsl")
);

/// The springs' solve over the valence buckets.
const VALENCE: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/implicit_solve.wgsl"),
    include_str!("../../../shaders/implicit_spring_block.wgsl"),
    include_str!("../../../shaders/implicit_springs.wgsl"),
    include_str!("../../../shaders/implicit_slots.wgsl"),
    include_str!("../../../shaders/implicit_slots_springs.wgsl"),
    include_str!("../../../shaders/valence_buckets.wgsl"),
    include_str!("../../../shaders/implicit_valence.wgsl")
);

/// The springs' solve over the edge layout's springs and incidence table.
const EDGES: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/implicit_solve.wgsl"),
    include_str!("../../../shaders/implicit_spring_block.wgsl"),
    include_str!("../../../shaders/implicit_springs.wgsl"),
    include_str!("../../../shaders/implicit_edges.wgsl")
);

/// The tensor-mass solve over the connectivity table.
const TENSOR_CONNECTIVITY: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/implicit_solve.wgsl"),
    include_str!("../../../shaders/implicit_tensor.wgsl"),
    include_str!("../../../shaders/implicit_tensor_force.wgsl"),
    include_str!("../../../shaders/implicit_slots.wgsl"),
    include_str!("../../../shaders/implicit_slots_tensor.wgsl"),
    include_str!("../../../shaders/implicit_connectivity.wgsl")
);

/// The tensor-mass solve over the valence buckets.
const TENSOR_VALENCE: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/implicit_solve.wgsl"),
    include_str!("../../../shaders/implicit_tensor.wgsl"),
    include_str!("../../../shaders/implicit_tensor_force.wgsl"),
    include_str!("../../../shaders/implicit_slots.wgsl"),
    include_str!("../../../shaders/implicit_slots_tensor.wgsl"),
    include_str!("../../../shaders/valence_buckets.wgsl"),
    include_str!("../../../shaders/implicit_valence.wgsl")
);

/// The tensor-mass solve over the edge layout's records and incidence table.
const TENSOR_EDGES: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/implicit_solve.wgsl"),
    include_str!("../../../shaders/implicit_tensor.wgsl"),
    include_str!("../../../shaders/implicit_tensor_force.wgsl"),
    include_str!("../../../shaders/implicit_tensor_edges.wgsl")
);

/// The corotational solve over the connectivity table: the tensor-mass solve on the blocks the
/// corotational block pass writes each step, its force the tet pass's corner forces.
const COROTATIONAL_CONNECTIVITY: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/implicit_solve.wgsl"),
    include_str!("../../../shaders/implicit_tensor.wgsl"),
    include_str!("../../../shaders/implicit_corotational.wgsl"),
    include_str!("../../../shaders/implicit_slots.wgsl"),
    include_str!("../../../shaders/implicit_slots_tensor.wgsl"),
    include_str!("../../../shaders/implicit_connectivity.wgsl")
);

/// The corotational solve over the valence buckets.
const COROTATIONAL_VALENCE: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/implicit_solve.wgsl"),
    include_str!("../../../shaders/implicit_tensor.wgsl"),
    include_str!("../../../shaders/implicit_corotational.wgsl"),
    include_str!("../../../shaders/implicit_slots.wgsl"),
    include_str!("../../../shaders/implicit_slots_tensor.wgsl"),
    include_str!("../../../shaders/valence_buckets.wgsl"),
    include_str!("../../../shaders/implicit_valence.wgsl")
);

/// The corotational solve over the edge layout's records and incidence table.
const COROTATIONAL_EDGES: &str = concat!(
    include_str!("../../../shaders/common.wgsl"),
    include_str!("../../../shaders/implicit_solve.wgsl"),
    include_str!("../../../shaders/implicit_tensor.wgsl"),
    include_str!("../../../shaders/implicit_corotational.wgsl"),
    include_str!("../../../shaders/implicit_tensor_edges.wgsl")
);

/// What the solve's stiffness and force are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolveModel {
    /// Each spring's Jacobian block from its geometry.
    Springs,
    /// The constant tensor-mass blocks (group 1).
    TensorMass,
    /// The corotational blocks of the step (group 1, with the tet table's node rows, records
    /// and corner forces, whose sum is the force).
    Corotational,
}

impl SolveModel {
    /// Storage buffers the model binds in group 1.
    fn group_one(self) -> u32 {
        match self {
            SolveModel::Springs => 0,
            SolveModel::TensorMass => 1,
            SolveModel::Corotational => 4,
        }
    }
}

/// Float accumulators per node slot of the atomic variant (`shaders/implicit_atomic.wgsl`).
const ATOMIC_TERMS: u64 = 16;

/// The solver vectors held in one buffer, in this order (see the shader).
const VECTORS: u64 = 7;

/// Bytes of the scalar block before the partial sums.
const SCALARS: u64 = std::mem::size_of::<Scalars>() as u64;

/// The solve's constants; mirrors `struct Solve` in `shaders/implicit_solve.wgsl` (64 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct SolveUniform {
    gravity: [f32; 3],
    h: f32,
    alpha: f32,
    tolerance: f32,
    n: u32,
    width: u32,
    row: u32,
    damped: u32,
    definite: u32,
    max_iterations: u32,
    groups: u32,
    stride: u32,
    springs: u32,
    pad: u32,
}

const _: () = assert!(std::mem::size_of::<SolveUniform>() == 64);
const _: () = assert!(std::mem::size_of::<Scalars>() == 32);

/// One pass of the solve, to run alone (`GpuEngine::run_solve_pass`) in the device tests.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolvePass {
    /// The edge layout's atomic variant: each spring's setup terms added to its ends.
    SetupRecords,
    /// Right-hand side, preconditioner, first residual and direction.
    Setup,
    /// `|b|`, the first `r . z`, the status.
    Start,
    /// The edge layout's spring pass of `A p`: each spring's block product.
    SpringMultiply,
    /// `A p` (on the edge layout, gathered from [`SolvePass::SpringMultiply`]).
    Multiply,
    /// `rz / pap`.
    StepLength,
    /// `y`, `r`, `z`.
    Update,
    /// Relative residual, convergence, `beta`.
    Residual,
    /// `p = z + beta p`.
    Direction,
    /// The next state, once the solve has ended.
    Finish,
}

impl SolvePass {
    const ALL: [SolvePass; 10] = [
        SolvePass::SetupRecords,
        SolvePass::Setup,
        SolvePass::Start,
        SolvePass::SpringMultiply,
        SolvePass::Multiply,
        SolvePass::StepLength,
        SolvePass::Update,
        SolvePass::Residual,
        SolvePass::Direction,
        SolvePass::Finish,
    ];

    fn entry(self) -> &'static str {
        match self {
            SolvePass::SetupRecords => "setup_records",
            SolvePass::Setup => "setup",
            SolvePass::Start => "start",
            SolvePass::SpringMultiply => "spring_multiply",
            SolvePass::Multiply => "multiply",
            SolvePass::StepLength => "step_length",
            SolvePass::Update => "update",
            SolvePass::Residual => "residual",
            SolvePass::Direction => "direction",
            SolvePass::Finish => "finish",
        }
    }

    /// Whether the pass runs over the nodes (else over the springs, or in one workgroup).
    fn over_nodes(self) -> bool {
        !matches!(
            self,
            SolvePass::Start
                | SolvePass::StepLength
                | SolvePass::Residual
                | SolvePass::SpringMultiply
                | SolvePass::SetupRecords
        )
    }
}

/// The device side of the implicit step: pipelines, solver buffers, bind groups per phase of
/// the state rotation, and the statistics of the solves so far.
pub struct ImplicitSolver {
    settings: SolverSettings,
    uniform_data: SolveUniform,
    uniform: wgpu::Buffer,
    layout: wgpu::BindGroupLayout,
    /// One per [`SolvePass::ALL`]; `None` for the spring pass of a node-centric layout.
    pipelines: Vec<Option<wgpu::ComputePipeline>>,
    /// Whether the product runs as the edge layout's spring and node passes.
    edges: bool,
    /// Whether these are the float-atomic variant's passes (`spring_values` then holds
    /// [`ATOMIC_TERMS`] accumulators per node slot).
    atomic: bool,
    /// The edge layout's per-spring block products (a placeholder on the other layouts).
    spring_values: wgpu::Buffer,
    /// The workgroups of a dispatch over the spring records (edge layout).
    spring_groups: (u32, u32),
    /// The tensor-mass blocks' layout (group 1) and its bind group once bound; `None` for
    /// springs. Its bindings: the blocks, then the corotational solve's tet rows, records and
    /// corner forces.
    blocks_layout: Option<wgpu::BindGroupLayout>,
    blocks_group: Option<wgpu::BindGroup>,
    vectors: wgpu::Buffer,
    reduce: wgpu::Buffer,
    staging: wgpu::Buffer,
    bind_groups: Vec<wgpu::BindGroup>,
    stats: SolverStats,
}

/// Workgroups of a node dispatch over `groups` (x, y).
fn group_count(groups: (u32, u32)) -> u32 {
    groups.0 * groups.1
}

impl ImplicitSolver {
    /// The pipelines and buffers of a solve with `settings` at step constants `p`, on the
    /// springs' Jacobian or on the blocks of `model`.
    pub(super) fn new(
        ctx: &GpuContext,
        settings: SolverSettings,
        p: &StepParams,
        state: &StateBuffers,
        kind: LayoutKind,
        model: SolveModel,
        atomic: bool,
    ) -> Result<Self> {
        if settings.newton_iterations > 1 {
            return Err(Error::Unsupported(format!(
                "the GPU engine solves one Newton iteration per step (Baraff and Witkin's \
                 linearised step); newton_iterations: {} runs on the reference engine",
                settings.newton_iterations
            )));
        }
        let uniform_data = SolveUniform {
            gravity: p.gravity,
            h: p.h,
            alpha: p.alpha,
            tolerance: settings.tolerance as f32,
            n: 0,
            width: 0,
            row: 0,
            damped: p.damped as u32,
            definite: (settings.linearization == Linearization::Definite) as u32,
            max_iterations: settings.max_iterations,
            groups: 0,
            stride: 0,
            springs: 0,
            pad: 0,
        };
        let uniform = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("solve constants"),
            size: std::mem::size_of::<SolveUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // slots, masses, velocities, displacements (read); next displacements, next velocities,
        // solver vectors, scalars and partials (written); the valence layout's bucket table.
        let mut bindings = vec![true, true, true, true, false, false, false, false];
        let (connectivity, valence, edges) = match model {
            SolveModel::Springs => (CONNECTIVITY, VALENCE, EDGES),
            SolveModel::TensorMass => (TENSOR_CONNECTIVITY, TENSOR_VALENCE, TENSOR_EDGES),
            SolveModel::Corotational => (
                COROTATIONAL_CONNECTIVITY,
                COROTATIONAL_VALENCE,
                COROTATIONAL_EDGES,
            ),
        };
        let source = match kind {
            LayoutKind::Connectivity => connectivity,
            LayoutKind::Valence => {
                bindings.push(true);
                valence
            }
            LayoutKind::Edges if atomic => {
                // The accumulators (written).
                bindings.push(false);
                super::implicit_atomic::source(model)
            }
            LayoutKind::Edges => {
                // Incidence rows and entries (read), the spring values (written).
                bindings.extend([true, true, false]);
                edges
            }
        };
        // The blocks (and the corotational tet table's buffers) are more, in group 1.
        let count = bindings.len() as u32 + model.group_one();
        let most = ctx.limits.max_storage_buffers_per_shader_stage;
        if count > 8 && most < count {
            return Err(Error::Unsupported(format!(
                "the implicit step over the {kind:?} layout binds {count} storage buffers, {} \
                 allows {most}: use --layout connectivity",
                ctx.info.name
            )));
        }
        let edges = kind == LayoutKind::Edges;
        let layout = buffers::pass_layout(ctx, "implicit solve", &bindings);
        let blocks_layout = (model != SolveModel::Springs).then(|| {
            let entries: Vec<_> = (0..model.group_one())
                .map(|b| buffers::storage_entry(b, true))
                .collect();
            ctx.device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("implicit tensor blocks"),
                    entries: &entries,
                })
        });
        let groups: Vec<&wgpu::BindGroupLayout> =
            std::iter::once(&layout).chain(&blocks_layout).collect();
        let pipelines = SolvePass::ALL
            .iter()
            .map(|pass| {
                if (*pass == SolvePass::SpringMultiply && !edges)
                    || (*pass == SolvePass::SetupRecords && !atomic)
                {
                    return Ok(None);
                }
                buffers::compute_pipeline_at(ctx, pass.entry(), source, pass.entry(), &groups)
                    .map(Some)
            })
            .collect::<Result<Vec<_>>>()?;
        let spring_values =
            buffers::zeroed_storage(ctx, "solver spring values", 16, buffers::Sizing::Exact)?;
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("solve status"),
            size: SCALARS,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let (vectors, reduce) = Self::solver_buffers(ctx, state.capacity())?;
        Ok(ImplicitSolver {
            settings,
            uniform_data,
            uniform,
            layout,
            pipelines,
            edges,
            atomic,
            spring_values,
            spring_groups: (0, 0),
            blocks_layout,
            blocks_group: None,
            vectors,
            reduce,
            staging,
            bind_groups: Vec::new(),
            stats: SolverStats::default(),
        })
    }

    /// The vector buffer and the reduction buffer for `capacity` node slots.
    fn solver_buffers(ctx: &GpuContext, capacity: usize) -> Result<(wgpu::Buffer, wgpu::Buffer)> {
        let cap = capacity.max(1) as u64;
        let vectors = buffers::zeroed_storage(
            ctx,
            "solver vectors",
            VECTORS * cap * 16,
            buffers::Sizing::Exact,
        )?;
        // Every workgroup of a node dispatch writes one pair; the dispatch may fold into rows
        // whose last holds up to a row of idle workgroups.
        let (x, y) = super::dispatch_size(ctx, cap as u32);
        let groups = (x * y) as u64 + x as u64;
        let reduce = buffers::zeroed_storage(
            ctx,
            "solver scalars",
            SCALARS + 8 * groups,
            buffers::Sizing::Exact,
        )?;
        Ok((vectors, reduce))
    }

    /// Bind the layout's slot (or edge spring) and mass buffers, its further tables (the
    /// valence buckets; the edge layout's incidence rows and entries), the group 1 buffers
    /// (the blocks, and for the corotational solve the tet rows, records and corner forces;
    /// empty for springs) and the node state (again after a patch, which may have
    /// replaced any of them), with the dispatch sizes and connectivity width of now; the solver
    /// buffers grow with the state and the springs.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn rebind(
        &mut self,
        ctx: &GpuContext,
        slots: &wgpu::Buffer,
        inv_mass: &wgpu::Buffer,
        tables: &[&wgpu::Buffer],
        blocks: &[&wgpu::Buffer],
        state: &StateBuffers,
        n: u32,
        width: u32,
        row: u32,
        groups: (u32, u32),
        springs: (u32, (u32, u32)),
    ) -> Result<()> {
        let capacity = state.capacity();
        if self.vectors.size() < VECTORS * capacity as u64 * 16 {
            (self.vectors, self.reduce) = Self::solver_buffers(ctx, capacity)?;
        }
        // Room for every spring record the layout's buffer holds, so that most patches keep it:
        // one value per record, two for the tensor-mass blocks (a tensor's ends differ).
        let per_record = if self.blocks_layout.is_some() { 32 } else { 16 };
        let want = match self.atomic {
            true => capacity.max(1) as u64 * ATOMIC_TERMS * 4,
            false => (slots.size() / 32).max(1) * per_record,
        };
        if self.edges && self.spring_values.size() < want {
            self.spring_values =
                buffers::zeroed_storage(ctx, "solver spring values", want, buffers::Sizing::Exact)?;
        }
        self.blocks_group = match &self.blocks_layout {
            Some(_) if blocks.is_empty() => {
                return Err(Error::Gpu(
                    "the implicit solve on blocks was given no blocks to bind".into(),
                ));
            }
            Some(layout) => Some(ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("implicit tensor blocks"),
                layout,
                entries: &buffers::entries(blocks),
            })),
            None => None,
        };
        self.spring_groups = springs.1;
        let u = &mut self.uniform_data;
        (u.n, u.width, u.row) = (n, width, row);
        u.groups = group_count(groups);
        u.stride = capacity as u32;
        u.springs = springs.0;
        self.write_uniform(ctx);
        self.bind_groups = (0..state.phases())
            .map(|phase| {
                let b = state.bindings(phase);
                let mut bound = vec![
                    &self.uniform,
                    slots,
                    inv_mass,
                    b.second_in,
                    b.cur,
                    b.next,
                    b.second_out,
                    &self.vectors,
                    &self.reduce,
                ];
                bound.extend(tables);
                if self.edges {
                    bound.push(&self.spring_values);
                }
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("implicit solve"),
                    layout: &self.layout,
                    entries: &buffers::entries(&bound),
                })
            })
            .collect();
        Ok(())
    }

    fn write_uniform(&self, ctx: &GpuContext) {
        ctx.queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&self.uniform_data));
    }

    /// A new time step (the next step's system is built with it).
    pub(super) fn set_time_step(&mut self, ctx: &GpuContext, h: f32) {
        self.uniform_data.h = h;
        self.write_uniform(ctx);
    }

    /// Springs with damping turn the damping terms on.
    pub(super) fn set_damped(&mut self, ctx: &GpuContext, damped: bool) {
        self.uniform_data.damped = damped as u32;
        self.write_uniform(ctx);
    }

    /// What the solves did so far.
    pub fn stats(&self) -> SolverStats {
        self.stats
    }

    /// The constants as the twin takes them.
    pub fn params(&self) -> SolveParams {
        let u = &self.uniform_data;
        SolveParams {
            h: u.h,
            alpha: u.alpha,
            gravity: u.gravity,
            tolerance: u.tolerance,
            max_iterations: u.max_iterations,
            damped: u.damped != 0,
            definite: u.definite != 0,
        }
    }

    fn record(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        which: SolvePass,
        phase: usize,
        groups: (u32, u32),
    ) {
        let index = SolvePass::ALL.iter().position(|&p| p == which).unwrap_or(0);
        // Only the spring pass of a node-centric layout has no pipeline: nothing to run.
        let Some(pipeline) = &self.pipelines[index] else {
            return;
        };
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.bind_groups[phase], &[]);
        if let Some(blocks) = &self.blocks_group {
            pass.set_bind_group(1, blocks, &[]);
        }
        let g = match which {
            SolvePass::SpringMultiply | SolvePass::SetupRecords => self.spring_groups,
            w if w.over_nodes() => groups,
            _ => (1, 1),
        };
        pass.dispatch_workgroups(g.0, g.1, 1);
    }

    /// Run one pass alone in `phase` over `groups` node workgroups and wait for it.
    pub(super) fn run_pass(
        &self,
        ctx: &GpuContext,
        which: SolvePass,
        phase: usize,
        groups: (u32, u32),
    ) -> Result<()> {
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("solve pass"),
            });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(which.entry()),
                timestamp_writes: None,
            });
            self.record(&mut pass, which, phase, groups);
        }
        enc.copy_buffer_to_buffer(&self.reduce, 0, &self.staging, 0, SCALARS);
        buffers::submit_and_read(ctx, enc, &self.staging, SCALARS)?;
        Ok(())
    }

    /// One implicit step in `phase`: the solve in batches until the device says it has ended,
    /// the next state written into the phase's output buffers. `prelude` records what the
    /// setup reads that changes every step (the corotational tet and block passes) at the
    /// start of the first batch. Returns the final scalars.
    pub(super) fn step(
        &mut self,
        ctx: &GpuContext,
        phase: usize,
        groups: (u32, u32),
        prelude: &dyn Fn(&mut wgpu::ComputePass<'_>),
    ) -> Result<Scalars> {
        let max = self.uniform_data.max_iterations;
        // The cap ends the solve on the device; the bound only guards against a status word
        // that never changes.
        let batches = max.div_ceil(ITERATIONS_PER_SUBMISSION) + 1;
        for batch in 0..batches {
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("implicit step"),
                });
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("implicit step"),
                    timestamp_writes: None,
                });
                if batch == 0 {
                    prelude(&mut pass);
                    self.record(&mut pass, SolvePass::SetupRecords, phase, groups);
                    self.record(&mut pass, SolvePass::Setup, phase, groups);
                    self.record(&mut pass, SolvePass::Start, phase, groups);
                }
                for _ in 0..ITERATIONS_PER_SUBMISSION.min(max) {
                    for which in [
                        SolvePass::SpringMultiply,
                        SolvePass::Multiply,
                        SolvePass::StepLength,
                        SolvePass::Update,
                        SolvePass::Residual,
                        SolvePass::Direction,
                    ] {
                        self.record(&mut pass, which, phase, groups);
                    }
                }
                self.record(&mut pass, SolvePass::Finish, phase, groups);
            }
            enc.copy_buffer_to_buffer(&self.reduce, 0, &self.staging, 0, SCALARS);
            let bytes = buffers::submit_and_read(ctx, enc, &self.staging, SCALARS)?;
            let s: Scalars = bytemuck::pod_read_unaligned(&bytes);
            if s.status != status::RUNNING {
                self.note(s);
                return Ok(s);
            }
        }
        Err(Error::Gpu(format!(
            "the implicit solve did not end within {max} iterations: the device's status word \
             never changed"
        )))
    }

    fn note(&mut self, s: Scalars) {
        let st = &mut self.stats;
        st.solves += 1;
        st.iterations += s.iterations as u64;
        st.max_iterations = st.max_iterations.max(s.iterations);
        st.last_residual = s.residual as f64;
        if s.residual as f64 > self.settings.tolerance {
            st.capped += 1;
        }
    }

    /// The solver vectors and scalars as the device holds them, `n` nodes.
    pub(super) fn read_vectors(&self, ctx: &GpuContext, n: usize) -> Result<SolveVectors> {
        let stride = self.uniform_data.stride as usize;
        let all = buffers::read_vec4(ctx, &self.vectors)?;
        let part = |k: usize| all[k * stride..k * stride + n].to_vec();
        let (a, b) = (part(5), part(6));
        let red = buffers::read_bytes(ctx, &self.reduce, self.reduce.size())?;
        let groups = self.uniform_data.groups as usize;
        let partials: Vec<[f32; 2]> = bytemuck::pod_collect_to_vec(&red[SCALARS as usize..]);
        Ok(SolveVectors {
            y: part(0),
            r: part(1),
            z: part(2),
            p: part(3),
            ap: part(4),
            minv: a.iter().zip(&b).map(|(a, b)| [*a, *b]).collect(),
            scalars: bytemuck::pod_read_unaligned(&red[..SCALARS as usize]),
            partials: partials[..groups].to_vec(),
        })
    }

    /// Overwrite the solver vectors and scalars (`v.partials` may be shorter than the
    /// dispatch's workgroups: the rest are zeroed).
    pub(super) fn write_vectors(&self, ctx: &GpuContext, v: &SolveVectors) {
        let stride = self.uniform_data.stride as u64;
        let parts = [&v.y, &v.r, &v.z, &v.p, &v.ap];
        for (k, part) in parts.iter().enumerate() {
            ctx.queue.write_buffer(
                &self.vectors,
                k as u64 * stride * 16,
                bytemuck::cast_slice(part),
            );
        }
        let a: Vec<[f32; 4]> = v.minv.iter().map(|m| m[0]).collect();
        let b: Vec<[f32; 4]> = v.minv.iter().map(|m| m[1]).collect();
        ctx.queue
            .write_buffer(&self.vectors, 5 * stride * 16, bytemuck::cast_slice(&a));
        ctx.queue
            .write_buffer(&self.vectors, 6 * stride * 16, bytemuck::cast_slice(&b));
        let mut red = bytemuck::bytes_of(&v.scalars).to_vec();
        let mut partials = v.partials.clone();
        partials.resize(self.uniform_data.groups as usize, [0.0; 2]);
        red.extend_from_slice(bytemuck::cast_slice(&partials));
        ctx.queue.write_buffer(&self.reduce, 0, &red);
    }
}
