//! `lancet bench`: engines (and later layouts) side by side on the same meshes, with memory,
//! time per step, spring evaluations per second, achieved bandwidth against the floor, and the
//! error against the float64 reference after the same simulated time.

use std::path::PathBuf;
use std::time::Instant;

use serde::Serialize;

use super::bandwidth::Bandwidth;
use crate::engine::{
    EngineKind, ForceModelKind, GpuOptions, Integrator, NodeOrdering, SimConfig, Simulation,
};
use crate::error::{Error, Result};
use crate::layout::edges::Accumulation;
use crate::layout::LayoutKind;
use crate::mesh::generate::{BoxGrid, TetSplit};
use crate::mesh::TetMesh;
use crate::model::{FixedSelector, Material, ModelConfig, PackedModel, SpringDamping};

/// A mesh to benchmark on.
#[derive(Debug, Clone, PartialEq)]
pub enum BenchMesh {
    /// A cube of `n^3` cells, six tets each, 1 cm cells.
    Cube(usize),
    /// A mesh file.
    File(PathBuf),
    /// A box of `cells` cells of edge `cell` m, split as `split` (the peers' benchmark grid:
    /// [`Preset`]).
    Grid {
        /// Cells along x, y, z.
        cells: [usize; 3],
        /// Cell edge, m.
        cell: f64,
        /// How each cell is split into tets.
        split: TetSplit,
    },
}

impl BenchMesh {
    fn build(&self) -> Result<(String, TetMesh)> {
        Ok(match self {
            BenchMesh::Cube(n) => (
                format!("cube {n}^3"),
                BoxGrid::cube_cells([*n; 3], 0.01).build()?,
            ),
            BenchMesh::Grid { cells, cell, split } => (
                format!(
                    "{}x{}x{}-{}tet",
                    cells[0],
                    cells[1],
                    cells[2],
                    match split {
                        TetSplit::Five => 5,
                        TetSplit::Six => 6,
                    }
                ),
                BoxGrid {
                    split: *split,
                    ..BoxGrid::cube_cells(*cells, *cell)
                }
                .build()?,
            ),
            #[cfg(feature = "formats")]
            BenchMesh::File(p) => (p.display().to_string(), crate::mesh::io::read(p)?.mesh),
            #[cfg(not(feature = "formats"))]
            BenchMesh::File(p) => {
                return Err(crate::Error::Unsupported(format!(
                    "{}: this build reads no mesh files (enable the `formats` feature)",
                    p.display()
                )))
            }
        })
    }
}

/// Why a row of `engine` (on the edge variant `accumulation`, `None` off the edge layout)
/// cannot run the implicit integrator with the options' force model; `None` where it runs (or
/// the integrator is explicit).
fn implicit_skip(
    opts: &BenchOptions,
    engine: EngineKind,
    accumulation: Option<Accumulation>,
) -> Option<String> {
    if !opts.integrator.is_implicit() || engine != EngineKind::Gpu {
        return None;
    }
    match accumulation {
        Some(Accumulation::AtomicFixed) => Some(
            "gpu atomic-fixed edge rows skipped: the GPU implicit solve runs on the gather and \
             the float atomics only"
                .into(),
        ),
        None | Some(Accumulation::Gather | Accumulation::AtomicFloat) => None,
    }
}

/// What to run.
#[derive(Debug, Clone)]
pub struct BenchOptions {
    /// Engines to compare.
    pub engines: Vec<EngineKind>,
    /// Layouts to run each GPU engine in.
    pub layouts: Vec<LayoutKind>,
    /// Accumulation variants to run the GPU edge layout in (the other layouts have none).
    pub accumulations: Vec<Accumulation>,
    /// Node orders to run the fast CPU and the GPU engines in (the reference engine keeps the
    /// model's order).
    pub orders: Vec<NodeOrdering>,
    /// Steps timed per engine (after a warm-up).
    pub steps: u64,
    /// Steps per timed chunk; the median chunk gives the time per step.
    pub chunk: u64,
    /// Integration scheme.
    pub integrator: Integrator,
    /// The model every engine runs: the tissue of [`bench_model`] (`None`) or a preset's.
    pub preset: Option<Preset>,
    /// The force model every engine steps (a finite-element one needs the tissue model, not
    /// a preset's springs). Rows that cannot run it with the integrator are skipped with the
    /// reason.
    pub force_model: crate::physics::ForceModelKind,
}

