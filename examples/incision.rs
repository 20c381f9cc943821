//! An incision: a blade swept down through a block of tissue hanging from its top face, one
//! pose per step, printing each cut the world makes (the step, the tets touched, the nodes
//! created, the bytes patched into the engine) and the pieces left at the end.
//!
//! `cargo run --release --example incision`

use lancet::collide::ToolShape;
use lancet::cut::CutMethod;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{FixedSelector, Material, SpringDamping};
use lancet::world::{CutSettings, TimeStepPolicy, WorldBuilder};
use lancet::{EngineKind, ModelConfig, SimConfig};
use nalgebra::Isometry3;

fn main() -> lancet::Result<()> {
    // A 4 cm block of 20 kPa tissue hanging from its y = 0 face, gravity along +y (as in
    // `fixtures/scenes/cut_box_through.ron`).
    let mesh = BoxGrid::cube_cells([4, 4, 4], 0.01).build()?;
    let material = Material::elastic(2e4, 0.3, 1000.0)
        .with_damping(SpringDamping::StiffnessProportional(2e-3));
    let mut model = ModelConfig::new(material);
    model.gravity = [0.0, 9.81, 0.0];
    model.fixed = vec![FixedSelector::Plane {
        point: [0.0; 3],
        normal: [0.0, 1.0, 0.0],
        tolerance: 1e-9,
    }];
    let mut world = WorldBuilder::new(mesh, &model, SimConfig::new(1.0))?
        .engine(EngineKind::Fast)
        .bound_fraction(0.8)?
        .build()?;
    world.enable_cutting(CutSettings {
        method: CutMethod::Separate,
        // A cut that lowers the stable bound lowers the step with it.
        time_step: TimeStepPolicy::Substep,
        ..CutSettings::default()
    })?;
    // Upright in the plane y = 1.7 cm (off the grid planes), edge along x, wider than the block.
    let blade = ToolShape::Blade {
        width: 0.1,
        length: 0.1,
        thickness: 2e-4,
    };
    let pose = |z: f64| Isometry3::translation(0.02, 0.017, z);
    let scalpel = world.add_tool("scalpel", blade, pose(0.05))?;
    // Down through the block at 2 m/s, from 1 cm above its top to 1 cm below its bottom.
    let speed = 2.0;
    let mut z = 0.05;
    while z > -0.01 {
        z -= speed * world.sim().config().dt;
        world.set_tool_pose(scalpel, pose(z))?;
        let report = world.step()?;
        for cut in &report.cuts {
            println!(
                "step {:4} t {:.5} s: {} cut {} tets ({} removed), {} nodes added, {} of {} \
                 layout bytes uploaded",
                cut.step,
                report.time,
                cut.blade,
                cut.tets_touched,
                cut.tets_removed,
                cut.nodes_added,
                cut.bytes_uploaded,
                cut.layout_bytes
            );
        }
        // Cut tets are watched for inversion again.
        world.rewatch()?;
    }
    let report = world.cut_report().expect("cutting is on");
    println!(
        "{} cuts, {} nodes added, {} pieces, median cut {:.3} ms, dt {:.3e} s",
        report.cuts,
        report.nodes_added,
        report.fragments,
        report.p50_ms,
        world.sim().config().dt
    );
    Ok(())
}
