//! Self-contact response: a block dropped onto another block of the same mesh comes to rest on
//! it instead of sinking into it (and without the response it does sink in, so the check can
//! fail), the correction carries no linear momentum, fixed nodes never move, and the fast CPU
//! and GPU engines give the same result.

#![cfg(feature = "collide")]

use crate::common;
use lancet::collide::broad::Surface;
use lancet::collide::self_narrow::closest_on_triangle;
use lancet::contact::self_response::{
    resolve_self_contacts, SelfContactReport, SelfContactSettings,
};
use lancet::engine::{EngineKind, SimConfig, Simulation};
use lancet::mesh::generate::BoxGrid;
use lancet::mesh::TetMesh;
use lancet::model::{stable_time_step, FixedSelector, Material, ModelConfig, SpringModel};
use nalgebra::{Point3, Vector3};

type P = Point3<f64>;

/// Top of the lower block, m.
const TOP: f64 = 0.008;
/// Starting gap under the upper block, m.
const GAP: f64 = 5e-4;
/// Simulated time of a drop, s: without the response the upper block sinks several
/// millimetres into the lower one by then.
const DROP_TIME: f64 = 0.08;
/// A surface node may end this far inside the other body, m: the thickness keeps the surfaces
/// 0.1 mm apart after each correction, and one step under gravity moves a resting node by
/// far less than that. Measured: no node inside at any check, on either engine.
const INSIDE_TOLERANCE: f64 = 1e-5;

/// The lower block, 20 x 20 x 8 mm of 2 mm cells at the origin, and the upper block, 12.5 x
/// 12.5 x 7.5 mm of 2.5 mm cells, offset sideways so that no node lies over a node, 0.5 mm
/// above it: two pieces of one mesh.
fn two_blocks() -> TetMesh {
    let mut mesh = BoxGrid::cube_cells([10, 10, 4], 0.002).build().unwrap();
    let upper = BoxGrid {
        origin: [0.0043, 0.0037, TOP + GAP],
        ..BoxGrid::cube_cells([5, 5, 3], 0.0025)
    }
    .build()
    .unwrap();
    let mut keys = std::collections::HashMap::new();
    for (k, n) in upper.nodes() {
        keys.insert(k, mesh.add_node(n.rest));
    }
    for (_, t) in upper.tets() {
        mesh.add_tet(t.nodes.map(|k| keys[&k]), 1).unwrap();
    }
    mesh
}

/// The scene on `kind`: gravity, damping, the lower block's base fixed (and every node in
/// `also_fixed`, a box), no gravity when `weightless`.
fn scene(kind: EngineKind, weightless: bool, also_fixed: Option<FixedSelector>) -> Simulation {
    let mesh = two_blocks();
    let mut config = ModelConfig::new(Material::elastic(20e3, 0.3, 1000.0));
    config.mass_damping = 40.0;
    if !weightless {
        config.gravity = [0.0, 0.0, -9.81];
        config.fixed.push(FixedSelector::Plane {
            point: [0.0; 3],
            normal: [0.0, 0.0, 1.0],
            tolerance: 1e-9,
        });
    }
    config.fixed.extend(also_fixed);
    let model = SpringModel::build(&mesh, &config)
        .unwrap()
        .pack(&mesh)
        .unwrap();
    let dt = 0.5 * stable_time_step(&model).dt;
    let mut sim = Simulation::new(model, kind, SimConfig::new(dt)).unwrap();
    sim.set_surface(Surface::of(&mesh).triangles).unwrap();
    sim
}

/// Whether a node belongs to the upper block (by its rest position).
fn upper(rest: &[f64; 3]) -> bool {
    rest[2] > TOP + 0.5 * GAP
}

/// Solid angle of triangle `t` seen from `p` (Van Oosterom and Strackee), signed by the
/// triangle's orientation.
fn solid_angle(p: &P, t: &[P; 3]) -> f64 {
    let [a, b, c] = t.map(|q| q - p);
    let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
    let num = a.dot(&b.cross(&c));
    let den = la * lb * lc + a.dot(&b) * lc + a.dot(&c) * lb + b.dot(&c) * la;
    2.0 * num.atan2(den)
}

