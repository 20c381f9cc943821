//! The surface a simulation culls against, edited in place by each cut's `CutOutcome::surface`
//! (`Simulation::edit_surface`) instead of being rebuilt: it stays the cutter's boundary, as a
//! set of outward triangles, on every engine and layout; the device culler over the edited
//! surface finds exactly what the float64 brute force finds (up to float32 rounding), and its
//! buffers, written slot by slot, equal an upload from scratch; and an
//! edit that does not fit the surface is refused with nothing changed.

use crate::common;
use std::collections::BTreeSet;

use lancet::collide::broad::{cull_exact, SurfaceEdit, ToolBox};
use lancet::collide::ToolShape;
use lancet::cut::{CutMethod, Cutter, Sweep};
use lancet::engine::{EngineKind, SimConfig, Simulation};
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::model::{stable_time_step, FixedSelector, Material, ModelConfig, SpringModel};
use nalgebra::Isometry3;
use rstest::rstest;

/// A triangle rotated so that its smallest index comes first: the same orientation, one
/// spelling.
fn canonical(t: [u32; 3]) -> [u32; 3] {
    let k = (0..3).min_by_key(|&i| t[i]).expect("three corners");
    [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
}

fn oriented_set(triangles: &[[u32; 3]]) -> BTreeSet<[u32; 3]> {
    triangles.iter().map(|&t| canonical(t)).collect()
}

/// A clamped 6 x 6 x 3 cm box under gravity and a cutter for it.
fn setup(method: CutMethod, kind: EngineKind, layout: LayoutKind) -> (Simulation, Cutter) {
    let mesh = BoxGrid::cube_cells([6, 6, 3], 0.01).build().unwrap();
    let mut config = ModelConfig::new(Material::elastic(5e3, 0.3, 1000.0));
    config.gravity = [0.0, 0.0, -9.81];
    config.fixed = vec![FixedSelector::Box {
        min: [-1.0; 3],
        max: [1.0, 1.0, 1e-9],
    }];
    let model = SpringModel::build(&mesh, &config).unwrap();
    let packed = model.pack(&mesh).unwrap();
    let sim_config = SimConfig {
        allow_unstable: true,
        ..SimConfig::new(0.4 * stable_time_step(&packed).dt)
    };
    let mut sim = Simulation::with_gpu(packed, kind, sim_config, layout.into()).unwrap();
    let cutter = Cutter::new(mesh, model, method).unwrap();
    sim.set_surface(cutter.surface()).unwrap();
    (sim, cutter)
}

/// Draw a blade through the box in strokes (along x, then down across it), editing the
/// surface after every cut and checking it against the cutter's and the culling against the
/// brute force.
fn edited_surface_stays_the_boundary(method: CutMethod, kind: EngineKind, layout: LayoutKind) {
    let (mut sim, mut cutter) = setup(method, kind, layout);
    let blade = ToolShape::Blade {
        width: 0.01,
        length: 0.1,
        thickness: 2e-4,
    };
    let along = |x: f64| Isometry3::translation(x, 0.0317, 0.0153);
    let across = |z: f64| {
        Isometry3::translation(0.0213, 0.03, z)
            * Isometry3::rotation(nalgebra::Vector3::z() * std::f64::consts::FRAC_PI_2)
    };
    let strokes: Vec<(Isometry3<f64>, Isometry3<f64>)> = (0..8)
        .map(|k| (along(0.0069 * k as f64), along(0.0069 * (k + 1) as f64)))
        .chain((0..4).map(|k| {
            let z = 0.035 - 0.006 * k as f64;
            (across(z), across(z - 0.006))
        }))
        .collect();
    let mut cuts = 0;
    for (from, to) in strokes {
        sim.run(5).unwrap();
        let sweep = Sweep::of_blade(&blade, &from, &to).unwrap();
        let outcome = cutter.cut(&sweep, &sim.positions()).unwrap();
        if outcome.is_empty() {
            continue;
        }
        cuts += 1;
        sim.apply(&outcome.diff).unwrap();
        sim.edit_surface(&outcome.surface).unwrap();
        let edited = sim.surface().unwrap().to_vec();
        let boundary = cutter.surface();
        assert_eq!(edited.len(), boundary.len(), "cut {cuts}: triangle count");
        assert_eq!(
            oriented_set(&edited),
            oriented_set(&boundary),
            "cut {cuts}: the edited surface is not the cutter's boundary"
        );
        // The device holds what it would after an upload from scratch (the surface written
        // slot by slot, with the triangles and rest positions of nodes the layout moved).
        let diffs = sim.differences_from_rebuild().unwrap();
        assert!(diffs.is_empty(), "cut {cuts}: {diffs:?}");

        // Boxes around the blade's path and over the whole box: the culler over the edited
        // surface (on the device for the GPU engine) against the float64 brute force.
        let x = sim.positions();
        let exact_boxes = [
            ([0.0, 0.025, 0.005], [0.06, 0.038, 0.04]),
            ([0.015, -0.01, -0.01], [0.028, 0.07, 0.04]),
            ([-0.01, -0.01, -0.01], [0.07, 0.07, 0.04]),
        ];
        let boxes: Vec<ToolBox> = exact_boxes
            .iter()
            .map(|&(lo, hi)| ToolBox::containing(lo, hi))
            .collect();
        let got: BTreeSet<([u32; 3], u32)> = sim
            .cull_tools(&boxes)
            .unwrap()
            .into_iter()
            .map(|[t, b]| (canonical(edited[t as usize]), b))
            .collect();
        let named = |c: Vec<[u32; 2]>| -> BTreeSet<([u32; 3], u32)> {
            c.into_iter()
                .map(|[t, b]| (canonical(edited[t as usize]), b))
                .collect()
        };
        let exact = named(cull_exact(&x, &edited, &exact_boxes));
        // Float32 rounding may add triangles within a micrometre of a box, never more.
        let grown: Vec<([f64; 3], [f64; 3])> = exact_boxes
            .iter()
            .map(|(lo, hi)| (lo.map(|v| v - 1e-6), hi.map(|v| v + 1e-6)))
            .collect();
        let loose = named(cull_exact(&x, &edited, &grown));
        assert!(
            exact.is_subset(&got),
            "cut {cuts}: the culler missed {:?}",
            exact.difference(&got).take(3).collect::<Vec<_>>()
        );
        assert!(
            got.is_subset(&loose),
            "cut {cuts}: the culler found triangles not on the surface or far from the boxes: {:?}",
            got.difference(&loose).take(3).collect::<Vec<_>>()
        );
    }
    assert!(cuts >= 3, "the blade cut {cuts} times");
}

#[rstest]
fn cpu_engine_surface_follows_the_cuts(
    #[values(CutMethod::Remove, CutMethod::Separate, CutMethod::Subdivide)] method: CutMethod,
) {
    edited_surface_stays_the_boundary(method, EngineKind::Fast, LayoutKind::Connectivity);
}

#[rstest]
fn gpu_surface_follows_the_cuts(
    #[values(CutMethod::Remove, CutMethod::Separate, CutMethod::Subdivide)] method: CutMethod,
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] layout: LayoutKind,
) {
    if common::gpu().is_none() {
        return;
    }
    edited_surface_stays_the_boundary(method, EngineKind::Gpu, layout);
}

