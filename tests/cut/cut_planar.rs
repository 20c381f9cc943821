//! Planar cuts of a box, where the outcome is known exactly: which layer carving removes,
//! which faces splitting opens, and the volumes of the two pieces.

use lancet::collide::ToolShape;
use lancet::cut::{CutMethod, Cutter, Sweep};
use lancet::mesh::generate::BoxGrid;
use lancet::model::{Material, ModelConfig, SpringModel};
use lancet::TetMesh;
use nalgebra::Isometry3;

const H: f64 = 0.01;
const BLADE: ToolShape = ToolShape::Blade {
    width: 0.1,
    length: 0.1,
    thickness: 1e-4,
};

fn box_mesh() -> TetMesh {
    BoxGrid::cube_cells([4, 4, 4], H).build().unwrap()
}

fn config() -> ModelConfig {
    ModelConfig::new(Material::elastic(3e3, 0.3, 1000.0))
}

/// A blade upright in the plane `y = y0` (its normal along +y), edge at height `z`. The
/// rotation is the identity, so the plane is exactly `y = y0` (a turned blade's plane is off by
/// the rounding of its rotation).
fn blade_at(y0: f64, z: f64) -> Isometry3<f64> {
    Isometry3::translation(0.02, y0, z)
}

/// Sweep the upright blade at `y = y0` from edge height `z0` to `z1` through the mesh at rest.
fn cut_at_rest(cutter: &mut Cutter, y0: f64, z0: f64, z1: f64) -> lancet::cut::CutOutcome {
    let sweep = Sweep::of_blade(&BLADE, &blade_at(y0, z0), &blade_at(y0, z1)).unwrap();
    let rest: Vec<[f64; 3]> = cutter
        .mesh()
        .nodes()
        .map(|(_, n)| n.rest.coords.into())
        .collect();
    cutter.cut(&sweep, &rest).unwrap()
}

/// Cut the box with a blade moving down through it from above in `steps` steps. Subdividing
/// goes without a quality floor: only the parameter rule then decides where the cut goes, so
/// where it goes is known exactly (the floor's snapping is tested in `cut_snap.rs`).
fn cut_down(method: CutMethod, y0: f64, steps: usize) -> (Cutter, f64) {
    let mesh = box_mesh();
    let volume = mesh.volume();
    let model = SpringModel::build(&mesh, &config()).unwrap();
    let mut cutter = Cutter::new(mesh, model, method)
        .unwrap()
        .with_quality_floor(0.0);
    let (top, bottom) = (0.05, -0.01);
    for k in 0..steps {
        let z0 = top + (bottom - top) * k as f64 / steps as f64;
        let z1 = top + (bottom - top) * (k + 1) as f64 / steps as f64;
        cut_at_rest(&mut cutter, y0, z0, z1);
    }
    (cutter, volume)
}

fn fragment_volumes(cutter: &Cutter) -> Vec<f64> {
    let mesh = cutter.mesh();
    let (of, n) = lancet::mesh::topology::components(mesh);
    let mut v = vec![0.0; n];
    for (tk, _) in mesh.tets() {
        v[of[tk] as usize] += mesh.tet_volume(tk);
    }
    v.sort_by(f64::total_cmp);
    v
}

/// Every tet's corners, in nanometres, sorted: a node made on an edge sits at the crossing's
/// parameter, which a sweep triangle of another size rounds differently in the last bit.
fn corner_points(cutter: &Cutter) -> Vec<[[i64; 3]; 4]> {
    let mut v: Vec<_> = cutter
        .mesh()
        .tets()
        .map(|(_, t)| {
            cutter
                .mesh()
                .tet_points(t)
                .map(|p| p.coords.map(|x| (x * 1e9).round() as i64).into())
        })
        .collect();
    v.sort();
    v
}

fn assert_invariants(cutter: &Cutter, volume: f64) {
    let report = cutter.check_invariants(volume, 0.0);
    assert!(report.passed(), "{:#?}", report);
    assert_eq!(report.springs_differing_from_rebuild, Some(0));
}

