//! [`Simulation`]: an engine with the checks a user relies on. A time step above the stable
//! bound is refused, divergence is caught within [`SimConfig::check_every`] steps and reported
//! with the step and node, and model changes, surfaces and contact corrections reach the engine
//! through it. One idea per file: changes to the model and the time step (`changes.rs`), the
//! divergence checks and energies (`checks.rs`), the surface and contact calls (`contact.rs`),
//! the watch for inverted tets (`inversion.rs`).

mod changes;
mod checks;
mod contact;
#[cfg(feature = "gpu")]
mod host_gpu;
mod inversion;

#[cfg(feature = "gpu")]
use host_gpu::HostDevice;

/// Without the GPU engine there is no host device to keep.
#[cfg(not(feature = "gpu"))]
#[derive(Clone, Default)]
struct HostDevice;

pub use inversion::INVERSION_CHECK_EVERY;

use std::collections::{HashMap, HashSet};

use super::surface_list::{self, surface_key};
use super::*;

/// Energies of a state, J.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Energy {
    /// Kinetic.
    pub kinetic: f64,
    /// Elastic, of the force model the engine steps (springs or finite elements).
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
fn make_engine(
    model: &PackedModel,
    kind: EngineKind,
    config: SimConfig,
    gpu: GpuOptions,
    host: &HostDevice,
) -> Result<Made> {
    use crate::physics::Preconditioner;
    let fast_only = match config.solver.preconditioner {
        Preconditioner::SymmetricGaussSeidel => Some("symmetric Gauss-Seidel"),
        Preconditioner::Factored | Preconditioner::FactoredDouble => {
            Some("factored (sparse Cholesky)")
        }
        Preconditioner::Auto | Preconditioner::BlockJacobi => None,
    };
    if let Some(name) = fast_only.filter(|_| {
        config.integrator.is_implicit() && matches!(kind, EngineKind::Reference | EngineKind::Gpu)
    }) {
        return Err(Error::Unsupported(format!(
            "the {name} preconditioner runs on the fast engine only, not on the {kind} \
             engine: leave solver.preconditioner out (Auto) or choose BlockJacobi"
        )));
    }
    if cfg!(not(feature = "factor"))
        && config.integrator.is_implicit()
        && config.solver.preconditioner.is_factored()
    {
        return Err(Error::Unsupported(
            "the factored (sparse Cholesky) preconditioner needs lancet built with the `factor` \
             feature (`cargo build --release --features factor`): leave solver.preconditioner \
             out (Auto) or choose SymmetricGaussSeidel or BlockJacobi"
                .into(),
        ));
    }
    let fast = || -> Result<Box<dyn Engine>> {
        fast::check_size(model).map_err(Error::Unsupported)?;
        Ok(Box::new(
            fast::FastEngine::new(model, config).with_force_model(model, config.force_model)?,
        ))
    };
    Ok(match kind {
        EngineKind::Reference => (
            Box::new(
                reference::ReferenceEngine::new(model, config)
                    .with_force_model(model, config.force_model)?,
            ),
            kind,
            None,
        ),
        EngineKind::Fast => (fast()?, kind, None),
        EngineKind::Gpu => (gpu_engine(model, config, gpu, host)?, kind, None),
        EngineKind::Auto if config.force_model.is_finite_element() => (
            fast()?,
            EngineKind::Fast,
            Some(auto_fem_note(config.force_model)),
        ),
        EngineKind::Auto if fast_only.is_some() && config.integrator.is_implicit() => (
            fast()?,
            EngineKind::Fast,
            Some(format!(
                "Auto runs the {} preconditioner on the fast CPU engine, the only one that has it",
                fast_only.unwrap_or_default()
            )),
        ),
        EngineKind::Auto => match gpu_engine(model, config, gpu, host) {
            Ok(e) => (e, EngineKind::Gpu, None),
            Err(e) => (
                {
                    fast::check_size(model).map_err(|why| {
                        Error::Unsupported(format!("no usable GPU ({e}), and {why}"))
                    })?;
                    Box::new(fast::FastEngine::new(model, config))
                },
                EngineKind::Fast,
                Some(format!("no usable GPU ({e}); running the fast CPU engine")),
            ),
        },
    })
}

/// Why `Auto` runs a finite-element model on the fast CPU engine.
fn auto_fem_note(kind: crate::physics::ForceModelKind) -> String {
    // Auto keeps the CPU: the GPU's finite-element passes are explicit only (tensor-mass also
    // gather-only on the edge layout), and the fast engine runs every scheme; a program asks
    // for them with engine: Gpu.
    format!(
        "Auto runs the {kind} force model on the fast CPU engine; choose engine: Gpu \
         (--engine gpu) for its GPU passes"
    )
}

