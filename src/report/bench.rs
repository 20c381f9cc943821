//! `lancet bench`: engines (and later layouts) side by side on the same meshes, with memory,
//! time per step, spring evaluations per second, achieved bandwidth against the floor, and the
//! error against the float64 reference after the same simulated time.

use std::path::PathBuf;
use std::time::Instant;

use serde::Serialize;

use super::bandwidth::Bandwidth;
use crate::engine::{EngineKind, Integrator, SimConfig, Simulation};
use crate::error::Result;
use crate::mesh::generate::BoxGrid;
use crate::mesh::TetMesh;
use crate::model::{stable_time_step, FixedSelector, Material, ModelConfig, PackedModel};

/// A mesh to benchmark on.
#[derive(Debug, Clone, PartialEq)]
pub enum BenchMesh {
    /// A cube of `n^3` cells, six tets each, 1 cm cells.
    Cube(usize),
    /// A mesh file.
    File(PathBuf),
}

impl BenchMesh {
    fn build(&self) -> Result<(String, TetMesh)> {
        Ok(match self {
            BenchMesh::Cube(n) => (
                format!("cube {n}^3"),
                BoxGrid::cube_cells([*n; 3], 0.01).build()?,
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

/// What to run.
#[derive(Debug, Clone)]
pub struct BenchOptions {
    /// Engines to compare.
    pub engines: Vec<EngineKind>,
    /// Layouts to run each GPU engine in.
    pub layouts: Vec<crate::layout::LayoutKind>,
    /// Steps timed per engine (after a warm-up).
    pub steps: u64,
    /// Steps per timed chunk; the median chunk gives the time per step.
    pub chunk: u64,
    /// Integration scheme.
    pub integrator: Integrator,
}

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions {
            engines: vec![EngineKind::Reference, EngineKind::Fast],
            layouts: vec![crate::layout::LayoutKind::Connectivity],
            steps: 200,
            chunk: 20,
            integrator: Integrator::Verlet,
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
    /// Engine (and layout).
    pub engine: String,
    /// Bytes the engine keeps.
    pub memory_bytes: u64,
    /// Padding share of that, per cent.
    pub padding_percent: f64,
    /// Bytes one step must move.
    pub bytes_per_step: u64,
    /// Median wall time per step, ms.
    pub ms_per_step: f64,
    /// Springs evaluated per second (each spring counted once per step).
    pub spring_evals_per_s: f64,
    /// `bytes_per_step / time per step`.
    pub achieved_bytes_per_s: f64,
    /// Measured memory bandwidth of this machine, same run.
    pub bandwidth_bytes_per_s: f64,
    /// `achieved / bandwidth`: 1 means the step runs at the memory-bandwidth floor.
    pub floor_ratio: f64,
    /// Relative L2 displacement error against the float64 reference after the same steps.
    pub error_vs_reference: f64,
}

/// The model every engine runs: soft tissue (E = 10 kPa, nu = 1/4, 1000 kg/m^3), the bottom
/// fixed, gravity, light damping, at 0.9 of the stable bound.
pub fn bench_model(mesh: &TetMesh) -> Result<PackedModel> {
    let zmin = mesh.bounds().map_or(0.0, |(lo, _)| lo.z);
    let mut config = ModelConfig::new(Material::elastic(10e3, 0.25, 1000.0));
    config.gravity = [0.0, 0.0, -9.81];
    config.mass_damping = 5.0;
    config.fixed.push(FixedSelector::HalfSpace {
        point: [0.0, 0.0, zmin],
        normal: [0.0, 0.0, 1.0],
        tolerance: 1e-9,
    });
    crate::model::SpringModel::build(mesh, &config)?.pack(mesh)
}

/// Run the benchmark matrix.
pub fn run_bench(
    meshes: &[BenchMesh],
    opts: &BenchOptions,
    bandwidth: &Bandwidth,
) -> Result<Vec<BenchRow>> {
    let mut rows = Vec::new();
    for m in meshes {
        let (name, mesh) = m.build()?;
        let model = bench_model(&mesh)?;
        let dt = 0.9 * stable_time_step(&model).dt;
        let config = SimConfig {
            integrator: opts.integrator,
            ..SimConfig::new(dt)
        };
        let total = opts.steps.max(opts.chunk);
        // The reference state after the same number of steps, for the error column.
        let mut reference = Simulation::new(model.clone(), EngineKind::Reference, config)?;
        reference.run(total)?;
        let x_ref = reference.positions();
        // GPU engines run once per layout; CPU engines have none.
        let runs = opts.engines.iter().flat_map(|&e| {
            let layouts = if matches!(e, EngineKind::Gpu | EngineKind::Auto) {
                opts.layouts.clone()
            } else {
                vec![config.layout]
            };
            layouts.into_iter().map(move |l| (e, l))
        });
        for (engine, layout) in runs {
            let config = SimConfig { layout, ..config };
            let mut sim = Simulation::new(model.clone(), engine, config)?;
            // Warm-up: first touches of memory, thread pools, shader compilation.
            sim.step_unchecked(opts.chunk.min(10) as u32);
            sim.set_state(&model.rest, &vec![[0.0; 3]; model.node_count()])?;
            let mut times = Vec::new();
            let mut done = 0;
            while done < total {
                let n = opts.chunk.min(total - done);
                let t = Instant::now();
                sim.step_unchecked(n as u32);
                times.push(t.elapsed().as_secs_f64() / n as f64);
                done += n;
            }
            sim.check()?;
            times.sort_by(f64::total_cmp);
            let per_step = times[times.len() / 2];
            let memory = sim.memory();
            let achieved = memory.bytes_per_step as f64 / per_step;
            rows.push(BenchRow {
                mesh: name.clone(),
                nodes: model.node_count(),
                springs: model.springs.len(),
                engine: sim.engine_name(),
                memory_bytes: memory.stats.total,
                padding_percent: memory.stats.padding_percent(),
                bytes_per_step: memory.bytes_per_step,
                ms_per_step: per_step * 1e3,
                spring_evals_per_s: model.springs.len() as f64 / per_step,
                achieved_bytes_per_s: achieved,
                bandwidth_bytes_per_s: bandwidth.bytes_per_s,
                floor_ratio: achieved / bandwidth.bytes_per_s,
                error_vs_reference: relative_l2(&model.rest, &sim.positions(), &x_ref),
            });
        }
    }
    Ok(rows)
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