#[test]
fn separating_off_the_grid_follows_faces_to_pieces_of_known_volume() {
    // In each cell of the 6-tet split, two tets have centroids at y = 1.25 h, two at 1.5 h and
    // two at 1.75 h of their cell: a cut at y = 1.7 h opens the faces between the 1.5 h and
    // 1.75 h tets of the second layer, leaving (1 + 4/6) / 4 of the volume on one side.
    let (cutter, volume) = cut_down(CutMethod::Separate, 1.7 * H, 1);
    assert_invariants(&cutter, volume);
    let v = fragment_volumes(&cutter);
    assert_eq!(v.len(), 2, "{v:?}");
    let left = (1.0 + 4.0 / 6.0) / 4.0 * volume;
    assert!((v[0] - left).abs() < 1e-12 * volume, "{v:?} vs {left}");
    assert!((v[1] - (volume - left)).abs() < 1e-12 * volume);
    // No material lost, nothing removed.
    assert!((cutter.mesh().volume() - volume).abs() < 1e-12 * volume);
    assert_eq!(cutter.crack_front(), 0);
}

#[test]
fn separating_through_grid_nodes_splits_exactly_on_the_plane() {
    let (cutter, volume) = cut_down(CutMethod::Separate, 2.0 * H, 1);
    assert_invariants(&cutter, volume);
    let v = fragment_volumes(&cutter);
    assert_eq!(v.len(), 2, "{v:?}");
    assert!((v[0] - 0.5 * volume).abs() < 1e-12 * volume, "{v:?}");
    // Every node of the plane is split in two: 5 x 5 copies.
    assert_eq!(cutter.mesh().node_count(), 125 + 25);
}

#[test]
fn carving_removes_the_layer_the_blade_passes() {
    // Every tet of the second layer has corners at y = h and y = 2 h, so a blade at 1.7 h
    // meets all of them and no other; at exactly 2 h the tie rule (on the plane counts as the
    // blade's positive side, +y here) takes the same layer.
    for y0 in [1.7 * H, 2.0 * H] {
        let (cutter, volume) = cut_down(CutMethod::Remove, y0, 1);
        assert_invariants(&cutter, volume);
        assert!(
            (cutter.volume_removed() - 0.25 * volume).abs() < 1e-12 * volume,
            "y0 {y0}: removed {}",
            cutter.volume_removed()
        );
        let v = fragment_volumes(&cutter);
        assert_eq!(v.len(), 2, "y0 {y0}: {v:?}");
        assert!((v[0] - 0.25 * volume).abs() < 1e-12 * volume);
    }
}

#[test]
fn a_fast_blade_cuts_the_same_as_a_slow_one() {
    for method in [CutMethod::Separate, CutMethod::Remove, CutMethod::Subdivide] {
        let (fast, _) = cut_down(method, 1.7 * H, 1);
        let (slow, _) = cut_down(method, 1.7 * H, 37);
        assert!(
            corner_points(&fast) == corner_points(&slow),
            "{method}: different tets"
        );
        // Same tets; the volumes are summed in a different storage order.
        let (vf, vs) = (fragment_volumes(&fast), fragment_volumes(&slow));
        assert_eq!(vf.len(), vs.len(), "{method}");
        for (a, b) in vf.iter().zip(&vs) {
            assert!((a - b).abs() <= 1e-14 * a, "{method}: {vf:?} vs {vs:?}");
        }
        assert_eq!(
            fast.mesh().node_count(),
            slow.mesh().node_count(),
            "{method}"
        );
    }
}

#[test]
fn subdividing_off_the_grid_cuts_exactly_on_the_blade_plane() {
    // Every crossed edge spans y = h..2h and is crossed at 0.7 of its length: all are split,
    // none snapped, so the pieces meet exactly on y = 1.7 h.
    let (cutter, volume) = cut_down(CutMethod::Subdivide, 1.7 * H, 1);
    assert_invariants(&cutter, volume);
    let v = fragment_volumes(&cutter);
    assert_eq!(v.len(), 2, "{v:?}");
    let left = 1.7 / 4.0 * volume;
    assert!((v[0] - left).abs() < 1e-12 * volume, "{v:?} vs {left}");
    assert!(cutter.mesh().tet_count() > 384);
}

