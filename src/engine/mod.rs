//! Engines that step a [`PackedModel`], and the [`Simulation`] that drives one safely.
//!
//! An [`Engine`] only steps: it has no checks, so that its inner loop stays tight (and, on the
//! GPU, so that many steps go into one submission). [`Simulation`] owns an engine and
//! adds what a user must be able to rely on: a time step above the stable bound is refused,
//! and divergence (NaN, infinity, exploding energy) is caught within [`SimConfig::check_every`]
//! steps and reported with the step and node.

mod config;
pub mod fast;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod reading;
pub mod reference;
mod simulation;
mod surface_list;

use serde::{Deserialize, Serialize};

pub use crate::physics::{ForceModelKind, Integrator};
pub use config::{GpuOptions, NodeOrdering, SimConfig};
pub use simulation::{
    Energy, Simulation, ENERGY_GROWTH_LIMIT, EXACT_CHECK_EVERY, FLOAT32_NODE_FRACTION,
    INVERSION_CHECK_EVERY,
};

use crate::error::{Error, Result};
use crate::model::{ModelDiff, PackedModel, StabilityBound};

/// Which engine to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum EngineKind {
    /// Float64, serial, edge-by-edge: plainly correct, the reference for everything else.
    Reference,
    /// Float32, node-centric gather, nodes reordered for locality, multi-threaded.
    #[default]
    Fast,
    /// Float32 on a wgpu device, in the layout of [`GpuOptions::layout`].
    Gpu,
    /// The GPU engine when an adapter is found, else the fast CPU engine (and say so).
    Auto,
}

impl std::fmt::Display for EngineKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            EngineKind::Reference => "cpu-reference-f64",
            EngineKind::Fast => "cpu-fast-f32",
            EngineKind::Gpu => "gpu",
            EngineKind::Auto => "auto",
        })
    }
}

