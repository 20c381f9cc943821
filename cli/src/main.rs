//! The `lancet` command-line tool: run scenes, benchmark engines, report accuracy, inspect
//! meshes.
//!
//! Exit codes: 0 success, 1 an expectation failed or the run diverged, 2 bad input or another
//! error.

mod accuracy;
mod bench;
mod info;
mod progress;
mod render;
mod run;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use serde_json::json;

use lancet::engine::{EngineKind, NodeOrdering};
use lancet::layout::edges::Accumulation;
use lancet::scene::{run_scene, RunOptions, RunSummary, Scene};

use accuracy::*;
use bench::*;
use info::*;
use render::*;
use run::*;

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
        /// Engines to compare, comma-separated. The GPU's rows (one per layout) are measured
        /// when an adapter exists and listed as skipped, with the reason, when none does.
        #[arg(long, value_enum, value_delimiter = ',', default_values = ["reference", "fast", "gpu"])]
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
        /// Integration scheme of every run (default: verlet; symplectic-euler with --preset).
        #[arg(long, value_enum)]
        integrator: Option<IntegratorArg>,
        /// Run the mass-spring benchmark of NVIDIA Warp, Newton and Taichi users instead of the
        /// tissue model: boxes of 40x20x20 and 72x36x36 five-tet cells of 5 cm, springs of
        /// 5e4 N/m on the tet edges, 0.125 kg per node, the face x = 0 fixed, gravity, dt
        /// 2e-4 s, symplectic Euler (`benches/peers/` runs the same in Taichi and Warp).
        /// With --cube or --mesh, the preset's model on those meshes.
        #[arg(long, value_enum)]
        preset: Option<PresetArg>,
        /// How the preset's box cells are split into tets (with --preset).
        #[arg(long, value_enum, default_value = "five")]
        split: SplitArg,
        /// Force model every engine steps. Tensor-mass runs on every GPU layout and edge
        /// accumulation too; corotational runs one element path on the GPU whatever the layout
        /// (a per-tet pass and a node gather; atomic edge rows, which would time the same
        /// passes, are skipped).
        #[arg(long, value_enum, default_value = "springs", conflicts_with = "preset")]
        force_model: ForceModelArg,
        /// Print JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Reports on a scene (`lancet report accuracy SCENE`).
    Report {
        #[command(subcommand)]
        report: ReportCommand,
    },
    /// Run a scene and write PNG pictures of it, drawn headless with wgpu (any adapter,
    /// lavapipe included): the tissue's surface (the render surface, else the boundary of the
    /// mesh as cut so far) shaded and coloured by displacement (viridis, from 0 to the colour
    /// bar's top), the tools in grey. The camera is fitted to the tissue at rest.
    Render {
        /// A `.ron` scene file.
        scene: PathBuf,
        /// Folder for the pictures, `<series>_<frame>.png`.
        #[arg(long, default_value = "render")]
        output: PathBuf,
        /// Pictures, evenly spaced through the run, the last at its end.
        #[arg(long, default_value_t = 10)]
        frames: u64,
        /// Width, pixels.
        #[arg(long, default_value_t = 800)]
        width: u32,
        /// Height, pixels.
        #[arg(long, default_value_t = 600)]
        height: u32,
        /// Camera azimuth about the up axis, degrees (0: from +x, or +y when up is x).
        #[arg(long, default_value_t = -60.0, allow_hyphen_values = true)]
        azimuth: f64,
        /// Camera elevation above the plane across up, degrees.
        #[arg(long, default_value_t = 25.0, allow_hyphen_values = true)]
        elevation: f64,
        /// Zoom: above 1 moves the camera closer than the distance that fits the tissue.
        #[arg(long, default_value_t = 1.0)]
        zoom: f64,
        /// Up in the picture, as `x,y,z` (default: against the scene's gravity, else +z).
        #[arg(long, value_delimiter = ',', num_args = 3, allow_hyphen_values = true)]
        up: Option<Vec<f64>>,
        /// Top of the colour bar, m (default: each picture's largest displacement).
        #[arg(long)]
        colour_max: Option<f64>,
        /// Leave out the colour bar.
        #[arg(long)]
        no_legend: bool,
        /// Engine to use instead of the scene's.
        #[arg(long, value_enum)]
        engine: Option<EngineArg>,
        /// GPU memory layout instead of the scene's.
        #[arg(long, value_enum)]
        layout: Option<LayoutArg>,
        /// Number of steps instead of the scene's.
        #[arg(long)]
        steps: Option<u64>,
        /// Cut with this method (default: the scene's first).
        #[arg(long, value_enum)]
        method: Option<MethodArg>,
        /// Print a JSON summary (pictures, camera, colour ranges) on stdout.
        #[arg(long)]
        json: bool,
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
        /// Accumulation variants of the GPU edge layout, comma-separated (each gives its own
        /// series; `atomic-float` is skipped with a note on adapters without float atomics).
        #[arg(long, value_enum, value_delimiter = ',', default_values = ["gather"])]
        accumulation: Vec<AccumulationArg>,
        /// Time steps as fractions of the stable bound, comma-separated, each in (0, 1].
        #[arg(long, value_delimiter = ',', default_values = ["1", "0.5", "0.25", "0.125", "0.0625"])]
        ladder: Vec<f64>,
        /// Time steps of the implicit (backward Euler) series as multiples of the stable
        /// bound, comma-separated; engines without the implicit integrator are skipped with
        /// the reason.
        #[arg(long, value_delimiter = ',', default_values = ["4", "16", "64"])]
        implicit_ladder: Vec<f64>,
        /// No implicit series.
        #[arg(long, conflicts_with = "implicit_ladder")]
        no_implicit: bool,
        /// The relative L2 error at which the series' run times are compared ("time to error").
        #[arg(long, default_value_t = lancet::report::accuracy::DEFAULT_TARGET_ERROR)]
        target_error: f64,
        /// Simulated times to measure the error at, s, comma-separated (default: a quarter, a
        /// half and all of the scene's duration).
        #[arg(long, value_delimiter = ',')]
        time: Vec<f64>,
        /// Step of the converged float64 reference (fourth-order Runge–Kutta) as a fraction of
        /// the bound (it is also run at twice this step as a self-check).
        #[arg(long, default_value_t = lancet::report::accuracy::DEFAULT_REFERENCE_FRACTION)]
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
        /// Also measure the model error: each force model's static answer against an analytic
        /// one (a Beam scene clamped at x = 0 under gravity: Timoshenko's tip deflection),
        /// printed beside the time-step error.
        #[arg(long)]
        model_error: bool,
        /// Meshes of the model-error table: the scene's, then twice and four times its cells
        /// each way.
        #[arg(long, default_value_t = 1, requires = "model_error")]
        refinements: usize,
        /// Only the model error: skip the time-step ladder.
        #[arg(long, requires = "model_error")]
        model_error_only: bool,
        /// Force models of the model-error table, comma-separated.
        #[arg(long, value_enum, value_delimiter = ',', requires = "model_error",
              default_values = ["springs", "tensor-mass", "corotational"])]
        force_models: Vec<ForceModelArg>,
        /// Cells along the beam of the model-error table's first mesh (default: the scene's).
        #[arg(long, requires = "model_error")]
        cells_along: Option<usize>,
        /// Cells across each side of the beam's section (default: the scene's).
        #[arg(long, requires = "model_error")]
        cells_across: Option<usize>,
        /// How the beam's cells are split into tets (default: the scene's).
        #[arg(long, value_enum, requires = "model_error")]
        split: Option<SplitArg>,
        /// Exit with failure unless every finite-element model's error on its finest mesh is
        /// within this fraction of the analytic answer (0.03: 3%); springs are not checked.
        #[arg(long, requires = "model_error")]
        expect_within: Option<f64>,
    },
}