/// How deep `p` is inside the closed, outward oriented surface `tris` (float64: the winding
/// number decides inside, the nearest triangle gives the depth); 0 outside.
fn depth_inside(p: &P, tris: &[[P; 3]]) -> f64 {
    let winding: f64 =
        tris.iter().map(|t| solid_angle(p, t)).sum::<f64>() / (4.0 * std::f64::consts::PI);
    if winding < 0.5 {
        return 0.0;
    }
    tris.iter()
        .map(|t| (p - closest_on_triangle(p, &t[0], &t[1], &t[2]).0).norm())
        .fold(f64::INFINITY, f64::min)
}

/// The deepest surface node of either block inside the other, m.
fn deepest_inside(sim: &Simulation) -> f64 {
    let x: Vec<P> = sim.positions().into_iter().map(P::from).collect();
    let rest = &sim.model().rest;
    let surface = sim.surface().unwrap();
    let mut worst: f64 = 0.0;
    for side in [true, false] {
        // The other body's closed surface, and this body's surface nodes.
        let other: Vec<[P; 3]> = surface
            .iter()
            .filter(|t| upper(&rest[t[0] as usize]) != side)
            .map(|t| t.map(|i| x[i as usize]))
            .collect();
        let mut mine: Vec<u32> = surface
            .iter()
            .filter(|t| upper(&rest[t[0] as usize]) == side)
            .flatten()
            .copied()
            .collect();
        mine.sort_unstable();
        mine.dedup();
        for n in mine {
            worst = worst.max(depth_inside(&x[n as usize], &other));
        }
    }
    worst
}

/// Drop the upper block for `DROP_TIME`, resolving self-contacts after every step when
/// `respond`; returns the simulation, the deepest penetration seen at the checks (every 50
/// steps and at the end) and the last report.
fn drop(kind: EngineKind, respond: bool) -> (Simulation, f64, SelfContactReport) {
    let settings = SelfContactSettings::default();
    let mut sim = scene(kind, false, None);
    let steps = (DROP_TIME / sim.config().dt).ceil() as usize;
    let (mut worst, mut last) = (0.0f64, SelfContactReport::default());
    for k in 0..steps {
        sim.run(1).unwrap();
        if respond {
            last = resolve_self_contacts(&mut sim, &settings).unwrap();
        }
        if k % 50 == 49 || k + 1 == steps {
            worst = worst.max(deepest_inside(&sim));
        }
    }
    (sim, worst, last)
}

fn lowest_upper_node(sim: &Simulation) -> f64 {
    sim.positions()
        .iter()
        .zip(&sim.model().rest)
        .filter(|(_, r)| upper(r))
        .map(|(p, _)| p[2])
        .fold(f64::INFINITY, f64::min)
}

/// The drop on `kind` rests: no surface node ends up inside the other block, the blocks are
/// in contact at the end, and the upper block's lowest node is near the lower block's top.
fn assert_rests(kind: EngineKind, sim: &Simulation, worst: f64, last: &SelfContactReport) {
    let lowest = lowest_upper_node(sim);
    eprintln!(
        "{kind:?}: {} steps of {:.2e} s; deepest surface node inside the other block {worst:.2e} \
         m; lowest node of the upper block {:.3e} m above the lower block's rest top; last \
         call: {last:?}",
        sim.steps(),
        sim.config().dt,
        lowest - TOP
    );
    assert!(
        worst < INSIDE_TOLERANCE,
        "{kind:?}: a node {worst:e} m inside"
    );
    assert!(
        last.vertex_face + last.edge_edge > 0,
        "{kind:?}: the blocks are not in contact at the end: {last:?}"
    );
    // It landed: the upper block's lowest node is near the lower block's top (which sags a
    // little under the weight).
    assert!(
        lowest < TOP + 2e-4 && lowest > TOP - 5e-4,
        "{kind:?}: lowest node of the upper block at {lowest}"
    );
}

