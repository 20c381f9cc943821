//! Two explicit steps per sweep against one step a sweep on the peer benchmark's box (the
//! `--preset` model of `lancet bench`): CPU time and wall time of each, alternated round by
//! round so that a shared machine's drift shows in both, and whether the two give the same bits.
//!
//! `cargo run --release --example fused_steps [damped|undamped] [cells_x] [steps] [rounds]`
//! (cells_x 72 is the 100k-node box, 40 the 18k one; the box is cells_x x cells_x/2 x cells_x/2).

use std::time::Instant;

use lancet::engine::fast::FastEngine;
use lancet::engine::Engine;
use lancet::mesh::generate::{BoxGrid, TetSplit};
use lancet::report::bench::Preset;
use lancet::{Integrator, SimConfig};

fn main() -> lancet::Result<()> {
    let mut args = std::env::args().skip(1);
    let preset = match args.next().as_deref() {
        Some("undamped") => Preset::Undamped,
        _ => Preset::Damped,
    };
    let cx: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(72);
    let steps: u32 = args.next().and_then(|a| a.parse().ok()).unwrap_or(400);
    let rounds: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(5);
    let mesh = BoxGrid {
        split: TetSplit::Five,
        ..BoxGrid::cube_cells([cx, cx / 2, cx / 2], Preset::CELL)
    }
    .build()?;
    let model = preset.model(&mesh)?;
    let mut config = SimConfig::new(Preset::DT);
    config.integrator = Integrator::SymplecticEuler;
    let make = |fused: bool| {
        let mut e = FastEngine::new(&model, config);
        e.set_fused_steps(fused);
        e.step(20); // first touches, the thread pool
        e
    };
    let (mut fused, mut single) = (make(true), make(false));
    println!(
        "{preset:?}: {} nodes, {} springs, bandwidth {}",
        model.node_count(),
        model.springs().len(),
        fused.bandwidth()
    );
    let (mut cpu, mut wall) = ([0.0; 2], [0.0; 2]);
    for _ in 0..rounds {
        for (k, e) in [&mut fused, &mut single].into_iter().enumerate() {
            let (t, c) = (Instant::now(), cpu_seconds());
            e.step(steps);
            wall[k] += t.elapsed().as_secs_f64();
            cpu[k] += cpu_seconds() - c;
        }
    }
    let per = |s: f64| 1e3 * s / (rounds as f64 * steps as f64);
    for (k, name) in ["two steps a sweep", "one step a sweep"].iter().enumerate() {
        println!(
            "{name}: {:.3} ms CPU per step, {:.3} ms wall per step ({:.0} steps/s)",
            per(cpu[k]),
            per(wall[k]),
            1e3 / per(wall[k])
        );
    }
    println!(
        "pairs made in one sweep: {}; same bits: {}",
        fused.fused_step_pairs(),
        same_bits(&fused, &single)
    );
    Ok(())
}

fn same_bits(a: &FastEngine, b: &FastEngine) -> bool {
    let (pa, pb) = (a.positions(), b.positions());
    let (va, vb) = (a.velocities(), b.velocities());
    let bits = |v: &[[f64; 3]]| v.iter().flatten().map(|f| f.to_bits()).collect::<Vec<_>>();
    bits(&pa) == bits(&pb) && bits(&va) == bits(&vb)
}

/// User + system CPU time of this process so far, s (Linux; 0 elsewhere).
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    let rest = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0)
        + f.get(12).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    ticks / 100.0
}
