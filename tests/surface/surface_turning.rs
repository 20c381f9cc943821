//! A blade that turns during its stroke sweeps a curved surface: the cut stays one cut (each
//! stroke starts where the last ended), and once it is through, its caps lie on the swept
//! surface itself, not on a plane fitted to it, and the drawn surface is closed and outward.

use lancet::cut::{CutMethod, Sweep};
use lancet::surface::embed::closest_on_triangle;
use lancet::surface::{Capped, Capper, Embedding, RenderSurface};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rstest::rstest;

use crate::cut_box::{
    closed_box, cut_once, cutter, enclosed_volume, not_closed, sweeps_between, Y0,
};

/// Distance from `p` to the swept surface `sweeps`.
fn to_sweep(sweeps: &[Sweep], p: &Point3<f64>) -> f64 {
    sweeps
        .iter()
        .flat_map(|s| &s.triangles)
        .map(|t| (closest_on_triangle(p, &t[0], &t[1], &t[2]) - p).norm())
        .fold(f64::INFINITY, f64::min)
}

/// The upright blade moving down through the box in six steps while turning 45 degrees about
/// the vertical through the middle of its edge (its edge sweeps a twisted surface), and a box
/// surface whose rows of vertices 4.67 mm apart put one at the height the third stroke ends.
fn turning() -> (Vec<Sweep>, RenderSurface) {
    let steps = 6;
    let poses: Vec<_> = (0..=steps)
        .map(|k| {
            let f = k as f64 / steps as f64;
            let turn = UnitQuaternion::from_axis_angle(
                &Vector3::z_axis(),
                std::f64::consts::FRAC_PI_4 * f,
            );
            Isometry3::from_parts(Translation3::new(0.02, Y0, 0.045 - 0.06 * f), turn)
        })
        .collect();
    let strokes = sweeps_between(&poses);
    let surface = closed_box([0.001; 3], [0.049, 0.039, 0.029], [10, 8, 6]);
    (strokes, surface)
}

#[rstest]
fn a_turning_blade_inside_leaves_the_surface_closed_after_every_stroke(
    #[values(CutMethod::Remove, CutMethod::Separate, CutMethod::Subdivide)] method: CutMethod,
) {
    let (strokes, surface) = turning();
    // The case under test: the third stroke's edge ends on a row of render vertices.
    let end = 0.045 - 0.06 * 3.0 / 6.0;
    let on_row = surface
        .positions
        .iter()
        .filter(|p| (p[2] - end).abs() < 1e-12)
        .count();
    assert!(
        on_row >= 20,
        "{on_row} render vertices at the third stroke's end"
    );
    let own = surface.vertex_count();
    let volume = enclosed_volume(&surface.positions, &surface.triangles);
    assert!(volume > 0.0);

    let mut cutter = cutter(method);
    let mut e = Embedding::new(cutter.mesh(), &surface).unwrap();
    let mut rebinder = lancet::surface::Rebinder::new(cutter.mesh(), &e);
    let mut capper = Capper::new(own, &surface.triangles);
    let mut failures = Vec::new();
    for (k, sweep) in strokes.iter().enumerate() {
        cut_once(&mut cutter, sweep, Some((&mut rebinder, &mut e)));
        let capped = capper.cut(&mut e, cutter.mesh(), sweep);
        let stroke = k + 1;
        // Closed: every edge used once each way round.
        if let Some(why) = not_closed(&capped.triangles) {
            failures.push(format!("stroke {stroke}: open: {why}"));
        }
        if capped.open != 0 {
            failures.push(format!("stroke {stroke}: {} rims left open", capped.open));
        }
        // Outward: at rest a slit encloses nothing, so the drawn surface encloses the box (a
        // cap the wrong way round would take twice its own contribution off).
        let v = enclosed_volume(&e.rest, &capped.triangles);
        if (v - volume).abs() > 1e-9 * volume {
            failures.push(format!("stroke {stroke}: {v} m3 enclosed, box {volume}"));
        }
        // Every vertex the cut added lies on the swept surface so far.
        for v in own..e.len() {
            let d = to_sweep(&strokes[..stroke], &Point3::from(e.rest[v]));
            if d > 1e-12 {
                failures.push(format!("stroke {stroke}: vertex {v} {d} m off the sweep"));
                break;
            }
        }
    }
    assert!(failures.is_empty(), "{method}:\n{}", failures.join("\n"));
}

