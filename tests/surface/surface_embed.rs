//! Embedding a render surface in the simulation mesh: vertices at nodes move exactly as the
//! nodes, vertices inside tets move linearly with their tet, and every vertex, inside or
//! outside the mesh, follows an affine motion of the whole mesh (so a rigid rotation moves the
//! outside vertices rigidly). The grid finds the same tets and faces a scan of all of them does.

use lancet::mesh::generate::BoxGrid;
use lancet::mesh::{TetMesh, Topology};
use lancet::surface::embed::{barycentric, closest_on_triangle};
use lancet::surface::{Binding, Embedding, RenderSurface};
use nalgebra::{Matrix3, Point3, Rotation3, Vector3};

use crate::splitmix::Rng;

/// A 5 x 3 x 2 cm block of 1 cm cells (tets of several shapes and orientations).
fn block() -> TetMesh {
    let mut g = BoxGrid::cube_cells([5, 3, 2], 0.01);
    g.origin = [-0.01, 0.002, 0.0];
    g.build().unwrap()
}

/// Random vertices in the block's box grown by `out` on every side (those beyond the block lie
/// outside the mesh), joined in arbitrary triangles (the embedding does not look at them).
fn cloud(rng: &mut Rng, mesh: &TetMesh, n: usize, out: f64) -> RenderSurface {
    let (lo, hi) = mesh.bounds().unwrap();
    let positions: Vec<[f64; 3]> = (0..n)
        .map(|_| [0, 1, 2].map(|c| rng.range(lo[c] - out, hi[c] + out)))
        .collect();
    let triangles = (0..n as u32 / 3)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    RenderSurface::new(positions, triangles, "cloud").unwrap()
}

fn dense_rest(mesh: &TetMesh) -> Vec<Point3<f64>> {
    mesh.dense_nodes()
        .keys
        .iter()
        .map(|&k| mesh.rest(k))
        .collect()
}

/// Largest distance between two lists of points.
fn max_gap(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (Vector3::from(*p) - Vector3::from(*q)).norm())
        .fold(0.0, f64::max)
}

#[test]
fn vertices_at_nodes_move_exactly_as_the_nodes() {
    let mesh = block();
    let rest = dense_rest(&mesh);
    let surface = RenderSurface::new(
        rest.iter().map(|p| [p.x, p.y, p.z]).collect(),
        vec![[0, 1, 2]],
        "nodes",
    )
    .unwrap();
    let e = Embedding::new(&mesh, &surface).unwrap();
    assert_eq!(e.outside_count(), 0, "a node is on the mesh");
    let mut rng = Rng(11);
    let x: Vec<[f64; 3]> = rest
        .iter()
        .map(|p| [p.x, p.y, p.z].map(|c| c + rng.range(-3e-3, 3e-3)))
        .collect();
    let got = e.evaluate(&x);
    for (i, (g, w)) in got.iter().zip(&x).enumerate() {
        assert_eq!(
            g.map(f64::to_bits),
            w.map(f64::to_bits),
            "vertex at node {i}"
        );
    }
    // Float32 node positions (the fast and GPU engines) too.
    let x32: Vec<[f32; 3]> = x.iter().map(|p| p.map(|c| c as f32)).collect();
    for (g, w) in e.evaluate(&x32).iter().zip(&x32) {
        assert_eq!(*g, w.map(f64::from));
    }
}

#[test]
fn vertices_inside_move_linearly_with_their_tet() {
    let mesh = block();
    let mut rng = Rng(5);
    let surface = cloud(&mut rng, &mesh, 600, 0.0);
    let e = Embedding::new(&mesh, &surface).unwrap();
    assert_eq!(e.outside_count(), 0, "every vertex is in the block");
    // An arbitrary (non-affine) motion: each node on its own.
    let x: Vec<[f64; 3]> = dense_rest(&mesh)
        .iter()
        .map(|p| [p.x, p.y, p.z].map(|c| c + rng.range(-2e-3, 2e-3)))
        .collect();
    let got = e.evaluate(&x);
    for (v, b) in e.bindings.iter().enumerate() {
        let Binding::Inside(tet) = *b else {
            unreachable!()
        };
        let t = mesh.tet(tet).unwrap();
        // The vertex's rest coordinates in its tet ...
        let w = barycentric(&mesh.tet_points(t), &Point3::from(surface.positions[v]));
        assert!(
            w.iter().all(|&w| w >= -1e-10),
            "vertex {v} lies in its tet: {w:?}"
        );
        // ... are its coordinates in the deformed tet: it moved linearly with the tet.
        let dense = mesh.dense_nodes();
        let moved = t.nodes.map(|k| Point3::from(x[dense.index[k] as usize]));
        let w2 = barycentric(&moved, &Point3::from(got[v]));
        for k in 0..4 {
            assert!(
                (w[k] - w2[k]).abs() < 1e-9,
                "vertex {v}: {w:?} became {w2:?}"
            );
        }
    }
}