/// A stepping engine. Positions and velocities are in the packed model's node order.
pub trait Engine: Send {
    /// Advance `steps` steps without any check.
    fn step(&mut self, steps: u32);
    /// Current positions, m.
    fn positions(&self) -> Vec<[f64; 3]>;
    /// Current velocities, m/s (for Verlet, the backward difference the damping uses).
    fn velocities(&self) -> Vec<[f64; 3]>;
    /// Positions and velocities together (one readback for engines that must copy them back).
    fn state(&self) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        (self.positions(), self.velocities())
    }
    /// Replace the state (fixed nodes keep their rest position whatever is given).
    fn set_state(&mut self, positions: &[[f64; 3]], velocities: &[[f64; 3]]);
    /// Go on at the time step `dt` (s, finite and positive; [`Simulation::set_time_step`]
    /// checks it against the stable bound) from the same positions and velocities: the step
    /// parameters are written and nothing else is rebuilt or uploaded. Verlet keeps the
    /// previous positions, so its velocity `(x - x-) / h` is kept by moving them to
    /// `x - (x - x-) h' / h`; symplectic Euler keeps the velocity itself and its state does not
    /// change. The CPU engines continue exactly as an engine built at `dt` and given
    /// [`Engine::state`] would; the GPU engine rescales on the device in float32
    /// (`shaders/time_step.wgsl`). The cost counts the bytes of the step parameters written
    /// (on the GPU, the uniform uploaded).
    fn set_time_step(&mut self, dt: f64) -> Result<PatchCost>;
    /// The engine's name, with its device where it has one.
    fn name(&self) -> String;
    /// What the implicit integrator's solver did so far (`None` for an explicit scheme).
    fn solver_stats(&self) -> Option<crate::physics::SolverStats> {
        None
    }
    /// The bytes one iteration of the implicit integrator's solver must move at least (`None`
    /// for an explicit scheme, or where the engine does not count them): beside
    /// [`EngineMemory::bytes_per_step`], which counts an explicit step's.
    fn bytes_per_solver_iteration(&self) -> Option<u64> {
        None
    }
    /// Hold `constraints`' nodes on their tools' planes inside the implicit solve at the next
    /// steps ([`crate::physics::contact_constraint`]), replacing any set before; `false` (the
    /// default: the explicit schemes and the GPU engine) where the engine cannot, and contact
    /// must correct positions instead. Node indices are checked by the caller.
    fn set_contact_constraints(&mut self, constraints: &[crate::physics::NodeConstraint]) -> bool {
        let _ = constraints;
        false
    }
    /// The normal force each constraint put on its node in the last step, N (positive pushes
    /// along its normal), in the order they were set; empty where none was.
    fn contact_constraint_forces(&self) -> Vec<f64> {
        Vec::new()
    }
    /// The engine's arrays and the bytes one step must move at least (each array it reads or
    /// writes, once): the numerator of the memory-bandwidth floor.
    fn memory(&self) -> EngineMemory;
    /// Apply a change to the model in place, between steps (`model` is the model after
    /// `diff`), and say what it cost; `Ok(None)` where the engine cannot patch itself and must
    /// be rebuilt (the float64 reference engine, which [`Simulation::apply`] rebuilds with its
    /// state).
    fn patch(&mut self, model: &PackedModel, diff: &ModelDiff) -> Result<Option<PatchCost>> {
        let _ = (model, diff);
        Ok(None)
    }
    /// How the engine's structures, after patches, differ from `model` packed from scratch
    /// (on a device, its buffers included): empty where they agree, or where the engine has
    /// nothing patched to check (the reference engine is rebuilt at every change).
    fn differences_from_rebuild(&self, model: &PackedModel) -> Result<Vec<String>> {
        let _ = model;
        Ok(Vec::new())
    }
    /// Positions of the nodes `nodes` (model indices), m, reading back only those where the
    /// state lives on a device. Out-of-range indices are an error.
    fn node_positions(&self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        let x = self.positions();
        nodes
            .iter()
            .map(|&i| {
                x.get(i as usize)
                    .copied()
                    .ok_or_else(|| bad_node(i, x.len()))
            })
            .collect()
    }
    /// The nodes (model indices, ascending) whose current position lies in the box `lo..=hi`
    /// (m), with their positions exactly as [`Engine::positions`] gives them; a few just outside
    /// may come too. What a cut reads ([`crate::cut::Cutter::cut_from`]): engines whose state
    /// lives on a device find the nodes there and read back only those.
    fn nodes_near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Result<Vec<(u32, [f64; 3])>> {
        crate::engine::reading::PositionSource::near(
            &mut crate::engine::reading::AllPositions(&self.positions()),
            lo,
            hi,
        )
    }
    /// Find the nodes in the box `lo..=hi` (m) as the last pass of the next [`Engine::step`]
    /// and start reading them back with it, so that a [`Engine::nodes_near`] for a box inside
    /// this one, before the state changes again, needs no round trip of its own: the read
    /// came back with the step. The fast CPU engine scans for them on the step's threads
    /// after its last iteration; the reference engine ignores it.
    fn prefetch_near(&mut self, lo: [f64; 3], hi: [f64; 3]) {
        let _ = (lo, hi);
    }
    /// How this engine's reads of nodes near a blade were served.
    fn near_reads(&self) -> NearReads {
        NearReads::default()
    }
    /// Positions of the nodes `nodes` (model indices) at the start of the last step, m: where
    /// the step's motion began, after any correction made before it. Both integrators make the
    /// current position less `dt` times the velocity exactly that (Verlet's velocity is the
    /// backward difference from the start of the step; symplectic Euler moves by `dt` times
    /// its new velocity), which is the default; engines whose state lives on a device read
    /// back only those nodes.
    fn node_start_positions(&self, nodes: &[u32], dt: f64) -> Result<Vec<[f64; 3]>> {
        let (x, v) = self.state();
        nodes
            .iter()
            .map(|&i| {
                let (x, v) = (
                    x.get(i as usize).ok_or_else(|| bad_node(i, x.len()))?,
                    v[i as usize],
                );
                Ok([0, 1, 2].map(|c| x[c] - dt * v[c]))
            })
            .collect()
    }
    /// Velocities of the nodes `nodes` (model indices), m/s, as [`Engine::velocities`] gives
    /// them, reading back only those where the state lives on a device.
    fn node_velocities(&self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        let v = self.velocities();
        nodes
            .iter()
            .map(|&i| {
                v.get(i as usize)
                    .copied()
                    .ok_or_else(|| bad_node(i, v.len()))
            })
            .collect()
    }
    /// Move nodes to new positions between steps (contact response by position correction):
    /// the previous positions stay, so Verlet turns the move into velocity; symplectic Euler
    /// adds `move / dt` to the velocity. Fixed nodes do not move.
    fn correct_positions(&mut self, nodes: &[u32], positions: &[[f64; 3]]) -> Result<()>;
    /// What this engine can do because its state lives on a device (the GPU engine): waiting
    /// for the device, its timings, the surface it culls against, its divergence probe.
    /// `None` for the CPU engines, whose callers do the same work on the CPU.
    fn device(&self) -> Option<&dyn DeviceEngine> {
        None
    }
    /// A cheap divergence probe over the state where it lives (no copy of it, no spring pass):
    /// the GPU engine's reduced on the device, the fast CPU engine's one read of its own
    /// arrays. `None` where the engine has none; the simulation then checks the whole state
    /// exactly at every check.
    fn divergence_probe(&self) -> Option<Result<Health>> {
        self.device().map(|d| d.health())
    }
    /// [`Engine::device`], mutably.
    fn device_mut(&mut self) -> Option<&mut dyn DeviceEngine> {
        None
    }
    /// The GPU engine itself, for what only it has (the buffers a host draws from); `None`
    /// for the CPU engines.
    #[cfg(feature = "gpu")]
    fn gpu_mut(&mut self) -> Option<&mut gpu::GpuEngine> {
        None
    }
    /// The elastic energy of `model` at positions `x`, J, under the force model this engine
    /// steps: the springs' ([`PackedModel::elastic_energy`]) unless it runs another.
    fn elastic_energy(&self, model: &PackedModel, x: &[[f64; 3]]) -> f64 {
        model.elastic_energy(x)
    }
}