#[test]
fn subdividing_through_grid_nodes_snaps_and_splits_like_separating() {
    let (cutter, volume) = cut_down(CutMethod::Subdivide, 2.0 * H, 1);
    assert_invariants(&cutter, volume);
    let v = fragment_volumes(&cutter);
    assert_eq!(v.len(), 2, "{v:?}");
    assert!((v[0] - 0.5 * volume).abs() < 1e-12 * volume, "{v:?}");
    assert_eq!(
        cutter.mesh().tet_count(),
        384,
        "nothing to split: every crossing is a node"
    );
    assert_eq!(cutter.mesh().node_count(), 125 + 25);
}

#[test]
fn a_crossing_near_a_node_snaps_to_it_and_makes_no_sliver() {
    // At y = 1.9 h every crossing is within a fifth of an edge of a y = 2 h node.
    let (cutter, volume) = cut_down(CutMethod::Subdivide, 1.9 * H, 1);
    assert_invariants(&cutter, volume);
    assert_eq!(cutter.mesh().tet_count(), 384);
    let report = cutter.check_invariants(volume, 0.0);
    let original = lancet::mesh::quality::tet_quality(
        &box_mesh().tet_points(box_mesh().tets().next().unwrap().1),
    )
    .volume_length_ratio;
    assert!(
        report.min_quality >= 0.99 * original,
        "{} vs {original}",
        report.min_quality
    );
}

/// A partial incision: the blade stops halfway down. The box stays one piece with a crack
/// front (faces cut but still shared, Separate and Subdivide); moving the blade back up and
/// down the cut, or trembling at its end, cuts nothing new; going on down completes the cut
/// into two pieces and the front closes.
#[test]
fn a_partial_incision_keeps_its_front_and_re_sweeping_it_makes_nothing_new() {
    for method in [CutMethod::Separate, CutMethod::Subdivide, CutMethod::Remove] {
        let mesh = box_mesh();
        let volume = mesh.volume();
        let model = SpringModel::build(&mesh, &config()).unwrap();
        let mut cutter = Cutter::new(mesh, model, method).unwrap();
        let y0 = 1.7 * H;
        let cut = |cutter: &mut Cutter, z0: f64, z1: f64| cut_at_rest(cutter, y0, z0, z1);
        // Down to z = 2.5 cm of the 4 cm box, in steps of a fifth of a cell.
        let path: Vec<f64> = (0..=12).map(|k| 0.05 - 0.002 * k as f64 - 0.001).collect();
        for w in path.windows(2) {
            cut(&mut cutter, w[0], w[1]);
        }
        assert_eq!(fragment_volumes(&cutter).len(), 1, "{method}: one piece");
        assert_invariants(&cutter, volume);
        let front = cutter.crack_front();
        let end = *path.last().unwrap();
        match method {
            // Faces cut but still shared where the opened faces end.
            CutMethod::Separate => assert!(front > 0, "{method}: a crack front"),
            // The front is the tets the blade is in, not split yet: no node is made below the
            // blade's edge, but for snapping (a fifth of an edge).
            CutMethod::Subdivide => {
                let lowest = cutter
                    .mesh()
                    .nodes()
                    .skip(box_mesh().node_count())
                    .map(|(_, n)| n.rest.z)
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    lowest >= end - 0.2 * H,
                    "{method}: a node made at z = {lowest}, below the blade's edge at {end}"
                );
            }
            CutMethod::Remove => {}
        }
        let (nodes, tets) = (cutter.mesh().node_count(), cutter.mesh().tet_count());
        // Back up the cut and down again, then trembling at its end.
        let moves = [
            (end, 0.05),
            (0.05, end),
            (end, end + 0.002),
            (end + 0.002, end),
        ];
        for (z0, z1) in moves
            .into_iter()
            .chain([(end, end + 0.001), (end + 0.001, end)])
        {
            let outcome = cut(&mut cutter, z0, z1);
            assert!(
                outcome.is_empty(),
                "{method}: the blade moved {z0} -> {z1} along its cut and cut again"
            );
        }
        assert_eq!(cutter.mesh().node_count(), nodes, "{method}");
        assert_eq!(cutter.mesh().tet_count(), tets, "{method}");
        assert_eq!(cutter.crack_front(), front, "{method}");
        // On down through the box: two pieces, no front left.
        cut(&mut cutter, end, -0.01);
        assert_eq!(fragment_volumes(&cutter).len(), 2, "{method}: two pieces");
        if method != CutMethod::Remove {
            assert_eq!(cutter.crack_front(), 0, "{method}: the front closed");
        }
        assert_invariants(&cutter, volume);
    }
}

