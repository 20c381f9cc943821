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
pub mod buffers;
pub mod context;
pub mod node_gather;
pub mod springs_connectivity;
pub mod springs_edges;
pub mod springs_valence;
pub mod timing;

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

pub use context::GpuContext;

use super::{Engine, EngineMemory, Integrator, SimConfig};
use crate::error::Result;
use crate::layout::connectivity::{ConnectivityLayout, StepParams};
use crate::layout::edges::{Accumulation, EdgeLayout};
use crate::layout::valence::ValenceLayout;
use crate::layout::{LayoutKind, NodeOrder};
use crate::model::PackedModel;

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
    pad: [u32; 3],
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
    fn new(ctx: &GpuContext, n: usize, integrator: Integrator) -> Result<Self> {
        let bytes = (n.max(1) * 16) as u64;
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
    /// With the spring pass's workgroup counts.
    Edges(springs_edges::EdgePasses, (u32, u32)),
    /// Atomic accumulation, with the spring pass's workgroup counts.
    AtomicEdges(atomic_edges::AtomicEdgePasses, (u32, u32)),
}

/// Mass-spring engine on a wgpu device.
pub struct GpuEngine {
    ctx: GpuContext,
    layout: LayoutKind,
    accumulation: Accumulation,
    order: NodeOrder,
    rest: Vec<[f64; 3]>,
    fixed: Vec<bool>,
    dt: f64,
    state: NodeState,
    passes: Passes,
    _uniform: wgpu::Buffer,
    phase: usize,
    groups: (u32, u32),
    memory: EngineMemory,
    /// Device timing of the step pass, where the adapter has timestamp queries.
    timer: Option<timing::PassTimer>,
}

impl GpuEngine {
    /// Open the preferred adapter and upload `model` in `layout`.
    pub fn new(model: &PackedModel, config: SimConfig, layout: LayoutKind) -> Result<Self> {
        Self::with_context(GpuContext::new()?, model, config, layout)
    }

    /// Upload `model` in `layout` on an open device.
    pub fn with_context(
        ctx: GpuContext,
        model: &PackedModel,
        config: SimConfig,
        layout: LayoutKind,
    ) -> Result<Self> {
        let n = model.node_count();
        let locality = config.node_order.order(model);
        let m = model.springs.len() as u32;
        // One row width serves both the node and the spring dispatches.
        let groups = dispatch_size(&ctx, (n as u32).max(m));
        let row = groups.0 * WORKGROUP;
        let fold = |count: u32| {
            (
                count.div_ceil(WORKGROUP).clamp(1, groups.0),
                count.div_ceil(row).max(1),
            )
        };
        let params = step_params(model, config);
        // The packing decides the node order (valence regroups nodes) and the slot width.
        enum Packed {
            Connectivity(ConnectivityLayout),
            Valence(ValenceLayout),
            Edges(EdgeLayout),
        }
        let packed = match layout {
            LayoutKind::Connectivity => {
                Packed::Connectivity(ConnectivityLayout::new(model, locality, None)?)
            }
            LayoutKind::Valence => Packed::Valence(ValenceLayout::new(model, &locality)),
            LayoutKind::Edges => Packed::Edges(EdgeLayout::new(model, locality)),
        };
        let width = match &packed {
            Packed::Connectivity(c) => c.capacity,
            _ => 0,
        };
        let uniform_data = StepUniform {
            h: params.h,
            h2: params.h * params.h,
            inv_h: 1.0 / params.h,
            alpha: params.alpha,
            gravity: params.gravity,
            integrator: (config.integrator == Integrator::SymplecticEuler) as u32,
            n: n as u32,
            width,
            damped: params.damped as u32,
            row,
            springs: m,
            pad: [0; 3],
        };
        let uniform = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("step constants"),
                contents: bytemuck::bytes_of(&uniform_data),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let state = NodeState::new(&ctx, n, config.integrator)?;
        let (order, passes, (stats, bytes_per_step)) = match packed {
            Packed::Connectivity(c) => (
                c.order.clone(),
                Passes::Connectivity(springs_connectivity::ConnectivityPass::new(
                    &ctx, &c, &uniform, &state,
                )?),
                c.memory(config.integrator),
            ),
            Packed::Valence(v) => (
                v.order.clone(),
                Passes::Valence(springs_valence::ValencePass::new(
                    &ctx,
                    &v,
                    &uniform,
                    &state,
                    uniform_data.row,
                )?),
                v.memory(config.integrator, springs_valence::bucket_stride(&ctx)),
            ),
            Packed::Edges(e) => (
                e.order.clone(),
                match config.accumulation {
                    Accumulation::Gather => Passes::Edges(
                        springs_edges::EdgePasses::new(&ctx, &e, &uniform, &state)?,
                        fold(m),
                    ),
                    atomic => Passes::AtomicEdges(
                        atomic_edges::AtomicEdgePasses::new(
                            &ctx,
                            &e,
                            atomic,
                            e.fixed_point(model),
                            &uniform,
                            &state,
                        )?,
                        fold(m),
                    ),
                },
                e.memory(config.integrator, config.accumulation),
            ),
        };
        let timer = timing::PassTimer::new(&ctx);
        Ok(GpuEngine {
            timer,
            ctx,
            layout,
            accumulation: config.accumulation,
            order,
            rest: model.rest.clone(),
            fixed: model.fixed.clone(),
            dt: config.dt,
            state,
            passes,
            _uniform: uniform,
            phase: 0,
            groups: fold(n as u32),
            memory: EngineMemory {
                stats,
                bytes_per_step,
            },
        })
    }