/// What an engine whose state lives on a device does besides stepping: reached through
/// [`Engine::device`] / [`Engine::device_mut`], so that a CPU engine implements none of it and
/// a caller asks once. [`Simulation`] does the same work on the CPU where an engine has no
/// device.
pub trait DeviceEngine: Send {
    /// Block until the steps submitted have run, and with them (a queue runs in order)
    /// whatever this engine submitted before them.
    fn wait(&mut self);
    /// Seconds the device itself spent on the last `step` call, measured with timestamp
    /// queries (after [`DeviceEngine::wait`]); `None` on devices without them.
    fn last_device_seconds(&self) -> Option<f64>;
    /// Take the tissue's boundary triangles (dense model indices) for
    /// [`DeviceEngine::cull_tools`] and [`DeviceEngine::cull_self`].
    fn set_surface(&mut self, triangles: &[[u32; 3]]) -> Result<()>;
    /// The surface after an edit: `triangles` is the whole new list, of which only the slots
    /// `changed` (and any appended) differ from the last list given; only those are written.
    fn edit_surface(&mut self, triangles: &[[u32; 3]], changed: &[u32]) -> Result<()>;
    /// Broad phase of the surface given to [`DeviceEngine::set_surface`] against tool boxes,
    /// on the device: (triangle, tool) pairs whose bounds overlap.
    fn cull_tools(
        &mut self,
        boxes: &[crate::collide::broad::ToolBox],
    ) -> Result<Vec<crate::collide::broad::Candidate>>;
    /// Broad phase of the surface given to [`DeviceEngine::set_surface`] against itself, on the
    /// device: pairs of surface triangles (t < u, sorted) sharing no node whose boxes, widened
    /// by `margin / 2` (m), overlap.
    #[cfg(feature = "collide")]
    fn cull_self(&mut self, margin: f64) -> Result<Vec<[u32; 2]>>;
    /// A cheap divergence probe reduced on the device (a few bytes read back instead of the
    /// state).
    fn health(&self) -> Result<Health>;
}