/// The mass-spring benchmark that users of NVIDIA Warp, Newton and Taichi know (a box of
/// five-tet cells like `warp.sim`'s `add_soft_grid`), so that `benches/peers/` can run the same
/// configuration in those frameworks beside lancet: cells of 5 cm, a spring on every unique tet
/// edge of stiffness 5e4 N/m, 0.125 kg per node, the face x = 0 fixed, gravity, a step of
/// 2e-4 s, symplectic Euler.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Preset {
    /// Damping 5 N s/m along each spring.
    Damped,
    /// No damping.
    Undamped,
}

impl Preset {
    /// Cell edge, m.
    pub const CELL: f64 = 0.05;
    /// Spring stiffness, N/m.
    pub const STIFFNESS: f64 = 5e4;
    /// Damping along each spring (the damped preset), N s/m.
    pub const DAMPING: f64 = 5.0;
    /// Mass per node, kg.
    pub const MASS: f64 = 0.125;
    /// Time step, s.
    pub const DT: f64 = 2e-4;
    /// The two sizes of the comparison: 18,081 nodes and 102,080 springs; 99,937 nodes and
    /// 579,456 springs.
    pub const GRIDS: [[usize; 3]; 2] = [[40, 20, 20], [72, 36, 36]];

    /// The preset's meshes, split as `split`.
    pub fn meshes(split: TetSplit) -> Vec<BenchMesh> {
        Self::GRIDS
            .iter()
            .map(|&cells| BenchMesh::Grid {
                cells,
                cell: Self::CELL,
                split,
            })
            .collect()
    }

    /// The preset's model on `mesh`, packed as every engine of `lancet bench` runs it.
    pub fn model(self, mesh: &TetMesh) -> Result<PackedModel> {
        crate::model::SpringModel::build(mesh, &self.model_config(mesh))?.pack(mesh)
    }

    /// The preset's model settings on `mesh` (its face of least x is fixed), for a
    /// [`WorldBuilder`](crate::world::WorldBuilder) or a [`crate::model::SpringModel`].
    pub fn model_config(self, mesh: &TetMesh) -> ModelConfig {
        let xmin = mesh.bounds().map_or(0.0, |(lo, _)| lo.x);
        let damping = match self {
            Preset::Damped => SpringDamping::Absolute(Self::DAMPING),
            Preset::Undamped => SpringDamping::None,
        };
        let mut config =
            ModelConfig::new(Material::springs(Self::STIFFNESS, Self::MASS).with_damping(damping));
        config.gravity = [0.0, 0.0, -9.81];
        config.fixed.push(FixedSelector::HalfSpace {
            point: [xmin, 0.0, 0.0],
            normal: [1.0, 0.0, 0.0],
            tolerance: 1e-9,
        });
        config
    }

    /// The preset's time stepping: [`Preset::DT`], symplectic Euler.
    pub fn sim_config() -> SimConfig {
        let mut config = SimConfig::new(Self::DT);
        config.integrator = Integrator::SymplecticEuler;
        config
    }
}

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions {
            engines: vec![EngineKind::Reference, EngineKind::Fast],
            layouts: vec![LayoutKind::Connectivity],
            accumulations: vec![Accumulation::Gather],
            orders: vec![NodeOrdering::Locality],
            steps: 200,
            chunk: 20,
            integrator: Integrator::Verlet,
            preset: None,
            force_model: crate::physics::ForceModelKind::Springs,
        }
    }
}