#[test]
fn an_edit_that_does_not_fit_changes_nothing() {
    let (mut sim, cutter) = setup(
        CutMethod::Separate,
        EngineKind::Fast,
        LayoutKind::Connectivity,
    );
    let before = sim.surface().unwrap().to_vec();
    let on = before[0];
    let n = sim.model().node_count() as u32;
    let bad = [
        // Not on the surface.
        SurfaceEdit {
            removed: vec![[0, 1, n - 1]],
            added: vec![],
        },
        // Removed twice.
        SurfaceEdit {
            removed: vec![on, [on[1], on[2], on[0]]],
            added: vec![],
        },
        // Already on the surface (in the other orientation).
        SurfaceEdit {
            removed: vec![],
            added: vec![[on[0], on[2], on[1]]],
        },
        // A node past the model.
        SurfaceEdit {
            removed: vec![on],
            added: vec![[0, 1, n]],
        },
    ];
    for edit in bad {
        let err = sim.edit_surface(&edit).unwrap_err().to_string();
        assert!(err.contains("surface edit"), "{err}");
        assert_eq!(
            sim.surface().unwrap(),
            &before[..],
            "{edit:?} changed the surface"
        );
    }
    // The cutter's own boundary fits: removing a triangle and adding it back reversed is
    // accepted, and swaps it into the place of the last.
    let flip = SurfaceEdit {
        removed: vec![on],
        added: vec![[on[0], on[2], on[1]]],
    };
    sim.edit_surface(&flip).unwrap();
    let after = sim.surface().unwrap();
    assert_eq!(after.len(), before.len());
    assert_eq!(after[after.len() - 1], [on[0], on[2], on[1]]);
    assert_eq!(after[0], before[before.len() - 1]);
    drop(cutter);
}

