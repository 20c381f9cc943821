//! A render surface through cuts (every method): after each sweep of a blade right through a
//! box, every vertex is bound to a tet of the cut mesh, inside it or beyond one of its boundary
//! faces, with the weights its rest position has there; and when the two pieces are pulled
//! apart, every vertex moves exactly as the nodes of its own side, the side of the blade it
//! lies on wherever the cut follows the blade.

use lancet::cut::{CutMethod, Cutter};
use lancet::surface::embed::barycentric;
use lancet::surface::{Binding, Embedding, Rebinder};
use nalgebra::{Point3, Vector3};
use rstest::rstest;

use crate::cut_box::{cloud, cut_once, cutter, sweeps, Pulled, H, Y0};

/// Cut the box in three sweeps, the surface following each; returns the cutter, the embedding
/// and the vertices rebound over all cuts.
fn cut_with_surface(method: CutMethod, check: bool) -> (Cutter, Embedding, usize) {
    let mut cutter = cutter(method);
    let surface = cloud(17, 900);
    let mut e = Embedding::new(cutter.mesh(), &surface).unwrap();
    let mut rebinder = Rebinder::new(cutter.mesh(), &e);
    let mut rebound = 0;
    for sweep in sweeps(3) {
        rebound += cut_once(&mut cutter, &sweep, Some((&mut rebinder, &mut e))).1;
        if check {
            check_bound(&cutter, &e);
        }
    }
    (cutter, e, rebound)
}

/// Every drawn vertex is bound to a tet of the cut mesh by that tet's nodes now, with its rest
/// position's coordinates there: inside the tet, or beyond one of its boundary faces.
fn check_bound(cutter: &Cutter, e: &Embedding) {
    let mesh = cutter.mesh();
    let dense = mesh.dense_nodes();
    for (v, b) in e.bindings.iter().enumerate() {
        if e.dropped[v] {
            continue;
        }
        let t = mesh
            .tet(b.tet())
            .unwrap_or_else(|| panic!("vertex {v} is bound to a tet the cut removed"));
        assert_eq!(
            e.nodes[v],
            t.nodes.map(|k| dense.index[k]),
            "vertex {v} follows other nodes than its tet's"
        );
        let w = barycentric(&mesh.tet_points(t), &Point3::from(e.rest[v]));
        for k in 0..4 {
            assert!((w[k] - e.weights[v][k]).abs() < 1e-12, "vertex {v}: {w:?}");
        }
        match *b {
            Binding::Inside(_) => assert!(
                w.iter().all(|&w| w >= -1e-10),
                "vertex {v} lies outside its tet: {w:?}"
            ),
            Binding::Outside { tet, face, .. } => {
                assert!(
                    cutter.faces().neighbour(tet, t, face as usize).is_none(),
                    "vertex {v}: its face is not on the boundary"
                );
                assert!(
                    w[face as usize] <= 1e-10,
                    "vertex {v} is not beyond its face: {w:?}"
                );
            }
        }
    }
}

#[rstest]
fn every_vertex_is_bound_in_the_cut_mesh_after_each_cut(
    #[values(CutMethod::Remove, CutMethod::Separate, CutMethod::Subdivide)] method: CutMethod,
) {
    let (cutter, e, rebound) = cut_with_surface(method, true);
    assert_eq!(cutter.mesh().component_count(), 2, "{method}: cut through");
    // The blade passes through a row of cells: a fair share of the vertices were near it.
    assert!(rebound > 40, "{method}: only {rebound} vertices rebound");
    assert!(rebound < e.len(), "{method}: every vertex rebound");
}

#[rstest]
fn the_two_sides_move_with_their_own_nodes(
    #[values(CutMethod::Remove, CutMethod::Separate, CutMethod::Subdivide)] method: CutMethod,
) {
    let (cutter, e, _) = cut_with_surface(method, false);
    let pulled = Pulled::apart(cutter.mesh());
    let got = e.evaluate(&pulled.x);
    let mut checked = 0;
    for (v, at) in got.iter().enumerate() {
        if e.dropped[v] {
            continue;
        }
        let moved = Vector3::from(*at) - Vector3::from(e.rest[v]);
        // Carving rebinds by the blade's side; the other methods' cut follows the faces (or
        // the sub-tets) near the blade, within a cell of it: nearer, a vertex moves with the
        // piece its tet is in. Weights summing to one move a vertex as its tet's nodes when
        // they move together.
        let ry = e.rest[v][1];
        let want = if method == CutMethod::Remove || (ry - Y0).abs() > H {
            checked += 1;
            pulled.of_side(ry < Y0)
        } else {
            pulled.of_tet(e.bindings[v].tet())
        };
        assert!(
            (moved - want).norm() < 1e-12,
            "{method}: vertex {v} at y {ry} moved {moved:?}, its side {want:?}"
        );
    }
    assert!(checked > 300, "{method}: {checked} vertices checked");
}
