//! `lancet report accuracy`: error against run time.
//!
//! A scene is run on each engine (and each GPU layout) at a ladder of time steps up to the
//! stable bound. At fixed simulated times each run's positions are compared with a converged
//! float64 reference of the same scene (the classical fourth-order Runge–Kutta scheme,
//! [`crate::physics::RungeKutta4`], on the reference engine, by default at 1/4 of the bound:
//! it converges sixteen times per halving where the engines' Verlet converges two to four
//! times, so a converged reference costs 16 force evaluations per stable step instead of the 64
//! Verlet steps at 1/64 of the bound it replaced), giving the relative L2 error of the nodal displacements and the largest
//! nodal error in metres. Beside each error stands the wall time the engine needed per simulated
//! second, so that a user sees what accuracy costs.
//!
//! The reference is also run at twice its step; the difference between the two (its
//! *self-check*) shows how far the reference itself is from convergence: at fourth order its
//! own error is about a fifteenth of that difference.
//!
//! Two things make a scene's runs converge at first order in the time step, not the second
//! order of Verlet, and the ladder shows it: the engines start Verlet with the previous
//! positions equal to the current ones, so under a load (gravity) the first step moves
//! `h^2 a0` where the exact motion moves `h^2 a0 / 2`, an `O(h)` error in the initial
//! velocity; and the damping force uses the backward-difference velocity, also `O(h)`. From an
//! unloaded state with an initial velocity ([`AccuracyOptions::initial_velocity`]) and no
//! damping, halving the step cuts the error four times.
//!
//! Every step count lands exactly on the sample times: each rung of the ladder uses the largest
//! step at or below its target that divides all sample times ([`step_for_times`]).

use serde::Serialize;

mod runs;
use runs::{errors_of, gpu_series, run_reference, run_to};

use crate::engine::{EngineKind, GpuOptions, Integrator, SimConfig};
use crate::error::{Error, Result};
use crate::layout::edges::Accumulation;
use crate::layout::LayoutKind;
use crate::model::PackedModel;

/// The default ladder of time steps, as fractions of the stable bound.
pub const DEFAULT_LADDER: [f64; 5] = [1.0, 0.5, 0.25, 0.125, 0.0625];

/// The default ladder of the implicit series ([`Integrator::BackwardEuler`]), as multiples of
/// the explicit stable bound: the implicit step is stable above it, and what it buys is read
/// there. A rung at the bound itself (`1`) costs a conjugate-gradient solve per explicit step
/// (on the default scene 64 s of wall per simulated second on the reference engine, against
/// 2.8 for explicit Verlet there), so it is left to be asked for.
pub const DEFAULT_IMPLICIT_LADDER: [f64; 3] = [4.0, 16.0, 64.0];

/// The default error that "time to error" compares the series at: the least wall time per
/// simulated second among a series' rows whose worst relative L2 error is at or below it.
pub const DEFAULT_TARGET_ERROR: f64 = 1e-3;

/// The default step of the converged reference (fourth-order Runge–Kutta), as a fraction of
/// the stable bound.
pub const DEFAULT_REFERENCE_FRACTION: f64 = 1.0 / 4.0;