/// One row of the table.
#[derive(Debug, Clone, Serialize)]
pub struct BenchRow {
    /// The mesh.
    pub mesh: String,
    /// Nodes.
    pub nodes: usize,
    /// Springs.
    pub springs: usize,
    /// Engine (and layout), with its device for the GPU.
    pub engine: String,
    /// The force model stepped ("springs", "tensor-mass", "corotational").
    pub force_model: String,
    /// GPU layout; none for the CPU engines.
    pub layout: Option<String>,
    /// Accumulation variant of the GPU edge layout ("gather", "atomic-fixed", "atomic-float");
    /// none for the other layouts and engines.
    pub accumulation: Option<String>,
    /// Node order the engine packed its arrays in ("rcm", "identity", "random(seed)"); none
    /// for the reference engine, which keeps the model's order.
    pub order: Option<String>,
    /// Bytes the engine keeps.
    pub memory_bytes: u64,
    /// Padding share of that, per cent.
    pub padding_percent: f64,
    /// Bytes one step must move.
    pub bytes_per_step: u64,
    /// Median wall time per step, ms.
    pub ms_per_step: f64,
    /// Median device time per step from timestamp queries, ms: the GPU engine on adapters
    /// with `TIMESTAMP_QUERY`; none otherwise.
    pub gpu_ms_per_step: Option<f64>,
    /// Process CPU time (every thread's) over the timed steps, per step, ms: less sensitive to
    /// other processes' load than the wall time; none where the platform does not report it.
    pub cpu_ms_per_step: Option<f64>,
    /// Springs evaluated per second (each spring counted once per step).
    pub spring_evals_per_s: f64,
    /// `bytes_per_step / time per step`.
    pub achieved_bytes_per_s: f64,
    /// The memory-bandwidth floor this row is measured against, same run: the host's STREAM
    /// triad for CPU engines, the device's buffer copy for GPU engines (the host's where it was
    /// not measured).
    pub bandwidth_bytes_per_s: f64,
    /// `achieved / bandwidth`: 1 means the step runs at the memory-bandwidth floor.
    pub floor_ratio: f64,
    /// Relative L2 displacement error against the float64 reference after the same steps.
    pub error_vs_reference: f64,
    /// Implicit integrators: conjugate-gradient iterations per step over the timed steps.
    pub cg_iterations_per_step: Option<f64>,
    /// Implicit integrators: the median time per step over the iterations a step took, ms
    /// (the step's assembly of its system, about one explicit step's work, included).
    pub ms_per_cg_iteration: Option<f64>,
    /// Implicit integrators: the bytes one iteration moves at least, where the engine counts
    /// them (then the bandwidth columns are per iteration, not per step).
    pub bytes_per_cg_iteration: Option<u64>,
}

/// CPU time this process has used so far, every thread's, s; `None` where the platform does
/// not report it.
fn process_cpu_seconds() -> Option<f64> {
    #[cfg(unix)]
    {
        let mut t = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `t` is a valid timespec for the call to write.
        let ok = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) } == 0;
        ok.then_some(t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// The time step implicit integrators are benchmarked at, s: a haptic loop's 1 ms, far above
/// the explicit bound of every bench mesh (explicit schemes run at 0.9 of it).
pub const IMPLICIT_BENCH_DT: f64 = 1e-3;

/// The model every engine runs: tissue of E = 100 kPa, nu = 1/4, 1000 kg/m^3, the bottom
/// fixed, gravity, light damping, at 0.9 of the stable bound. Stiff enough that a tall mesh
/// sags by a few per cent: at 10 kPa a 26 cm column sinks by a quarter of its height and starts
/// to buckle, where float32 and float64 runs part by 3e-3 within 300 steps, so the error column
/// would measure that sensitivity rather than the engines' rounding (1e-6 here).
pub fn bench_model(mesh: &TetMesh) -> Result<PackedModel> {
    let zmin = mesh.bounds().map_or(0.0, |(lo, _)| lo.z);
    let mut config = ModelConfig::new(Material::elastic(100e3, 0.25, 1000.0));
    config.gravity = [0.0, 0.0, -9.81];
    config.mass_damping = 5.0;
    config.fixed.push(FixedSelector::HalfSpace {
        point: [0.0, 0.0, zmin],
        normal: [0.0, 0.0, 1.0],
        tolerance: 1e-9,
    });
    crate::model::SpringModel::build(mesh, &config)?.pack(mesh)
}

/// The rows of a benchmark and the combinations it could not run, with why.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    /// One row per mesh and engine variant that ran.
    pub rows: Vec<BenchRow>,
    /// "mesh, variant: reason" for each variant the device cannot run (atomic float
    /// accumulation without `SHADER_FLOAT32_ATOMIC`).
    pub skipped: Vec<String>,
}

