//! Nodes a grasper holds belong to the grasp: contact resolution leaves them where the grasp
//! put them, even where the jaws squeeze into the tissue, and pushes only the others.

use crate::tissue;
use lancet::collide::{Tool, ToolShape};
use lancet::contact::grasp::Grasp;
use lancet::contact::response::{resolve_contacts, resolve_contacts_excluding, ContactSettings};
use lancet::engine::{EngineKind, Simulation};
use lancet::mesh::generate::BoxGrid;
use nalgebra::{Isometry3, Vector3};

/// A 20 x 10 x 2 mm flap clamped at x = 0 and a grasper whose jaws (1.6 mm apart) squeeze its
/// free end 0.2 mm deep from above and below.
fn squeezed() -> (Simulation, Tool) {
    let grid = BoxGrid::cube_cells([10, 5, 1], 0.002);
    let sim = tissue::tissue(
        grid,
        &tissue::clamped([1.0, 0.0, 0.0], 40.0),
        EngineKind::Fast,
    );
    // The tool's z axis along -x, its x axis along +z: the jaws close along z on the flap's
    // last 6 mm.
    let jaws = ToolShape::Grasper {
        jaw: [0.001, 0.006, 0.003],
        opening: 0.0016,
    };
    let pose = Isometry3::new(
        Vector3::new(0.0221, 0.005, 0.001),
        Vector3::new(0.0, -std::f64::consts::FRAC_PI_2, 0.0),
    );
    (sim, Tool::new(jaws, pose).unwrap())
}

#[test]
fn contacts_leave_the_nodes_a_grasp_holds_where_the_grasp_put_them() {
    let (mut sim, mut tool) = squeezed();
    let grasp = Grasp::close(&mut sim, &tool, 1e-3).unwrap();
    let held = grasp.nodes().to_vec();
    // The top and bottom nodes of the three columns under the jaws, across the width.
    assert_eq!(held.len(), 36, "captured {held:?}");
    let s = ContactSettings::default();

    // Lift 1 mm over 100 steps, holding and resolving contacts each step.
    let start = *tool.pose();
    let lift = |k: usize| {
        let mut p = start;
        p.translation.vector.z += 1e-5 * k as f64;
        p
    };
    for k in 1..=100 {
        tool.set_pose(lift(k));
        sim.run(1).unwrap();
        grasp.hold(&mut sim, &tool).unwrap();
        let f = resolve_contacts_excluding(&mut sim, std::slice::from_ref(&tool), &s, &held)
            .unwrap()[0];
        // The held nodes sit where the grasp put them (up to the engine's float32 storage).
        let at = sim.node_positions(&held).unwrap();
        for (a, b) in at.iter().zip(grasp.targets(&tool)) {
            let off = (Vector3::from(*a) - Vector3::from(b)).norm();
            assert!(
                off < 1e-8,
                "step {k}: a held node is {off} m off its grasp position"
            );
        }
        // They are all the jaws touch, so the contacts push nothing and the tool feels no
        // contact force (what it carries is the grasp's business).
        assert_eq!(f.force, Vector3::zeros(), "step {k}: {f:?}");
    }

    // Without the exclusion the same contacts push the squeezed nodes 0.2 mm back out of the
    // jaws, off their grasp positions.
    let before = sim.node_positions(&held).unwrap();
    let f = resolve_contacts(&mut sim, std::slice::from_ref(&tool), &s).unwrap()[0];
    let after = sim.node_positions(&held).unwrap();
    let pushed = before
        .iter()
        .zip(&after)
        .map(|(a, b)| (Vector3::from(*a) - Vector3::from(*b)).norm())
        .fold(0.0, f64::max);
    assert!(
        pushed > 1.5e-4 && f.contacts > 0,
        "held nodes pushed by at most {pushed} m ({f:?})"
    );
}
