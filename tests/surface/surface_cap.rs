//! A render surface stays closed and outward through cuts (every method): a finer closed box
//! inside the simulation box, cut by a blade right through or stopping inside, has every edge
//! of its drawn triangles used once each way round and encloses the box's volume; the caps'
//! vertices are bound on their own side of the blade, and when the two pieces are pulled
//! apart every drawn triangle moves whole with one piece (none stretches across the opening)
//! and the enclosed volume stays the box's (each piece moved rigidly).

use lancet::cut::{CutMethod, Cutter};
use lancet::surface::embed::barycentric;
use lancet::surface::{Binding, Capped, Capper, Embedding, Rebinder, RenderSurface};
use nalgebra::{Point3, Vector3};
use rstest::rstest;

use crate::cut_box::{
    closed_box, cut_once, cutter, enclosed_volume, not_closed, sweeps, sweeps_down_to, Pulled, H,
    Y0,
};

/// The surface: a closed box 1 mm inside the 5 x 4 x 3 cm mesh, about 5 mm triangles (none of
/// its vertices on the blade's plane).
fn organ() -> RenderSurface {
    closed_box([0.001; 3], [0.049, 0.039, 0.029], [10, 8, 6])
}

/// Its volume.
const VOLUME: f64 = 0.048 * 0.038 * 0.028;

/// The drawn edges that cross one of `sweeps`' triangles, ends more than a micrometre from its
/// plane on either side and the crossing inside it: an edge across the opening.
fn edges_across(e: &Embedding, triangles: &[[u32; 3]], sweeps: &[lancet::cut::Sweep]) -> usize {
    let mut n = 0;
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (
                Point3::from(e.rest[t[k] as usize]),
                Point3::from(e.rest[t[(k + 1) % 3] as usize]),
            );
            let across = sweeps.iter().flat_map(|s| &s.triangles).any(|q| {
                let normal = (q[1] - q[0]).cross(&(q[2] - q[0])).normalize();
                let (da, db) = (normal.dot(&(a - q[0])), normal.dot(&(b - q[0])));
                if da * db >= 0.0 || da.abs() < 1e-6 || db.abs() < 1e-6 {
                    return false;
                }
                let x = a + (b - a) * (da / (da - db));
                (0..3).all(|i| {
                    let (p, r) = (q[i], q[(i + 1) % 3]);
                    (r - p).cross(&(x - p)).dot(&normal) > 0.0
                })
            });
            n += across as usize;
        }
    }
    n
}

/// Cut with `sweeps`, the surface rebound and capped after each; returns the cutter, the
/// embedding and what the last cut left drawn.
fn cut_and_cap(method: CutMethod, sweeps: &[lancet::cut::Sweep]) -> (Cutter, Embedding, Capped) {
    let mut cutter = cutter(method);
    let surface = organ();
    let mut e = Embedding::new(cutter.mesh(), &surface).unwrap();
    let mut rebinder = Rebinder::new(cutter.mesh(), &e);
    let mut capper = Capper::new(e.len(), &surface.triangles);
    let mut last = Capped::default();
    for sweep in sweeps {
        cut_once(&mut cutter, sweep, Some((&mut rebinder, &mut e)));
        last = capper.cut(&mut e, cutter.mesh(), sweep);
        // Closed after every stroke, not only at the end.
        if let Some(why) = not_closed(&last.triangles) {
            panic!("{method}: the drawn surface is open after a stroke: {why}");
        }
    }
    // The blade opened the surface: no drawn edge crosses where it swept.
    let across = edges_across(&e, &last.triangles, sweeps);
    assert_eq!(across, 0, "{method}: {across} drawn edges cross the cut");
    (cutter, e, last)
}