/// One engine configuration of the matrix.
#[derive(Debug, Clone, Copy)]
struct Variant {
    engine: EngineKind,
    layout: Option<LayoutKind>,
    accumulation: Option<Accumulation>,
    order: Option<NodeOrdering>,
}

/// The CLI spelling of an accumulation variant.
pub fn accumulation_name(a: Accumulation) -> &'static str {
    match a {
        Accumulation::Gather => "gather",
        Accumulation::AtomicFixed => "atomic-fixed",
        Accumulation::AtomicFloat => "atomic-float",
    }
}

/// The matrix: the reference engine once; the fast engine once per order; GPU engines once
/// per order and layout, and the edge layout once per accumulation variant.
fn variants(opts: &BenchOptions) -> Vec<Variant> {
    let mut out = Vec::new();
    // An empty list means the default, so that a caller can leave a dimension out.
    let orders = if opts.orders.is_empty() {
        vec![NodeOrdering::Locality]
    } else {
        opts.orders.clone()
    };
    let accumulations = if opts.accumulations.is_empty() {
        vec![Accumulation::Gather]
    } else {
        opts.accumulations.clone()
    };
    for &engine in &opts.engines {
        match engine {
            EngineKind::Reference => out.push(Variant {
                engine,
                layout: None,
                accumulation: None,
                order: None,
            }),
            EngineKind::Fast => out.extend(orders.iter().map(|&o| Variant {
                engine,
                layout: None,
                accumulation: None,
                order: Some(o),
            })),
            EngineKind::Gpu | EngineKind::Auto => {
                for &layout in &opts.layouts {
                    let accs: Vec<Option<Accumulation>> = if layout == LayoutKind::Edges {
                        accumulations.iter().copied().map(Some).collect()
                    } else {
                        vec![None]
                    };
                    for accumulation in accs {
                        out.extend(orders.iter().map(|&o| Variant {
                            engine,
                            layout: Some(layout),
                            accumulation,
                            order: Some(o),
                        }));
                    }
                }
            }
        }
    }
    out
}