/// The GPU engine, on the host's device where the simulation was given one.
#[cfg(feature = "gpu")]
fn gpu_engine(
    model: &PackedModel,
    config: SimConfig,
    gpu: GpuOptions,
    host: &HostDevice,
) -> Result<Box<dyn Engine>> {
    Ok(Box::new(match &host.context {
        Some(ctx) => gpu::GpuEngine::with_context(ctx.clone(), model, config, gpu)?,
        None => gpu::GpuEngine::new(model, config, gpu)?,
    }))
}

#[cfg(not(feature = "gpu"))]
fn gpu_engine(
    _: &PackedModel,
    _: SimConfig,
    _: GpuOptions,
    _: &HostDevice,
) -> Result<Box<dyn Engine>> {
    Err(Error::Unsupported(
        "this build has no GPU engine (enable the `gpu` cargo feature)".into(),
    ))
}

/// Below this fraction of a node's own stable bound (the per-node Gershgorin bound of
/// `model::stability`), a float32 engine's step is so small against the node's displacement
/// that rounding `u + step` may lose a measurable part of it (not measured below 1/64 of the
/// bound: this threshold is a conservative guess, not a measured edge).
pub const FLOAT32_NODE_FRACTION: f64 = 1.0 / 4096.0;

/// Advice for a float32 engine running some node far below its own stable bound. Each node is
/// measured against its own bound, not the global one: in a stiffness contrast the stiff part
/// sets the global bound and the soft part runs far below its own.
///
/// Before the step was kept (Verlet stored two displacements and rounded `u + step` plainly),
/// float32 Verlet lost precision from 0.3 of the bound down (the default scene with `lancet
/// report accuracy`: relative error 4.6e-5 at the bound, 1.2e-3 at a quarter of it, 0.16 at a
/// sixteenth); both integrators now follow float64 to 1/64 of the bound and beyond
/// (`tests/engine/float32_precision.rs`), so the note is left for steps far below that.
fn float32_precision_note(
    kind: EngineKind,
    config: &SimConfig,
    bound: &StabilityBound,
) -> Option<String> {
    let float32 = matches!(kind, EngineKind::Fast | EngineKind::Gpu);
    let explicit = matches!(
        config.integrator,
        Integrator::Verlet | Integrator::SymplecticEuler
    );
    if !(float32 && explicit) {
        return None;
    }
    let (fraction, node) = bound
        .per_node
        .iter()
        .enumerate()
        .filter(|(_, h)| h.is_finite())
        .map(|(i, h)| (config.dt / h, i))
        .min_by(|a, b| a.0.total_cmp(&b.0))?;
    (fraction < FLOAT32_NODE_FRACTION).then(|| {
        format!(
            "float32 steps node {node} at {fraction:.2e} of its own stable bound, where rounding \
             can lose part of each step; the float64 reference engine does not"
        )
    })
}

/// An engine with safety checks around it.
pub struct Simulation {
    engine: Box<dyn Engine>,
    model: PackedModel,
    config: SimConfig,
    /// The GPU engine's layout and accumulation (kept for rebuilds; unused by CPU engines).
    gpu: GpuOptions,
    kind: EngineKind,
    bound: StabilityBound,
    steps: u64,
    /// The boundary triangles for tool culling, once given.
    surface: Option<Vec<[u32; 3]>>,
    /// Counts changes of `surface`, so that a host's index buffer is written only after one.
    #[cfg_attr(not(feature = "gpu"), allow(dead_code))]
    surface_generation: u64,
    /// The host's device and what the host bound, kept for engines built later.
    host: HostDevice,
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
    /// The tets watched for inversion, once given ([`Simulation::watch_mesh`]).
    watch: Option<inversion::TetWatch>,
    /// Steps since the watched tets were last checked.
    steps_since_inversion: u64,
    /// The state at the last check that found the energy good (`good_energy`), and at the
    /// last that found the watched tets upright as well (`good_shape`): where a replay to the
    /// first bad step starts.
    good_energy: Option<Snapshot>,
    good_shape: Option<Snapshot>,
    /// The step of the last check that found the energy good, and the tets upright.
    last_good: u64,
    last_upright: u64,
    /// Counts the changes that make a replay from a kept state differ from the run (model
    /// changes, position corrections, a new state or time step).
    changes: u64,
    /// A box whose nodes the last step of the next run reads ahead ([`Simulation::prefetch_near`]).
    near_ahead: Option<([f64; 3], [f64; 3])>,
    /// How reads of nodes near a blade were served, over every engine this simulation had (a
    /// new time step rebuilds it).
    near_reads: NearReads,
    /// The nodes held on tools' planes inside the implicit solve
    /// ([`Simulation::set_contact_constraints`]).
    contact_constraints: Vec<crate::physics::NodeConstraint>,
}