/// What to run.
#[derive(Debug, Clone)]
pub struct AccuracyOptions {
    /// Engines to measure. `Auto` is taken as `Gpu`; GPU rows are skipped (with the reason in
    /// [`AccuracyReport::skipped`]) when there is no usable adapter.
    pub engines: Vec<EngineKind>,
    /// Layouts to run each GPU engine in.
    pub layouts: Vec<LayoutKind>,
    /// How the edge layout accumulates spring forces: one series per variant (`gpu-edges` for
    /// the gather, `gpu-edges-atomic-fixed`, `gpu-edges-atomic-float`); a variant the adapter
    /// cannot run is listed in [`AccuracyReport::skipped`] with the reason.
    pub accumulations: Vec<Accumulation>,
    /// Time steps as fractions of the stable bound, each in (0, 1].
    pub ladder: Vec<f64>,
    /// Time steps of the implicit series (backward Euler on each engine that has it) as
    /// multiples of the stable bound, each finite and positive; empty for no implicit series.
    /// An engine without an implicit integrator is listed in [`AccuracyReport::skipped`].
    pub implicit_ladder: Vec<f64>,
    /// The error the report's time-to-error summary compares the series at
    /// ([`AccuracyReport::time_to_error`]).
    pub target_error: f64,
    /// Simulated times at which errors are measured, s; empty for a quarter, a half and all of
    /// the run's duration.
    pub times: Vec<f64>,
    /// Step of the converged reference as a fraction of the bound; it is also run at twice this
    /// step for its self-check.
    pub reference_fraction: f64,
    /// Steps run (and thrown away) before timing each row: first touches of memory, thread
    /// pools, shader compilation.
    pub warmup_steps: u32,
    /// Steps per timed batch (batches also end at sample times).
    pub batch: u64,
    /// Start every run at the rest positions with these velocities (packed node order, m/s)
    /// instead of at rest. Scenes start at rest; a run from rest under a load converges at
    /// first order only (see the module notes), so a study of the integrator's order starts
    /// from an unloaded state with a velocity instead.
    pub initial_velocity: Option<Vec<[f64; 3]>>,
    /// The force model every run steps (the reference and each engine): springs by default;
    /// [`scene_accuracy`] takes the scene's `force_model`. A finite-element model runs on the
    /// CPU engines (GPU rows are skipped with the reason, as is backward Euler on the fast
    /// engine), its ladder in fractions of its own stable bound.
    pub force_model: crate::physics::ForceModelKind,
    /// How the implicit series solve each step: [`scene_accuracy`] takes the scene's `solver`
    /// (a stiff scene raises the iteration cap, which the default of 100 would otherwise cut
    /// short at large steps).
    pub solver: crate::physics::SolverSettings,
}

impl Default for AccuracyOptions {
    fn default() -> Self {
        AccuracyOptions {
            engines: vec![EngineKind::Reference, EngineKind::Fast, EngineKind::Gpu],
            layouts: vec![
                LayoutKind::Connectivity,
                LayoutKind::Valence,
                LayoutKind::Edges,
            ],
            accumulations: vec![Accumulation::Gather],
            ladder: DEFAULT_LADDER.to_vec(),
            implicit_ladder: DEFAULT_IMPLICIT_LADDER.to_vec(),
            target_error: DEFAULT_TARGET_ERROR,
            times: Vec::new(),
            reference_fraction: DEFAULT_REFERENCE_FRACTION,
            warmup_steps: 20,
            batch: 500,
            initial_velocity: None,
            force_model: crate::physics::ForceModelKind::Springs,
            solver: crate::physics::SolverSettings::default(),
        }
    }
}

/// The error of one run at one sample time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SampleError {
    /// Simulated time, s.
    pub time: f64,
    /// `|x - x_ref| / |x_ref - x_rest|` over all nodes.
    pub relative_l2: f64,
    /// Largest nodal distance `|x_i - x_ref,i|`, m.
    pub max_error_m: f64,
}

/// One engine (and layout) at one time step.
#[derive(Debug, Clone, Serialize)]
pub struct AccuracyRow {
    /// Engine and layout without the device, e.g. `cpu-fast-f32` or `gpu-valence`: the series
    /// name in tables and plots; implicit series end in `-backward-euler`.
    pub series: String,
    /// The integration scheme of the row.
    pub integrator: String,
    /// The engine's full name (with its device for the GPU).
    pub engine: String,
    /// The ladder fraction asked for (a multiple of the bound for implicit rows).
    pub fraction: f64,
    /// The step used, s (at or below `fraction` times the bound, dividing the sample times).
    pub dt: f64,
    /// `dt` over the stable bound.
    pub dt_over_bound: f64,
    /// Steps to the last sample time.
    pub steps: u64,
    /// Wall time of the stepping per simulated second (setup and warm-up excluded).
    pub wall_s_per_sim_s: f64,
    /// The error at each sample time (empty if the run diverged before the first).
    pub errors: Vec<SampleError>,
    /// The divergence message, if the run diverged.
    pub diverged: Option<String>,
    /// For an implicit row: the conjugate-gradient iterations per linear solve (one solve a
    /// step unless more Newton iterations are asked for) over the timed steps, mean and most;
    /// where an implicit series' time goes.
    pub cg_iterations: Option<CgIterations>,
}

