//! Cuts whose crossings fall on the render surface's own vertices and edges: a blade exactly
//! along a row of render vertices (the edges between them lying in its sweep), and a tilted
//! blade along a line of the quads' diagonal edges. Every method leaves the drawn surface
//! closed and outward, the vertices it adds on the sweep bound in a tet on their own side, and
//! each side moving with its own piece when the pieces are pulled apart.

use lancet::cut::{CutMethod, Sweep};
use lancet::surface::embed::barycentric;
use lancet::surface::{Binding, Capped, Capper, Embedding, Rebinder, RenderSurface};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rstest::rstest;

use crate::cut_box::{
    closed_box, cut_once, cutter, enclosed_volume, not_closed, sweeps_between, Pulled, H, Y0,
};

/// A blade's plane: a point on it and its unit normal (the blade's +y side).
struct Plane {
    point: Point3<f64>,
    normal: Vector3<f64>,
}

impl Plane {
    fn distance(&self, p: &[f64; 3]) -> f64 {
        self.normal.dot(&(Point3::from(*p) - self.point))
    }
}

/// The upright blade in the plane `y = Y0` moving down through the box in three steps, and a
/// box surface with a row of vertices at `y = Y0` (rows 6 mm apart from 1.3 mm: the fifth is
/// at 25.3 mm).
fn along_a_row() -> (RenderSurface, Vec<Sweep>, Plane) {
    let surface = closed_box([0.001, 0.0013, 0.001], [0.049, 0.0373, 0.029], [10, 6, 6]);
    let poses: Vec<_> = (0..4)
        .map(|k| Isometry3::translation(0.02, Y0, 0.045 - 0.02 * k as f64))
        .collect();
    let plane = Plane {
        point: Point3::new(0.0, Y0, 0.0),
        normal: Vector3::y(),
    };
    (surface, sweeps_between(&poses), plane)
}

/// The blade turned 45 degrees about x, in the plane `y - z = 15.3 mm`, moving down along it
/// through the box in three steps, and a box surface of 5 mm squares whose diagonals on the two
/// faces normal to x run along that plane (`y - z` = 5.3 mm at the lowest corner), and whose
/// rows on the other faces it crosses lie in it.
fn along_diagonals() -> (RenderSurface, Vec<Sweep>, Plane) {
    let surface = closed_box([0.001, 0.0063, 0.001], [0.049, 0.0363, 0.026], [10, 6, 5]);
    let c = 0.0153;
    let turn = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -std::f64::consts::FRAC_PI_4);
    let poses: Vec<_> = (0..4)
        .map(|k| {
            let z = 0.05 - 0.025 * k as f64;
            Isometry3::from_parts(Translation3::new(0.02, z + c, z), turn)
        })
        .collect();
    let plane = Plane {
        point: Point3::new(0.0, c, 0.0),
        normal: Vector3::new(0.0, 1.0, -1.0).normalize(),
    };
    (surface, sweeps_between(&poses), plane)
}

/// Cut by `method` with `strokes`, rebinding and capping after each; then every check.
fn cut_and_check(method: CutMethod, (surface, strokes, plane): (RenderSurface, Vec<Sweep>, Plane)) {
    let own = surface.vertex_count();
    // The surface's vertices on the blade's plane: the case under test.
    let on = surface
        .positions
        .iter()
        .filter(|p| plane.distance(p).abs() < 1e-12)
        .count();
    assert!(on >= 20, "{on} render vertices on the blade's plane");
    let volume = enclosed_volume(&surface.positions, &surface.triangles);
    assert!(volume > 0.0);

    let mut cutter = cutter(method);
    let mut e = Embedding::new(cutter.mesh(), &surface).unwrap();
    let mut rebinder = Rebinder::new(cutter.mesh(), &e);
    let mut capper = Capper::new(own, &surface.triangles);
    let mut capped = Capped::default();
    for sweep in &strokes {
        cut_once(&mut cutter, sweep, Some((&mut rebinder, &mut e)));
        capped = capper.cut(&mut e, cutter.mesh(), sweep);
        if let Some(why) = not_closed(&capped.triangles) {
            panic!("{method}: the drawn surface is open after a stroke: {why}");
        }
    }
    let mesh = cutter.mesh();
    assert_eq!(mesh.component_count(), 2, "{method}: cut through");
    assert!(
        capped.cap_triangles > 0 && capped.open == 0,
        "{method}: {capped:?}"
    );
    // Outward, and at rest each side's cap lies on the other's: the box's volume.
    let v = enclosed_volume(&e.rest, &capped.triangles);
    assert!(
        (v - volume).abs() < 1e-9 * volume,
        "{method}: {v} enclosed, box {volume}"
    );
    // No drawn triangle uses a vertex the blade went through: each has a copy per side.
    for t in &capped.triangles {
        for &v in t {
            if (v as usize) < own {
                let d = plane.distance(&e.rest[v as usize]);
                assert!(
                    d.abs() > 1e-12,
                    "{method}: vertex {v} on the cut still drawn"
                );
            }
        }
    }
    // The vertices added lie on the cut, bound in a tet on their side (within a cell of it when
    // the mesh's cut does not follow the blade).
    assert!(e.len() - own >= 2 * on, "{method}: {} added", e.len() - own);
    for v in own..e.len() {
        assert!(
            plane.distance(&e.rest[v]).abs() < 1e-12,
            "vertex {v} off the cut"
        );
        assert!(!e.dropped[v], "{method}: vertex {v} dropped");
        let t = mesh
            .tet(e.bindings[v].tet())
            .expect("a tet of the cut mesh");
        let w = barycentric(&mesh.tet_points(t), &Point3::from(e.rest[v]));
        match e.bindings[v] {
            Binding::Inside(_) => assert!(w.iter().all(|&w| w >= -1e-10), "vertex {v}: {w:?}"),
            Binding::Outside { distance, .. } => assert!(
                method != CutMethod::Subdivide && distance <= H,
                "{method}: vertex {v} {distance} m from its tet"
            ),
        }
    }
    // Pulled apart: every drawn triangle moves with one piece, the surface's vertices off the
    // cut with the piece of their side, the two copies of each point on it one with each.
    let pulled = Pulled::apart(mesh);
    let x = e.evaluate(&pulled.x);
    let what = method.to_string();
    let piece = crate::surface_cap::piece_pulled(&pulled, &e, &x, &what);
    crate::surface_cap::triangles_with_one_piece(&capped.triangles, &piece, &what);
    for t in &capped.triangles {
        for &v in t {
            let d = plane.distance(&e.rest[v as usize]);
            if d.abs() > H {
                assert_eq!(piece(v), d < 0.0, "{method}: vertex {v} {d} m from the cut");
            }
        }
    }
    crate::surface_cap::one_copy_per_piece(own..e.len(), &e.rest, &piece, &what);
    let v = enclosed_volume(&x, &capped.triangles);
    assert!(
        (v - volume).abs() < 1e-9 * volume,
        "{method}: {v} pulled apart"
    );
}

#[rstest]
fn a_blade_along_a_row_of_render_vertices_is_capped(
    #[values(CutMethod::Remove, CutMethod::Separate, CutMethod::Subdivide)] method: CutMethod,
) {
    cut_and_check(method, along_a_row());
}

#[rstest]
fn a_blade_along_render_edges_is_capped(
    #[values(CutMethod::Remove, CutMethod::Separate, CutMethod::Subdivide)] method: CutMethod,
) {
    cut_and_check(method, along_diagonals());
}