/// Under the default quality floor too, a blade through the box in one step and in many makes
/// the same tets: each tet is subdivided by one template of all its crossings, judged whole, and
/// a crossing whose split would make part of a tet below the floor waits for the blade to finish
/// it. (Splitting edges one at a time as they came, the upright blade at y = 1.7 cm added 85,
/// 70, 85, 90, 76, 76 and 45 nodes in 1, 2, 3, 5, 8, 13 and 30 steps.) Three planes: between
/// grid nodes, nearer one layer, and near enough to snap to it.
#[test]
fn a_fast_blade_subdivides_like_a_slow_one_at_the_floor() {
    for y in [1.7, 1.43, 1.9] {
        let cut = |steps: usize| {
            let mesh = box_mesh();
            let volume = mesh.volume();
            let model = SpringModel::build(&mesh, &config()).unwrap();
            let mut cutter = Cutter::new(mesh, model, CutMethod::Subdivide).unwrap();
            let (top, bottom) = (0.05, -0.01);
            for k in 0..steps {
                let z0 = top + (bottom - top) * k as f64 / steps as f64;
                let z1 = top + (bottom - top) * (k + 1) as f64 / steps as f64;
                cut_at_rest(&mut cutter, y * H, z0, z1);
            }
            assert_invariants(&cutter, volume);
            let floor = lancet::cut::subdivide::DEFAULT_QUALITY_FLOOR;
            assert!(cutter.check_invariants(volume, floor).passed());
            cutter
        };
        let fast = cut(1);
        assert_eq!(fragment_volumes(&fast).len(), 2, "y = {y} cm: two pieces");
        for steps in [2, 3, 5, 8, 13, 30] {
            let slow = cut(steps);
            assert_eq!(
                corner_points(&fast),
                corner_points(&slow),
                "y = {y} cm: different tets in {steps} steps"
            );
        }
    }
}

/// A blade turned out of the grid's planes and moved out of its own plane, in steps: its sweep
/// is curved, so later steps mark edges of tets an earlier step finished. Faces shared by a tet
/// split earlier and one split now must still be split alike on both sides (the invariants
/// count boundary triangles without a twin), with and without the quality floor, whatever the
/// number of steps.
#[test]
fn a_turned_blade_moved_out_of_its_plane_keeps_the_mesh_conforming() {
    let axis = nalgebra::Unit::new_normalize(nalgebra::Vector3::new(0.72787, 0.06216, -0.68290));
    let turn = nalgebra::UnitQuaternion::from_axis_angle(&axis, 0.4862);
    let from = nalgebra::Vector3::new(0.020466, 0.016936, 0.052835);
    let to = nalgebra::Vector3::new(0.022180, 0.037638, -0.003454);
    for floor in [0.0, lancet::cut::subdivide::DEFAULT_QUALITY_FLOOR] {
        for steps in [1, 3, 7] {
            let mesh = box_mesh();
            let volume = mesh.volume();
            let model = SpringModel::build(&mesh, &config()).unwrap();
            let mut cutter = Cutter::new(mesh, model, CutMethod::Subdivide)
                .unwrap()
                .with_quality_floor(floor);
            let pose = |s: f64| {
                Isometry3::from_parts(nalgebra::Translation3::from(from + (to - from) * s), turn)
            };
            for k in 0..steps {
                let (s0, s1) = (k as f64 / steps as f64, (k + 1) as f64 / steps as f64);
                let sweep = Sweep::of_blade(&BLADE, &pose(s0), &pose(s1)).unwrap();
                let rest: Vec<[f64; 3]> = cutter
                    .mesh()
                    .nodes()
                    .map(|(_, n)| n.rest.coords.into())
                    .collect();
                cutter.cut(&sweep, &rest).unwrap();
                let report = cutter.check_invariants(volume, floor);
                assert!(
                    report.passed(),
                    "floor {floor}, step {k} of {steps}: {report:#?}"
                );
            }
            assert!(cutter.mesh().node_count() > box_mesh().node_count());
        }
    }
}

