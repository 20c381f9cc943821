//! Steps per second of the fast float32 engine on a box of about 20,000 nodes, and what the
//! simulation's divergence checks (every 10 steps) add to them.
//!
//! `cargo run --release --example fast_engine_speed [cells_per_side] [steps]`

use std::time::Instant;

use lancet::engine::fast::FastEngine;
use lancet::engine::Engine;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{FixedSelector, Material, SpringDamping};
use lancet::{EngineKind, Integrator, ModelConfig, SimConfig, Simulation, SpringModel};

fn main() -> lancet::Result<()> {
    let mut args = std::env::args().skip(1);
    let cells: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(26);
    let steps: u32 = args.next().and_then(|a| a.parse().ok()).unwrap_or(2000);
    let h = 0.01;
    let mesh = BoxGrid::cube_cells([cells; 3], h).build()?;
    for damped in [false, true] {
        let mut material = Material::elastic(3e4, 0.25, 1000.0);
        if damped {
            material = material.with_damping(SpringDamping::StiffnessProportional(1e-4));
        }
        let mut config = ModelConfig::new(material);
        config.gravity = [0.0, 0.0, -9.81];
        config.fixed = vec![FixedSelector::Plane {
            point: [0.0; 3],
            normal: [1.0, 0.0, 0.0],
            tolerance: 1e-9,
        }];
        let packed = SpringModel::build(&mesh, &config)?.pack(&mesh)?;
        let dt = 0.9 * lancet::model::stable_time_step(&packed).dt;
        for integrator in [Integrator::Verlet, Integrator::SymplecticEuler] {
            let mut sim = SimConfig::new(dt);
            sim.integrator = integrator;
            let mut engine = FastEngine::new(&packed, sim);
            engine.step(50); // warm caches and the thread pool
            let (t, cpu) = (Instant::now(), cpu_seconds());
            engine.step(steps);
            let (secs, cpu) = (t.elapsed().as_secs_f64(), cpu_seconds() - cpu);
            println!(
                "{integrator:?}, damped {damped}: {} nodes, {} springs, bandwidth {}: \
                 {:.0} steps/s wall, {:.0} steps per CPU-second",
                packed.node_count(),
                packed.springs().len(),
                engine.bandwidth(),
                steps as f64 / secs,
                steps as f64 / cpu
            );
            // The same steps through `Simulation::run`, checked every `check_every` steps,
            // against unchecked steps, alternated so that the machine's drift shows in both.
            let mut checked = Simulation::new(packed.clone(), EngineKind::Fast, sim)?;
            checked.run(50)?;
            let (mut with, mut without) = (0.0, 0.0);
            for _ in 0..3 {
                let t = cpu_seconds();
                checked.run(steps as u64 / 3)?;
                with += cpu_seconds() - t;
                let t = cpu_seconds();
                checked.step_unchecked(steps / 3);
                without += cpu_seconds() - t;
            }
            // What an exact check costs (the state copied to float64 in model order and its
            // total energy, springs included): what every check cost before the probe.
            let t = cpu_seconds();
            for _ in 0..20 {
                std::hint::black_box(checked.energy());
            }
            let exact = (cpu_seconds() - t) / 20.0;
            let per_step = without / (3 * (steps / 3)) as f64;
            println!(
                "  checked every {} steps: {:.1}% more CPU time than unchecked; an exact check \
                 at that cadence would add {:.1}%",
                sim.check_every,
                100.0 * (with / without - 1.0),
                100.0 * exact / (per_step * sim.check_every as f64)
            );
        }
    }
    Ok(())
}

/// User + system CPU time of this process so far, s (Linux; 0 elsewhere). On a shared machine
/// wall time depends on the neighbours; CPU time says what the engine itself costs.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the parenthesised command name; utime and stime are the 14th and 15th.
    let rest = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0)
        + f.get(12).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    ticks / 100.0
}