/// What the implicit solver did over a row's timed steps.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CgIterations {
    /// Mean conjugate-gradient iterations per solve.
    pub mean: f64,
    /// Solves that stopped above the tolerance (at the iteration cap).
    pub capped: u64,
}

impl AccuracyRow {
    /// The largest relative L2 error over the sample times (NaN if there is none).
    pub fn worst_relative_l2(&self) -> f64 {
        worst(&self.errors)
    }
}

/// The converged reference and how converged it is.
#[derive(Debug, Clone, Serialize)]
pub struct ReferenceRun {
    /// Engine (always the float64 reference engine).
    pub engine: String,
    /// Its step, s.
    pub dt: f64,
    /// Its step over the stable bound.
    pub dt_over_bound: f64,
    /// Steps to the last sample time.
    pub steps: u64,
    /// Wall time per simulated second.
    pub wall_s_per_sim_s: f64,
    /// The step of the self-check run: `2 dt`, or the largest step below that which divides the
    /// sample times.
    pub check_dt: f64,
    /// The self-check run's error against the reference at each sample time. The reference's
    /// own error is about a third of this for undamped (second-order) Verlet, about equal to
    /// it with damping (first order).
    pub self_error: Vec<SampleError>,
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct AccuracyReport {
    /// Scene name.
    pub scene: String,
    /// Nodes of the model.
    pub nodes: usize,
    /// Springs of the model.
    pub springs: usize,
    /// Integration scheme.
    pub integrator: String,
    /// Force model ("springs", "tensor-mass", "corotational").
    pub force_model: String,
    /// Stable time-step bound, s.
    pub dt_bound: f64,
    /// Simulated times at which errors are measured, s.
    pub sample_times: Vec<f64>,
    /// The converged reference.
    pub reference: ReferenceRun,
    /// One row per engine/layout and ladder step, grouped by series.
    pub rows: Vec<AccuracyRow>,
    /// Engines that were asked for but not run, with the reason.
    pub skipped: Vec<String>,
}

impl AccuracyReport {
    /// The series names in row order, each once.
    pub fn series(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for r in &self.rows {
            if !out.contains(&r.series) {
                out.push(r.series.clone());
            }
        }
        out
    }

    /// For each series, the least wall time per simulated second among its rows whose worst
    /// relative L2 error is at or below `target` (`None` when no row reaches it): what the
    /// series costs to reach that accuracy.
    pub fn time_to_error(&self, target: f64) -> Vec<(String, Option<f64>)> {
        self.series()
            .into_iter()
            .map(|name| {
                let best = self
                    .rows
                    .iter()
                    .filter(|r| r.series == name && r.diverged.is_none())
                    .filter(|r| r.worst_relative_l2() <= target)
                    .map(|r| r.wall_s_per_sim_s)
                    .min_by(f64::total_cmp);
                (name, best)
            })
            .collect()
    }

