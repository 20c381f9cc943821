//! Running a scene: build the mesh and model, step, write frames, check expectations.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use super::driver::SceneDriver;
use super::expect::{self, ExpectationResult, FinalState};
use super::schema::{resolve_mesh_path, MeshSource, Scene};
use crate::engine::{Energy, EngineKind};
use crate::error::{Error, Result};
use crate::mesh::generate::{beam, BoxGrid};
use crate::mesh::io::pvd::PvdWriter;
use crate::mesh::TetMesh;
use crate::model::ModelConfig;
use crate::world::{World, WorldBuilder};

/// Overrides from the command line or the embedding program.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Run on this engine instead of the scene's.
    pub engine: Option<EngineKind>,
    /// Use this GPU layout instead of the scene's.
    pub layout: Option<crate::layout::LayoutKind>,
    /// Use this accumulation in the GPU edge layout instead of the scene's.
    pub accumulation: Option<crate::layout::edges::Accumulation>,
    /// Run this many steps instead of the scene's.
    pub steps: Option<u64>,
    /// Write frames here instead of the scene's output folder.
    pub output_dir: Option<PathBuf>,
    /// Do not write any output.
    pub no_output: bool,
    /// Cut with this method instead of the scene's first.
    pub cut_method: Option<crate::cut::CutMethod>,
    /// Check the cut invariants after every cut.
    pub check: bool,
    /// Steps between frames instead of the scene's `output.every` (or a tenth of the run).
    pub frame_every: Option<u64>,
}

/// What the implicit integrator's conjugate-gradient solver did over a run.
#[derive(Debug, Clone, Serialize)]
pub struct SolverReport {
    /// Linear solves (steps times Newton iterations).
    pub solves: u64,
    /// Mean conjugate-gradient iterations per solve.
    pub mean_iterations: f64,
    /// The most iterations one solve took.
    pub max_iterations: u32,
    /// Relative residual at the end of the last solve.
    pub final_residual: f64,
    /// Solves that stopped above the tolerance (at the iteration cap).
    pub capped: u64,
    /// The tolerance asked for.
    pub tolerance: f64,
    /// The iteration cap asked for.
    pub iteration_cap: u32,
    /// Sparse Cholesky factorisations taken (the factored preconditioner only).
    pub factorisations: u64,
    /// Wall time of those factorisations, seconds.
    pub factor_seconds: f64,
    /// Applications of the factor (a pair of triangular solves each) over the run.
    pub factor_solves: u64,
}

impl SolverReport {
    /// The report of `stats` under `settings`.
    pub fn new(
        stats: crate::physics::SolverStats,
        settings: crate::physics::SolverSettings,
    ) -> Self {
        SolverReport {
            solves: stats.solves,
            mean_iterations: stats.mean_iterations(),
            max_iterations: stats.max_iterations,
            final_residual: stats.last_residual,
            capped: stats.capped,
            tolerance: settings.tolerance,
            iteration_cap: settings.max_iterations,
            factorisations: stats.factorisations,
            factor_seconds: stats.factor_seconds,
            factor_solves: stats.factor_solves,
        }
    }
}

