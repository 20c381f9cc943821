//! Engines that step a [`PackedModel`], and the [`Simulation`] that drives one safely.
//!
//! An [`Engine`] only steps: it has no checks, so that its inner loop stays tight (and, for the
//! GPU later, so that many steps go into one submission). [`Simulation`] owns an engine and
//! adds what a user must be able to rely on: a time step above the stable bound is refused,
//! and divergence (NaN, infinity, exploding energy) is caught within [`SimConfig::check_every`]
//! steps and reported with the step and node.

pub mod fast;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod reference;
mod surface_list;

use std::collections::{HashMap, HashSet};
use surface_list::surface_key;

use serde::{Deserialize, Serialize};

pub use crate::physics::Integrator;

use crate::error::{Error, Result};
use crate::model::{stable_time_step, ModelDiff, PackedModel, StabilityBound};

/// Which engine to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum EngineKind {
    /// Float64, serial, edge-by-edge: plainly correct, the reference for everything else.
    Reference,
    /// Float32, node-centric gather, nodes reordered for locality, multi-threaded.
    #[default]
    Fast,
    /// Float32 on a wgpu device, in the layout of [`SimConfig::layout`].
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
    /// Block until the steps submitted have run, and with them (a queue runs in order)
    /// whatever this engine submitted before them (GPU engines; CPU engines finish in `step`).
    fn wait(&mut self) {}
    /// Seconds the device itself spent on the last `step` call, measured with timestamp
    /// queries (after [`Engine::wait`]); `None` for CPU engines and devices without them.
    fn last_device_seconds(&self) -> Option<f64> {
        None
    }
    /// The engine's name, with its device where it has one.
    fn name(&self) -> String;
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
        crate::cut::PositionSource::near(&mut crate::cut::AllPositions(&self.positions()), lo, hi)
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
    /// Take the tissue's boundary triangles (dense model indices) for [`Engine::cull_tools`].
    /// Engines that cull on the CPU need nothing and ignore it.
    fn set_surface(&mut self, triangles: &[[u32; 3]]) -> Result<()> {
        let _ = triangles;
        Ok(())
    }
    /// The surface after an edit: `triangles` is the whole new list, of which only the slots
    /// `changed` (and any appended) differ from the last list given. Engines that hold the
    /// surface write only those; the default gives the whole list to [`Engine::set_surface`].
    fn edit_surface(&mut self, triangles: &[[u32; 3]], changed: &[u32]) -> Result<()> {
        let _ = changed;
        self.set_surface(triangles)
    }
    /// Broad phase of the surface given to [`Engine::set_surface`] against tool boxes where
    /// the state lives (the GPU engine); `Ok(None)` where the caller should cull on the CPU.
    fn cull_tools(
        &mut self,
        boxes: &[crate::collide::broad::ToolBox],
    ) -> Result<Option<Vec<crate::collide::broad::Candidate>>> {
        let _ = boxes;
        Ok(None)
    }
    /// Broad phase of the surface given to [`Engine::set_surface`] against itself where the
    /// state lives (the GPU engine): pairs of surface triangles (t < u, sorted) sharing no node
    /// whose boxes, widened by `margin / 2` (m), overlap; `Ok(None)` where the caller should
    /// cull on the CPU.
    fn cull_self(&mut self, margin: f64) -> Result<Option<Vec<[u32; 2]>>> {
        let _ = margin;
        Ok(None)
    }
    /// A cheap divergence probe computed where the state lives (the GPU engine reduces it on
    /// the device and reads back a few bytes); `Ok(None)` where reading the state is as cheap.
    fn health(&self) -> Result<Option<Health>> {
        Ok(None)
    }
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
pub(crate) fn bad_node(i: u32, n: usize) -> Error {
    Error::Model(format!("node {i} does not exist: the model has {n} nodes"))
}

/// Check a position correction's arguments.
pub(crate) fn check_correction(nodes: &[u32], positions: &[[f64; 3]], n: usize) -> Result<()> {
    if nodes.len() != positions.len() {
        return Err(Error::Model(format!(
            "{} nodes but {} positions to correct them to",
            nodes.len(),
            positions.len()
        )));
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

/// How a simulation runs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SimConfig {
    /// Time step, s.
    pub dt: f64,
    /// Integration scheme.
    #[serde(default)]
    pub integrator: Integrator,
    /// Run even when `dt` is above the stable bound (divergence is still detected).
    #[serde(default)]
    pub allow_unstable: bool,
    /// Steps between divergence checks; divergence is reported at most this many steps after
    /// the energy crosses the limit.
    #[serde(default = "default_check_every")]
    pub check_every: u32,
    /// Spring layout of the GPU engine.
    #[serde(default)]
    pub layout: crate::layout::LayoutKind,
    /// How the edge layout brings spring forces to the nodes (default: the deterministic
    /// gather, the fastest on lavapipe); ignored by the other layouts.
    #[serde(default)]
    pub accumulation: crate::layout::edges::Accumulation,
    /// How the fast CPU engine and the GPU engine number the nodes when they pack the model
    /// (default: reverse Cuthill–McKee). Internal: results are the same physics in any order,
    /// only memory locality, hence speed, changes.
    #[serde(default)]
    pub node_order: NodeOrdering,
}

/// The node numbering an engine packs its arrays in.
///
/// Engines renumber nodes so that a node's neighbours sit close in memory; the other orders
/// exist to measure what that buys (`lancet bench --order`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum NodeOrdering {
    /// Reverse Cuthill–McKee order of the spring graph: neighbours get nearby indices.
    #[default]
    Locality,
    /// The model's own order (as the mesh file or generator numbered the nodes).
    Identity,
    /// A random permutation drawn from this seed (the same seed gives the same order): the
    /// worst case for locality.
    Random(u64),
}

impl NodeOrdering {
    /// The renumbering of `model`'s nodes this ordering gives.
    pub fn order(self, model: &PackedModel) -> crate::layout::NodeOrder {
        use crate::layout::NodeOrder;
        match self {
            NodeOrdering::Locality => NodeOrder::locality(model),
            NodeOrdering::Identity => NodeOrder::identity(model.node_count()),
            NodeOrdering::Random(seed) => {
                NodeOrder::from_order(random_permutation(model.node_count(), seed))
            }
        }
    }
}

