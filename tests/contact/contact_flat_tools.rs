//! Flat tools pressed into a block: a blade laid flat and the tips of a closed grasper's jaws
//! push the surface down with them, no tissue node ends a step inside the tool by more than a
//! stated tolerance, and the force on the tool points away from the tissue and grows with
//! depth. On the fast CPU engine and, where there is an adapter, on the GPU.

use crate::{common, tissue};
use lancet::collide::{Tool, ToolPart, ToolShape};
use lancet::contact::response::{resolve_contacts, ContactSettings};
use lancet::engine::{EngineKind, Simulation};
use lancet::mesh::generate::BoxGrid;
use nalgebra::{Isometry3, Point3, Vector3};
use rstest::rstest;

const TOP: f64 = 0.012;
/// How far a node may end a step inside a tool, m: the tool advances 1 um per step and a node
/// pulled on by several contacts is left a few um inside (as for the probe).
const TOLERANCE: f64 = 2e-5;

/// A 24 x 24 x 12 mm block of soft tissue (2 mm cells) on a fixed base, and its surface.
fn block(kind: EngineKind) -> Simulation {
    let grid = BoxGrid::cube_cells([12, 12, 6], 0.002);
    tissue::tissue(grid, &tissue::clamped([0.0, 0.0, 1.0], 80.0), kind)
}

/// How deep `p` lies inside a box part of the tool (negative outside).
fn inside(tool: &Tool, p: &Point3<f64>) -> f64 {
    tool.shape
        .parts()
        .iter()
        .map(|part| {
            let ToolPart::Box {
                centre,
                half_extents,
            } = *part
            else {
                unreachable!("flat tools are boxes")
            };
            let q = tool.pose().inverse_transform_point(p) - centre;
            (0..3)
                .map(|k| half_extents[k] - q[k].abs())
                .fold(f64::INFINITY, f64::min)
        })
        .fold(f64::NEG_INFINITY, f64::max)
}

/// The two flat tools, each with its pose for a press `depth` (m) below the block's top, its
/// flat 6 x 6 mm face down over the middle of the block (x and y from 9 to 15 mm).
fn flat_tool(name: &str) -> (ToolShape, Box<dyn Fn(f64) -> Isometry3<f64>>) {
    match name {
        // A 6 mm wide, 6 mm long, 1 mm thick blade laid flat: its y axis (across the blade)
        // turned to +z, its length along -y.
        "blade" => (
            ToolShape::Blade {
                width: 0.006,
                length: 0.006,
                thickness: 0.001,
            },
            Box::new(|depth: f64| {
                Isometry3::new(
                    Vector3::new(0.012, 0.015, TOP + 0.0005 - depth),
                    Vector3::new(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
                )
            }),
        ),
        // A closed grasper (jaws 3 x 6 x 10 mm each, no gap) upright: the jaws reach up from
        // their tips, which press down side by side.
        "grasper" => (
            ToolShape::Grasper {
                jaw: [0.0015, 0.003, 0.005],
                opening: 0.0,
            },
            Box::new(|depth: f64| Isometry3::translation(0.012, 0.012, TOP - depth)),
        ),
        _ => unreachable!(),
    }
}

#[rstest]
fn a_flat_tool_pressed_deeper_pushes_the_surface_out_and_is_pushed_back_harder(
    #[values("blade", "grasper")] name: &str,
    #[values(EngineKind::Fast, EngineKind::Gpu)] kind: EngineKind,
) {
    if kind == EngineKind::Gpu && common::gpu().is_none() {
        return;
    }
    let (shape, pose) = flat_tool(name);
    let s = ContactSettings::default();
    let mut sim = block(kind);
    let mut tool = Tool::new(shape, pose(-5e-4)).unwrap();
    let mut step = |sim: &mut Simulation, depth: f64| {
        tool.set_pose(pose(depth));
        sim.run(1).unwrap();
        let f = resolve_contacts(sim, std::slice::from_ref(&tool), &s).unwrap()[0];
        let deepest = sim
            .positions()
            .iter()
            .map(|p| inside(&tool, &Point3::from(*p)))
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(
            deepest < TOLERANCE,
            "{name} on {kind:?} at {depth}: a node is {deepest:.2e} m inside"
        );
        f.force
    };
    let (mut depth, mut last_force): (f64, f64) = (-5e-4, 0.0);
    for target in [0.25e-3, 0.5e-3, 0.75e-3] {
        while depth < target {
            depth = (depth + 1e-6).min(target);
            step(&mut sim, depth);
        }
        let mut f = Vector3::zeros();
        for k in 0..1200 {
            let fk = step(&mut sim, depth);
            if k >= 1000 {
                f += fk / 200.0;
            }
        }
        // The top-face node under the middle of the face went down with the tool.
        let dent = sim
            .positions()
            .iter()
            .zip(&sim.model().rest)
            .filter(|(_, r)| r[2] > TOP - 1e-9 && (r[0] - 0.012).abs() < 1e-9)
            .filter(|(_, r)| (r[1] - 0.012).abs() < 1e-9)
            .map(|(p, r)| r[2] - p[2])
            .next()
            .unwrap();
        eprintln!(
            "{name} on {kind:?}: press {target:.2e} m, centre node down {dent:.3e} m, force \
             ({:.2e}, {:.2e}, {:.3e}) N",
            f.x, f.y, f.z
        );
        assert!(
            (dent - target).abs() < 0.1 * target,
            "{name} on {kind:?}: the node under the face went down {dent} m at {target} m"
        );
        assert!(
            f.z > last_force,
            "{name} on {kind:?}: force {f:?} at {target} not up and above {last_force}"
        );
        assert!(
            f.xy().norm() < 0.1 * f.z,
            "{name} on {kind:?}: a centred flat press is pushed sideways: {f:?}"
        );
        last_force = f.z;
    }
}