/// What a run did, for humans and for `--json`.
#[derive(Debug, Clone, Serialize)]
pub struct RunSummary {
    /// The scene's name.
    pub scene: String,
    /// Nodes, tets and springs of the model.
    pub nodes: usize,
    /// Tets.
    pub tets: usize,
    /// Springs.
    pub springs: usize,
    /// Steps taken.
    pub steps: u64,
    /// Simulated time, s: the steps taken at each time step, summed (a cut under the `Substep`
    /// policy lowers the step during the run).
    pub simulated_s: f64,
    /// Time step the run started with, s.
    pub dt: f64,
    /// Stable bound at the start, s.
    pub dt_bound: f64,
    /// Node that limits the bound at the start.
    pub dt_bound_node: usize,
    /// Time step at the end, s: `dt` unless a cut lowered it (`Substep`).
    pub dt_final: f64,
    /// Stable bound at the end, s (cuts change it).
    pub dt_bound_final: f64,
    /// Node that limits the bound at the end.
    pub dt_bound_node_final: usize,
    /// Engine that ran (with its device for the GPU).
    pub engine: String,
    /// Why the engine differs from the one asked for (no GPU for `Auto`), if it does.
    pub engine_note: Option<String>,
    /// Integration scheme.
    pub integrator: String,
    /// What the implicit integrator's solver did (`integrator: BackwardEuler`).
    pub solver: Option<SolverReport>,
    /// Force model (`springs`, `tensor-mass`, `corotational`).
    pub force_model: String,
    /// Wall time of the stepping, s.
    pub wall_s: f64,
    /// Steps per second of wall time.
    pub steps_per_s: f64,
    /// Largest nodal displacement at the end, m.
    pub max_displacement: f64,
    /// Deformed over rest volume at the end.
    pub volume_ratio: f64,
    /// Energies at the end.
    pub energy: Energy,
    /// Whether the run diverged.
    pub diverged: bool,
    /// Whether the time step was refused.
    pub refused: bool,
    /// Whether the run stopped early because a cut lowered the stable bound below dt (cut
    /// policy `Stop`).
    pub stopped: bool,
    /// The divergence, refusal or stop message.
    pub message: Option<String>,
    /// Frames written (VTU files).
    pub frames_written: usize,
    /// The `.pvd` series written, if any.
    pub pvd: Option<PathBuf>,
    /// The render surface (scenes with `surface`): its size and the frames written of it.
    pub surface: Option<super::surface::SurfaceReport>,
    /// The `.glb` frames and the tools' VTP series written beside the VTU frames, if any.
    pub frame_files: Option<super::frames::FrameFilesReport>,
    /// What each tool felt (scenes with tools).
    pub tools: Vec<super::expect::ToolReport>,
    /// The cut method of this run (scenes that cut).
    pub cut_method: Option<String>,
    /// What the cuts did (scenes that cut).
    pub cuts: Option<super::cuts::CutReport>,
    /// Steps at which the tissue's surfaces touched each other (scenes with self-contact).
    pub self_contact_steps: u64,
    /// Deepest self-penetration found before it was resolved, m.
    pub self_contact_deepest: f64,
    /// Each expectation's outcome.
    pub expectations: Vec<ExpectationResult>,
    /// Whether all expectations held (and the run neither diverged nor was refused, unless
    /// expected).
    pub expectations_passed: bool,
}

/// Steps between checks for inverted tets (unless the scene allows them): the simulation's
/// cadence ([`crate::engine::INVERSION_CHECK_EVERY`]), kept here under its old name.
pub const INVERSION_CHECK_EVERY: u64 = crate::engine::INVERSION_CHECK_EVERY;

/// Build the scene's mesh, with region boxes applied.
pub fn build_mesh(scene: &Scene, scene_path: &Path) -> Result<TetMesh> {
    let dir = scene_path.parent().unwrap_or(Path::new("."));
    let mut mesh = match &scene.mesh {
        MeshSource::File(f) => {
            let p = resolve_mesh_path(f, dir, scene_path)?;
            crate::mesh::io::read(&p)?.mesh
        }
        MeshSource::Box(b) => b.build()?,
        MeshSource::Boxes(boxes) => {
            let mut mesh = TetMesh::new();
            for b in boxes {
                mesh.append(&b.build()?)?;
            }
            mesh
        }
        MeshSource::Beam {
            length,
            width,
            height,
            cells_along,
            cells_across,
            split,
        } => {
            if *split == crate::mesh::generate::TetSplit::Six {
                beam(*length, *width, *height, *cells_along, *cells_across)?
            } else {
                BoxGrid {
                    cells: [*cells_along, *cells_across, *cells_across],
                    size: [*length, *width, *height],
                    origin: [0.0; 3],
                    split: *split,
                }
                .build()?
            }
        }
    };
    scene.mesh_transform.apply_to(&mut mesh);
    for rb in &scene.region_boxes {
        mesh.set_region_where(rb.tag, |c| {
            (0..3).all(|i| c[i] >= rb.min[i] && c[i] <= rb.max[i])
        });
    }
    Ok(mesh)
}

/// The model configuration a scene describes.
pub fn model_config(scene: &Scene) -> ModelConfig {
    ModelConfig {
        material: scene.material,
        regions: scene.regions.clone(),
        gravity: scene.gravity,
        mass_damping: scene.mass_damping,
        fixed: scene.fixed.clone(),
    }
}

