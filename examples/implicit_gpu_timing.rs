//! Time per conjugate-gradient iteration of the GPU engine's implicit step (backward Euler),
//! per layout, on a stiff box (E = 1 MPa, base clamped) at dt = 1 ms: wall time per step,
//! CG iterations per solve, and wall time per iteration (a step's time over its iterations:
//! the right-hand-side pass and the status reads are shared out among them).
//!
//! `cargo run --release --example implicit_gpu_timing [cells_per_side] [steps]`
//! (28 cells a side: 24,389 nodes.)

use std::time::Instant;

use lancet::engine::gpu::GpuEngine;
use lancet::engine::Engine;
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{FixedSelector, Material, SpringDamping};
use lancet::{Integrator, ModelConfig, SimConfig, SpringModel};

fn main() -> lancet::Result<()> {
    let mut args = std::env::args().skip(1);
    let cells: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(28);
    let steps: u32 = args.next().and_then(|a| a.parse().ok()).unwrap_or(50);
    let mesh = BoxGrid::cube_cells([cells; 3], 0.1 / cells as f64).build()?;
    let material = Material::elastic(1e6, 0.3, 1000.0)
        .with_damping(SpringDamping::StiffnessProportional(1e-4));
    let mut config = ModelConfig::new(material);
    config.gravity = [0.0, 0.0, -9.81];
    config.fixed = vec![FixedSelector::Plane {
        point: [0.0; 3],
        normal: [1.0, 0.0, 0.0],
        tolerance: 1e-9,
    }];
    let packed = SpringModel::build(&mesh, &config)?.pack(&mesh)?;
    let bound = lancet::model::stable_time_step(&packed).dt;
    let dt = 1e-3;
    println!(
        "{} nodes, {} springs, dt {dt} s = {:.0} times the explicit bound",
        packed.node_count(),
        packed.springs().len(),
        dt / bound
    );
    for layout in [LayoutKind::Connectivity, LayoutKind::Valence] {
        let mut sim = SimConfig::new(dt);
        sim.integrator = Integrator::BackwardEuler;
        let mut engine = GpuEngine::new(&packed, sim, layout)?;
        engine.step(3); // compile, upload, first solves
        let before = engine.solver_stats().unwrap_or_default();
        let t = Instant::now();
        engine.step(steps);
        let _ = engine.positions(); // the last step has ended on the device
        let secs = t.elapsed().as_secs_f64();
        let after = engine.solver_stats().unwrap_or_default();
        let iterations = (after.iterations - before.iterations) as f64;
        println!(
            "{}: {:.3} ms/step, {:.1} CG iterations/solve (max {}), {:.4} ms/iteration, \
             {:.2}x real time, last residual {:.1e}, {} capped",
            engine.describe(),
            1e3 * secs / steps as f64,
            iterations / steps as f64,
            after.max_iterations,
            1e3 * secs / iterations.max(1.0),
            dt * steps as f64 / secs,
            after.last_residual,
            after.capped
        );
    }
    Ok(())
}