/// Run the benchmark matrix. CPU rows are measured against `bandwidth`, GPU rows against what
/// `device_floor` gives (the device's copy bandwidth, [`super::device_copy`]; `bandwidth` where
/// it gives none). It is called after every row has run, so that the buffers it copies
/// (512 MiB on a GPU) are allocated before none of the engines on a shared device.
pub fn run_bench(
    meshes: &[BenchMesh],
    opts: &BenchOptions,
    bandwidth: &Bandwidth,
    device_floor: impl FnOnce() -> Option<f64>,
) -> Result<BenchReport> {
    let mut report = BenchReport {
        rows: Vec::new(),
        skipped: Vec::new(),
    };
    let mut gpu_state: Option<std::result::Result<(), String>> = None;
    for m in meshes {
        let (name, mesh) = m.build()?;
        let (model, dt) = match opts.preset {
            // The peers' step: refused (with the bound) if a mesh makes it unstable.
            Some(preset) => (preset.model(&mesh)?, Preset::DT),
            None => {
                let model = bench_model(&mesh)?;
                let dt = if opts.integrator.is_implicit() {
                    IMPLICIT_BENCH_DT
                } else {
                    0.9 * opts.force_model.stable_time_step(&model)?.dt
                };
                (model, dt)
            }
        };
        let base = SimConfig {
            integrator: opts.integrator,
            force_model: opts.force_model,
            ..SimConfig::new(dt)
        };
        let total = opts.steps.max(opts.chunk);
        // The reference state after the same number of steps, for the error column.
        let mut reference = Simulation::new(model.clone(), EngineKind::Reference, base)?;
        reference.run(total)?;
        let x_ref = reference.positions();
        for v in variants(opts) {
            // Without a usable adapter the GPU rows are skipped with the reason, once, and the
            // CPU rows still run, as `lancet report accuracy` does.
            let atomic = matches!(
                v.accumulation,
                Some(Accumulation::AtomicFixed | Accumulation::AtomicFloat)
            );
            if let Some(msg) = implicit_skip(opts, v.engine, v.accumulation) {
                if !report.skipped.contains(&msg) {
                    report.skipped.push(msg);
                }
                continue;
            }
            let gpu_fem = match opts.force_model {
                // Tensor-mass runs in every accumulation (the atomic variants add both end
                // forces of a record, `engine::gpu::tensor_atomic`).
                ForceModelKind::Springs | ForceModelKind::TensorMass => None,
                // One explicit element path whatever the layout: the atomic variants would
                // time the same passes again under another name. Under backward Euler the
                // float-atomic solve is a path of its own (`engine::gpu::implicit_atomic`).
                ForceModelKind::Corotational if atomic && !opts.integrator.is_implicit() => Some(
                    "gpu atomic edge rows skipped: the explicit corotational passes are the same \
                     in every layout and accumulation (a per-tet pass and a node gather)",
                ),
                ForceModelKind::Corotational => None,
            };
            if let (EngineKind::Gpu, Some(msg)) = (v.engine, gpu_fem) {
                let msg = msg.to_string();
                if !report.skipped.contains(&msg) {
                    report.skipped.push(msg);
                }
                continue;
            }
            if v.engine == EngineKind::Gpu {
                if let Err(why) = gpu_state.get_or_insert_with(super::gpu_usable) {
                    let msg = format!("gpu rows skipped: {why}");
                    if !report.skipped.contains(&msg) {
                        report.skipped.push(msg);
                    }
                    continue;
                }
            }
            let config = SimConfig {
                node_order: v.order.unwrap_or(base.node_order),
                ..base
            };
            let gpu = GpuOptions {
                layout: v.layout.unwrap_or_default(),
                accumulation: v.accumulation.unwrap_or_default(),
            };
            let mut sim = match Simulation::with_gpu(model.clone(), v.engine, config, gpu) {
                Ok(sim) => sim,
                // A variant the device lacks a feature for is skipped with the reason; the rest
                // of the matrix still runs.
                Err(Error::Unsupported(why))
                    if v.accumulation == Some(Accumulation::AtomicFloat) =>
                {
                    report
                        .skipped
                        .push(format!("{name}, gpu-edges-atomic-float: {why}"));
                    continue;
                }
                Err(e) => return Err(e),
            };
            // Auto without an adapter runs the CPU engine, which has no layout.
            let on_gpu = sim.kind() == EngineKind::Gpu;
            // Warm-up: first touches of memory, thread pools, shader compilation.
            sim.step_unchecked(opts.chunk.min(10) as u32);
            sim.set_state(&model.rest, &vec![[0.0; 3]; model.node_count()])?;
            let iterations_before = sim.solver_stats().map(|s| s.iterations);
            let mut times = Vec::new();
            let mut device_times = Vec::new();
            let mut done = 0;
            let cpu_before = process_cpu_seconds();
            while done < total {
                let n = opts.chunk.min(total - done);
                let t = Instant::now();
                sim.step_unchecked(n as u32);
                times.push(t.elapsed().as_secs_f64() / n as f64);
                // Read after the wall time is taken: the readback is not part of a step.
                if let Some(s) = sim.last_device_seconds() {
                    device_times.push(s / n as f64);
                }
                done += n;
            }
            let cpu_ms_per_step = cpu_before
                .zip(process_cpu_seconds())
                .map(|(a, b)| (b - a) / total as f64 * 1e3);
            // Only when every chunk was timed, so the median is over the same chunks.
            let gpu_ms_per_step = (device_times.len() == times.len()).then(|| {
                device_times.sort_by(f64::total_cmp);
                device_times[device_times.len() / 2] * 1e3
            });
            sim.check()?;
            times.sort_by(f64::total_cmp);
            let per_step = times[times.len() / 2];
            let memory = sim.memory();
            let cg_per_step = iterations_before
                .zip(sim.solver_stats())
                .map(|(before, s)| (s.iterations - before) as f64 / total as f64);
            let per_iteration = cg_per_step.filter(|&i| i > 0.0).map(|i| per_step / i);
            let bytes_per_iteration = sim.bytes_per_solver_iteration();
            let achieved = match (per_iteration, bytes_per_iteration) {
                (Some(t), Some(b)) => b as f64 / t,
                _ => memory.bytes_per_step as f64 / per_step,
            };
            report.rows.push(BenchRow {
                mesh: name.clone(),
                nodes: model.node_count(),
                springs: model.springs().len(),
                engine: sim.engine_name(),
                force_model: opts.force_model.to_string(),
                layout: v
                    .layout
                    .filter(|_| on_gpu)
                    .map(|l| format!("{l:?}").to_lowercase()),
                accumulation: v
                    .accumulation
                    .filter(|_| on_gpu)
                    .map(|a| accumulation_name(a).to_string()),
                order: v.order.map(|o| o.to_string()),
                memory_bytes: memory.stats.total,
                padding_percent: memory.stats.padding_percent(),
                bytes_per_step: memory.bytes_per_step,
                ms_per_step: per_step * 1e3,
                gpu_ms_per_step,
                cpu_ms_per_step,
                spring_evals_per_s: model.springs().len() as f64 / per_step,
                achieved_bytes_per_s: achieved,
                bandwidth_bytes_per_s: bandwidth.bytes_per_s,
                floor_ratio: achieved / bandwidth.bytes_per_s,
                error_vs_reference: relative_l2(&model.rest, &sim.positions(), &x_ref),
                cg_iterations_per_step: cg_per_step,
                ms_per_cg_iteration: per_iteration.map(|t| t * 1e3),
                bytes_per_cg_iteration: bytes_per_iteration,
            });
        }
    }
    if report.rows.iter().any(|r| r.layout.is_some()) {
        if let Some(d) = device_floor() {
            // The GPU rows (the only ones with a layout) against the device's own floor.
            for r in report.rows.iter_mut().filter(|r| r.layout.is_some()) {
                r.bandwidth_bytes_per_s = d;
                r.floor_ratio = r.achieved_bytes_per_s / d;
            }
        }
    }
    Ok(report)
}

/// `|u - u_ref| / |u_ref|` over all nodes, `u` being displacements from `rest`.
pub fn relative_l2(rest: &[[f64; 3]], x: &[[f64; 3]], x_ref: &[[f64; 3]]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for ((r, a), b) in rest.iter().zip(x).zip(x_ref) {
        for i in 0..3 {
            num += (a[i] - b[i]).powi(2);
            den += (b[i] - r[i]).powi(2);
        }
    }
    if den > 0.0 {
        (num / den).sqrt()
    } else {
        num.sqrt()
    }
}