/// A force model on the command line.
#[derive(Clone, Copy, ValueEnum)]
enum ForceModelArg {
    /// Springs on the tet edges.
    Springs,
    /// Linear finite elements as node and edge tensors.
    TensorMass,
    /// Corotational finite elements.
    Corotational,
}

impl From<ForceModelArg> for lancet::physics::ForceModelKind {
    fn from(a: ForceModelArg) -> Self {
        match a {
            ForceModelArg::Springs => Self::Springs,
            ForceModelArg::TensorMass => Self::TensorMass,
            ForceModelArg::Corotational => Self::Corotational,
        }
    }
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
    /// Linearised backward Euler with conjugate gradients, at 1 ms (the CPU engines; the GPU
    /// rows are skipped): the table adds iterations per step and time and bytes per iteration.
    BackwardEuler,
}

impl From<IntegratorArg> for lancet::Integrator {
    fn from(i: IntegratorArg) -> Self {
        match i {
            IntegratorArg::Verlet => lancet::Integrator::Verlet,
            IntegratorArg::SymplecticEuler => lancet::Integrator::SymplecticEuler,
            IntegratorArg::BackwardEuler => lancet::Integrator::BackwardEuler,
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
enum PresetArg {
    /// Damping of 5 N s/m along each spring.
    Damped,
    /// No damping.
    Undamped,
}

impl From<PresetArg> for lancet::report::bench::Preset {
    fn from(p: PresetArg) -> Self {
        match p {
            PresetArg::Damped => lancet::report::bench::Preset::Damped,
            PresetArg::Undamped => lancet::report::bench::Preset::Undamped,
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum SplitArg {
    /// Five tets per cell, alternating with cell parity (as Warp's add_soft_grid).
    Five,
    /// Six tets per cell around the main diagonal.
    Six,
}

impl From<SplitArg> for lancet::mesh::generate::TetSplit {
    fn from(s: SplitArg) -> Self {
        match s {
            SplitArg::Five => lancet::mesh::generate::TetSplit::Five,
            SplitArg::Six => lancet::mesh::generate::TetSplit::Six,
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

/// One `gpu device:` line per device the rows ran on (engine names read `<engine> on <device>`),
/// in the order they first appear.
fn print_gpu_devices<'a>(engines: impl Iterator<Item = &'a str>) {
    let mut devices: Vec<&str> = engines
        .filter_map(|e| e.split_once(" on ").map(|(_, d)| d))
        .collect();
    devices.dedup();
    for d in devices {
        println!("gpu device: {d}");
    }
}

/// Let a closed pipe end the process as it ends other Unix tools (`lancet run --json | head`),
/// instead of a panic at the next print: Rust ignores SIGPIPE, so a write to a closed pipe
/// fails, and `println!` panics on the failure.
fn quiet_on_closed_pipe() {
    #[cfg(unix)]
    // SAFETY: called first thing in `main`, before any thread exists; SIG_DFL is a valid
    // action for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Whether the command asked for JSON output: its errors are then a JSON object on stdout.
fn wants_json(command: &Command) -> bool {
    match command {
        Command::Run { json, .. } | Command::Info { json, .. } | Command::Render { json, .. } => {
            *json
        }
        Command::Report {
            report: ReportCommand::Accuracy { json, .. },
        } => *json,
        Command::Bench {
            what: Some(BenchWhat::Collide { json, .. }),
            ..
        }
        | Command::Bench {
            what: Some(BenchWhat::Cut { json, .. }),
            ..
        }
        | Command::Bench { json, .. } => *json,
    }
}

fn main() -> ExitCode {
    quiet_on_closed_pipe();
    let cli = Cli::parse();
    let json = wants_json(&cli.command);
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
                frame_every: None,
            };
            run(scene.as_deref(), json, &opts)
        }
        Command::Info { mesh, json } => info(&mesh, json),
        Command::Render {
            scene,
            output,
            frames,
            width,
            height,
            azimuth,
            elevation,
            zoom,
            up,
            colour_max,
            no_legend,
            engine,
            layout,
            steps,
            method,
            json,
        } => render(RenderRequest {
            scene,
            output,
            frames,
            pictures: lancet::render::frames::PictureOptions {
                width,
                height,
                view: lancet::render::View {
                    azimuth,
                    elevation,
                    zoom,
                    ..Default::default()
                },
                up: up.map(|u| nalgebra::Vector3::new(u[0], u[1], u[2])),
                colour_max,
                legend: !no_legend,
            },
            run: RunOptions {
                engine: engine.map(Into::into),
                layout: layout.map(Into::into),
                steps,
                cut_method: method.map(Into::into),
                ..Default::default()
            },
            json,
        }),
        Command::Report {
            report:
                ReportCommand::Accuracy {
                    scene,
                    engine,
                    layout,
                    accumulation,
                    ladder,
                    implicit_ladder,
                    no_implicit,
                    target_error,
                    time,
                    reference,
                    json,
                    plot,
                    no_plot,
                    model_error,
                    refinements,
                    model_error_only,
                    force_models,
                    cells_along,
                    cells_across,
                    split,
                    expect_within,
                },
        } => {
            let opts = lancet::report::accuracy::AccuracyOptions {
                engines: engine.iter().map(|&e| e.into()).collect(),
                layouts: layout.iter().map(|&l| l.into()).collect(),
                accumulations: accumulation.iter().map(|&a| a.into()).collect(),
                ladder,
                implicit_ladder: if no_implicit {
                    Vec::new()
                } else {
                    implicit_ladder
                },
                target_error,
                times: time,
                reference_fraction: reference,
                ..Default::default()
            };
            let plot = if no_plot {
                PlotTo::Nowhere
            } else {
                plot.map_or(PlotTo::Default, PlotTo::Dir)
            };
            let model_error = ModelErrorArgs {
                on: model_error,
                refinements,
                only: model_error_only,
                force_models: force_models.iter().map(|&m| m.into()).collect(),
                cells_along,
                cells_across,
                split: split.map(Into::into),
                expect_within,
            };
            accuracy(scene.as_deref(), &opts, json, plot, model_error)
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
            preset,
            split,
            force_model,
            json,
        } => {
            let default_integrator = match preset {
                Some(_) => lancet::Integrator::SymplecticEuler,
                None => lancet::Integrator::Verlet,
            };
            let opts = lancet::report::bench::BenchOptions {
                integrator: integrator.map_or(default_integrator, Into::into),
                preset: preset.map(Into::into),
                engines: engine.iter().map(|&e| e.into()).collect(),
                layouts: layout.iter().map(|&l| l.into()).collect(),
                accumulations: accumulation.iter().map(|&a| a.into()).collect(),
                orders: order.iter().map(|&o| o.into()).collect(),
                steps,
                force_model: force_model.into(),
                ..Default::default()
            };
            bench(&cubes, &mesh, &opts, split.into(), json)
        }
    };
    match result {
        Ok(code) => code,
        Err(e) if json => {
            // A program reading the output gets an object it can parse, not a line of text.
            println!("{}", json!({ "error": e.to_string() }));
            ExitCode::from(2)
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