    /// The largest self-check error of the reference over the sample times.
    pub fn reference_self_error(&self) -> f64 {
        worst(&self.reference.self_error)
    }
}

fn worst(errors: &[SampleError]) -> f64 {
    errors
        .iter()
        .map(|e| e.relative_l2)
        .fold(f64::NAN, f64::max)
}

/// A quarter, a half and all of `duration`.
pub fn default_sample_times(duration: f64) -> Vec<f64> {
    vec![duration / 4.0, duration / 2.0, duration]
}

/// The largest step at or below `target` that divides every one of `times`, and the number of
/// steps to each time.
///
/// With `t0` the smallest time, candidates are `t0 / n` for `n = ceil(t0 / target), ...`; the
/// first for which every time is an integer number of steps (to 1e-9 relative) wins. Times
/// with no common step near `target` (irrational ratios) are an error.
pub fn step_for_times(times: &[f64], target: f64) -> Result<(f64, Vec<u64>)> {
    if !(target.is_finite() && target > 0.0) {
        return Err(Error::Options(format!(
            "target time step {target} must be finite and positive"
        )));
    }
    let t0 = times.iter().copied().fold(f64::INFINITY, f64::min);
    if times.is_empty() || !(t0.is_finite() && t0 > 0.0) || times.iter().any(|t| !t.is_finite()) {
        return Err(Error::Options(format!(
            "sample times {times:?} must be finite and positive"
        )));
    }
    let n0 = (t0 / target * (1.0 - 1e-12)).ceil().max(1.0) as u64;
    for n in n0..n0 + n0.max(1000) {
        let dt = t0 / n as f64;
        let counts: Vec<f64> = times.iter().map(|t| t / dt).collect();
        if counts
            .iter()
            .all(|c| (c - c.round()).abs() <= 1e-9 * c.max(1.0))
        {
            // `t0 / n` may round a few ulps above a target it equals in exact arithmetic (the
            // slack in `n0` lets it): never return a step above the target, which the
            // simulation would refuse when the target is the stable bound itself.
            return Ok((
                dt.min(target),
                counts.iter().map(|c| c.round() as u64).collect(),
            ));
        }
    }
    Err(Error::Options(format!(
        "no time step near {target:e} s divides all sample times {times:?}; give times that are \
         simple multiples of one another"
    )))
}

/// Largest nodal distance between `x` and `x_ref`, m.
pub fn max_nodal_error(x: &[[f64; 3]], x_ref: &[[f64; 3]]) -> f64 {
    x.iter()
        .zip(x_ref)
        .map(|(a, b)| {
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
        })
        .fold(0.0, f64::max)
}

/// The accuracy report of `model` run for `duration` simulated seconds with `integrator`.
///
/// `progress` receives a line before each run starts (what runs, at which step), for a
/// command line to show on stderr. Setup errors are returned; a row that diverges is kept with
/// its message and no errors.
pub fn model_accuracy(
    name: &str,
    model: &PackedModel,
    integrator: Integrator,
    duration: f64,
    opts: &AccuracyOptions,
    mut progress: impl FnMut(&str),
) -> Result<AccuracyReport> {
    let bound = opts.force_model.stable_time_step(model)?;
    if !bound.dt.is_finite() {
        return Err(Error::Options(
            "the model has no finite stable time step (nothing free to oscillate), so there is \
             no ladder to run"
                .into(),
        ));
    }
    if opts.engines.is_empty() {
        return Err(Error::Options("no engine to measure".into()));
    }
    if let Some(v) = &opts.initial_velocity {
        if v.len() != model.node_count() {
            return Err(Error::Options(format!(
                "initial velocity has {} entries for {} nodes",
                v.len(),
                model.node_count()
            )));
        }
    }
    if opts.ladder.is_empty() {
        return Err(Error::Options("the time-step ladder is empty".into()));
    }
    if let Some(f) = opts
        .ladder
        .iter()
        .chain([&opts.reference_fraction])
        .find(|f| !(f.is_finite() && **f > 0.0 && **f <= 1.0))
    {
        return Err(Error::Options(format!(
            "time-step fraction {f} must be in (0, 1]: steps above the stable bound are refused"
        )));
    }
    if let Some(m) = opts
        .implicit_ladder
        .iter()
        .find(|m| !(m.is_finite() && **m > 0.0))
    {
        return Err(Error::Options(format!(
            "implicit time-step multiple {m} of the bound must be finite and positive"
        )));
    }
    let times = if opts.times.is_empty() {
        if !(duration.is_finite() && duration > 0.0) {
            return Err(Error::Options(format!(
                "simulated duration {duration} s must be finite and positive"
            )));
        }
        default_sample_times(duration)
    } else {
        let mut t = opts.times.clone();
        t.sort_by(f64::total_cmp);
        t.dedup();
        t
    };
    let base = SimConfig {
        integrator,
        force_model: opts.force_model,
        solver: opts.solver,
        ..SimConfig::new(bound.dt)
    };

    // The reference takes its step by the same rule as the ladder, so that a rung at the
    // reference's fraction reproduces it exactly; the self-check takes the largest step at or
    // below twice that (exactly twice when the reference's step counts are even).
    let (ref_dt, ref_counts) = step_for_times(&times, opts.reference_fraction * bound.dt)?;
    let (check_dt, check_counts) = step_for_times(&times, 2.0 * ref_dt)?;
    let last = |c: &[u64]| c.last().copied().unwrap_or(0);
    progress(&format!(
        "reference: cpu-reference-f64 (runge-kutta-4) at dt {ref_dt:.3e} s ({} steps)",
        last(&ref_counts)
    ));
    let reference = run_reference(model, ref_dt, &ref_counts, opts)?;
    if let Some(m) = reference.diverged {
        return Err(Error::Options(format!("the reference run failed: {m}")));
    }
    progress(&format!(
        "reference self-check at dt {check_dt:.3e} s ({} steps)",
        last(&check_counts)
    ));
    let check = run_reference(model, check_dt, &check_counts, opts)?;
    let reference_run = ReferenceRun {
        engine: reference.engine.clone(),
        dt: ref_dt,
        dt_over_bound: ref_dt / bound.dt,
        steps: last(&ref_counts),
        wall_s_per_sim_s: reference.wall_per_sim_s(),
        check_dt,
        self_error: errors_of(model, &times, &check.states, &reference.states),
    };

    // The series: each CPU engine once, each GPU engine once per layout.
    let mut skipped = Vec::new();
    let mut gpu_state: Option<std::result::Result<(), String>> = None;
    let mut series: Vec<(EngineKind, GpuOptions, String)> = Vec::new();
    for &e in &opts.engines {
        let e = if e == EngineKind::Auto {
            EngineKind::Gpu
        } else {
            e
        };
        let entries: Vec<(GpuOptions, String)> = match e {
            EngineKind::Gpu => {
                let usable = gpu_state.get_or_insert_with(super::gpu_usable);
                if let Err(why) = usable {
                    let msg = format!("gpu rows skipped: {why}");
                    if !skipped.contains(&msg) {
                        skipped.push(msg);
                    }
                    continue;
                }
                gpu_series(&opts.layouts, &opts.accumulations)
            }
            _ => vec![(GpuOptions::default(), e.to_string())],
        };
        for (l, name) in entries {
            if !series.iter().any(|(_, _, n)| *n == name) {
                series.push((e, l, name));
            }
        }
    }

    // Each engine's explicit series, then its implicit one (when the scene's scheme is
    // explicit: an implicit scene's own ladder is already implicit).
    let implicit_ladder: &[f64] = if integrator.is_implicit() {
        &[]
    } else {
        &opts.implicit_ladder
    };
    let mut runs: Vec<(EngineKind, GpuOptions, String, Integrator, &[f64])> = Vec::new();
    for (kind, gpu, name) in &series {
        runs.push((*kind, *gpu, name.clone(), integrator, &opts.ladder));
    }
    if !implicit_ladder.is_empty() {
        for (kind, gpu, name) in &series {
            let implicit = Integrator::BackwardEuler;
            let name = format!("{name}-backward-euler");
            runs.push((*kind, *gpu, name, implicit, implicit_ladder));
        }
    }
    let mut rows = Vec::new();
    'series: for (kind, gpu, name, integrator, ladder) in &runs {
        for &fraction in ladder.iter() {
            let (dt, counts) = step_for_times(&times, fraction * bound.dt)?;
            let of = if integrator.is_implicit() {
                format!("{fraction} times the bound")
            } else {
                format!("{fraction} of the bound")
            };
            progress(&format!(
                "{name} at dt {dt:.3e} s ({of}, {} steps)",
                last(&counts)
            ));
            let config = SimConfig {
                dt,
                integrator: *integrator,
                ..base
            };
            let run = match run_to(model, (*kind, *gpu), config, &counts, opts) {
                Ok(run) => run,
                // A variant the adapter lacks a feature for (float atomics), or an engine
                // without the implicit integrator, is skipped with the reason; the other
                // series still run.
                Err(Error::Unsupported(why))
                    if *kind == EngineKind::Gpu
                        || integrator.is_implicit()
                        || opts.force_model.is_finite_element() =>
                {
                    skipped.push(format!("{name} skipped: {why}"));
                    continue 'series;
                }
                Err(e) => return Err(e),
            };
            let wall_s_per_sim_s = run.wall_per_sim_s();
            rows.push(AccuracyRow {
                series: name.clone(),
                integrator: format!("{integrator:?}"),
                engine: run.engine,
                fraction,
                dt,
                dt_over_bound: dt / bound.dt,
                steps: last(&counts),
                wall_s_per_sim_s,
                errors: errors_of(model, &times, &run.states, &reference.states),
                diverged: run.diverged,
                cg_iterations: run.cg_iterations,
            });
        }
    }

