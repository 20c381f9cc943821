//! The world's API: what a step reports against what the world keeps, and the clear refusals
//! of calls that cannot be honoured.

use lancet::collide::ToolShape;
use lancet::cut::CutMethod;
use lancet::mesh::generate::BoxGrid;
use lancet::model::Material;
use lancet::world::{CutSettings, TimeStepPolicy, World, WorldBuilder};
use lancet::{EngineKind, ModelConfig, SimConfig};
use nalgebra::{Isometry3, Vector3};

/// A 2 cm cube of soft tissue on the fast engine at half the stable step.
fn cube() -> World {
    let mesh = BoxGrid::cube_cells([4, 4, 4], 0.005).build().unwrap();
    let model = ModelConfig::new(Material::elastic(2e4, 0.3, 1000.0));
    WorldBuilder::new(mesh, &model, SimConfig::new(1.0))
        .unwrap()
        .engine(EngineKind::Fast)
        .bound_fraction(0.5)
        .unwrap()
        .build()
        .unwrap()
}

fn at(x: f64, y: f64, z: f64) -> Isometry3<f64> {
    Isometry3::translation(x, y, z)
}

#[test]
fn a_blade_swept_through_reports_each_cut_at_the_step_that_made_it() {
    let mut world = cube();
    world
        .enable_cutting(CutSettings {
            method: CutMethod::Separate,
            time_step: TimeStepPolicy::Substep,
            ..CutSettings::default()
        })
        .unwrap();
    let blade = ToolShape::Blade {
        width: 0.05,
        length: 0.05,
        thickness: 2e-4,
    };
    let scalpel = world
        .add_tool("scalpel", blade, at(0.0101, 0.0117, 0.03))
        .unwrap();
    let nodes = world.model().node_count();
    let mut events = Vec::new();
    // Down through the cube along -z at 1 mm a step, off the grid planes.
    for k in 1..=40 {
        let z = 0.03 - 1e-3 * k as f64;
        world.set_tool_pose(scalpel, at(0.0101, 0.0117, z)).unwrap();
        let report = world.step().unwrap();
        assert!(report.tools[scalpel.index()].cuts);
        // A blade that cuts pushes nothing and feels nothing.
        assert_eq!(report.tools[scalpel.index()].force, Vector3::zeros());
        for e in &report.cuts {
            assert_eq!(e.step, report.step);
            assert_eq!(e.blade, "scalpel");
        }
        events.extend(report.cuts);
    }
    let report = world.cut_report().unwrap();
    assert!(!events.is_empty(), "the blade cut nothing");
    assert_eq!(report.events, events);
    // The copies a split makes are new nodes, at the end of the node order, in the mesh and
    // the simulation alike; the blade went through, so the cube is in two pieces.
    let added: usize = events.iter().map(|e| e.nodes_added).sum();
    assert!(added > 0);
    assert_eq!(world.model().node_count(), nodes + added);
    assert_eq!(world.mesh().node_count(), nodes + added);
    assert_eq!(report.fragments, 2);
}

#[test]
fn calls_that_cannot_be_honoured_are_refused_with_what_to_do() {
    let mut world = cube();
    let probe = world
        .add_tool(
            "probe",
            ToolShape::Sphere { radius: 0.002 },
            at(0.01, 0.01, 0.03),
        )
        .unwrap();
    let e = world
        .add_tool(
            "probe",
            ToolShape::Sphere { radius: 0.002 },
            at(0.0, 0.0, 0.03),
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("`probe`") && e.contains("own name"), "{e}");

    let e = world.grasp(probe, 1e-3).unwrap_err().to_string();
    assert!(e.contains("`probe`") && e.contains("Grasper"), "{e}");

    let e = world
        .set_device_pose(probe, at(0.0, 0.0, 0.0), Vector3::zeros())
        .unwrap_err()
        .to_string();
    assert!(e.contains("couple it first"), "{e}");

    let coupling = lancet::world::VirtualCoupling {
        stiffness: -1.0,
        damping: 0.0,
        proxy_mass: 0.01,
    };
    assert!(world.couple(probe, coupling).is_err());
    world
        .couple(
            probe,
            lancet::world::VirtualCoupling {
                stiffness: 100.0,
                ..coupling
            },
        )
        .unwrap();
    let e = world
        .set_tool_pose(probe, at(0.0, 0.0, 0.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("set_device_pose"), "{e}");
}

#[test]
fn a_tool_left_unposed_stays_where_it_was_and_sweeps_nothing() {
    let mut world = cube();
    let probe = world
        .add_tool(
            "probe",
            ToolShape::Sphere { radius: 0.003 },
            at(0.01, 0.01, 0.05),
        )
        .unwrap();
    // Pressed 1 mm into the top in one step, then left alone.
    world.set_tool_pose(probe, at(0.01, 0.01, 0.022)).unwrap();
    let pressed = world.step().unwrap();
    assert!(pressed.contacts > 0);
    for _ in 0..5 {
        world.step().unwrap();
        let tool = world.tool(probe);
        assert_eq!(tool.pose(), tool.previous_pose());
        assert_eq!(tool.pose().translation.z, 0.022);
    }
}