#[rstest]
fn a_cut_right_through_leaves_the_surface_closed_and_each_side_moving_whole(
    #[values(CutMethod::Remove, CutMethod::Separate, CutMethod::Subdivide)] method: CutMethod,
) {
    let strokes = sweeps(3);
    let (cutter, e, capped) = cut_and_cap(method, &strokes);
    assert_eq!(cutter.mesh().component_count(), 2, "{method}: cut through");
    assert!(
        capped.cap_triangles > 0 && capped.open == 0,
        "{method}: {capped:?}"
    );
    // At rest the two caps of each side coincide: the box's volume.
    let v = enclosed_volume(&e.rest, &capped.triangles);
    assert!(
        (v - VOLUME).abs() < 1e-9 * VOLUME,
        "{method}: {v} enclosed, box {VOLUME}"
    );

    // The new vertices: on the blade's plane, bound to a tet on their own side (inside it when
    // the mesh's cut follows the blade, subdividing; within a cell of it otherwise).
    let own = organ().vertex_count();
    let added = own..e.len();
    assert!(
        added.len() >= 2 * 2 * (10 + 6),
        "{method}: {} added",
        added.len()
    );
    let mesh = cutter.mesh();
    for v in added.clone() {
        assert!((e.rest[v][1] - Y0).abs() < 1e-12, "vertex {v} off the cut");
        assert!(!e.dropped[v], "{method}: cap vertex {v} dropped");
        let t = mesh
            .tet(e.bindings[v].tet())
            .expect("a tet of the cut mesh");
        let w = barycentric(&mesh.tet_points(t), &Point3::from(e.rest[v]));
        match e.bindings[v] {
            Binding::Inside(_) => assert!(w.iter().all(|&w| w >= -1e-10), "vertex {v}: {w:?}"),
            Binding::Outside { distance, .. } => {
                assert!(
                    method != CutMethod::Subdivide,
                    "vertex {v} outside a sub-tet"
                );
                assert!(
                    distance <= H,
                    "{method}: vertex {v} {distance} m from its tet"
                );
            }
        }
    }

    // Pulled apart: every drawn triangle moves with one piece, the pieces' own vertices away
    // from the blade with their side, each crossing's two vertices one with each piece.
    let pulled = Pulled::apart(mesh);
    let x = e.evaluate(&pulled.x);
    let what = method.to_string();
    let piece = piece_pulled(&pulled, &e, &x, &what);
    triangles_with_one_piece(&capped.triangles, &piece, &what);
    for v in 0..own as u32 {
        let y = e.rest[v as usize][1];
        if (y - Y0).abs() > H {
            assert_eq!(piece(v), y < Y0, "{method}: vertex {v} at y {y}");
        }
    }
    one_copy_per_piece(added, &e.rest, &piece, &what);
    // Each piece moved rigidly: the enclosed volume is still the box's.
    let v = enclosed_volume(&x, &capped.triangles);
    assert!(
        (v - VOLUME).abs() < 1e-9 * VOLUME,
        "{method}: {v} pulled apart"
    );
}

#[rstest]
fn a_blade_stopping_inside_leaves_the_surface_closed(
    #[values(CutMethod::Remove, CutMethod::Separate, CutMethod::Subdivide)] method: CutMethod,
) {
    let (cutter, e, capped) = cut_and_cap(method, &sweeps_down_to(2, 0.012));
    assert_eq!(
        cutter.mesh().component_count(),
        1,
        "{method}: not cut through"
    );
    assert!(
        capped.split > 0 && capped.cap_triangles > 0,
        "{method}: {capped:?}"
    );
    let v = enclosed_volume(&e.rest, &capped.triangles);
    assert!(
        (v - VOLUME).abs() < 1e-9 * VOLUME,
        "{method}: {v} enclosed, box {VOLUME}"
    );
    // The slit ends on the box's sides at the blade's edge: vertices both sides share there.
    let ends = (organ().vertex_count()..e.len())
        .filter(|&v| (e.rest[v][2] - 0.012).abs() < 1e-9)
        .count();
    assert_eq!(ends, 2, "{method}: slit ends");
}

/// Whether embedded vertex `v` moved with the piece on the negative side when the box's pieces
/// are pulled apart (`x`: the embedding evaluated at `pulled.x`); a vertex that moved with
/// neither fails, named with `what`.
pub(crate) fn piece_pulled<'a>(
    pulled: &'a Pulled,
    e: &'a Embedding,
    x: &'a [[f64; 3]],
    what: &'a str,
) -> impl Fn(u32) -> bool + 'a {
    move |v: u32| {
        let m = Vector3::from(x[v as usize]) - Vector3::from(e.rest[v as usize]);
        [true, false]
            .into_iter()
            .find(|&minus| (m - pulled.of_side(minus)).norm() < 1e-12)
            .unwrap_or_else(|| panic!("{what}: vertex {v} moved {m:?}, with neither piece"))
    }
}

/// Every triangle moves with one piece (`piece` as [`piece_pulled`] gives it).
pub(crate) fn triangles_with_one_piece(
    triangles: &[[u32; 3]],
    piece: impl Fn(u32) -> bool,
    what: &str,
) {
    for t in triangles {
        let p = t.map(&piece);
        assert!(
            p[0] == p[1] && p[1] == p[2],
            "{what}: triangle {t:?} stretched across"
        );
    }
}

/// Each point on the cut among the `added` vertices has two copies, one moving with each piece
/// (`piece(v)`: whether vertex `v` moved with the piece on the negative side).
pub(crate) fn one_copy_per_piece(
    added: impl IntoIterator<Item = usize>,
    rest: &[[f64; 3]],
    piece: impl Fn(u32) -> bool,
    what: &str,
) {
    let mut at: std::collections::BTreeMap<[u64; 3], Vec<bool>> = Default::default();
    for v in added {
        at.entry(rest[v].map(f64::to_bits))
            .or_default()
            .push(piece(v as u32));
    }
    for (p, sides) in &at {
        let mut s = sides.clone();
        s.sort_unstable();
        assert_eq!(
            s,
            [false, true],
            "{what}: the copies at {p:?} moved with {sides:?}"
        );
    }
}
