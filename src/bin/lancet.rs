//! The `lancet` command-line tool: run scenes, benchmark engines, report accuracy, inspect
//! meshes.
//!
//! Exit codes: 0 success, 1 an expectation failed or the run diverged, 2 bad input or another
//! error.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use lancet::engine::{EngineKind, NodeOrdering};
use lancet::layout::edges::Accumulation;
use lancet::scene::{run_scene, RunOptions, RunSummary, Scene};

#[derive(Parser)]
#[command(
    name = "lancet",
    version,
    about = "Soft-tissue simulation with cutting"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum BenchWhat {
    /// The collision broad phases (tool against tissue, tissue against itself) on the GPU and
    /// their CPU twins, against surface size and tool count: median latency including the
    /// readback, and the culling ratio.
    Collide {
        /// Boundary triangles of the test surfaces (thin slabs), comma-separated.
        #[arg(long, value_delimiter = ',', default_values = ["10000", "50000", "200000"])]
        triangles: Vec<usize>,
        /// Tool counts, comma-separated.
        #[arg(long, value_delimiter = ',', default_values = ["1", "3"])]
        tools: Vec<usize>,
        /// Timed runs per row (the median is reported).
        #[arg(long, default_value_t = 20)]
        repeats: usize,
        /// Print JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Local incisions (four parallel ones, two cells apart) into boxes of growing size and
    /// with growing length: latency per cut event (positions read, cut, engine patched, surface refreshed), bytes uploaded against
    /// the whole layout, mesh growth per cut area, stable time step before and after.
    Cut {
        /// Boxes of N x N x N/2 cells of 1 cm (6 tets each), comma-separated.
        #[arg(long = "cube", value_delimiter = ',', default_values = ["10", "20", "30"])]
        cubes: Vec<usize>,
        /// Cut lengths, m, comma-separated.
        #[arg(long, value_delimiter = ',', default_values = ["0.03"])]
        length: Vec<f64>,
        /// Cut methods, comma-separated.
        #[arg(long, value_enum, value_delimiter = ',', default_values = ["separate", "remove", "subdivide"])]
        method: Vec<MethodArg>,
        /// Engines, comma-separated.
        #[arg(long, value_enum, value_delimiter = ',', default_values = ["fast", "gpu"])]
        engine: Vec<EngineArg>,
        /// GPU layouts, comma-separated (one GPU row each).
        #[arg(long, value_enum, value_delimiter = ',', default_values = ["connectivity", "valence", "edges"])]
        layout: Vec<LayoutArg>,
        /// Quality floors for subdividing, comma-separated (one row each; 0: none).
        #[arg(long = "quality-floor", value_delimiter = ',', default_values = ["0.2"])]
        floors: Vec<f64>,
        /// Incisions per row, two cells apart, each two cells deep in 11 cut events: more give
        /// the percentiles more events and grow the mesh further.
        #[arg(long, default_value_t = lancet::report::cut_bench::INCISIONS)]
        incisions: usize,
        /// Do not read ahead: each cut reads the nodes near the blade with a round trip of its
        /// own (on the GPU; a scan of every node on the fast CPU engine), instead of with the
        /// step before it.
        #[arg(long)]
        no_read_ahead: bool,
        /// Print JSON on stdout.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene file, every scene in a folder, or (with no argument) the embedded default
    /// scene; check its expectations.
    Run {
        /// A `.ron` scene file or a folder of them.
        scene: Option<PathBuf>,
        /// Print a machine-readable JSON summary on stdout.
        #[arg(long)]
        json: bool,
        /// Engine to use instead of the scene's.
        #[arg(long, value_enum)]
        engine: Option<EngineArg>,
        /// GPU memory layout instead of the scene's.
        #[arg(long, value_enum)]
        layout: Option<LayoutArg>,
        /// How the GPU edge layout accumulates spring forces, instead of the scene's
        /// (`atomic-float` needs an adapter with float32 atomics).
        #[arg(long, value_enum)]
        accumulation: Option<AccumulationArg>,
        /// Number of steps instead of the scene's.
        #[arg(long)]
        steps: Option<u64>,
        /// Folder for VTU frames instead of the scene's.
        #[arg(long)]
        output: Option<PathBuf>,
        /// Write no VTU frames.
        #[arg(long)]
        no_output: bool,
        /// Cut with this method only (scenes that cut run once per method they name
        /// otherwise).
        #[arg(long, value_enum)]
        method: Option<MethodArg>,
        /// Check the cut invariants after every cut (volume, mass, closed fragment surfaces,
        /// quality, agreement with a rebuild); a violation fails the scene.
        #[arg(long)]
        check: bool,
    },
    /// Benchmark engines side by side: memory, time per step, spring evaluations per second,
    /// achieved bandwidth against this machine's measured floor, error against the reference.
    Bench {
        /// `collide`: the collision broad phases instead of the engines.
        #[command(subcommand)]
        what: Option<BenchWhat>,
        /// Cube meshes of N^3 cells, six tets each (repeatable; cubes 10 and 26 when neither
        /// --cube nor --mesh is given).
        #[arg(long = "cube")]
        cubes: Vec<usize>,
        /// Mesh files (repeatable).
        #[arg(long)]
        mesh: Vec<PathBuf>,
        /// Engines to compare, comma-separated.
        #[arg(long, value_enum, value_delimiter = ',', default_values = ["reference", "fast"])]
        engine: Vec<EngineArg>,
        /// GPU layouts to compare, comma-separated.
        #[arg(long, value_enum, value_delimiter = ',', default_values = ["connectivity", "valence", "edges"])]
        layout: Vec<LayoutArg>,
        /// Accumulation variants of the GPU edge layout, comma-separated (each gives its own
        /// edges row; `atomic-float` is skipped with a note on adapters without float atomics).
        #[arg(long, value_enum, value_delimiter = ',', default_values = ["gather"])]
        accumulation: Vec<AccumulationArg>,
        /// Node orders for the fast CPU and GPU engines, comma-separated (`rcm` is what they
        /// use by default; `identity` keeps the mesh's numbering; `random` is a seeded shuffle).
        #[arg(long, value_enum, value_delimiter = ',', default_values = ["rcm"])]
        order: Vec<OrderArg>,
        /// Steps timed per engine.
        #[arg(long, default_value_t = 200)]
        steps: u64,
        /// Integration scheme of every run.
        #[arg(long, value_enum, default_value = "verlet")]
        integrator: IntegratorArg,
        /// Print JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Reports on a scene (`lancet report accuracy SCENE`).
    Report {
        #[command(subcommand)]
        report: ReportCommand,
    },
    /// Describe a mesh file: counts, volume, quality, components, regions.
    Info {
        /// The mesh (for TetGen, either file of the `.node`/`.ele` pair).
        mesh: PathBuf,
        /// Print JSON on stdout.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand)]
enum ReportCommand {
    /// Error against run time: the scene on each engine and layout at a ladder of time steps up
    /// to the stable bound, compared with a converged float64 run at fixed simulated times;
    /// prints a table and writes accuracy.svg and accuracy.png.
    Accuracy {
        /// A `.ron` scene file (default: the embedded default scene).
        scene: Option<PathBuf>,
        /// Engines to measure, comma-separated (gpu rows are skipped, with the reason, when
        /// there is no adapter).
        #[arg(long, value_enum, value_delimiter = ',', default_values = ["reference", "fast", "gpu"])]
        engine: Vec<EngineArg>,
        /// GPU layouts, comma-separated.
        #[arg(long, value_enum, value_delimiter = ',', default_values = ["connectivity", "valence", "edges"])]
        layout: Vec<LayoutArg>,
        /// Time steps as fractions of the stable bound, comma-separated, each in (0, 1].
        #[arg(long, value_delimiter = ',', default_values = ["1", "0.5", "0.25", "0.125", "0.0625"])]
        ladder: Vec<f64>,
        /// Simulated times to measure the error at, s, comma-separated (default: a quarter, a
        /// half and all of the scene's duration).
        #[arg(long, value_delimiter = ',')]
        time: Vec<f64>,
        /// Step of the converged float64 reference as a fraction of the bound (it is also run
        /// at twice this step as a self-check).
        #[arg(long, default_value_t = 1.0 / 64.0)]
        reference: f64,
        /// Print JSON only on stdout.
        #[arg(long)]
        json: bool,
        /// Folder for accuracy.svg and accuracy.png (default: the scene's output folder, else
        /// the current folder).
        #[arg(long)]
        plot: Option<PathBuf>,
        /// Write no plots.
        #[arg(long, conflicts_with = "plot")]
        no_plot: bool,
    },
}

#[derive(Clone, Copy, ValueEnum)]
enum EngineArg {
    /// Float64 serial reference engine.
    Reference,
    /// Float32 multi-threaded CPU engine.
    Fast,
    /// The default CPU engine (same as `fast`).
    Cpu,
    /// The wgpu engine on the preferred adapter.
    Gpu,
    /// The GPU when there is one, else the CPU engine (and say so).
    Auto,
}

#[derive(Clone, Copy, ValueEnum)]
enum LayoutArg {
    /// Fixed slots per node.
    Connectivity,
    /// Nodes grouped by valence.
    Valence,
    /// One record per spring.
    Edges,
}

#[derive(Clone, Copy, ValueEnum)]
enum IntegratorArg {
    /// Position Verlet over the two most recent positions.
    Verlet,
    /// Symplectic Euler (the same trajectory in exact arithmetic; keeps float32 precision
    /// far below the stable bound).
    SymplecticEuler,
}

impl From<IntegratorArg> for lancet::Integrator {
    fn from(i: IntegratorArg) -> Self {
        match i {
            IntegratorArg::Verlet => lancet::Integrator::Verlet,
            IntegratorArg::SymplecticEuler => lancet::Integrator::SymplecticEuler,
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum AccumulationArg {
    /// A node pass gathers each node's spring forces (deterministic, no atomics).
    Gather,
    /// Atomic adds in 32-bit fixed point (deterministic).
    AtomicFixed,
    /// Atomic float adds (needs SHADER_FLOAT32_ATOMIC; summation order varies).
    AtomicFloat,
}

impl From<AccumulationArg> for Accumulation {
    fn from(a: AccumulationArg) -> Self {
        match a {
            AccumulationArg::Gather => Accumulation::Gather,
            AccumulationArg::AtomicFixed => Accumulation::AtomicFixed,
            AccumulationArg::AtomicFloat => Accumulation::AtomicFloat,
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum OrderArg {
    /// Reverse Cuthill–McKee (the engines' default).
    Rcm,
    /// The mesh's own numbering.
    Identity,
    /// A random permutation (fixed seed, so runs compare).
    Random,
}

/// Seed of `--order random`: fixed, so that two bench runs time the same permutation.
const RANDOM_ORDER_SEED: u64 = 1;

impl From<OrderArg> for NodeOrdering {
    fn from(o: OrderArg) -> Self {
        match o {
            OrderArg::Rcm => NodeOrdering::Locality,
            OrderArg::Identity => NodeOrdering::Identity,
            OrderArg::Random => NodeOrdering::Random(RANDOM_ORDER_SEED),
        }
    }
}

impl From<LayoutArg> for lancet::layout::LayoutKind {
    fn from(l: LayoutArg) -> Self {
        match l {
            LayoutArg::Connectivity => Self::Connectivity,
            LayoutArg::Valence => Self::Valence,
            LayoutArg::Edges => Self::Edges,
        }
    }
}

impl From<EngineArg> for EngineKind {
    fn from(e: EngineArg) -> Self {
        match e {
            EngineArg::Reference => EngineKind::Reference,
            EngineArg::Fast | EngineArg::Cpu => EngineKind::Fast,
            EngineArg::Gpu => EngineKind::Gpu,
            EngineArg::Auto => EngineKind::Auto,
        }
    }
}

/// Cut methods on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum MethodArg {
    /// Delete the tets the blade passes.
    Remove,
    /// Open the faces the blade passes, duplicating nodes.
    Separate,
    /// Split the tets the blade crosses along its sweep, then open the cut.
    Subdivide,
}

impl From<MethodArg> for lancet::cut::CutMethod {
    fn from(m: MethodArg) -> Self {
        match m {
            MethodArg::Remove => lancet::cut::CutMethod::Remove,
            MethodArg::Separate => lancet::cut::CutMethod::Separate,
            MethodArg::Subdivide => lancet::cut::CutMethod::Subdivide,
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run {
            scene,
            json,
            engine,
            layout,
            accumulation,
            steps,
            output,
            no_output,
            method,
            check,
        } => {
            let opts = RunOptions {
                engine: engine.map(Into::into),
                layout: layout.map(Into::into),
                accumulation: accumulation.map(Into::into),
                steps,
                output_dir: output,
                no_output,
                cut_method: method.map(Into::into),
                check,
            };
            run(scene.as_deref(), json, &opts)
        }
        Command::Info { mesh, json } => info(&mesh, json),
        Command::Report {
            report:
                ReportCommand::Accuracy {
                    scene,
                    engine,
                    layout,
                    ladder,
                    time,
                    reference,
                    json,
                    plot,
                    no_plot,
                },
        } => {
            let opts = lancet::report::accuracy::AccuracyOptions {
                engines: engine.iter().map(|&e| e.into()).collect(),
                layouts: layout.iter().map(|&l| l.into()).collect(),
                ladder,
                times: time,
                reference_fraction: reference,
                ..Default::default()
            };
            let plot = if no_plot {
                PlotTo::Nowhere
            } else {
                plot.map_or(PlotTo::Default, PlotTo::Dir)
            };
            accuracy(scene.as_deref(), &opts, json, plot)
        }
        Command::Bench {
            what:
                Some(BenchWhat::Collide {
                    triangles,
                    tools,
                    repeats,
                    json,
                }),
            ..
        } => bench_collide(&triangles, &tools, repeats, json),
        Command::Bench {
            what:
                Some(BenchWhat::Cut {
                    cubes,
                    length,
                    method,
                    engine,
                    layout,
                    floors,
                    incisions,
                    no_read_ahead,
                    json,
                }),
            ..
        } => bench_cut(
            &lancet::report::cut_bench::CutBench {
                cubes,
                lengths: length,
                methods: method.iter().map(|&m| m.into()).collect(),
                engines: engine.iter().map(|&e| e.into()).collect(),
                layouts: layout.iter().map(|&l| l.into()).collect(),
                floors,
                incisions,
                read_ahead: !no_read_ahead,
            },
            json,
        ),
        Command::Bench {
            what: None,
            cubes,
            mesh,
            engine,
            layout,
            accumulation,
            order,
            steps,
            integrator,
            json,
        } => {
            let opts = lancet::report::bench::BenchOptions {
                integrator: integrator.into(),
                engines: engine.iter().map(|&e| e.into()).collect(),
                layouts: layout.iter().map(|&l| l.into()).collect(),
                accumulations: accumulation.iter().map(|&a| a.into()).collect(),
                orders: order.iter().map(|&o| o.into()).collect(),
                steps,
                ..Default::default()
            };
            bench(&cubes, &mesh, &opts, json)
        }
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

/// Run one scene, a folder of scenes, or the default scene.
fn run(scene: Option<&Path>, json: bool, opts: &RunOptions) -> lancet::Result<ExitCode> {
    let scenes: Vec<(Scene, PathBuf)> = match scene {
        None => vec![(
            Scene::default_scene(),
            PathBuf::from("<embedded default scene>"),
        )],
        Some(p) if p.is_dir() => {
            let mut files: Vec<PathBuf> = std::fs::read_dir(p)
                .map_err(|e| lancet::Error::io(p, e))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| f.extension().is_some_and(|x| x == "ron"))
                .collect();
            files.sort();
            if files.is_empty() {
                return Err(lancet::Error::Scene {
                    path: p.to_path_buf(),
                    message: "folder holds no .ron scene files".into(),
                });
            }
            files
                .into_iter()
                .map(|f| Scene::read(&f).map(|s| (s, f)))
                .collect::<lancet::Result<_>>()?
        }
        Some(p) => vec![(Scene::read(p)?, p.to_path_buf())],
    };
    let folder = scene.is_some_and(|p| p.is_dir());
    let mut summaries = Vec::with_capacity(scenes.len());
    for (scene, path) in &scenes {
        for w in scene.warnings() {
            eprintln!("warning: {}: {w}", path.display());
        }
        if let Some(note) = ignored_cut_options(scene, opts) {
            eprintln!("note: {}: {note}", path.display());
        }
        // In a folder run, a scene on a real mesh is skipped (with a note) when the folder of
        // real meshes is not configured; run on its own it is an error that says so.
        if folder && needs_mesh_dir(scene) && std::env::var_os("LANCET_MESH_DIR").is_none() {
            eprintln!(
                "skipped {}: its mesh is under $LANCET_MESH_DIR, which is not set",
                path.display()
            );
            continue;
        }
        // A scene that cuts runs once per method it names, unless --method picks one.
        let methods: Vec<Option<lancet::cut::CutMethod>> = match (&scene.cut, opts.cut_method) {
            (Some(_), Some(m)) => vec![Some(m)],
            (Some(c), None) => c.methods.iter().map(|&m| Some(m)).collect(),
            (None, _) => vec![None],
        };
        for method in methods {
            let opts = RunOptions {
                cut_method: method,
                ..opts.clone()
            };
            let bar = progress_bar(scene, &opts, json);
            let summary = run_scene(scene, path, &opts, |done, _| bar.set_position(done));
            bar.finish_and_clear();
            let summary = summary?;
            if !json {
                print_summary(&summary);
            }
            summaries.push(summary);
        }
    }
    let all_passed = summaries.iter().all(|s| s.expectations_passed);
    if json {
        let value = if summaries.len() == 1 {
            serde_json::to_value(&summaries[0])
        } else {
            serde_json::to_value(&summaries)
        };
        println!(
            "{}",
            serde_json::to_string_pretty(
                &value.unwrap_or_else(|e| json!({"error": e.to_string()}))
            )
            .unwrap_or_default()
        );
    } else if summaries.len() > 1 {
        print_table(&summaries);
    }
    Ok(if all_passed {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// Why `--method` or `--check`, when given, do nothing for `scene`: both act on cuts, and a
/// scene without a `cut` section makes none. Said rather than refused, so that a folder of
/// scenes, some of which cut, can still be run with them.
fn ignored_cut_options(scene: &Scene, opts: &RunOptions) -> Option<String> {
    if scene.cut.is_some() {
        return None;
    }
    let given: Vec<&str> = [
        opts.cut_method.map(|_| "--method"),
        opts.check.then_some("--check"),
    ]
    .into_iter()
    .flatten()
    .collect();
    (!given.is_empty()).then(|| {
        format!(
            "{} {} no effect: the scene does not cut (it has no `cut` section)",
            given.join(" and "),
            if given.len() > 1 { "have" } else { "has" }
        )
    })
}

/// Whether a scene reads its mesh from the folder of real meshes.
fn needs_mesh_dir(scene: &Scene) -> bool {
    matches!(&scene.mesh, lancet::scene::MeshSource::File(f) if f.starts_with("$LANCET_MESH_DIR/"))
}

/// A progress bar on stderr for long runs; hidden for short runs, JSON output, or when stderr
/// is not a terminal (indicatif checks that).
fn progress_bar(scene: &Scene, opts: &RunOptions, json: bool) -> ProgressBar {
    let steps = opts.steps.unwrap_or(scene.steps);
    if json || steps < 2000 {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(steps);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} steps, eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_message(scene.name.clone());
    bar
}

fn print_summary(s: &RunSummary) {
    println!("scene: {}", s.scene);
    println!(
        "model: {} nodes, {} tets, {} springs",
        s.nodes, s.tets, s.springs
    );
    println!(
        "engine: {} ({}), dt {:.3e} s, stable bound {:.3e} s (node {})",
        s.engine, s.integrator, s.dt, s.dt_bound, s.dt_bound_node
    );
    if let Some(line) = time_step_change(s) {
        println!("{line}");
    }
    if let Some(n) = &s.engine_note {
        println!("note: {n}");
    }
    if let Some(m) = &s.message {
        let what = if s.refused {
            "refused"
        } else if s.stopped {
            "stopped after a cut"
        } else {
            "diverged"
        };
        println!("{what}: {m}");
    }
    println!(
        "ran {} steps ({:.4} s simulated) in {:.3} s wall, {:.0} steps/s",
        s.steps, s.simulated_s, s.wall_s, s.steps_per_s
    );
    println!(
        "max displacement {:.4e} m, volume ratio {:.5}, energy: kinetic {:.3e} J, elastic {:.3e} J",
        s.max_displacement, s.volume_ratio, s.energy.kinetic, s.energy.elastic
    );
    if let Some(p) = &s.pvd {
        println!("wrote {} frames, series {}", s.frames_written, p.display());
    }
    for t in &s.tools {
        let f = t.final_force;
        println!(
            "tool {}: largest force {:.4e} N, final force ({:.3e}, {:.3e}, {:.3e}) N, deepest \
             penetration {:.2e} m, in contact {} steps",
            t.name, t.max_force, f[0], f[1], f[2], t.max_depth, t.contact_steps
        );
        if t.max_held > 0 {
            println!(
                "tool {}: held up to {} nodes, carried them up to {:.4e} m from rest",
                t.name, t.max_held, t.max_carried
            );
        }
    }
    if s.self_contact_steps > 0 {
        println!(
            "self-contact: {} steps in contact, deepest penetration {:.2e} m before resolution",
            s.self_contact_steps, s.self_contact_deepest
        );
    }
    if let Some(c) = &s.cuts {
        println!(
            "cuts ({}): {} steps cut, {} tets touched ({} removed), {} nodes added, {} springs \
             touched, {} fragments, volume removed {:.3}%",
            c.method,
            c.cuts,
            c.tets_touched,
            c.tets_removed,
            c.nodes_added,
            c.springs_touched,
            c.fragments,
            100.0 * c.volume_removed_fraction
        );
        println!(
            "  uploaded {} of {} layout bytes a rebuild per cut would{} ({:.2}%; at most {:.2}% \
             in one cut); passes rebuilt at {} cuts, {} buffers grown ({} bytes copied on the \
             device); per cut p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms; {} invariant checks, \
             {} violations; lowest tet quality {:.3} (uncut {:.3}, floor {})",
            c.bytes_uploaded,
            c.bytes_full,
            time_step_part(c.bytes_time_step),
            100.0 * c.bytes_uploaded as f64 / c.bytes_full.max(1) as f64,
            100.0 * c.max_upload_fraction,
            c.passes_rebuilt,
            c.buffers_grown,
            c.bytes_copied,
            c.p50_ms,
            c.p99_ms,
            c.max_ms,
            c.checks,
            c.violations.len(),
            c.min_quality,
            c.min_quality_uncut,
            c.quality_floor
        );
        let reads = c.near_reads;
        if reads.ahead + reads.direct > 0 {
            println!(
                "  reads of the nodes near a blade: {} with the step before the cut, {} with a \
                 round trip of their own",
                reads.ahead, reads.direct
            );
        }
        // A few cuts one by one; `--json` lists them all.
        const SHOWN: usize = 8;
        for e in c.events.iter().take(SHOWN) {
            println!(
                "  cut at step {} by {}: {} tets touched ({} removed), {} nodes added, {} springs \
                 touched, {} of {} layout bytes uploaded{}{}, {:.3} ms",
                e.step,
                e.blade,
                e.tets_touched,
                e.tets_removed,
                e.nodes_added,
                e.springs_touched,
                e.bytes_uploaded,
                e.layout_bytes,
                time_step_part(e.time_step_bytes),
                patched(e),
                e.ms
            );
        }
        if c.events.len() > SHOWN {
            println!(
                "  ... {} more cuts (--json lists every one)",
                c.events.len() - SHOWN
            );
        }
        for e in &c.time_step_events {
            println!("  {e}");
        }
        for v in c.violations.iter().take(5) {
            println!("  violation: {v}");
        }
    }
    if !s.expectations.is_empty() {
        println!("expectations:");
        for e in &s.expectations {
            let measured = e.measured.map_or(String::new(), |v| {
                format!(" (measured {})", measured_text(v))
            });
            let verdict = match (e.skipped, e.passed) {
                (true, _) => "skip",
                (false, true) => "pass",
                (false, false) => "FAIL",
            };
            println!("  {verdict}  {}{measured}", e.expectation);
        }
    }
    println!(
        "result: {}\n",
        if s.expectations_passed {
            "pass"
        } else {
            "FAIL"
        }
    );
}

/// What part of an upload rebuilt the engine at a new time step, for the cut lines.
/// How a cut's patch met buffers without room: ", passes rebuilt", ", 1 buffer grown (N
/// bytes copied on the device)", or nothing.
fn patched(e: &lancet::scene::cuts::CutEvent) -> String {
    if e.passes_rebuilt {
        ", passes rebuilt".into()
    } else if e.buffers_grown > 0 {
        let s = if e.buffers_grown == 1 { "" } else { "s" };
        format!(
            ", {} buffer{s} grown ({} bytes copied on the device)",
            e.buffers_grown, e.bytes_copied
        )
    } else {
        String::new()
    }
}

fn time_step_part(bytes: u64) -> String {
    if bytes == 0 {
        String::new()
    } else {
        format!(" ({bytes} of them step parameters at a new dt)")
    }
}

/// A line saying how cuts changed the time step or its bound during the run, if they did (the
/// engine line gives the values the run started with).
fn time_step_change(s: &RunSummary) -> Option<String> {
    let bound = format!(
        "stable bound now {:.3e} s (node {})",
        s.dt_bound_final, s.dt_bound_node_final
    );
    if s.dt_final != s.dt {
        Some(format!(
            "dt changed from {:.3e} s to {:.3e} s during the run; {bound}",
            s.dt, s.dt_final
        ))
    } else if s.dt_bound_final != s.dt_bound {
        Some(format!("dt unchanged; {bound}"))
    } else {
        None
    }
}

/// The one-line-per-run table of a folder run.
fn print_table(summaries: &[RunSummary]) {
    let w = summaries
        .iter()
        .map(|s| s.scene.len())
        .max()
        .unwrap_or(5)
        .max(5);
    println!(
        "{:<w$}  {:>9}  {:>8}  {:>9}  {:>8}  {:>10}  {:>9}  {:>6}  result",
        "scene", "method", "nodes", "after cut", "steps", "dt (s)", "wall (s)", "expect"
    );
    for s in summaries {
        // Expectations for another cut method were skipped: counted neither way.
        let checked = s.expectations.iter().filter(|e| !e.skipped);
        let (passed, total) = checked.fold((0, 0), |(p, t), e| (p + e.passed as usize, t + 1));
        // The step the run ended at, marked where a cut lowered it.
        let mark = if s.dt_final != s.dt { '*' } else { ' ' };
        // Cuts only append nodes, so the count at the end is the start's plus those added.
        let after_cut = s
            .cuts
            .as_ref()
            .map_or("-".to_string(), |c| (s.nodes + c.nodes_added).to_string());
        println!(
            "{:<w$}  {:>9}  {:>8}  {:>9}  {:>8}  {:>10}  {:>9.3}  {:>6}  {}",
            s.scene,
            s.cut_method.as_deref().unwrap_or("-"),
            s.nodes,
            after_cut,
            s.steps,
            format!("{:.3e}{mark}", s.dt_final),
            s.wall_s,
            format!("{passed}/{total}"),
            if s.expectations_passed {
                "pass"
            } else {
                "FAIL"
            }
        );
    }
    println!(
        "nodes: before cutting; after cut: at the end of a scene that cuts; expect: expectations \
         met / checked (those for another cut method are skipped)"
    );
    if summaries.iter().any(|s| s.dt_final != s.dt) {
        println!("* a cut lowered dt during the run; the final dt is shown");
    }
    let failed = summaries.iter().filter(|s| !s.expectations_passed).count();
    println!("{} scenes, {} failed", summaries.len(), failed);
}

/// Run the benchmark matrix and print it.
#[cfg(all(feature = "gpu", feature = "collide"))]
fn bench_collide(
    triangles: &[usize],
    tools: &[usize],
    repeats: usize,
    json: bool,
) -> lancet::Result<ExitCode> {
    let (device, rows) = lancet::report::collide_bench::run(triangles, tools, repeats.max(1))?;
    if json {
        let v = json!({ "device": device, "rows": rows });
        println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return Ok(ExitCode::SUCCESS);
    }
    println!("gpu device: {device}");
    println!(
        "{:>9} {:>5} {:>9} {:>9} {:>9} {:>10} {:>9} {:>9} {:>9} {:>10} {:>8} {:>9} {:>9}",
        "triangles",
        "tools",
        "gpu ms",
        "cpu ms",
        "bvh ms",
        "candidates",
        "ratio",
        "self gpu",
        "self cpu",
        "self pairs",
        "narrow",
        "gpu p2f",
        "cpu p2f"
    );
    for r in &rows {
        println!(
            "{:>9} {:>5} {:>9.3} {:>9.3} {:>9.3} {:>10.1} {:>9.2e} {:>9.3} {:>9.3} {:>10} {:>8.2} {:>9.3} {:>9.3}",
            r.triangles,
            r.tools,
            r.gpu_tool_ms,
            r.cpu_tool_ms,
            r.bvh_tool_ms,
            r.candidates,
            r.culling_ratio,
            r.gpu_self_ms,
            r.cpu_self_ms,
            r.self_pairs,
            r.narrow_us_per_candidate,
            r.gpu_pose_to_force_ms,
            r.cpu_pose_to_force_ms
        );
    }
    println!(
        "gpu/cpu ms: median wall time of one tool cull, readback included; bvh: parry's BVH \
         refitted and queried instead (the baseline); ratio: candidates \
         over triangle-tool pairs; self: tissue against itself, margin 0.5 mm; narrow: parry \
         tool-triangle query, us per candidate; p2f: pose to force (cull, read back the \
         candidates' nodes, narrow phase, correction) for a 3 mm probe pressed 0.5 mm, ms"
    );
    Ok(ExitCode::SUCCESS)
}

/// Run the cut benchmark and print it.
fn bench_cut(bench: &lancet::report::cut_bench::CutBench, json: bool) -> lancet::Result<ExitCode> {
    let rows = bench.run()?;
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&rows).unwrap_or_default()
        );
        return Ok(ExitCode::SUCCESS);
    }
    // The engine column holds the short label ("gpu-valence"); the adapter, whose name is long
    // and the same on every GPU row, is named once above the table.
    let (labels, devices) = engine_labels(rows.iter().map(|r| r.engine.as_str()));
    for d in devices {
        println!("gpu device: {d}");
    }
    let ew = labels.iter().map(|l| l.len()).max().unwrap_or(0).max(6);
    println!(
        "{:>7} {:>6} {:>9} {:<ew$} {:>4} {:>7} {:>7} {:>7} {:>6} {:>6} {:>5} {:>6} {:>6} {:>6} {:>6} {:>10} {:>7} {:>7} {:>5} {:>8} {:>9} {:>9} {:>5} {:>5} {:>6} {:>6} {:>6} {:>6}  slowest in",
        "tets", "len cm", "method", "engine", "cuts", "p50 ms", "p99 ms", "max ms", "read", "nodes",
        "ahead", "cut", "apply", "surf", "step", "bytes/cut", "% lay", "rebuilt", "grown", "nodes/cm2", "dt before",
        "dt after", "floor", "min q", "quiet0", "quiet1", "dev0", "dev1"
    );
    for (r, engine) in rows.iter().zip(&labels) {
        let (part, ms) = r.slowest.largest();
        let grew = if r.slowest.grew { " (grew)" } else { "" };
        println!(
            "{:>7} {:>6.1} {:>9} {:<ew$} {:>4} {:>7.3} {:>7.3} {:>7.3} {:>6.3} {:>6.0} {:>5} {:>6.3} {:>6.3} {:>6.3} {:>6.3} {:>10.0} {:>7.2} {:>7} {:>5} {:>8.1} {:>9.3e} {:>9.3e} {:>5} {:>5.3} {:>6.3} {:>6.3} {:>6} {:>6}  {part} {ms:.3}{grew}",
            r.tets,
            r.length * 100.0,
            r.method,
            engine,
            r.cuts,
            r.p50_ms,
            r.p99_ms,
            r.max_ms,
            r.read_ms,
            r.nodes_read,
            r.reads_ahead,
            r.cut_ms,
            r.apply_ms,
            r.surface_ms,
            r.step_ms,
            r.bytes_per_cut,
            100.0 * r.bytes_per_cut / r.layout_bytes.max(1) as f64,
            r.passes_rebuilt,
            r.buffers_grown,
            r.nodes_per_cm2,
            r.dt_before,
            r.dt_after,
            r.quality_floor,
            r.min_quality,
            r.quiet_step_before_ms,
            r.quiet_step_after_ms,
            optional_ms(r.quiet_device_before_ms),
            optional_ms(r.quiet_device_after_ms)
        );
    }
    println!(
        "p50/p99/max: latency of a cut event (read + cut + apply + surf), ms; read: positions \
         near the blade read back; nodes: how many; ahead: events whose read came with the step \
         before; cut: the cutter; apply: the engine patched; surf: the surface handed over; \
         step: the step before each event, waited for (not in the latency); % lay: bytes per \
         cut against the whole layout; rebuilt / grown: passes rebuilt, buffers grown; dt: \
         stable step before and after; min q: lowest tet quality after; quiet0/quiet1 \
         (dev0/dev1): median of {quiet} steps before the first incision and after the last, wall \
         (device) ms; \
         slowest in: the largest part of the slowest event",
        quiet = lancet::report::cut_bench::QUIET_STEPS
    );
    Ok(ExitCode::SUCCESS)
}

/// A time the engine may not measure, ms, for a table column: "-" where it does not.
fn optional_ms(ms: Option<f64>) -> String {
    ms.map_or_else(|| "-".to_string(), |ms| format!("{ms:.3}"))
}

/// Split engine names such as "gpu-valence on llvmpipe (LLVM 15.0.7, 256 bits)" into the short
/// labels for a table column and the distinct devices, in order of first appearance.
fn engine_labels<'a>(names: impl Iterator<Item = &'a str>) -> (Vec<&'a str>, Vec<&'a str>) {
    let mut labels = Vec::new();
    let mut devices: Vec<&str> = Vec::new();
    for name in names {
        let (label, device) = name.split_once(" on ").unwrap_or((name, ""));
        labels.push(label);
        if !device.is_empty() && !devices.contains(&device) {
            devices.push(device);
        }
    }
    (labels, devices)
}

#[cfg(not(all(feature = "gpu", feature = "collide")))]
fn bench_collide(_: &[usize], _: &[usize], _: usize, _: bool) -> lancet::Result<ExitCode> {
    Err(lancet::Error::Unsupported(
        "bench collide runs the GPU broad phases and the narrow phase; build with the `gpu` \
         and `collide` features"
            .into(),
    ))
}

/// The device's copy bandwidth, the floor of the GPU rows (asked for only when there are
/// some), where an adapter opens.
#[cfg(feature = "gpu")]
fn device_bandwidth() -> Option<lancet::report::device_copy::DeviceBandwidth> {
    let ctx = lancet::engine::gpu::GpuContext::new().ok()?;
    match lancet::report::device_copy::device_copy(&ctx) {
        Ok(d) => Some(d),
        Err(e) => {
            eprintln!("note: the device copy bandwidth was not measured ({e}); the gpu rows use the host's");
            None
        }
    }
}

#[cfg(not(feature = "gpu"))]
fn device_bandwidth() -> Option<lancet::report::device_copy::DeviceBandwidth> {
    None
}

fn bench(
    cubes: &[usize],
    files: &[PathBuf],
    opts: &lancet::report::bench::BenchOptions,
    json: bool,
) -> lancet::Result<ExitCode> {
    use lancet::report::{bandwidth, bench};
    // With no mesh named, the two default cubes (about 1,300 and 20,000 nodes).
    let cubes = if cubes.is_empty() && files.is_empty() {
        &[10, 26][..]
    } else {
        cubes
    };
    let mut meshes: Vec<bench::BenchMesh> =
        cubes.iter().map(|&n| bench::BenchMesh::Cube(n)).collect();
    meshes.extend(files.iter().cloned().map(bench::BenchMesh::File));
    // 2^24 doubles per array (128 MiB): far beyond any cache, as STREAM requires.
    let bw = bandwidth::stream_triad(1 << 24, 5);
    let mut device_bw = None;
    let report = bench::run_bench(&meshes, opts, &bw, || {
        device_bw = device_bandwidth();
        device_bw.as_ref().map(|d| d.bytes_per_s)
    })?;
    if json {
        let v = json!({
            "bandwidth": bw,
            "device_bandwidth": device_bw,
            "rows": report.rows,
            "skipped": report.skipped
        });
        println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return Ok(ExitCode::SUCCESS);
    }
    let rows = &report.rows;
    println!(
        "memory bandwidth (STREAM triad, {} threads): {:.1} GB/s",
        bw.threads,
        bw.bytes_per_s / 1e9
    );
    if let Some(d) = &device_bw {
        println!(
            "device copy bandwidth ({}, read + written, {} MiB arrays): {:.1} GB/s on {}; the \
             floor of the gpu rows",
            d.method,
            d.bytes >> 20,
            d.bytes_per_s / 1e9,
            d.device
        );
    }
    let mut devices: Vec<&str> = rows
        .iter()
        .filter_map(|r| r.engine.split_once(" on ").map(|(_, d)| d))
        .collect();
    devices.dedup();
    for d in devices {
        println!("gpu device: {d}");
    }
    println!(
        "{:<14} {:>8} {:>9} {:<24} {:<9} {:>9} {:>6} {:>9} {:>8} {:>10} {:>8} {:>7} {:>9}",
        "mesh",
        "nodes",
        "springs",
        "engine",
        "order",
        "mem (MB)",
        "pad %",
        "ms/step",
        "gpu ms",
        "Mspring/s",
        "GB/s",
        "floor %",
        "error"
    );
    for r in rows {
        let mut engine = r
            .engine
            .split(" on ")
            .next()
            .unwrap_or(&r.engine)
            .to_string();
        // The engine name carries the atomic variants; say "gather" too, so that every edges
        // row names its variant.
        if r.accumulation.as_deref() == Some("gather") {
            engine.push_str("-gather");
        }
        let mesh = r.mesh.rsplit('/').next().unwrap_or(&r.mesh);
        println!(
            "{:<14} {:>8} {:>9} {:<24} {:<9} {:>9.2} {:>6.1} {:>9.3} {:>8} {:>10.1} {:>8.2} {:>7.1} {:>9.2e}",
            mesh,
            r.nodes,
            r.springs,
            engine,
            r.order.as_deref().unwrap_or("-"),
            r.memory_bytes as f64 / 1e6,
            r.padding_percent,
            r.ms_per_step,
            r.gpu_ms_per_step.map_or("-".into(), |g| format!("{g:.3}")),
            r.spring_evals_per_s / 1e6,
            r.achieved_bytes_per_s / 1e9,
            100.0 * r.floor_ratio,
            r.error_vs_reference
        );
    }
    for s in &report.skipped {
        println!("skipped: {s}");
    }
    Ok(ExitCode::SUCCESS)
}

/// Where `lancet report accuracy` writes its plots.
enum PlotTo {
    /// The scene's output folder, else the current folder.
    Default,
    /// This folder.
    Dir(PathBuf),
    /// No plots.
    Nowhere,
}

/// Run the accuracy report, print it, write its plots.
fn accuracy(
    scene_path: Option<&Path>,
    opts: &lancet::report::accuracy::AccuracyOptions,
    json: bool,
    plot: PlotTo,
) -> lancet::Result<ExitCode> {
    let (scene, path) = match scene_path {
        None => (
            Scene::default_scene(),
            PathBuf::from("<embedded default scene>"),
        ),
        Some(p) => (Scene::read(p)?, p.to_path_buf()),
    };
    let report = lancet::report::accuracy::scene_accuracy(&scene, &path, opts, |line| {
        if !json {
            eprintln!("running {line}");
        }
    })?;
    let plot_dir = match plot {
        PlotTo::Nowhere => None,
        PlotTo::Dir(d) => Some(d),
        PlotTo::Default => Some(match (&scene.output, scene_path) {
            (Some(o), Some(p)) => p.parent().unwrap_or(Path::new(".")).join(&o.dir),
            _ => PathBuf::from("."),
        }),
    };
    let plots = match plot_dir {
        Some(dir) => Some(write_accuracy_plots(&report, &dir)?),
        None => None,
    };
    if json {
        let v = json!({ "report": report, "plots": plots });
        println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return Ok(ExitCode::SUCCESS);
    }
    print_accuracy(&report);
    if let Some(p) = plots {
        for f in ["svg", "png"] {
            if let Some(path) = p.get(f).and_then(|v| v.as_str()) {
                println!("wrote {path}");
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Write the plots; their paths (and a note when the PNG has no text) as JSON.
#[cfg(feature = "plot")]
fn write_accuracy_plots(
    report: &lancet::report::accuracy::AccuracyReport,
    dir: &Path,
) -> lancet::Result<serde_json::Value> {
    use lancet::report::plot;
    let font = plot::find_font();
    let files = plot::write_plots(report, dir, font.as_deref())?;
    if let Some(n) = &files.note {
        eprintln!("note: {n}");
    }
    Ok(json!({
        "svg": files.svg.display().to_string(),
        "png": files.png.display().to_string(),
        "font": font.map(|f| f.display().to_string()),
        "note": files.note,
    }))
}

#[cfg(not(feature = "plot"))]
fn write_accuracy_plots(
    _: &lancet::report::accuracy::AccuracyReport,
    _: &Path,
) -> lancet::Result<serde_json::Value> {
    eprintln!("note: this build draws no plots (enable the `plot` cargo feature)");
    Ok(json!({ "note": "this build draws no plots" }))
}

fn print_accuracy(r: &lancet::report::accuracy::AccuracyReport) {
    println!(
        "scene: {} ({} nodes, {} springs), {}, stable bound {:.4e} s",
        r.scene, r.nodes, r.springs, r.integrator, r.dt_bound
    );
    let times: Vec<String> = r.sample_times.iter().map(|t| format!("{t:.4e}")).collect();
    println!("sample times (s): {}", times.join(", "));
    let self_err: Vec<String> = r
        .reference
        .self_error
        .iter()
        .map(|e| format!("{:.2e}", e.relative_l2))
        .collect();
    println!(
        "reference: {} at dt {:.4e} s ({:.4} of the bound, {} steps, {:.3} s wall per simulated s)",
        r.reference.engine,
        r.reference.dt,
        r.reference.dt_over_bound,
        r.reference.steps,
        r.reference.wall_s_per_sim_s
    );
    println!(
        "reference self-check (dt {:.4e} s against dt {:.4e} s), rel L2 at each time: {}",
        r.reference.check_dt,
        r.reference.dt,
        self_err.join(", ")
    );
    for s in &r.skipped {
        println!("note: {s}");
    }
    let mut devices: Vec<&str> = r
        .rows
        .iter()
        .filter_map(|r| r.engine.split_once(" on ").map(|(_, d)| d))
        .collect();
    devices.dedup();
    for d in devices {
        println!("gpu device: {d}");
    }
    print!(
        "{:<18} {:>8} {:>10} {:>8} {:>11}",
        "series", "dt/bound", "dt (s)", "steps", "wall s/sim s"
    );
    for k in 1..=r.sample_times.len() {
        print!(" {:>9} {:>9}", format!("relL2@t{k}"), format!("maxm@t{k}"));
    }
    println!();
    for row in &r.rows {
        print!(
            "{:<18} {:>8.4} {:>10.3e} {:>8} {:>11.3e}",
            row.series, row.dt_over_bound, row.dt, row.steps, row.wall_s_per_sim_s
        );
        for e in &row.errors {
            print!(" {:>9.2e} {:>9.2e}", e.relative_l2, e.max_error_m);
        }
        if let Some(m) = &row.diverged {
            print!("  {m}");
        }
        println!();
    }
    println!(
        "relL2: |x - x_ref| / |x_ref - x_rest| over all nodes; maxm: largest nodal error, m; \
         wall s/sim s: stepping time per simulated second"
    );
}

/// Print what a mesh file holds.
fn info(path: &Path, json: bool) -> lancet::Result<ExitCode> {
    let loaded = lancet::mesh::io::read(path)?;
    let mesh = &loaded.mesh;
    let topo = mesh.topology();
    let quality = mesh.quality();
    let components = mesh.component_count();
    let regions: serde_json::Map<String, serde_json::Value> = mesh
        .regions()
        .into_iter()
        .map(|(r, n)| (r.to_string(), json!(n)))
        .collect();
    let edges = mesh.edges().len();
    if json {
        let v = json!({
            "path": path.display().to_string(),
            "format": loaded.report.format.to_string(),
            "nodes": mesh.node_count(),
            "tets": mesh.tet_count(),
            "edges": edges,
            "boundary_faces": topo.boundary.len(),
            "surface_triangles": loaded.surface.len(),
            "volume": mesh.volume(),
            "inverted": loaded.report.reoriented,
            "dropped_nodes": loaded.report.dropped_nodes,
            "min_quality": quality.map(|q| q.min_volume_length_ratio),
            "mean_quality": quality.map(|q| q.mean_volume_length_ratio),
            "min_dihedral_deg": quality.map(|q| q.min_dihedral_deg),
            "max_dihedral_deg": quality.map(|q| q.max_dihedral_deg),
            "components": components,
            "regions": regions,
            "notes": loaded.report.notes,
        });
        println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return Ok(ExitCode::SUCCESS);
    }
    println!("{} ({})", path.display(), loaded.report.format);
    println!(
        "{} nodes, {} tets, {} edges (springs), {} boundary faces",
        mesh.node_count(),
        mesh.tet_count(),
        edges,
        topo.boundary.len()
    );
    println!(
        "volume {:.6e}, {} component(s), {} inverted tet(s) reoriented",
        mesh.volume(),
        components,
        loaded.report.reoriented
    );
    if let Some(q) = quality {
        println!(
            "quality: volume-length ratio min {:.4} mean {:.4}; dihedral angles {:.2}..{:.2} deg",
            q.min_volume_length_ratio,
            q.mean_volume_length_ratio,
            q.min_dihedral_deg,
            q.max_dihedral_deg
        );
    }
    let regions: Vec<String> = mesh
        .regions()
        .iter()
        .map(|(r, n)| format!("{r}: {n} tets"))
        .collect();
    println!("regions: {}", regions.join(", "));
    for note in &loaded.report.notes {
        println!("note: {note}");
    }
    Ok(ExitCode::SUCCESS)
}

/// A measured value for the summary: a whole number (a count: fragments, cuts, nodes) as one,
/// anything else in scientific notation.
fn measured_text(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 {
        format!("{v:.0}")
    } else {
        format!("{v:.4e}")
    }
}