#[rstest]
fn a_turning_blade_is_capped_on_its_swept_surface(
    #[values(CutMethod::Remove, CutMethod::Separate, CutMethod::Subdivide)] method: CutMethod,
) {
    let (strokes, surface) = turning();
    let own = surface.vertex_count();
    let volume = enclosed_volume(&surface.positions, &surface.triangles);

    let mut cutter = cutter(method);
    let mut e = Embedding::new(cutter.mesh(), &surface).unwrap();
    let mut rebinder = lancet::surface::Rebinder::new(cutter.mesh(), &e);
    let mut capper = Capper::new(own, &surface.triangles);
    let mut capped = Capped::default();
    for sweep in &strokes {
        cut_once(&mut cutter, sweep, Some((&mut rebinder, &mut e)));
        capped = capper.cut(&mut e, cutter.mesh(), sweep);
    }
    // Closed once the blade is through (while it is inside, see the module's limits).
    if let Some(why) = not_closed(&capped.triangles) {
        panic!("{method}: the drawn surface is open: {why}");
    }
    assert!(
        capped.cap_triangles > 0 && capped.open == 0,
        "{method}: {capped:?}"
    );
    let v = enclosed_volume(&e.rest, &capped.triangles);
    assert!(
        (v - volume).abs() < 1e-9 * volume,
        "{method}: {v} enclosed, box {volume}"
    );
    // Every vertex the cut added lies on the swept surface.
    for v in own..e.len() {
        let d = to_sweep(&strokes, &Point3::from(e.rest[v]));
        assert!(d < 1e-12, "{method}: vertex {v} {d} m off the sweep");
    }
    // The caps (the triangles made of added vertices alone) follow it: the middle of each lies
    // closer to the sweep than a quarter of the sweep's departure from a plane over the cap (a
    // cap on the sweep's best-fit plane would be off it by about that departure; the cap's
    // triangles, about 2.5 mm across, sag from the twisted sweep by far less).
    let caps: Vec<_> = capped
        .triangles
        .iter()
        .filter(|t| t.iter().all(|&v| v as usize >= own))
        .collect();
    assert!(
        caps.len() >= capped.cap_triangles / 2,
        "{method}: {} caps",
        caps.len()
    );
    // How far a triangle's middle lies from the sweep.
    let middle_off = |t: &[u32; 3]| {
        let c = t
            .iter()
            .map(|&v| Vector3::from(e.rest[v as usize]))
            .sum::<Vector3<f64>>()
            / 3.0;
        to_sweep(&strokes, &Point3::from(c))
    };
    let worst = caps.iter().map(|t| middle_off(t)).fold(0.0, f64::max);
    // How far the sweep leaves a plane over the cap: its added vertices from their best fit.
    let pts: Vec<Vector3<f64>> = (own..e.len()).map(|v| Vector3::from(e.rest[v])).collect();
    let mean = pts.iter().sum::<Vector3<f64>>() / pts.len() as f64;
    let cov = pts
        .iter()
        .map(|p| (p - mean) * (p - mean).transpose())
        .sum::<nalgebra::Matrix3<f64>>();
    let eig = cov.symmetric_eigen();
    let k = eig.eigenvalues.imin();
    let normal = eig.eigenvectors.column(k).into_owned();
    let flat = pts
        .iter()
        .map(|p| normal.dot(&(p - mean)).abs())
        .fold(0.0, f64::max);
    assert!(
        flat > 2e-3,
        "{method}: the sweep is {flat} m from a plane: not curved"
    );
    // Away from the rim the caps lie on the sweep itself: split along its folds (where its flat
    // triangles meet), each cap triangle with no corner on the rim has its corners in one of
    // the sweep's triangles, so its middle lies in it too, up to rounding (the sweep is 0.1 m
    // across). On the plane, or split only by points of the sweep, they would sag from it by
    // its bending over one triangle.
    let rim: std::collections::HashSet<u32> = capped
        .triangles
        .iter()
        .filter(|t| t.iter().any(|&v| (v as usize) < own))
        .flatten()
        .copied()
        .collect();
    let inner: Vec<_> = caps
        .iter()
        .filter(|t| t.iter().all(|v| !rim.contains(v)))
        .collect();
    assert!(
        inner.len() >= caps.len() / 2,
        "{method}: {} of {} caps off the rim",
        inner.len(),
        caps.len()
    );
    let inner_worst = inner.iter().map(|t| middle_off(t)).fold(0.0, f64::max);
    assert!(
        inner_worst < 1e-12,
        "{method}: a cap triangle off the rim {inner_worst} m off the sweep"
    );
    assert!(
        worst < flat / 4.0,
        "{method}: a cap triangle {worst} m off the sweep, which is {flat} m from a plane"
    );
}