/// The cut happens in rest space: tissue moved rigidly, stretched or sheared, and cut by the
/// blade carried along by the same motion, is cut into the same tets, at the same rest
/// positions, as the tissue at rest; every method, at the default quality floor. The blade is
/// off the grid (y = 1.7 cells), so no node is within rounding of its plane.
#[test]
fn cutting_moved_or_deformed_tissue_cuts_as_at_rest() {
    use nalgebra::{Point3, Vector3};
    let rigid = Isometry3::new(
        Vector3::new(0.1, -0.05, 0.2),
        Vector3::new(0.3, -0.5, 0.8).normalize() * 0.7,
    );
    let y0 = 1.7 * H;
    // (what it is, where a rest point goes, the blade's pose at edge height z)
    type Motion = (
        &'static str,
        Box<dyn Fn(Point3<f64>) -> Point3<f64>>,
        Box<dyn Fn(f64) -> Isometry3<f64>>,
    );
    let motions: Vec<Motion> = vec![
        (
            "rigid",
            Box::new(move |p| rigid * p),
            Box::new(move |z| rigid * blade_at(y0, z)),
        ),
        (
            "stretched 1.5x across the blade",
            Box::new(|p| Point3::new(p.x, 1.5 * p.y, p.z)),
            Box::new(move |z| blade_at(1.5 * y0, z)),
        ),
        (
            "sheared along the blade",
            Box::new(|p| Point3::new(p.x + 0.4 * p.y + 0.2 * p.z, p.y, p.z)),
            Box::new(move |z| blade_at(y0, z)),
        ),
    ];
    for method in [CutMethod::Separate, CutMethod::Remove, CutMethod::Subdivide] {
        let cut = |to_world: &dyn Fn(Point3<f64>) -> Point3<f64>,
                   blade: &dyn Fn(f64) -> Isometry3<f64>| {
            let mesh = box_mesh();
            let model = SpringModel::build(&mesh, &config()).unwrap();
            let mut cutter = Cutter::new(mesh, model, method).unwrap();
            let sweep = Sweep::of_blade(&BLADE, &blade(0.05), &blade(-0.01)).unwrap();
            let world: Vec<[f64; 3]> = cutter
                .mesh()
                .nodes()
                .map(|(_, n)| to_world(n.rest).coords.into())
                .collect();
            cutter.cut(&sweep, &world).unwrap();
            cutter
        };
        let at_rest = cut(&|p| p, &|z| blade_at(y0, z));
        // The cut at rest does cut: two pieces, and carving takes a layer.
        assert_eq!(fragment_volumes(&at_rest).len(), 2, "{method:?}");
        assert_eq!(
            at_rest.volume_removed() > 0.0,
            method == CutMethod::Remove,
            "{method:?}"
        );
        for (what, to_world, blade) in &motions {
            let moved = cut(to_world.as_ref(), blade.as_ref());
            assert_eq!(
                corner_points(&moved),
                corner_points(&at_rest),
                "{method:?}, tissue {what}"
            );
            assert_eq!(
                moved.mesh().node_count(),
                at_rest.mesh().node_count(),
                "{method:?}, tissue {what}"
            );
        }
    }
}
