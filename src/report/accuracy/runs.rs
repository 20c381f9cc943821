//! The runs of the accuracy report: one engine (or the float64 Runge–Kutta reference) stepped
//! to each sample time, only the stepping timed, and the errors of its states against the
//! reference's.

use std::time::Instant;

use super::{max_nodal_error, AccuracyOptions, CgIterations, SampleError};
use crate::engine::reference::ReferenceEngine;
use crate::engine::{Engine, EngineKind, GpuOptions, SimConfig, Simulation};
use crate::error::{Error, Result};
use crate::layout::edges::Accumulation;
use crate::layout::LayoutKind;
use crate::model::PackedModel;
use crate::physics::RungeKutta4;
use crate::report::bench::relative_l2;

/// States at the sample times and the stepping wall time of one run.
pub(super) struct Run {
    pub(super) engine: String,
    pub(super) states: Vec<Vec<[f64; 3]>>,
    stepping_s: f64,
    /// Simulated time reached, s (short of the last sample time if the run diverged).
    simulated_s: f64,
    pub(super) diverged: Option<String>,
    pub(super) cg_iterations: Option<CgIterations>,
}

impl Run {
    fn new(engine: String, samples: usize) -> Self {
        Run {
            engine,
            states: Vec::with_capacity(samples),
            stepping_s: 0.0,
            simulated_s: 0.0,
            diverged: None,
            cg_iterations: None,
        }
    }

    pub(super) fn wall_per_sim_s(&self) -> f64 {
        self.stepping_s / self.simulated_s
    }

    /// Step `state` to each of `counts` steps of `dt`, in batches of at most `batch`: `step`
    /// advances (the only part timed), `failure` may end the run after each batch, `sample`
    /// reads the positions at each count (or says why they are unusable, which ends the run).
    #[allow(clippy::too_many_arguments)]
    fn through<S>(
        mut self,
        state: &mut S,
        counts: &[u64],
        batch: u64,
        dt: f64,
        step: impl Fn(&mut S, u32),
        failure: impl Fn(&S, u64) -> Option<String>,
        sample: impl Fn(&S, u64) -> std::result::Result<Vec<[f64; 3]>, String>,
    ) -> Self {
        let mut done = 0u64;
        for &target in counts {
            while done < target {
                let n = batch.max(1).min(target - done).min(u32::MAX as u64);
                let t = Instant::now();
                step(state, n as u32);
                self.stepping_s += t.elapsed().as_secs_f64();
                done += n;
                self.simulated_s = done as f64 * dt;
                if let Some(why) = failure(state, done) {
                    self.diverged = Some(why);
                    return self;
                }
            }
            match sample(state, done) {
                Ok(x) => self.states.push(x),
                Err(why) => {
                    self.diverged = Some(why);
                    return self;
                }
            }
        }
        self
    }
}

/// Run `model` on `kind` (in `layout` on the GPU) at `config.dt`, stopping at each of `counts` steps to read positions.
/// Only the stepping is timed (after a warm-up and a reset to rest); divergence checks and
/// readbacks are not.
pub(super) fn run_to(
    model: &PackedModel,
    (kind, gpu): (EngineKind, GpuOptions),
    config: SimConfig,
    counts: &[u64],
    opts: &AccuracyOptions,
) -> Result<Run> {
    let mut sim = Simulation::with_gpu(model.clone(), kind, config, gpu)?;
    let engine = sim.engine_name();
    sim.step_unchecked(opts.warmup_steps);
    let zero = vec![[0.0; 3]; model.node_count()];
    sim.set_state(&model.rest, opts.initial_velocity.as_ref().unwrap_or(&zero))?;
    let dt = config.dt;
    let warm = sim.solver_stats();
    let mut run = Run::new(engine, counts.len()).through(
        &mut sim,
        counts,
        opts.batch,
        dt,
        |sim, n| sim.step_unchecked(n),
        |sim, done| {
            // `step_unchecked` counted the warm-up too; report the step of this run.
            sim.check().err().map(|e| match e {
                Error::Diverged { node, reason, .. } => format!(
                    "diverged by step {done} (t = {:.4e} s), node {node}: {reason}",
                    done as f64 * dt
                ),
                e => e.to_string(),
            })
        },
        |sim, _| Ok(sim.positions()),
    );
    // The solver's counts over the timed steps: the warm-up's taken off.
    if let (Some(w), Some(end)) = (warm, sim.solver_stats()) {
        let solves = end.solves - w.solves;
        if solves > 0 {
            run.cg_iterations = Some(CgIterations {
                mean: (end.iterations - w.iterations) as f64 / solves as f64,
                capped: end.capped - w.capped,
            });
        }
    }
    Ok(run)
}

/// The GPU series: one per layout, and for the edge layout one per accumulation variant
/// (`gpu-edges` for the gather, `gpu-edges-<variant>` for the others).
pub(super) fn gpu_series(
    layouts: &[LayoutKind],
    accumulations: &[Accumulation],
) -> Vec<(GpuOptions, String)> {
    let mut out = Vec::new();
    for &layout in layouts {
        let base = format!("gpu-{layout:?}").to_lowercase();
        if layout != LayoutKind::Edges {
            out.push((GpuOptions::from(layout), base));
            continue;
        }
        let variants = if accumulations.is_empty() {
            &[Accumulation::Gather][..]
        } else {
            accumulations
        };
        for &accumulation in variants {
            let name = match accumulation {
                Accumulation::Gather => base.clone(),
                a => format!("{base}-{}", crate::report::bench::accumulation_name(a)),
            };
            out.push((
                GpuOptions {
                    layout,
                    accumulation,
                },
                name,
            ));
        }
    }
    out
}

/// The converged reference: [`RungeKutta4`] on the float64 reference engine at `dt`, read at
/// each of `counts` steps. A state that is not finite ends it as diverged.
pub(super) fn run_reference(
    model: &PackedModel,
    dt: f64,
    counts: &[u64],
    opts: &AccuracyOptions,
) -> Result<Run> {
    let mut engine = ReferenceEngine::with_integrator(model, dt, Box::new(RungeKutta4::new()))
        .with_force_model(model, opts.force_model)?;
    let zero = vec![[0.0; 3]; model.node_count()];
    engine.set_state(&model.rest, opts.initial_velocity.as_ref().unwrap_or(&zero));
    let name = format!("{} ({})", engine.name(), engine.integrator_name());
    Ok(Run::new(name, counts.len()).through(
        &mut engine,
        counts,
        opts.batch,
        dt,
        |engine, n| engine.step(n),
        |_, _| None,
        |engine, done| {
            let x = engine.positions();
            match x.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
                Some(i) => Err(format!("node {i} is not finite by step {done}")),
                None => Ok(x),
            }
        },
    ))
}

/// Errors of `states` against the reference states at the sample times.
pub(super) fn errors_of(
    model: &PackedModel,
    times: &[f64],
    states: &[Vec<[f64; 3]>],
    reference: &[Vec<[f64; 3]>],
) -> Vec<SampleError> {
    states
        .iter()
        .zip(reference)
        .zip(times)
        .map(|((x, x_ref), &time)| SampleError {
            time,
            relative_l2: relative_l2(&model.rest, x, x_ref),
            max_error_m: max_nodal_error(x, x_ref),
        })
        .collect()
}