/// Run a scene. `scene_path` locates relative paths (its folder) and names the scene in
/// messages. `progress(done, total)` is called as steps complete.
///
/// Setup problems (unreadable mesh, invalid material) are errors. A refused time step or a
/// divergence is reported in the summary, so that scenes can expect them; the summary's
/// `expectations_passed` is false unless they were expected.
pub fn run_scene(
    scene: &Scene,
    scene_path: &Path,
    opts: &RunOptions,
    progress: impl FnMut(u64, u64),
) -> Result<RunSummary> {
    run_scene_with(scene, scene_path, opts, progress, None)
}

/// [`run_scene`], handing every frame (the rest state, then every `every` steps and the last)
/// to `sink` as well, whether or not the run writes files. With a sink and no output folder,
/// frames still come every `opts.frame_every` steps, else the scene's `output.every`, else a
/// tenth of the run.
pub fn run_scene_with(
    scene: &Scene,
    scene_path: &Path,
    opts: &RunOptions,
    mut progress: impl FnMut(u64, u64),
    sink: Option<&mut dyn super::frames::FrameSink>,
) -> Result<RunSummary> {
    let builder = WorldBuilder::from_scene(scene, scene_path, opts)?;
    let (mesh, packed) = (builder.mesh(), builder.packed());
    let bound = builder.bound()?;
    let config = *builder.config();
    let dt = config.dt;
    let engine = opts.engine.unwrap_or(scene.engine);
    let steps = opts.steps.unwrap_or(scene.steps);
    let mut summary = RunSummary {
        scene: scene.name.clone(),
        nodes: packed.node_count(),
        tets: mesh.tet_count(),
        springs: packed.springs().len(),
        steps: 0,
        simulated_s: 0.0,
        dt,
        dt_bound: bound.dt,
        dt_bound_node: bound.node,
        dt_final: dt,
        dt_bound_final: bound.dt,
        dt_bound_node_final: bound.node,
        engine: engine.to_string(),
        engine_note: None,
        integrator: format!("{:?}", scene.integrator),
        solver: None,
        force_model: scene.force_model.to_string(),
        wall_s: 0.0,
        steps_per_s: 0.0,
        max_displacement: 0.0,
        volume_ratio: 1.0,
        energy: Energy {
            kinetic: 0.0,
            elastic: 0.0,
            gravity: 0.0,
        },
        diverged: false,
        refused: false,
        stopped: false,
        message: None,
        frames_written: 0,
        pvd: None,
        surface: None,
        frame_files: None,
        tools: Vec::new(),
        cut_method: None,
        cuts: None,
        self_contact_steps: 0,
        self_contact_deepest: 0.0,
        expectations: Vec::new(),
        expectations_passed: false,
    };
    let sim = match builder.simulation() {
        Ok(sim) => sim,
        Err(e @ Error::UnstableTimeStep { .. }) => {
            summary.refused = true;
            summary.message = Some(e.to_string());
            finish(scene, mesh, packed, &packed.rest, None, &mut summary);
            return Ok(summary);
        }
        Err(e) => return Err(e),
    };
    summary.engine = sim.engine_name();
    summary.engine_note = sim.engine_note().map(str::to_string);
    let mut world = builder.build_with(sim);

    // `--output DIR` turns output on even for a scene without an `output` section, writing
    // about ten frames.
    let every = opts.frame_every.filter(|&e| e > 0).unwrap_or_else(|| {
        scene
            .output
            .as_ref()
            .map_or((steps / 10).max(1), |o| o.every.max(1))
    });
    let dir = output_dir(scene, scene_path, opts);
    let stem = series_stem(scene, opts.cut_method);
    let mut frames = match &dir {
        Some(dir) => {
            let mut w = PvdWriter::new(dir, &stem, Default::default())?;
            w.frame(0.0, world.mesh(), Some(&world.positions()))?;
            summary.pvd = Some(w.pvd_path());
            Some((w, every))
        }
        None => None,
    };
    let mut outputs = super::frames::FrameOutputs::new(
        dir.as_deref()
            .map(|d| super::frames::FrameFiles::new(d, &stem, scene)),
        sink,
    );
    let mut surface =
        super::surface::SurfaceStage::new(scene, scene_path, world.mesh(), dir.as_deref(), &stem)?;
    if let Some(s) = surface.as_mut() {
        s.frame(0.0, &world.positions())?;
    }

    world.set_up_scene(scene, opts)?;
    let mut driver = SceneDriver::new(scene);
    let method = world.cutting().map(|c| c.method());
    if surface.is_some() {
        if let Some(cut) = world.cutting_mut() {
            cut.follow_cuts();
        }
    }
    summary.cut_method = method.map(|m| m.to_string());
    outputs.emit(
        scene,
        world.sim(),
        world.mesh(),
        &world.positions(),
        surface.as_ref(),
        world.tools(),
    )?;
    let start = Instant::now();
    let mut done = 0;
    let every = match &frames {
        Some((_, every)) => *every,
        None if outputs.is_active() => every,
        None => steps.max(1),
    };
    // Cuts leave the tets they touched unwatched until the tets are given again, at the end
    // of a chunk: chunks no longer than the inversion checks are apart.
    let chunk = every.min(INVERSION_CHECK_EVERY);
    while done < steps {
        // Chunks end at every frame's step, so that frames stay `every` steps apart.
        let to_frame = every - done % every;
        let n = chunk.min(to_frame).min(steps - done);
        let result = if world.has_contacts() {
            // Tools move and touch every step: step one at a time.
            (0..n).try_for_each(|k| {
                driver.step(&mut world)?;
                if let (Some(s), Some(cut)) = (surface.as_mut(), world.cutting_mut()) {
                    s.after_cuts(cut);
                }
                progress(done + k + 1, steps);
                Ok(())
            })
        } else {
            world.run_with(n, |d| progress(done + d, steps))
        };
        done = world.sim().steps();
        let result = result.and_then(|()| world.rewatch());
        if let Err(e) = result {
            summary.diverged = matches!(e, Error::Diverged { .. } | Error::Inverted { .. });
            // A cut that lowered the stable bound below dt under the `Stop` policy ends the run
            // here; it is reported, and fails the scene, like a divergence.
            summary.stopped = matches!(e, Error::CutLoweredTimeStep { .. });
            summary.message = Some(e.to_string());
            if !(summary.diverged || summary.stopped) {
                return Err(e);
            }
            break;
        }
        if done == steps {
            finish_surface(&mut world, surface.as_mut());
        }
        let frame_due = done % every == 0 || done == steps;
        if frame_due && (frames.is_some() || outputs.is_active()) {
            // Cuts add nodes at the end and never remove any, so the cut mesh's node order is
            // still the simulation's.
            let x = world.positions();
            if let Some((w, _)) = frames.as_mut() {
                w.frame(world.sim().time(), world.mesh(), Some(&x))?;
                if let Some(s) = surface.as_mut() {
                    s.frame(world.sim().time(), &x)?;
                }
            }
            outputs.emit(
                scene,
                world.sim(),
                world.mesh(),
                &x,
                surface.as_ref(),
                world.tools(),
            )?;
        }
    }
    // A run stopped early (divergence, a cut under `Stop`): its last strokes too.
    finish_surface(&mut world, surface.as_mut());
    let sim = world.sim();
    summary.wall_s = start.elapsed().as_secs_f64();
    summary.steps = sim.steps();
    summary.simulated_s = sim.time();
    summary.dt_final = sim.config().dt;
    summary.dt_bound_final = sim.bound().dt;
    summary.dt_bound_node_final = sim.bound().node;
    summary.steps_per_s = summary.steps as f64 / summary.wall_s.max(1e-12);
    summary.solver = sim
        .solver_stats()
        .map(|stats| SolverReport::new(stats, scene.solver));
    if let Some((w, _)) = frames.as_mut() {
        w.finish()?;
        summary.frames_written = w.frames();
    }
    if let Some(s) = surface.as_mut() {
        s.finish(world.mesh(), &world.positions());
    }
    summary.surface = surface.as_ref().map(super::surface::SurfaceStage::report);
    summary.frame_files = outputs.report();
    summary.energy = sim.energy();
    let x = sim.positions();
    summary.tools = driver.reports;
    summary.self_contact_steps = driver.self_contact_steps;
    summary.self_contact_deepest = driver.self_contact_deepest;
    summary.cuts = world.cut_report();
    finish(scene, world.mesh(), sim.model(), &x, method, &mut summary);
    Ok(summary)
}