    Ok(AccuracyReport {
        scene: name.to_string(),
        nodes: model.node_count(),
        springs: model.springs().len(),
        integrator: format!("{integrator:?}"),
        force_model: opts.force_model.to_string(),
        dt_bound: bound.dt,
        sample_times: times,
        reference: reference_run,
        rows,
        skipped,
    })
}

/// The accuracy report of a scene: its model, integrator and duration (`steps` times its step).
/// `scene_path` locates relative mesh paths and names the scene in messages.
#[cfg(feature = "scene")]
pub fn scene_accuracy(
    scene: &crate::scene::Scene,
    scene_path: &std::path::Path,
    opts: &AccuracyOptions,
    progress: impl FnMut(&str),
) -> Result<AccuracyReport> {
    use crate::scene::runner::{build_mesh, model_config};
    use crate::scene::TimeStep;
    let scene_err = |message: String| Error::Scene {
        path: scene_path.to_path_buf(),
        message,
    };
    // The report steps the scene's model alone: tools, cuts and self-contact would be dropped
    // without a word, and the error of a motionless model means nothing.
    let extras: Vec<&str> = [
        (!scene.tools.is_empty(), "tools"),
        (scene.cut.is_some(), "a cut"),
        (scene.self_contact.is_some(), "self-contact"),
    ]
    .iter()
    .filter(|(has, _)| *has)
    .map(|(_, what)| *what)
    .collect();
    if !extras.is_empty() {
        return Err(scene_err(format!(
            "report accuracy measures the time-step error of the model alone and would run this scene without its {}; give a scene without them (its material, mesh, fixed nodes and gravity)",
            extras.join(", ")
        )));
    }
    let mesh = build_mesh(scene, scene_path)?;
    let model = crate::model::SpringModel::build(&mesh, &model_config(scene))
        .map_err(|e| scene_err(e.to_string()))?
        .pack(&mesh)?;
    let opts = &AccuracyOptions {
        force_model: scene.force_model,
        solver: scene.solver,
        ..opts.clone()
    };
    let bound = scene.force_model.stable_time_step(&model)?.dt;
    let dt = match scene.dt {
        TimeStep::Seconds(s) => s,
        TimeStep::BoundFraction(f) => f * bound,
    };
    let duration = scene.steps as f64 * dt;
    if opts.times.is_empty() && !(duration.is_finite() && duration > 0.0) {
        return Err(scene_err(format!(
            "the scene's duration ({} steps of {dt:e} s) is not positive; give sample times",
            scene.steps
        )));
    }
    model_accuracy(
        &scene.name,
        &model,
        scene.integrator,
        duration,
        opts,
        progress,
    )
}