    /// "gpu-connectivity on <adapter>"; the edge layout with atomics names its variant
    /// ("gpu-edges-atomicfixed on ...").
    pub fn describe(&self) -> String {
        let variant = match (&self.passes, self.accumulation) {
            (Passes::AtomicEdges(..), a) => format!("-{a:?}").to_lowercase(),
            _ => String::new(),
        };
        format!(
            "gpu-{}{variant} on {}",
            format!("{:?}", self.layout).to_lowercase(),
            self.ctx.describe()
        )
    }

    /// Whether a spring force has saturated the fixed-point accumulators (edge layout with
    /// [`Accumulation::AtomicFixed`]) since setup; false for every other layout and variant.
    pub fn fixed_point_overflowed(&self) -> Result<bool> {
        match &self.passes {
            Passes::AtomicEdges(p, _) => p.overflowed(&self.ctx),
            _ => Ok(false),
        }
    }

    /// Current displacements and second state (previous displacements or velocities), layout
    /// order.
    fn read_state(&self) -> Result<StatePair> {
        let b = self.state.bindings(self.phase);
        Ok((
            buffers::read_vec4(&self.ctx, b.cur)?,
            buffers::read_vec4(&self.ctx, b.second_in)?,
        ))
    }

    /// Model-order positions and velocities from the device state; NaN if the device failed,
    /// which the simulation's divergence check then reports.
    fn state_f64(&self) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let n = self.rest.len();
        let (cur, second) = match self.read_state() {
            Ok(s) => s,
            Err(e) => {
                eprintln!("lancet: reading the GPU state failed: {e}");
                return (vec![[f64::NAN; 3]; n], vec![[f64::NAN; 3]; n]);
            }
        };
        let mut x = vec![[0.0; 3]; n];
        let mut v = vec![[0.0; 3]; n];
        for (new, &old) in self.order.order.iter().enumerate() {
            let old = old as usize;
            for c in 0..3 {
                x[old][c] = self.rest[old][c] + cur[new][c] as f64;
                v[old][c] = match self.state.integrator {
                    Integrator::Verlet => (cur[new][c] as f64 - second[new][c] as f64) / self.dt,
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

/// Workgroup counts covering `n` invocations, folded into two dimensions when one would exceed
/// the device's limit per dimension.
fn dispatch_size(ctx: &GpuContext, n: u32) -> (u32, u32) {
    let groups = n.div_ceil(WORKGROUP).max(1);
    let max = ctx.limits.max_compute_workgroups_per_dimension.max(1);
    if groups <= max {
        (groups, 1)
    } else {
        (max, groups.div_ceil(max))
    }
}

/// The step constants of a model and configuration, in float32.
pub fn step_params(model: &PackedModel, config: SimConfig) -> StepParams {
    let g = model.gravity;
    StepParams {
        h: config.dt as f32,
        gravity: [g[0] as f32, g[1] as f32, g[2] as f32],
        alpha: model.mass_damping as f32,
        integrator: config.integrator,
        damped: model.springs.iter().any(|s| s.damping != 0.0),
    }
}

impl Engine for GpuEngine {
    fn step(&mut self, steps: u32) {
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
                match &self.passes {
                    Passes::Connectivity(p) => p.record(&mut pass, self.phase, self.groups),
                    Passes::Valence(p) => p.record(&mut pass, self.phase),
                    Passes::Edges(p, spring_groups) => {
                        p.record(&mut pass, self.phase, *spring_groups, self.groups)
                    }
                    Passes::AtomicEdges(p, spring_groups) => {
                        p.record(&mut pass, self.phase, *spring_groups, self.groups)
                    }
                }
                self.phase = (self.phase + 1) % self.state.phases();
            }
        }
        if let Some(t) = &self.timer {
            t.resolve(&mut enc);
        }
        self.ctx.queue.submit([enc.finish()]);
    }

    fn last_device_seconds(&self) -> Option<f64> {
        // A failed readback only loses the timing; the step itself is unaffected.
        self.timer.as_ref()?.last_seconds(&self.ctx).ok().flatten()
    }

    fn wait(&mut self) {
        let _ = self.ctx.device.poll(wgpu::PollType::wait_indefinitely());
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

    fn set_state(&mut self, positions: &[[f64; 3]], velocities: &[[f64; 3]]) {
        let n = self.rest.len();
        let mut cur = vec![[0.0f32; 4]; n];
        let mut second = vec![[0.0f32; 4]; n];
        for (new, &old) in self.order.order.iter().enumerate() {
            let old = old as usize;
            if self.fixed[old] {
                continue;
            }
            for c in 0..3 {
                let u = positions[old][c] - self.rest[old][c];
                cur[new][c] = u as f32;
                second[new][c] = match self.state.integrator {
                    Integrator::Verlet => (u - velocities[old][c] * self.dt) as f32,
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

    fn memory(&self) -> EngineMemory {
        self.memory.clone()
    }

    fn name(&self) -> String {
        self.describe()
    }
}