/// Nodes `k` of a fixed sheet 1 mm apart, 40 to a row, 2 cm above a 7 cm box, without springs.
fn sheet(k: std::ops::Range<u32>) -> lancet::model::ModelDiff {
    let added = k
        .map(|k| lancet::model::diff::AddedNode {
            key: Default::default(),
            rest: [0.001 * (k % 40) as f64, 0.001 * (k / 40) as f64, 0.09],
            mass: 1e-3,
            fixed: true,
            state_from: None,
            blend: None,
        })
        .collect();
    lancet::model::ModelDiff {
        added_nodes: added,
        ..Default::default()
    }
}

/// A 14 x 14 x 7 cm box of 1 cm cells falling under gravity, on the GPU engine, and its
/// boundary.
fn falling_box(layout: LayoutKind) -> (Simulation, Vec<[u32; 3]>) {
    let mesh = BoxGrid::cube_cells([14, 14, 7], 0.01).build().unwrap();
    let mut model_config = ModelConfig::new(Material::elastic(5e3, 0.3, 1e3));
    model_config.gravity = [0.0, 0.0, -9.81];
    let model = SpringModel::build(&mesh, &model_config).unwrap();
    let packed = model.pack(&mesh).unwrap();
    let config = SimConfig::new(0.4 * stable_time_step(&packed).dt);
    let sim = Simulation::with_gpu(packed, EngineKind::Gpu, config, layout.into()).unwrap();
    let boundary = Cutter::new(mesh, model, CutMethod::Separate)
        .unwrap()
        .surface();
    (sim, boundary)
}

/// Boxes over the sheet, around the box, and over a hair under its top face, culled on the
/// device after the box fell for ten steps: exactly what the float64 brute force finds (a
/// culler reading node state the engine no longer steps would still see the top face).
fn culls_the_fallen_box(sim: &mut Simulation, box_nodes: usize) {
    sim.run(10).unwrap();
    let x = sim.positions();
    let top = x[..box_nodes].iter().map(|p| p[2]).fold(f64::MIN, f64::max);
    assert!(top < 0.07 - 2e-6, "the box fell to {top} m only");
    let surface = sim.surface().unwrap().to_vec();
    let exact_boxes = [
        ([0.005, 0.005, 0.085], [0.02, 0.02, 0.095]),
        ([-0.01, -0.01, -0.01], [0.15, 0.15, 0.08]),
        ([-0.01, -0.01, 0.07 - 1e-6], [0.15, 0.15, 0.08]),
    ];
    let boxes: Vec<ToolBox> = exact_boxes
        .iter()
        .map(|&(lo, hi)| ToolBox::containing(lo, hi))
        .collect();
    let named = |c: Vec<[u32; 2]>| -> BTreeSet<([u32; 3], u32)> {
        c.into_iter()
            .map(|[t, b]| (canonical(surface[t as usize]), b))
            .collect()
    };
    // The top box alone first: a cull with more boxes than the culler's box buffer holds
    // binds it anew, whatever it was bound to.
    let top_only = sim.cull_tools(&boxes[2..]).unwrap();
    assert!(
        top_only.is_empty(),
        "the culler sees the box's top where it was before it fell: {} triangles",
        top_only.len()
    );
    let got = named(sim.cull_tools(&boxes).unwrap());
    let exact = named(cull_exact(&x, &surface, &exact_boxes));
    assert!(
        exact.iter().filter(|(_, b)| *b == 0).count() > 20,
        "the box over the sheet met few triangles"
    );
    assert!(exact.iter().all(|(_, b)| *b != 2), "the box did not fall");
    assert_eq!(got, exact);
}

