//! A grasper lifts a flap and lets it go: closed on the free end of a clamped slab it captures
//! the surface nodes between its jaws, carries them 5 mm up with it (the flap bends, the
//! clamped end stays), and once opened the flap falls back to where it hung before.

use crate::tissue;
use lancet::collide::{Tool, ToolShape};
use lancet::contact::grasp::Grasp;
use lancet::engine::{EngineKind, Simulation};
use lancet::mesh::generate::BoxGrid;
use nalgebra::{Isometry3, Vector3};

/// Mean z of the nodes at the free end (x = 20 mm).
fn tip_z(sim: &Simulation) -> f64 {
    let (sum, n) = sim
        .positions()
        .iter()
        .zip(&sim.model().rest)
        .filter(|(_, r)| r[0] > 0.0199)
        .fold((0.0, 0), |(s, n), (p, _)| (s + p[2], n + 1));
    sum / n as f64
}

#[test]
fn a_grasper_lifts_a_flap_and_releases_it() {
    // A 20 x 10 x 2 mm flap of soft tissue clamped at x = 0, under gravity.
    let grid = BoxGrid::cube_cells([10, 5, 1], 0.002);
    let mut config = tissue::clamped([1.0, 0.0, 0.0], 40.0);
    config.gravity = [0.0, 0.0, -9.81];
    let mut sim = tissue::tissue(grid, &config, EngineKind::Fast);
    let dt = sim.config().dt;
    let steps = |t: f64| (t / dt) as usize;
    sim.run(steps(0.3) as u64).unwrap();
    let hanging = tip_z(&sim);
    assert!(
        hanging < 0.001,
        "the flap sags under gravity: tip at {hanging}"
    );

    // Jaws 2 x 12 x 6 mm, 2 mm apart, turned so that they close along z above and below the
    // flap's last 6 mm (the tool's z axis points along -x).
    let jaws = ToolShape::Grasper {
        jaw: [0.001, 0.006, 0.003],
        opening: 0.002,
    };
    let at = |lift: f64| {
        Isometry3::new(
            Vector3::new(0.0221, 0.005, hanging + lift),
            Vector3::new(0.0, -std::f64::consts::FRAC_PI_2, 0.0),
        )
    };
    let mut tool = Tool::new(jaws, at(0.0)).unwrap();
    let grasp = Grasp::close(&mut sim, &tool, 1e-3).unwrap();
    // At least the tip column's top and bottom nodes across the width (12); the flap sags, so
    // the columns nearer the clamp sit higher and only partly fall between the jaws.
    assert!(
        grasp.nodes().len() >= 12,
        "captured {} nodes",
        grasp.nodes().len()
    );
    let n = steps(0.2);
    for k in 1..=n + steps(0.1) {
        tool.set_pose(at(5e-3 * (k.min(n) as f64 / n as f64)));
        sim.run(1).unwrap();
        grasp.hold(&mut sim, &tool).unwrap();
    }
    let lifted = tip_z(&sim) - hanging;
    assert!(
        (lifted - 5e-3).abs() < 5e-4,
        "the tip rose {lifted} m with a 5 mm lift"
    );
    // The clamped end stays; the middle rises less than the tip: the flap bends.
    let mid = sim
        .positions()
        .iter()
        .zip(&sim.model().rest)
        .filter(|(_, r)| (r[0] - 0.01).abs() < 1e-9)
        .map(|(p, r)| p[2] - r[2])
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(
        mid > 0.0 && mid < lifted,
        "middle raised by {mid}, tip by {lifted}"
    );

    // Open: the flap is let go and hangs as before.
    sim.run(steps(0.6) as u64).unwrap();
    let back = tip_z(&sim) - hanging;
    assert!(
        back.abs() < 3e-4,
        "after release the tip is {back} m off where it hung"
    );
}