impl std::fmt::Display for NodeOrdering {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NodeOrdering::Locality => f.write_str("rcm"),
            NodeOrdering::Identity => f.write_str("identity"),
            NodeOrdering::Random(seed) => write!(f, "random({seed})"),
        }
    }
}

/// A Fisher–Yates shuffle of `0..n` driven by SplitMix64: deterministic for a seed and
/// identical on every platform, with no dependency on a random-number crate.
fn random_permutation(n: usize, seed: u64) -> Vec<u32> {
    let mut state = seed;
    let mut next = move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let mut order: Vec<u32> = (0..n as u32).collect();
    for i in (1..n).rev() {
        // Modulo bias is below 2^-40 for any mesh that fits in memory: irrelevant here.
        let j = (next() % (i as u64 + 1)) as usize;
        order.swap(i, j);
    }
    order
}

fn default_check_every() -> u32 {
    10
}

impl SimConfig {
    /// Verlet at step `dt`, refusing unstable steps, checking every 10 steps.
    pub fn new(dt: f64) -> Self {
        SimConfig {
            dt,
            integrator: Integrator::Verlet,
            allow_unstable: false,
            check_every: default_check_every(),
            layout: crate::layout::LayoutKind::Connectivity,
            accumulation: crate::layout::edges::Accumulation::Gather,
            node_order: NodeOrdering::Locality,
        }
    }
}

/// Energies of a state, J.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Energy {
    /// Kinetic.
    pub kinetic: f64,
    /// Elastic (springs).
    pub elastic: f64,
    /// Gravitational, zero at rest positions.
    pub gravity: f64,
}

impl Energy {
    /// Sum of all parts.
    pub fn total(&self) -> f64 {
        self.kinetic + self.elastic + self.gravity
    }
}

/// The factor by which total energy may exceed its start (in units of the model's energy
/// scale) before the run is declared diverged. Energy can only fall in a stable run (gravity is
/// part of the total, damping removes energy), so any real growth is instability; the margin
/// absorbs the oscillation of the discrete energy near the bound.
pub const ENERGY_GROWTH_LIMIT: f64 = 100.0;

/// Steps between exact energy checks (a readback of the whole state) on engines with a cheap
/// divergence probe, while position corrections hold the reference above where it was taken:
/// the probe sees only kinetic and gravitational energy, so only an exact check brings the
/// reference back down to the energy left after damping.
pub const EXACT_CHECK_EVERY: u64 = 500;

type Made = (Box<dyn Engine>, EngineKind, Option<String>);

/// Build the engine of `kind`; `Auto` resolves to the GPU or, failing that, the fast CPU engine
/// with a note saying why.
fn make_engine(model: &PackedModel, kind: EngineKind, config: SimConfig) -> Result<Made> {
    Ok(match kind {
        EngineKind::Reference => (
            Box::new(reference::ReferenceEngine::new(model, config)),
            kind,
            None,
        ),
        EngineKind::Fast => (Box::new(fast::FastEngine::new(model, config)), kind, None),
        EngineKind::Gpu => (gpu_engine(model, config)?, kind, None),
        EngineKind::Auto => match gpu_engine(model, config) {
            Ok(e) => (e, EngineKind::Gpu, None),
            Err(e) => (
                Box::new(fast::FastEngine::new(model, config)),
                EngineKind::Fast,
                Some(format!("no usable GPU ({e}); running the fast CPU engine")),
            ),
        },
    })
}

#[cfg(feature = "gpu")]
fn gpu_engine(model: &PackedModel, config: SimConfig) -> Result<Box<dyn Engine>> {
    Ok(Box::new(gpu::GpuEngine::new(model, config, config.layout)?))
}

#[cfg(not(feature = "gpu"))]
fn gpu_engine(_: &PackedModel, _: SimConfig) -> Result<Box<dyn Engine>> {
    Err(Error::Unsupported(
        "this build has no GPU engine (enable the `gpu` cargo feature)".into(),
    ))
}

/// Below this fraction of the stable bound, float32 Verlet rounds away a measurable part of
/// each step's increment (see `verlet_precision_note`).
pub const VERLET_F32_FRACTION: f64 = 0.3;

/// Advice for float32 Verlet far below the stable bound. Verlet stores two positions, and the
/// step's increment `h^2 a` becomes a few float32 ulps of the displacement as `h` falls, so the
/// error grows as the step shrinks (measured on the default scene with `lancet report accuracy`:
/// relative error 4.6e-5 at the bound, 1.2e-3 at a quarter of it, 0.16 at a sixteenth).
/// Symplectic Euler follows the same trajectory in exact arithmetic (Verlet's
/// backward-difference velocity is its stored velocity) and keeps the velocity, so it does not
/// lose precision: 1.1e-5 at a sixteenth, as float64.
fn verlet_precision_note(kind: EngineKind, config: &SimConfig, bound: f64) -> Option<String> {
    let float32 = matches!(kind, EngineKind::Fast | EngineKind::Gpu);
    (float32 && config.integrator == Integrator::Verlet && config.dt < VERLET_F32_FRACTION * bound)
        .then(|| {
            format!(
                "float32 Verlet at {:.2} of the stable bound rounds away part of each step; \
                 SymplecticEuler follows the same trajectory without that loss",
                config.dt / bound
            )
        })
}

/// An engine with safety checks around it.
pub struct Simulation {
    engine: Box<dyn Engine>,
    model: PackedModel,
    config: SimConfig,
    kind: EngineKind,
    bound: StabilityBound,
    steps: u64,
    /// The boundary triangles for tool culling, once given.
    surface: Option<Vec<[u32; 3]>>,
    /// Where each surface triangle (by its sorted corners) sits in `surface`, built with it.
    surface_slots: Option<HashMap<[u32; 3], u32>>,
    /// Simulated time and step count when the time step last changed.
    time_at_dt_change: f64,
    steps_at_dt_change: u64,
    /// The divergence check's reference total energy, J.
    start_energy: f64,
    /// The energy scale the allowed growth is a multiple of, J.
    energy_scale: f64,
    /// The reference and scale as last taken from the state (before any correction's work).
    base_energy: f64,
    base_scale: f64,
    /// Steps since the total energy was last measured exactly.
    steps_since_exact: u64,
    /// The springs at each node, built at the first position correction.
    node_springs: Option<NodeSprings>,
    note: Option<String>,
    /// A box whose nodes the last step of the next run reads ahead ([`Simulation::prefetch_near`]).
    near_ahead: Option<([f64; 3], [f64; 3])>,
    /// How reads of nodes near a blade were served, over every engine this simulation had (a
    /// new time step rebuilds it).
    near_reads: NearReads,
}