/// A divergence probe: the first non-finite node and the energies that need no spring data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Health {
    /// A node (model index) whose position or velocity is not finite, if any.
    pub non_finite: Option<usize>,
    /// Kinetic energy, J.
    pub kinetic: f64,
    /// Gravitational energy relative to the rest shape, J.
    pub gravity: f64,
}

/// The error for a node index past the model.
/// Append to the state `(x, v)` the nodes `diff` adds, where the engines start them: at rest
/// displaced as their source node is (mixed with its blend partner), with its velocity, or at
/// rest and still without a source. `rest` holds every node's rest position, the added ones
/// included (the model after the change).
pub(crate) fn grow_state(
    rest: &[[f64; 3]],
    x: &mut Vec<[f64; 3]>,
    v: &mut Vec<[f64; 3]>,
    diff: &crate::model::ModelDiff,
) {
    for a in &diff.added_nodes {
        let d = a.start_value(|i| {
            let i = i as usize;
            [0, 1, 2].map(|c| x[i][c] - rest[i][c])
        });
        let p = d.map_or(a.rest, |d| [0, 1, 2].map(|c| a.rest[c] + d[c]));
        let u = a.start_value(|i| v[i as usize]).unwrap_or([0.0; 3]);
        x.push(p);
        v.push(u);
    }
}

pub(crate) fn bad_node(i: u32, n: usize) -> Error {
    Error::NodeOutOfRange {
        node: i as u64,
        count: n,
        message: format!("node {i} does not exist: the model has {n} nodes"),
    }
}

/// Check a position correction's arguments.
pub(crate) fn check_correction(nodes: &[u32], positions: &[[f64; 3]], n: usize) -> Result<()> {
    if nodes.len() != positions.len() {
        return Err(Error::LengthMismatch {
            given: positions.len(),
            expected: nodes.len(),
            message: format!(
                "{} nodes but {} positions to correct them to",
                nodes.len(),
                positions.len()
            ),
        });
    }
    match nodes.iter().find(|&&i| i as usize >= n) {
        Some(&i) => Err(bad_node(i, n)),
        None => Ok(()),
    }
}

/// How an engine served [`Engine::nodes_near`]: from a read made ahead with the step before
/// it ([`Engine::prefetch_near`]), or by a read of its own (a round trip to the device).
/// The fast CPU engine counts its scans made with a step and on their own; the reference engine
/// counts neither.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct NearReads {
    /// Reads that came back with a step.
    pub ahead: u64,
    /// Reads that needed a round trip of their own.
    pub direct: u64,
}

/// What applying a model change cost an engine.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PatchCost {
    /// Bytes of layout data written to the device (all of it for a rebuilt engine); for the
    /// fast CPU engine, written into its arrays.
    pub uploaded_bytes: u64,
    /// Bytes copied on the device from buffers that outgrew their room into their larger
    /// successors: moved, not uploaded, so not in `uploaded_bytes`. For the fast CPU engine,
    /// the bytes its arrays' growth copied and those compaction slid over holes.
    pub copied_bytes: u64,
    /// Layout buffers replaced by larger ones while the passes kept their pipelines (for the
    /// fast CPU engine, arrays that grew into a new allocation).
    pub buffers_grown: usize,
    /// Bytes of layout data in all (a full upload would write this much).
    pub layout_bytes: u64,
    /// Node states moved or cleared.
    pub state_moves: usize,
    /// Whether the passes (or the engine) were rebuilt and the layout uploaded whole.
    pub reallocated: bool,
}

impl PatchCost {
    /// The cost of a change of the step parameters alone (a new time step): `uploaded` bytes of
    /// step parameters written (the engine's parameter block), no layout data, no state moved,
    /// nothing rebuilt.
    pub fn parameters_only(uploaded: u64, layout_bytes: u64) -> Self {
        PatchCost {
            uploaded_bytes: uploaded,
            copied_bytes: 0,
            buffers_grown: 0,
            layout_bytes,
            state_moves: 0,
            reallocated: false,
        }
    }
}

/// What an engine keeps in memory and moves per step.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EngineMemory {
    /// Arrays by name, total, padding, per node and per spring.
    pub stats: crate::layout::MemoryStats,
    /// Bytes read or written by one step, each array counted once.
    pub bytes_per_step: u64,
}