/// A patch that moves the node state to larger buffers, while the culler's own buffers keep
/// room (it was made after the first nodes were added), binds the culler to the new state:
/// it culls the box where it fell.
#[rstest]
fn a_patch_that_grows_the_node_state_rebinds_the_culler(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] layout: LayoutKind,
) {
    if common::gpu().is_none() {
        return;
    }
    let (mut sim, boundary) = falling_box(layout);
    let n = sim.model().node_count();
    // 1,800 nodes, and room for 1,024 more (16 KiB) in the state's first buffers.
    sim.apply(&sheet(0..600)).unwrap();
    let rows: Vec<[u32; 3]> = (0..560u32)
        .filter(|k| k % 40 < 39)
        .map(|k| [k, k + 1, k + 40].map(|i| n as u32 + i))
        .collect();
    sim.set_surface(boundary.iter().copied().chain(rows).collect())
        .unwrap();
    let cost = sim.apply(&sheet(600..1200)).unwrap();
    assert!(
        cost.reallocated,
        "the state kept room for 1,200 nodes more: {cost:?}"
    );
    let diffs = sim.differences_from_rebuild().unwrap();
    assert!(diffs.is_empty(), "{diffs:?}");
    culls_the_fallen_box(&mut sim, n);
}

/// A surface edit past the room of the culler's triangle buffer grows it on the device,
/// keeping what it held, after cuts that added more nodes than the first upload left room for
/// (the node state grows on the way): the device then holds
/// what an upload from scratch would, and culls as the float64 brute force does, the new
/// nodes' triangles included.
#[rstest]
fn a_surface_edit_past_the_buffers_room_grows_them(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] layout: LayoutKind,
) {
    if common::gpu().is_none() {
        return;
    }
    let (mut sim, boundary) = falling_box(layout);
    let n = sim.model().node_count() as u32;
    // 1,568 triangles; the first upload of 100 leaves room for about 1,100 (16 KiB).
    assert!(boundary.len() > 1500);
    sim.set_surface(boundary[..100].to_vec()).unwrap();
    // 1,200 nodes more, 100 a cut (more than the first upload left room for: 16 KiB, 1,024
    // nodes), in a sheet above the box, fixed and without springs; each cut's edit adds
    // triangles over the new row, each node with its neighbours along x and y.
    for round in 0..12u32 {
        sim.apply(&sheet(100 * round..100 * (round + 1))).unwrap();
        let rows = (100 * round.saturating_sub(1)..100 * round)
            .filter(|k| k % 40 < 39)
            .map(|k| [n + k, n + k + 1, n + k + 40]);
        let edit = SurfaceEdit {
            removed: vec![],
            added: rows.take(25).collect(),
        };
        if !edit.is_empty() {
            sim.edit_surface(&edit).unwrap();
            let diffs = sim.differences_from_rebuild().unwrap();
            assert!(
                diffs.is_empty(),
                "after {} nodes: {diffs:?}",
                100 * (round + 1)
            );
        }
    }
    let on_sheet = sim.surface().unwrap().len() - 100;
    assert_eq!(on_sheet, 11 * 25);
    // Then the rest of the box's boundary: more triangles than the first upload left room for.
    let edit = SurfaceEdit {
        removed: vec![],
        added: boundary[100..].to_vec(),
    };
    sim.edit_surface(&edit).unwrap();
    let edited = sim.surface().unwrap().to_vec();
    assert_eq!(edited.len(), boundary.len() + on_sheet);
    let diffs = sim.differences_from_rebuild().unwrap();
    assert!(diffs.is_empty(), "{diffs:?}");
    culls_the_fallen_box(&mut sim, n as usize);
}