/// A dropped block rests on the other instead of sinking into it, on the fast engine and on
/// the GPU, and the two engines agree on where it rests (one drop per engine serves both
/// checks: a drop is the most expensive run of this binary).
#[test]
fn a_dropped_block_rests_on_the_other_and_the_fast_and_gpu_engines_agree() {
    let (fast, worst, rf) = drop(EngineKind::Fast, true);
    assert_rests(EngineKind::Fast, &fast, worst, &rf);
    if common::gpu().is_none() {
        return;
    }
    let (gpu, worst, rg) = drop(EngineKind::Gpu, true);
    assert_rests(EngineKind::Gpu, &gpu, worst, &rg);
    let (xf, xg) = (fast.positions(), gpu.positions());
    let diff = xf
        .iter()
        .zip(&xg)
        .map(|(a, b)| (Vector3::from(*a) - Vector3::from(*b)).norm())
        .fold(0.0, f64::max);
    let moved = fast.max_displacement();
    eprintln!(
        "fast and GPU after the drop: max node difference {diff:.2e} m (largest displacement \
         {moved:.2e} m)"
    );
    // Measured: 3 nm.
    assert!(diff < 1e-6, "engines differ by {diff:e} m");
}

#[test]
fn without_the_response_the_blocks_interpenetrate() {
    let (sim, worst, _) = drop(EngineKind::Fast, false);
    eprintln!(
        "no response: deepest surface node inside {worst:.2e} m, lowest upper node {:.2e} m \
         below the top",
        TOP - lowest_upper_node(&sim)
    );
    assert!(worst > 1e-3, "deepest {worst:e} m");
}

/// Push the upper block `depth` into the lower one (no gravity, nothing fixed unless `fixed`).
fn pressed(kind: EngineKind, depth: f64, fixed: Option<FixedSelector>) -> Simulation {
    let mut sim = scene(kind, true, fixed);
    let x: Vec<[f64; 3]> = sim
        .model()
        .rest
        .iter()
        .map(|r| {
            if upper(r) {
                [r[0], r[1], r[2] - GAP - depth]
            } else {
                *r
            }
        })
        .collect();
    let v = vec![[0.0; 3]; x.len()];
    sim.set_state(&x, &v).unwrap();
    sim
}

#[test]
fn a_correction_without_fixed_nodes_carries_no_momentum() {
    let mut sim = pressed(EngineKind::Fast, 3e-4, None);
    assert!(sim.model().fixed.iter().all(|f| !f));
    let before = sim.positions();
    let r = resolve_self_contacts(&mut sim, &SelfContactSettings::default()).unwrap();
    let after = sim.positions();
    // As computed, in float64.
    let relative = r.momentum.norm() / r.moved_mass_distance;
    // As stored by the float32 engine.
    let mut sum = Vector3::zeros();
    let mut scale = 0.0;
    for ((a, b), m) in after.iter().zip(&before).zip(&sim.model().mass) {
        let dx = Vector3::from(*a) - Vector3::from(*b);
        sum += *m * dx;
        scale += m * dx.norm();
    }
    eprintln!(
        "{r:?}\nsum m dx / sum m |dx|: {relative:.2e} as computed, {:.2e} as stored",
        sum.norm() / scale
    );
    assert!(r.vertex_face > 0 && r.moved > 0, "{r:?}");
    assert!(relative < 1e-12, "{relative:e}");
    assert!(sum.norm() < 1e-5 * scale, "{sum:?} against {scale:e}");
    // The correction separated them: both move, the upper block up, the lower one down.
    assert!(
        deepest_inside(&sim) < INSIDE_TOLERANCE,
        "{}",
        deepest_inside(&sim)
    );
}

#[test]
fn fixed_nodes_never_move_and_the_other_side_takes_it_all() {
    // The whole lower block fixed.
    let lower = FixedSelector::Box {
        min: [-1.0, -1.0, -1.0],
        max: [1.0, 1.0, TOP + 1e-9],
    };
    let mut sim = pressed(EngineKind::Fast, 3e-4, Some(lower));
    let settings = SelfContactSettings::default();
    let before = sim.positions();
    let r = resolve_self_contacts(&mut sim, &settings).unwrap();
    let after = sim.positions();
    assert!(r.moved > 0, "{r:?}");
    for (i, r) in sim.model().rest.iter().enumerate() {
        if !upper(r) {
            assert_eq!(after[i], before[i], "fixed node {i} moved");
        }
    }
    // The upper block's bottom went all the way out, to the thickness above the top.
    let lowest = lowest_upper_node(&sim);
    assert!(
        (lowest - (TOP + settings.thickness)).abs() < 1e-6,
        "lowest upper node {:.3e} m from the top",
        lowest - TOP
    );
}