/// At the end of a run, give the render surface (if any) the strokes each blade swept since
/// its last cut ([`World::finish_cuts`]): a blade still moving inside the tissue at the end
/// cut the surface along them too. Calling it again gives nothing more.
fn finish_surface(world: &mut World, surface: Option<&mut super::surface::SurfaceStage>) {
    if let Some(s) = surface {
        world.finish_cuts();
        if let Some(cut) = world.cutting_mut() {
            s.after_cuts(cut);
        }
    }
}

/// Fill in the end-of-run measures and check the expectations.
fn finish(
    scene: &Scene,
    mesh: &TetMesh,
    packed: &crate::model::PackedModel,
    x: &[[f64; 3]],
    method: Option<crate::cut::CutMethod>,
    summary: &mut RunSummary,
) {
    let finite = x.iter().all(|p| p.iter().all(|c| c.is_finite()));
    if finite {
        summary.max_displacement = expect::max_displacement(packed, x);
        summary.volume_ratio = expect::deformed_volume(mesh, x) / mesh.volume();
    } else {
        summary.max_displacement = f64::NAN;
        summary.volume_ratio = f64::NAN;
    }
    let state = FinalState {
        mesh,
        model: packed,
        positions: x,
        energy: summary.energy,
        diverged: summary.diverged,
        refused: summary.refused,
        tools: &summary.tools,
        cuts: summary.cuts.as_ref(),
        method,
    };
    summary.expectations = scene
        .expect
        .iter()
        .map(|e| expect::check(e, &state))
        .collect();
    let expected_failure = scene.expect.iter().any(|e| {
        matches!(
            e,
            super::schema::Expectation::Diverges | super::schema::Expectation::RefusesTimeStep
        )
    });
    if summary.refused && !expected_failure {
        // The run took no step: what its expectations would measure is the rest state, which
        // says nothing of the scene. They are shown as not run (the run still fails).
        for r in &mut summary.expectations {
            r.skipped = true;
            r.measured = None;
        }
    }
    let clean = !(summary.diverged || summary.refused) || expected_failure;
    let clean = clean && !summary.stopped;
    summary.expectations_passed = clean && summary.expectations.iter().all(|r| r.passed);
}