/// A state kept by a check, to replay from.
#[derive(Clone)]
struct Snapshot {
    /// Steps taken when it was kept.
    step: u64,
    /// [`Simulation::changes`] when it was kept: a replay is the run's only while it is equal.
    changes: u64,
    x: Vec<[f64; 3]>,
    v: Vec<[f64; 3]>,
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
    /// Set up a run of `model` on engine `kind`. Fails if `dt` is not positive or, for an
    /// explicit integrator, is above the stable bound (unless `config.allow_unstable`). A GPU engine (`Gpu`, or `Auto` finding an
    /// adapter) takes the default [`GpuOptions`]; [`Simulation::with_gpu`] chooses them.
    pub fn new(model: PackedModel, kind: EngineKind, config: SimConfig) -> Result<Self> {
        Self::with_gpu(model, kind, config, GpuOptions::default())
    }

    /// [`Simulation::new`] with the GPU engine's layout and accumulation `gpu` (used where
    /// `kind` is `Gpu`, or `Auto` and an adapter is found; the CPU engines ignore them).
    pub fn with_gpu(
        model: PackedModel,
        kind: EngineKind,
        config: SimConfig,
        gpu: GpuOptions,
    ) -> Result<Self> {
        // A unit struct without the `gpu` feature, a struct with fields with it.
        #[allow(clippy::default_constructed_unit_structs)]
        let host = HostDevice::default();
        Self::build(model, kind, config, gpu, host)
    }