#[test]
fn an_affine_motion_moves_every_vertex_affinely_inside_and_outside() {
    let mesh = block();
    let mut rng = Rng(23);
    let surface = cloud(&mut rng, &mesh, 900, 4e-3);
    let e = Embedding::new(&mesh, &surface).unwrap();
    let outside = e.outside_count();
    assert!(outside > 100 && outside < 800, "{outside} of 900 outside");
    for round in 0..5 {
        // A random affine map: stretch, shear and rotation about a few per cent, a shift.
        let a = Matrix3::from_fn(|i, j| (i == j) as u8 as f64 + rng.range(-0.3, 0.3));
        assert!(a.determinant() > 0.1, "round {round}: a proper map");
        let b = Vector3::new(rng.range(-0.01, 0.01), rng.range(-0.01, 0.01), 0.0);
        let map = |p: [f64; 3]| -> [f64; 3] { (a * Vector3::from(p) + b).into() };
        let x: Vec<[f64; 3]> = dense_rest(&mesh)
            .iter()
            .map(|p| map([p.x, p.y, p.z]))
            .collect();
        let want: Vec<[f64; 3]> = surface.positions.iter().map(|&p| map(p)).collect();
        let gap = max_gap(&e.evaluate(&x), &want);
        // Rounding of centimetre coordinates in float64, amplified a little by the
        // extrapolation of vertices 4 mm outside 1 cm tets.
        assert!(
            gap < 1e-15 * 0.1 * 100.0,
            "round {round}: vertices off by {gap:e} m"
        );
    }
}

#[test]
fn a_rigid_rotation_moves_outside_vertices_rigidly() {
    let mesh = block();
    let mut rng = Rng(31);
    let surface = cloud(&mut rng, &mesh, 400, 5e-3);
    let e = Embedding::new(&mesh, &surface).unwrap();
    let r = Rotation3::from_axis_angle(
        &nalgebra::Unit::new_normalize(Vector3::new(1.0, 2.0, -0.5)),
        1.1,
    );
    let x: Vec<[f64; 3]> = dense_rest(&mesh).iter().map(|p| (r * p).into()).collect();
    let got = e.evaluate(&x);
    let outside: Vec<usize> = (0..e.len())
        .filter(|&v| matches!(e.bindings[v], Binding::Outside { .. }))
        .collect();
    assert!(outside.len() > 50);
    for &v in &outside {
        let want: [f64; 3] = (r * Point3::from(surface.positions[v])).into();
        let gap = max_gap(&[got[v]], &[want]);
        assert!(
            gap < 1e-15,
            "outside vertex {v} off the rotated position by {gap:e}"
        );
    }
    // Distances between outside vertices are kept.
    for w in outside.windows(2) {
        let d0 = max_gap(&[surface.positions[w[0]]], &[surface.positions[w[1]]]);
        let d1 = max_gap(&[got[w[0]]], &[got[w[1]]]);
        assert!((d0 - d1).abs() < 1e-15, "{d0} became {d1}");
    }
}

#[test]
fn the_grid_finds_what_a_scan_of_every_tet_and_face_finds() {
    let mesh = block();
    let mut rng = Rng(47);
    let surface = cloud(&mut rng, &mesh, 500, 2e-2);
    let e = Embedding::new(&mesh, &surface).unwrap();
    let boundary = Topology::of(&mesh).boundary;
    for (v, b) in e.bindings.iter().enumerate() {
        let p = Point3::from(surface.positions[v]);
        let held = mesh.tets().any(|(_, t)| {
            barycentric(&mesh.tet_points(t), &p)
                .iter()
                .all(|&w| w >= -1e-10)
        });
        match *b {
            Binding::Inside(_) => assert!(held),
            Binding::Outside {
                tet,
                face,
                distance,
            } => {
                assert!(!held, "vertex {v} is in a tet but was bound outside");
                let nearest = boundary
                    .iter()
                    .map(|f| {
                        let [a, b, c] = f.nodes.map(|k| mesh.rest(k));
                        (closest_on_triangle(&p, &a, &b, &c) - p).norm()
                    })
                    .fold(f64::INFINITY, f64::min);
                assert_eq!(distance, nearest, "vertex {v}: the nearest face's distance");
                assert!(boundary.iter().any(|f| f.tet == tet && f.local == face));
                // Its weights are the tet's own coordinates, extended outside it.
                let w = barycentric(&mesh.tet_points(mesh.tet(tet).unwrap()), &p);
                assert_eq!(w, e.weights[v]);
                assert!(w.iter().any(|&w| w < 0.0));
            }
        }
    }
}