/// The folder a run writes its frames to, if it writes any: `--output DIR` (which turns output
/// on even for a scene without an `output` section, writing about ten frames) or the scene's
/// `output.dir`, relative to the scene file's folder.
pub fn output_dir(scene: &Scene, scene_path: &Path, opts: &RunOptions) -> Option<PathBuf> {
    if opts.no_output {
        return None;
    }
    opts.output_dir.clone().or_else(|| {
        scene
            .output
            .as_ref()
            .map(|o| scene_path.parent().unwrap_or(Path::new(".")).join(&o.dir))
    })
}

/// The `.pvd` collection a run of `scene` with `opts` writes (its frames are named after it),
/// if it writes any. A folder run compares these before it starts, so that no run replaces
/// another's files.
pub fn series_path(scene: &Scene, scene_path: &Path, opts: &RunOptions) -> Option<PathBuf> {
    output_dir(scene, scene_path, opts)
        .map(|dir| dir.join(format!("{}.pvd", series_stem(scene, opts.cut_method))))
}

/// The name of a run's series (its `.pvd` and frames): the scene's name made file-name-safe,
/// and, for a scene that cuts, `.` and the method it runs with, so that the runs of a scene's
/// methods do not write over one another. A made-safe name never holds a `.`, so no scene's
/// name can read as another scene's name and method.
pub fn series_stem(scene: &Scene, cut_method: Option<crate::cut::CutMethod>) -> String {
    let stem = sanitize(&scene.name);
    let method = cut_method.or_else(|| scene.cut.as_ref().and_then(|c| c.methods.first().copied()));
    match method {
        Some(m) => format!("{stem}.{}", sanitize(&m.to_string()).to_lowercase()),
        None => stem,
    }
}

/// A file-name-safe version of a scene name, different for different names. A name of
/// letters, digits, `-` and spaces keeps its readable form, spaces made `_`. Any other name
/// (`a.b`, `a/b`, `a:b` and `a_b` would all read `a_b`, as would `a b`) is made safe the same
/// way, every other character made `_`, and gets a short hash of the whole name appended.
fn sanitize(name: &str) -> String {
    let keep = |c: char| c.is_ascii_alphanumeric() || c == '-';
    let s: String = name
        .chars()
        .map(|c| if keep(c) { c } else { '_' })
        .collect();
    if !s.is_empty() && name.chars().all(|c| keep(c) || c == ' ') {
        return s;
    }
    // FNV-1a: stable across builds and platforms (std's hasher is not).
    let hash = name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    });
    let base = if s.is_empty() { "scene" } else { &s };
    format!("{base}_{:08x}", hash as u32)
}
