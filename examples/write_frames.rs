//! Writing frames: a probe pressed into a block through the world's API, the deformed mesh
//! written every 200 steps as VTK (`.vtu`) frames listed in a `.pvd` series that ParaView
//! opens as an animation, with the probe's force printed beside each frame.
//!
//! `cargo run --release --example write_frames [output_dir]` (default: a folder under the
//! system's temporary folder).

use std::path::PathBuf;

use lancet::collide::ToolShape;
use lancet::mesh::generate::BoxGrid;
use lancet::mesh::io::pvd::PvdWriter;
use lancet::model::{FixedSelector, Material};
use lancet::world::WorldBuilder;
use lancet::{EngineKind, ModelConfig, SimConfig};
use nalgebra::Isometry3;

fn main() -> lancet::Result<()> {
    let dir = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("lancet_write_frames"));
    let mesh = BoxGrid::cube_cells([12, 12, 6], 0.002).build()?;
    let mut model = ModelConfig::new(Material::elastic(2e4, 0.3, 1000.0));
    model.mass_damping = 80.0;
    model.fixed = vec![FixedSelector::Plane {
        point: [0.0; 3],
        normal: [0.0, 0.0, 1.0],
        tolerance: 1e-9,
    }];
    let mut world = WorldBuilder::new(mesh, &model, SimConfig::new(1.0))?
        .engine(EngineKind::Fast)
        .bound_fraction(0.5)?
        .build()?;
    let sphere = ToolShape::Sphere { radius: 0.003 };
    let top = 0.012;
    let probe = world.add_tool(
        "probe",
        sphere,
        Isometry3::translation(0.012, 0.012, top + 0.004),
    )?;
    let mut frames = PvdWriter::new(&dir, "press", Default::default())?;
    frames.frame(0.0, world.mesh(), Some(&world.positions()))?;
    let dt = world.sim().config().dt;
    // Down 1 mm into the top over 0.1 s (from 1 mm above it), then held for 0.1 s.
    let steps = (0.2 / dt).round() as u64;
    for n in 1..=steps {
        let t = n as f64 * dt;
        let depth = 0.002 * (t / 0.1).min(1.0);
        let z = top + 0.004 - depth;
        world.set_tool_pose(probe, Isometry3::translation(0.012, 0.012, z))?;
        let report = world.step()?;
        if n % 200 == 0 || n == steps {
            frames.frame(report.time, world.mesh(), Some(&world.positions()))?;
            let f = report.tools[probe.index()].force;
            println!(
                "t {:.4} s: probe at z {z:.4} m, force {:.4} N",
                report.time,
                f.norm()
            );
        }
    }
    frames.finish()?;
    println!(
        "{} frames: {}",
        frames.frames(),
        frames.pvd_path().display()
    );
    Ok(())
}