    /// [`Simulation::with_gpu`], GPU engines made on the host's device if `host` has one.
    fn build(
        mut model: PackedModel,
        kind: EngineKind,
        config: SimConfig,
        gpu: GpuOptions,
        host: HostDevice,
    ) -> Result<Self> {
        // Cuts append nodes and springs: room made now (see `model::room`).
        use crate::model::room::reserve_room;
        reserve_room(&mut model.node_keys);
        reserve_room(&mut model.rest);
        reserve_room(&mut model.mass);
        reserve_room(&mut model.fixed);
        model.reserve_springs(crate::model::room::spare(model.springs().len()));
        if !(config.dt.is_finite() && config.dt > 0.0) {
            return Err(Error::InvalidParameter {
                name: "time step".into(),
                value: config.dt,
                requirement: "be finite and positive".into(),
            });
        }
        if config.check_every == 0 {
            return Err(Error::InvalidParameter {
                name: "check_every".into(),
                value: 0.0,
                requirement: "be at least 1 step".into(),
            });
        }
        let bound = config.force_model.stable_time_step(&model)?;
        // The stable bound limits the explicit schemes; backward Euler is stable at any step.
        if config.dt > bound.dt && !config.allow_unstable && !config.integrator.is_implicit() {
            return Err(Error::UnstableTimeStep {
                dt: config.dt,
                bound: bound.dt,
                node: bound.node,
            });
        }
        let (engine, kind, mut note) = make_engine(&model, kind, config, gpu, &host)?;
        if let Some(precision) = float32_precision_note(kind, &config, &bound) {
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
            gpu,
            kind,
            bound,
            steps: 0,
            surface: None,
            surface_generation: 0,
            host,
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
            contact_constraints: Vec::new(),
            note,
            watch: None,
            steps_since_inversion: 0,
            good_energy: None,
            good_shape: None,
            last_good: 0,
            last_upright: 0,
            changes: 0,
        };
        sim.reset_energy_reference();
        sim.keep_start();
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

    /// Run `steps` steps, checking for divergence every `check_every` steps and at the end,
    /// and the watched tets ([`Simulation::watch_mesh`]) for inversion at the first check at
    /// least [`INVERSION_CHECK_EVERY`] steps after the last. A check that measures the total
    /// energy exactly also lowers the reference that position corrections raised (see
    /// [`Simulation::correct_positions`]): every check on the reference engine; on the GPU and
    /// fast CPU engines, whose checks read a cheap probe
    /// ([`crate::engine::Engine::divergence_probe`]), one every [`EXACT_CHECK_EVERY`] steps
    /// while corrections hold the reference up, and one every [`INVERSION_CHECK_EVERY`] steps
    /// in any case.
    ///
    /// A failed check replays the steps since the last state a check kept (exact checks keep
    /// theirs), one at a time, and reports the first bad step; the simulation is left there.
    /// Where the run was changed since that state (corrections, cuts, a new state or time
    /// step), it reports the check's step and the last good one ([`crate::BadStep`]).
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
            let held = self.constrained_positions()?;
            self.engine.step(chunk);
            self.steps += chunk as u64;
            self.count_constraint_work(&held)?;
            done += chunk as u64;
            self.steps_since_exact += chunk as u64;
            self.steps_since_inversion += chunk as u64;
            // Engines with a cheap probe measure the total only now and then: while
            // corrections hold the reference more than a scale above where it was taken, and
            // at the inversion cadence, so that a failure has a state to replay from.
            let force = self.steps_since_inversion >= INVERSION_CHECK_EVERY
                || (self.steps_since_exact >= EXACT_CHECK_EVERY
                    && self.start_energy > self.base_energy + self.base_scale);
            if let Some(total) = self.check_run(force)? {
                self.tighten_reference(total);
                self.steps_since_exact = 0;
            }
            self.check_inversion_due()?;
            progress(done);
        }
        Ok(())
    }

    /// Wait until the steps already submitted have run (the GPU engine queues them; the CPU
    /// engines have finished when `run` returns). For timing what follows a step apart from
    /// the step itself.
    pub fn wait(&mut self) {
        if let Some(d) = self.engine.device_mut() {
            d.wait();
        }
    }

    /// Advance `steps` steps with no divergence check (for timing); call
    /// [`Simulation::check`] afterwards.
    pub fn step_unchecked(&mut self, steps: u32) {
        if steps > 0 {
            self.hand_prefetch();
        }
        self.engine.step(steps);
        self.wait();
        self.steps += steps as u64;
        self.steps_since_inversion += steps as u64;
    }

    /// Device time of the last [`Simulation::step_unchecked`] call, s, where the engine can
    /// measure it (the GPU engine on an adapter with timestamp queries).
    pub fn last_device_seconds(&self) -> Option<f64> {
        self.engine.device()?.last_device_seconds()
    }

    /// What the implicit integrator's solver did so far (`None` for an explicit scheme).
    pub fn solver_stats(&self) -> Option<crate::physics::SolverStats> {
        self.engine.solver_stats()
    }

    /// The bytes one iteration of the implicit integrator's solver moves at least (`None` for
    /// an explicit scheme or an engine that does not count them).
    pub fn bytes_per_solver_iteration(&self) -> Option<u64> {
        self.engine.bytes_per_solver_iteration()
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

    /// Replace the state (initial displacement or velocity); resets the divergence reference.
    pub fn set_state(&mut self, positions: &[[f64; 3]], velocities: &[[f64; 3]]) -> Result<()> {
        let n = self.model.node_count();
        if positions.len() != n || velocities.len() != n {
            return Err(Error::LengthMismatch {
                given: if positions.len() != n {
                    positions.len()
                } else {
                    velocities.len()
                },
                expected: n,
                message: format!(
                    "state has {} positions and {} velocities for {n} nodes",
                    positions.len(),
                    velocities.len()
                ),
            });
        }
        self.engine.set_state(positions, velocities);
        self.reset_energy_reference();
        self.keep_start();
        Ok(())
    }

    /// Keep the current state as the start of any replay: a new run or a new state, which
    /// nothing before can be replayed into.
    fn keep_start(&mut self) {
        self.changes += 1;
        let (x, v) = self.engine.state();
        let snap = Snapshot {
            step: self.steps,
            changes: self.changes,
            x,
            v,
        };
        self.good_shape = Some(snap.clone());
        self.good_energy = Some(snap);
        self.last_good = self.steps;
        self.last_upright = self.steps;
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

    /// The GPU engine's layout and accumulation this simulation was set up with (see
    /// [`Simulation::with_gpu`]; the CPU engines ignore them).
    pub fn gpu_options(&self) -> GpuOptions {
        self.gpu
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
impl crate::engine::reading::PositionSource for Simulation {
    fn near(&mut self, lo: [f64; 3], hi: [f64; 3]) -> Result<Vec<(u32, [f64; 3])>> {
        self.nodes_near(lo, hi)
    }

    fn of(&mut self, nodes: &[u32]) -> Result<Vec<[f64; 3]>> {
        self.node_positions(nodes)
    }
}