/// The springs at each node (indices into the model's springs), packed.
struct NodeSprings {
    offsets: Vec<u32>,
    springs: Vec<u32>,
}

impl NodeSprings {
    fn of(model: &PackedModel) -> Self {
        let n = model.node_count();
        let mut offsets = vec![0u32; n + 1];
        for s in model.springs() {
            for i in s.nodes {
                offsets[i as usize + 1] += 1;
            }
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut springs = vec![0u32; offsets[n] as usize];
        for (k, s) in model.springs().iter().enumerate() {
            for i in s.nodes {
                springs[fill[i as usize] as usize] = k as u32;
                fill[i as usize] += 1;
            }
        }
        NodeSprings { offsets, springs }
    }

    fn of_node(&self, i: u32) -> &[u32] {
        let i = i as usize;
        &self.springs[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }
}

impl Simulation {
    /// Set up a run of `model` on engine `kind`. Fails if `dt` is not positive or is above the
    /// stable bound (unless `config.allow_unstable`).
    pub fn new(mut model: PackedModel, kind: EngineKind, config: SimConfig) -> Result<Self> {
        // Cuts append nodes and springs: room made now (see `model::room`).
        use crate::model::room::reserve_room;
        reserve_room(&mut model.node_keys);
        reserve_room(&mut model.rest);
        reserve_room(&mut model.mass);
        reserve_room(&mut model.fixed);
        model.reserve_springs(crate::model::room::spare(model.springs().len()));
        if !(config.dt.is_finite() && config.dt > 0.0) {
            return Err(Error::Model(format!(
                "time step {} must be finite and positive",
                config.dt
            )));
        }
        if config.check_every == 0 {
            return Err(Error::Model("check_every must be at least 1 step".into()));
        }
        let bound = stable_time_step(&model);
        if config.dt > bound.dt && !config.allow_unstable {
            return Err(Error::UnstableTimeStep {
                dt: config.dt,
                bound: bound.dt,
                node: bound.node,
            });
        }
        let (engine, kind, mut note) = make_engine(&model, kind, config)?;
        if let Some(precision) = verlet_precision_note(kind, &config, bound.dt) {
            note = Some(match note {
                Some(n) => format!("{n}; {precision}"),
                None => precision,
            });
        }
        // Room for cuts' springs and nodes, so that a patch does not copy the whole model into
        // a larger array (a pause of milliseconds at 100,000 tets): a quarter, as the fast
        // engine keeps (350 subdividing cut events into a 104,544-tet box add 17% springs).
        let mut model = model;
        model.reserve_springs(model.springs().len() / 4);
        let extra = model.node_count() / 4;
        model.rest.reserve(extra);
        model.mass.reserve(extra);
        model.fixed.reserve(extra);
        model.node_keys.reserve(extra);
        let mut sim = Simulation {
            engine,
            model,
            config,
            kind,
            bound,
            steps: 0,
            surface: None,
            surface_slots: None,
            time_at_dt_change: 0.0,
            steps_at_dt_change: 0,
            start_energy: 0.0,
            energy_scale: 0.0,
            base_energy: 0.0,
            base_scale: 0.0,
            steps_since_exact: 0,
            node_springs: None,
            near_ahead: None,
            near_reads: NearReads::default(),
            note,
        };
        sim.reset_energy_reference();
        Ok(sim)
    }

    /// Energy reference for divergence checks: the current total, and a scale made of the
    /// energies present plus what gravity could release over the body's size plus a floor of
    /// 0.1% strain in every spring (so a body at rest without gravity still has a scale).
    fn reset_energy_reference(&mut self) {
        let e = self.energy();
        let m = &self.model;
        let (lo, hi) = m.rest.iter().fold(
            ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(lo, hi), p| {
                (
                    [lo[0].min(p[0]), lo[1].min(p[1]), lo[2].min(p[2])],
                    [hi[0].max(p[0]), hi[1].max(p[1]), hi[2].max(p[2])],
                )
            },
        );
        let diag = (0..3).map(|i| (hi[i] - lo[i]).powi(2)).sum::<f64>().sqrt();
        let g = m.gravity.iter().map(|g| g * g).sum::<f64>().sqrt();
        let gravity_scale: f64 = m.mass.iter().sum::<f64>() * g * diag;
        let strain_floor: f64 = m
            .springs()
            .iter()
            .map(|s| 0.5 * s.stiffness * (1e-3 * s.rest_length).powi(2))
            .sum();
        self.start_energy = e.total();
        self.energy_scale = e.kinetic.abs() + e.elastic.abs() + gravity_scale + strain_floor;
        self.base_energy = self.start_energy;
        self.base_scale = self.energy_scale;
    }

    /// Apply a change to the model between steps (what a cut produces): the GPU engine patches
    /// its layout and uploads only what changed, the fast CPU engine rewrites the rows of the
    /// touched nodes, the float64 reference engine is rebuilt with its state carried over. New nodes start with the state of the node they copy, or at rest. The
    /// stable time step is recomputed; a change that puts `dt` above it is refused (unless
    /// `allow_unstable`). A refused change (an invalid diff, an unstable step) leaves the model
    /// and engine as they were; a device failure while patching leaves the engine unusable.
    pub fn apply(&mut self, diff: &ModelDiff) -> Result<PatchCost> {
        self.apply_with(diff, self.config.allow_unstable)
    }

    /// [`Simulation::apply`], choosing whether a change that puts `dt` above the new stable
    /// bound is refused (`allow_unstable = false`) or applied anyway (a cut scene whose policy
    /// is to warn).
    pub fn apply_with(&mut self, diff: &ModelDiff, allow_unstable: bool) -> Result<PatchCost> {
        self.apply_inner(diff, allow_unstable, None)
    }

    /// [`Simulation::apply_with`], given the current positions (as [`Simulation::positions`]
    /// gave them, with no step since: what a cutter just read). The energy bookkeeping takes
    /// the positions of the touched springs' nodes from them instead of reading them back from
    /// the engine, which on the GPU is a round trip to the device per cut. Only those entries
    /// are read, so the positions of a cut that read only the nodes near its blade
    /// ([`crate::cut::ReadPositions::positions`]) will do. Positions of another length than
    /// the model's node count are an error, and nothing changes.
    pub fn apply_at(
        &mut self,
        diff: &ModelDiff,
        allow_unstable: bool,
        positions: &[[f64; 3]],
    ) -> Result<PatchCost> {
        let n = self.model.node_count();
        if positions.len() != n {
            return Err(Error::Model(format!(
                "{} positions given for a model of {n} nodes: pass the positions read since \
                 the last step or change",
                positions.len()
            )));
        }
        self.apply_inner(diff, allow_unstable, Some(positions))
    }

    fn apply_inner(
        &mut self,
        diff: &ModelDiff,
        allow_unstable: bool,
        positions: Option<&[[f64; 3]]>,
    ) -> Result<PatchCost> {
        // Everything below touches only what the diff names, so that a local cut costs the
        // same on a large mesh as on a small one.
        let undo = self.bound.update(&self.model, diff);
        if self.config.dt > self.bound.dt && !allow_unstable {
            let err = Error::UnstableTimeStep {
                dt: self.config.dt,
                bound: self.bound.dt,
                node: self.bound.node,
            };
            self.bound.undo(undo);
            return Err(err);
        }
        let before = self.model.node_count();
        // Validates first: on error nothing has changed (the bound is put back).
        let energies = self
            .diff_elastic_energy(diff, positions)
            .and_then(|e| self.model.apply(diff).map(|()| e));
        let (elastic_before, elastic_after) = match energies {
            Ok(e) => e,
            Err(e) => {
                self.bound.undo(undo);
                return Err(e);
            }
        };
        let cost = match self.engine.patch(&self.model, diff)? {
            Some(cost) => cost,
            None => {
                let (mut x, mut v) = self.engine.state();
                let before = x.len();
                for a in &diff.added_nodes {
                    // The source's displacement and velocity, mixed with the blend partner's.
                    let rest = &self.model.rest;
                    let d = a.start_value(|i| {
                        let i = i as usize;
                        [0, 1, 2].map(|c| x[i][c] - rest[i][c])
                    });
                    let p = d.map_or(a.rest, |d| [0, 1, 2].map(|c| a.rest[c] + d[c]));
                    let u = a.start_value(|i| v[i as usize]).unwrap_or([0.0; 3]);
                    x.push(p);
                    v.push(u);
                }
                debug_assert_eq!(x.len(), before + diff.added_nodes.len());
                let (mut engine, _, _) = make_engine(&self.model, self.kind, self.config)?;
                engine.set_state(&x, &v);
                if let Some(t) = &self.surface {
                    engine.set_surface(t)?;
                }
                let memory = engine.memory();
                self.engine = engine;
                PatchCost {
                    uploaded_bytes: memory.stats.total,
                    copied_bytes: 0,
                    buffers_grown: 0,
                    layout_bytes: memory.stats.total,
                    state_moves: diff.added_nodes.len(),
                    reallocated: true,
                }
            }
        };
        debug_assert_eq!(self.model.node_count(), before + diff.added_nodes.len());
        self.node_springs = None;
        // The divergence reference follows the energy the change took out of or put into the
        // springs it touched (splitting a node shares its mass and keeps its velocity, so the
        // kinetic and gravitational energies do not change; carving only lowers them).
        let delta = elastic_after - elastic_before;
        self.start_energy += delta;
        self.base_energy += delta;
        Ok(cost)
    }

    /// Elastic energy, at the current positions, of the springs `diff` removes or changes (as
    /// they are) and of those it adds or changes (as they will be; a new node is displaced as
    /// the node it copies, or as the mix of the two it blends). Reads back only the existing
    /// nodes of those springs and sources, once, unless `positions` (all nodes, current) are
    /// given.
    fn diff_elastic_energy(
        &self,
        diff: &ModelDiff,
        positions: Option<&[[f64; 3]]>,
    ) -> Result<(f64, f64)> {
        let n = self.model.node_count() as u32;
        let old: Vec<crate::model::PackedSpring> = diff
            .removed_springs
            .iter()
            .map(|&[a, b]| (a, b))
            .chain(
                diff.changed_springs
                    .iter()
                    .map(|s| (s.nodes[0], s.nodes[1])),
            )
            .filter_map(|(a, b)| {
                self.model
                    .spring_index(a, b)
                    .map(|i| self.model.springs()[i])
            })
            .collect();
        let new: Vec<crate::model::PackedSpring> = diff
            .added_springs
            .iter()
            .chain(&diff.changed_springs)
            .copied()
            .collect();
        // An added node is displaced as its source is (mixed with its blend partner); one
        // without a source starts at rest. Existing nodes are their own source.
        let sources = |i: u32| -> [Option<u32>; 2] {
            if i < n {
                return [Some(i), None];
            }
            diff.added_nodes
                .get((i - n) as usize)
                .map_or([None, None], |a| [a.state_from, a.blend.map(|b| b.with)])
        };
        let mut nodes: Vec<u32> = old
            .iter()
            .chain(&new)
            .flat_map(|s| s.nodes)
            .flat_map(sources)
            .flatten()
            .collect();
        nodes.sort_unstable();
        nodes.dedup();
        if nodes.is_empty() {
            return Ok((0.0, 0.0));
        }
        if let Some(&i) = nodes.last().filter(|&&i| i >= n) {
            // Validated again by `PackedModel::apply`; refused here before any position is
            // looked up.
            return Err(Error::Model(format!(
                "an added node starts from the state of node {i}, which does not exist yet"
            )));
        }
        let x: Vec<[f64; 3]> = match positions {
            Some(p) => {
                let x: Vec<[f64; 3]> = nodes.iter().map(|&i| p[i as usize]).collect();
                // Positions read from a device that failed come back as NaN: refuse them
                // rather than carry NaN into the energy reference.
                if let Some((&i, _)) = nodes
                    .iter()
                    .zip(&x)
                    .find(|(_, p)| !p.iter().all(|c| c.is_finite()))
                {
                    return Err(Error::Model(format!(
                        "the position given for node {i} is not finite; read the positions \
                         again, or apply without them"
                    )));
                }
                x
            }
            None => self.engine.node_positions(&nodes)?,
        };
        let read = |i: u32| x[nodes.binary_search(&i).expect("collected")];
        let at = |i: u32| -> [f64; 3] {
            if i < n {
                return read(i);
            }
            let a = &diff.added_nodes[(i - n) as usize];
            let d = a.start_value(|j| {
                let (p, r) = (read(j), self.model.rest[j as usize]);
                [0, 1, 2].map(|c| p[c] - r[c])
            });
            d.map_or(a.rest, |d| [0, 1, 2].map(|c| a.rest[c] + d[c]))
        };
        let energy = |springs: &[crate::model::PackedSpring]| -> f64 {
            springs
                .iter()
                .map(|s| {
                    let (a, b) = (at(s.nodes[0]), at(s.nodes[1]));
                    let l = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2))
                        .sqrt();
                    0.5 * s.stiffness * (l - s.rest_length).powi(2)
                })
                .sum()
        };
        Ok((energy(&old), energy(&new)))
    }

    /// Change the time step between steps, keeping the state (positions and velocities): a
    /// parameter of the step, so only the step parameters are written ([`Engine::set_time_step`]:
    /// no pipeline is rebuilt and no layout uploaded; Verlet's previous positions are moved
    /// where the state lives so that its velocity is kept). A step above the bound is refused
    /// unless `allow_unstable`, with nothing changed. Returns what it cost: the bytes of the
    /// engine's step parameters.
    pub fn set_time_step(&mut self, dt: f64) -> Result<PatchCost> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::Model(format!(
                "time step {dt} must be finite and positive"
            )));
        }
        if dt > self.bound.dt && !self.config.allow_unstable {
            return Err(Error::UnstableTimeStep {
                dt,
                bound: self.bound.dt,
                node: self.bound.node,
            });
        }
        // The time reached so far is counted at the old step before it changes.
        self.time_at_dt_change = self.time();
        self.steps_at_dt_change = self.steps;
        let cost = self.engine.set_time_step(dt)?;
        self.config.dt = dt;
        self.reset_energy_reference();
        Ok(cost)
    }

    /// Run `steps` steps, checking for divergence every `check_every` steps and at the end.
    /// A check that measures the total energy exactly also lowers the reference that position
    /// corrections raised (see [`Simulation::correct_positions`]): every check on the CPU
    /// engines; on the GPU, whose checks read a cheap probe, one every [`EXACT_CHECK_EVERY`]
    /// steps while corrections hold the reference up.
    pub fn run(&mut self, steps: u64) -> Result<()> {
        self.run_with(steps, |_| {})
    }

    /// Like [`Simulation::run`], calling `progress(steps_done_in_this_call)` after each chunk.
    pub fn run_with(&mut self, steps: u64, mut progress: impl FnMut(u64)) -> Result<()> {
        let mut done = 0;
        while done < steps {
            let chunk = (steps - done).min(self.config.check_every as u64) as u32;
            if done + chunk as u64 == steps {
                self.hand_prefetch();
            }
            self.engine.step(chunk);
            self.steps += chunk as u64;
            done += chunk as u64;
            let mut exact = self.check_total()?;
            self.steps_since_exact += chunk as u64;
            // Engines with a cheap probe measure the total only now and then, while
            // corrections hold the reference more than a scale above where it was taken.
            if exact.is_none()
                && self.steps_since_exact >= EXACT_CHECK_EVERY
                && self.start_energy > self.base_energy + self.base_scale
            {
                exact = Some(self.check_exact()?);
            }
            if let Some(total) = exact {
                self.tighten_reference(total);
                self.steps_since_exact = 0;
            }
            progress(done);
        }
        Ok(())
    }

    /// Wait until the steps already submitted have run (the GPU engine queues them; the CPU
    /// engines have finished when `run` returns). For timing what follows a step apart from
    /// the step itself.
    pub fn wait(&mut self) {
        self.engine.wait();
    }

    /// Advance `steps` steps with no divergence check (for timing); call
    /// [`Simulation::check`] afterwards.
    pub fn step_unchecked(&mut self, steps: u32) {
        if steps > 0 {
            self.hand_prefetch();
        }
        self.engine.step(steps);
        self.engine.wait();
        self.steps += steps as u64;
    }

    /// Device time of the last [`Simulation::step_unchecked`] call, s, where the engine can
    /// measure it (the GPU engine on an adapter with timestamp queries).
    pub fn last_device_seconds(&self) -> Option<f64> {
        self.engine.last_device_seconds()
    }

    /// The engine's name as reported in summaries (with its device for the GPU).
    pub fn engine_name(&self) -> String {
        self.engine.name()
    }

    /// Why the engine differs from the one asked for (`Auto` without a GPU), and advice about
    /// the configuration (float32 Verlet far below the stable bound), if any.
    pub fn engine_note(&self) -> Option<&str> {
        self.note.as_deref()
    }

    /// Check the current state for divergence. Engines with a device-side probe
    /// ([`Engine::health`]) read back a few bytes: kinetic plus gravitational energy is a lower
    /// bound of the total (elastic energy is never negative), so when it is within the limit
    /// nothing more is read; otherwise, or when a node is not finite, the whole state is read
    /// and checked exactly, which names the node.
    pub fn check(&self) -> Result<()> {
        self.check_total().map(|_| ())
    }

    /// [`Simulation::check`], returning the total energy where it was computed exactly.
    fn check_total(&self) -> Result<Option<f64>> {
        if let Some(h) = self.engine.health()? {
            let lower = h.kinetic + h.gravity;
            if h.non_finite.is_none()
                && lower.is_finite()
                && lower - self.start_energy <= ENERGY_GROWTH_LIMIT * self.energy_scale
            {
                return Ok(None);
            }
        }
        self.check_exact().map(Some)
    }

    /// The exact check over the whole state; returns the total energy.
    fn check_exact(&self) -> Result<f64> {
        let (x, v) = self.engine.state();
        let bad = x
            .iter()
            .zip(&v)
            .position(|(p, u)| !p.iter().chain(u).all(|c| c.is_finite()));
        if let Some(node) = bad {
            return Err(Error::Diverged {
                step: self.steps,
                node,
                reason: "position or velocity is not finite".into(),
            });
        }
        let e = self.energy_of(&x, &v);
        let total = e.total();
        if !total.is_finite() || total - self.start_energy > ENERGY_GROWTH_LIMIT * self.energy_scale
        {
            let node = v
                .iter()
                .zip(&self.model.mass)
                .enumerate()
                .max_by(|(_, (a, ma)), (_, (b, mb))| {
                    let ka = *ma * (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
                    let kb = *mb * (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
                    ka.total_cmp(&kb)
                })
                .map_or(0, |(i, _)| i);
            return Err(Error::Diverged {
                step: self.steps,
                node,
                reason: format!(
                    "total energy grew from {:.3e} J to {total:.3e} J (limit: +{:.0} x the \
                     energy scale {:.3e} J); the node shown moves fastest",
                    self.start_energy, ENERGY_GROWTH_LIMIT, self.energy_scale
                ),
            });
        }
        Ok(total)
    }

    /// Corrections raise the reference by their work, an upper bound of the energy (damping
    /// only takes energy out); where a check has measured the total exactly (every check on
    /// the CPU engines; on the GPU a failed lower bound, or every [`EXACT_CHECK_EVERY`] steps
    /// while the reference is up) and found it lower, the reference comes
    /// down to it, never below where it was last taken from the state. The scale keeps the
    /// growth of the reference above that level.
    fn tighten_reference(&mut self, total: f64) {
        if total < self.start_energy {
            self.start_energy = total.max(self.base_energy.min(self.start_energy));
            self.energy_scale = self.base_scale + (self.start_energy - self.base_energy).max(0.0);
        }
    }

    fn energy_of(&self, x: &[[f64; 3]], v: &[[f64; 3]]) -> Energy {
        Energy {
            kinetic: self.model.kinetic_energy(v),
            elastic: self.model.elastic_energy(x),
            gravity: self.model.gravity_energy(x),
        }
    }

    /// What the divergence check compares against: the reference total energy, J (the energy
    /// when the run started or its state was last set, plus the work of every position
    /// correction since), and the energy scale, J, of which [`ENERGY_GROWTH_LIMIT`] times is
    /// the allowed growth above the reference.
    pub fn energy_reference(&self) -> (f64, f64) {
        (self.start_energy, self.energy_scale)
    }

    /// Energies of the current state.
    pub fn energy(&self) -> Energy {
        let (x, v) = self.engine.state();
        self.energy_of(&x, &v)
    }

    /// Replace the state (initial displacement or velocity); resets the divergence reference.
    pub fn set_state(&mut self, positions: &[[f64; 3]], velocities: &[[f64; 3]]) -> Result<()> {
        let n = self.model.node_count();
        if positions.len() != n || velocities.len() != n {
            return Err(Error::Model(format!(
                "state has {} positions and {} velocities for {n} nodes",
                positions.len(),
                velocities.len()
            )));
        }
        self.engine.set_state(positions, velocities);
        self.reset_energy_reference();
        Ok(())
    }

    /// Set the tissue's boundary triangles (dense model indices, e.g.
    /// `collide::broad::Surface::of(&mesh).triangles`) for [`Simulation::cull_tools`]; again
    /// whenever a cut changes the surface.
    pub fn set_surface(&mut self, triangles: Vec<[u32; 3]>) -> Result<()> {
        let n = self.model.node_count();
        if let Some(t) = triangles
            .iter()
            .find(|t| t.iter().any(|&i| i as usize >= n))
        {
            return Err(Error::Model(format!(
                "surface triangle {t:?} names a node past the model's {n} nodes"
            )));
        }
        self.engine.set_surface(&triangles)?;
        // Built here, not at the first edit, so that the first cut does not pay for it.
        self.surface_slots = Some(
            triangles
                .iter()
                .enumerate()
                .map(|(i, t)| (surface_key(t), i as u32))
                .collect(),
        );
        self.surface = Some(triangles);
        Ok(())
    }

    /// Apply a cut's change to the surface given to [`Simulation::set_surface`] in place: a
    /// removed triangle's slot takes the last triangle, added ones go at the end, so only a
    /// few slots change and the GPU engine writes only those. Triangle indices reported by
    /// [`Simulation::cull_tools`] refer to the edited list ([`Simulation::surface`]). On error
    /// (a removed triangle not on the surface, an added one already on it, a node out of range)
    /// nothing changes.
    pub fn edit_surface(&mut self, edit: &crate::collide::broad::SurfaceEdit) -> Result<()> {
        let n = self.model.node_count();
        let Some(triangles) = &mut self.surface else {
            return Err(Error::Model(
                "no surface to edit: call set_surface with the boundary triangles first".into(),
            ));
        };
        if edit.is_empty() {
            return Ok(());
        }
        let key = surface_key;
        let slots = self.surface_slots.as_mut().expect("built with the surface");
        // Validate everything before changing anything.
        let mut gone = HashSet::new();
        for t in &edit.removed {
            if !slots.contains_key(&key(t)) || !gone.insert(key(t)) {
                return Err(Error::Model(format!(
                    "surface edit removes triangle {t:?}, which is not on the surface (or is \
                     removed twice)"
                )));
            }
        }
        let mut new = HashSet::new();
        for t in &edit.added {
            if let Some(&i) = t.iter().find(|&&i| i as usize >= n) {
                return Err(Error::Model(format!(
                    "surface edit adds triangle {t:?}, whose node {i} is past the model's {n} \
                     nodes"
                )));
            }
            let k = key(t);
            if (slots.contains_key(&k) && !gone.contains(&k)) || !new.insert(k) {
                return Err(Error::Model(format!(
                    "surface edit adds triangle {t:?}, which is already on the surface"
                )));
            }
        }
        // Edited in place; undone the same way if the engine refuses the edit.
        let applied = surface_list::apply(triangles, slots, edit);
        if let Err(e) = self.engine.edit_surface(triangles, &applied.changed) {
            surface_list::undo(triangles, slots, edit, applied);
            return Err(e);
        }
        Ok(())
    }

    /// The surface given to [`Simulation::set_surface`].
    pub fn surface(&self) -> Option<&[[u32; 3]]> {
        self.surface.as_deref()
    }

    /// Broad phase, tool against tissue: (triangle, tool) pairs of the surface whose bounds
    /// overlap `boxes`. On the GPU engine the pass runs on the device and only the candidates
    /// come back; elsewhere it runs on the CPU over float64 positions. Either way no overlapping
    /// pair is missed.
    pub fn cull_tools(
        &mut self,
        boxes: &[crate::collide::broad::ToolBox],
    ) -> Result<Vec<crate::collide::broad::Candidate>> {
        let Some(triangles) = &self.surface else {
            return Err(Error::Model(
                "no surface to cull: call set_surface with the boundary triangles first".into(),
            ));
        };
        if let Some(c) = self.engine.cull_tools(boxes)? {
            return Ok(c);
        }
        let exact: Vec<([f64; 3], [f64; 3])> = boxes
            .iter()
            .map(|b| {
                (
                    [b.lo[0] as f64, b.lo[1] as f64, b.lo[2] as f64],
                    [b.hi[0] as f64, b.hi[1] as f64, b.hi[2] as f64],
                )
            })
            .collect();
        Ok(crate::collide::broad::cull_exact(
            &self.engine.positions(),
            triangles,
            &exact,
        ))
    }

    /// Broad phase, tissue against itself: pairs of surface triangles (indices into the
    /// surface given to [`Simulation::set_surface`], t < u, sorted) that share no node and whose
    /// boxes, widened by `margin / 2` (m) on every side, overlap. On the GPU engine the spatial
    /// hash runs on the device and only the pairs come back; elsewhere its CPU twin
    /// ([`crate::collide::self_broad::self_pairs_cpu`]) runs over the current positions. Either
    /// way no pair the float64 brute force finds is missed.
    pub fn cull_self(&mut self, margin: f64) -> Result<Vec<[u32; 2]>> {
        use crate::collide::self_broad::{self_pairs_cpu, GridParams};
        if !(margin.is_finite() && margin >= 0.0) {
            return Err(Error::Options(format!(
                "self-contact margin must be zero or positive and finite, got {margin} m"
            )));
        }
        let Some(triangles) = &self.surface else {
            return Err(Error::Model(
                "no surface to cull: call set_surface with the boundary triangles first".into(),
            ));
        };
        if let Some(pairs) = self.engine.cull_self(margin)? {
            return Ok(pairs);
        }
        // The twin over float32 rest positions plus float32 displacements, as on the device.
        let rest = &self.model.rest;
        let x = self.engine.positions();
        let f4 = |p: [f64; 3]| [p[0] as f32, p[1] as f32, p[2] as f32, 0.0];
        let rest32: Vec<[f32; 4]> = rest.iter().map(|&r| f4(r)).collect();
        let disp32: Vec<[f32; 4]> = x
            .iter()
            .zip(rest)
            .map(|(p, r)| f4([p[0] - r[0], p[1] - r[1], p[2] - r[2]]))
            .collect();
        let mut grid = GridParams::for_surface(rest, triangles, margin);
        for _ in 0..40 {
            if let Some(pairs) = self_pairs_cpu(&grid, &rest32, &disp32, triangles) {
                return Ok(pairs);
            }
            // The surface stretched past the grid: coarser cells, as the device does.
            grid.inv_cell *= 0.5;
        }
        Err(Error::Diverged {
            step: self.steps,
            node: 0,
            reason: "the tissue surface stretched beyond any grid cell (non-finite or enormous \
                     positions)"
                .into(),
        })
    }

    /// Positions of a few nodes (model indices), m: on the GPU only those are read back.
    pub fn node_positions(&self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        self.engine.node_positions(nodes)
    }

    /// Read the nodes in the box `lo..=hi` (m) ahead, with the last step of the next
    /// [`Simulation::run`] (or [`Simulation::step_unchecked`]): on the GPU that step's
    /// submission ends with the pass that finds them and starts their readback, so that the
    /// cut after it ([`crate::cut::Cutter::cut_from`], whose box
    /// [`crate::cut::Cutter::reading_box_ahead`] bounds) reads them without a round trip of its
    /// own. A later read for a box that this one does not hold, or after the state changed
    /// again (a further step, a position correction, a patch), reads from the device as
    /// before; [`Simulation::near_reads`] counts which. The fast CPU engine scans for them
    /// after the step, on its threads, and the cut narrows that list instead of scanning every
    /// node itself; the reference engine ignores it.
    pub fn prefetch_near(&mut self, lo: [f64; 3], hi: [f64; 3]) {
        self.near_ahead = Some((lo, hi));
    }

    /// How the engine served reads of nodes near a blade: from a read made ahead with a step,
    /// or with a round trip (a scan, on the fast CPU engine) of their own (zero on the reference
    /// engine).
    pub fn near_reads(&self) -> NearReads {
        self.near_reads
    }

    /// Give the engine the box to read ahead, for the step about to be submitted.
    fn hand_prefetch(&mut self) {
        if let Some((lo, hi)) = self.near_ahead.take() {
            self.engine.prefetch_near(lo, hi);
        }
    }

    /// The nodes whose current position lies in the box `lo..=hi` (m), with their positions
    /// ([`Engine::nodes_near`]): on the GPU found on the device, and only they are read back.
    pub fn nodes_near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Result<Vec<(u32, [f64; 3])>> {
        let before = self.engine.near_reads();
        let found = self.engine.nodes_near(lo, hi);
        let after = self.engine.near_reads();
        self.near_reads.ahead += after.ahead - before.ahead;
        self.near_reads.direct += after.direct - before.direct;
        found
    }

    /// Positions of a few nodes at the start of the last step (after the corrections made
    /// before it), m: with [`Simulation::node_positions`] they give each node's motion over the
    /// step, which friction needs. On the GPU only those nodes are read back.
    pub fn node_start_positions(&self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        self.engine.node_start_positions(nodes, self.config.dt)
    }

    /// Move nodes between steps (contact response by position correction); see
    /// [`Engine::correct_positions`].
    ///
    /// The move is work done on the tissue from outside (a tool's push, a self-contact
    /// separation), so the energy the divergence check compares against grows by that work:
    /// the change of the total energy the move makes, computed from the moved nodes alone (their
    /// positions and velocities before, and the springs at them with their other ends), with
    /// the velocity the integrator gives the move (`dx / dt`). The energy scale grows with the
    /// reference above where it was last taken from the state, so that the check's margin stays
    /// in proportion to the energy brought in; a later check that measures the total exactly
    /// lowers both again where the energy went (see [`Simulation::run`]). On the GPU only the
    /// moved nodes and their spring neighbours are read back, not the state.
    pub fn correct_positions(&mut self, nodes: &[u32], positions: &[[f64; 3]]) -> Result<()> {
        check_correction(nodes, positions, self.model.node_count())?;
        let work = self.correction_work(nodes, positions)?;
        self.engine.correct_positions(nodes, positions)?;
        self.start_energy += work;
        self.energy_scale = self.base_scale + (self.start_energy - self.base_energy).max(0.0);
        Ok(())
    }

    /// The change of total energy (kinetic, elastic, gravitational, as [`Simulation::energy`]
    /// counts them) that moving `nodes` to `positions` makes, J. Fixed nodes do not move; a
    /// node listed twice takes its last position, as the engines do.
    pub fn correction_work(&mut self, nodes: &[u32], positions: &[[f64; 3]]) -> Result<f64> {
        let m = &self.model;
        let mut to: std::collections::BTreeMap<u32, [f64; 3]> = Default::default();
        for (&i, &p) in nodes.iter().zip(positions) {
            if !m.fixed[i as usize] {
                to.insert(i, p);
            }
        }
        if to.is_empty() {
            return Ok(0.0);
        }
        let moved: Vec<u32> = to.keys().copied().collect();
        let node_springs = self.node_springs.get_or_insert_with(|| NodeSprings::of(m));
        let mut springs: Vec<u32> = moved
            .iter()
            .flat_map(|&i| node_springs.of_node(i).iter().copied())
            .collect();
        springs.sort_unstable();
        springs.dedup();
        let mut ends: Vec<u32> = springs
            .iter()
            .flat_map(|&s| m.springs()[s as usize].nodes)
            .chain(moved.iter().copied())
            .collect();
        ends.sort_unstable();
        ends.dedup();
        let x = self.engine.node_positions(&ends)?;
        let v = self.engine.node_velocities(&moved)?;
        let at = |i: u32| x[ends.binary_search(&i).expect("every end was read")];
        let g = m.gravity;
        let inv_h = 1.0 / self.config.dt;
        let mut work = 0.0;
        for (k, (&i, p)) in to.iter().enumerate() {
            let (old, mass) = (at(i), m.mass[i as usize]);
            let dx = [0, 1, 2].map(|c| p[c] - old[c]);
            let v1 = [0, 1, 2].map(|c| v[k][c] + dx[c] * inv_h);
            let sq = |a: [f64; 3]| a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
            work += 0.5 * mass * (sq(v1) - sq(v[k]));
            work -= mass * (dx[0] * g[0] + dx[1] * g[1] + dx[2] * g[2]);
        }
        let spring_energy = |s: &crate::model::PackedSpring, a: [f64; 3], b: [f64; 3]| {
            let l = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt();
            0.5 * s.stiffness * (l - s.rest_length).powi(2)
        };
        for &s in &springs {
            let s = &m.springs()[s as usize];
            let [a, b] = s.nodes;
            let after = |i: u32| to.get(&i).copied().unwrap_or_else(|| at(i));
            work += spring_energy(s, after(a), after(b)) - spring_energy(s, at(a), at(b));
        }
        Ok(work)
    }

    /// Current positions, m, in packed node order.
    pub fn positions(&self) -> Vec<[f64; 3]> {
        self.engine.positions()
    }

    /// Current velocities, m/s.
    pub fn velocities(&self) -> Vec<[f64; 3]> {
        self.engine.velocities()
    }

    /// Largest nodal displacement from rest, m.
    pub fn max_displacement(&self) -> f64 {
        self.positions()
            .iter()
            .zip(&self.model.rest)
            .map(|(p, r)| {
                ((p[0] - r[0]).powi(2) + (p[1] - r[1]).powi(2) + (p[2] - r[2]).powi(2)).sqrt()
            })
            .fold(0.0, f64::max)
    }

    /// Steps taken so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Simulated time so far, s.
    pub fn time(&self) -> f64 {
        self.time_at_dt_change + (self.steps - self.steps_at_dt_change) as f64 * self.config.dt
    }

    /// The stable time-step bound (s) the model would have after `diff`, and the node that
    /// sets it, without applying it: what a caller asks before a change that may lower the
    /// bound below the time step (as [`Simulation::apply`] would refuse), to choose a new step
    /// or to go on. Touches only what the diff names.
    pub fn bound_after(&mut self, diff: &ModelDiff) -> (f64, usize) {
        let undo = self.bound.update(&self.model, diff);
        let after = (self.bound.dt, self.bound.node);
        self.bound.undo(undo);
        after
    }

    /// The stable time-step bound of the model.
    pub fn bound(&self) -> &StabilityBound {
        &self.bound
    }

    /// The model being run.
    pub fn model(&self) -> &PackedModel {
        &self.model
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// Memory and per-step traffic of the engine.
    pub fn memory(&self) -> EngineMemory {
        self.engine.memory()
    }

    /// How the engine, after the changes applied so far, differs from one built from scratch
    /// for the current model (its layout, and on the GPU every device buffer of it): empty when
    /// they agree. Reads the layout back from the device: for checks, not for every step.
    pub fn differences_from_rebuild(&self) -> Result<Vec<String>> {
        self.engine.differences_from_rebuild(&self.model)
    }

    /// Which engine runs.
    pub fn kind(&self) -> EngineKind {
        self.kind
    }
}

/// A simulation is where a cut reads the positions near its blade
/// ([`crate::cut::Cutter::cut_from`]).
impl crate::cut::PositionSource for Simulation {
    fn near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Result<Vec<(u32, [f64; 3])>> {
        self.nodes_near(lo, hi)
    }

    fn of(&mut self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        self.node_positions(nodes)
    }
}
