//! TetMesh topology, quality and generators, checked against counts and volumes derived by hand.

use approx::assert_relative_eq;
use lancet::mesh::generate::{beam, BoxGrid, TetSplit};
use lancet::mesh::quality::tet_quality;
use lancet::mesh::topology::components;
use lancet::{Error, TetMesh};
use nalgebra::Point3;
use rstest::rstest;

/// Unique edges of a box grid: axis edges + one diagonal per face + (six-split only) one body
/// diagonal per cell.
fn expected_edges(n: [usize; 3], split: TetSplit) -> usize {
    let [x, y, z] = n;
    let axis = x * (y + 1) * (z + 1) + (x + 1) * y * (z + 1) + (x + 1) * (y + 1) * z;
    let faces = x * y * (z + 1) + x * (y + 1) * z + (x + 1) * y * z;
    let body = if split == TetSplit::Six { x * y * z } else { 0 };
    axis + faces + body
}

#[rstest]
#[case([1, 1, 1], TetSplit::Six)]
#[case([3, 2, 4], TetSplit::Six)]
#[case([1, 1, 1], TetSplit::Five)]
#[case([3, 2, 4], TetSplit::Five)]
#[case([5, 5, 5], TetSplit::Five)]
fn box_grid_has_the_counts_volume_and_closed_surface_of_a_box(
    #[case] n: [usize; 3],
    #[case] split: TetSplit,
) {
    let size = [0.3, 0.2, 0.5];
    let mesh = BoxGrid {
        cells: n,
        size,
        origin: [1.0, -2.0, 0.5],
        split,
    }
    .build()
    .unwrap();
    let [x, y, z] = n;
    let per_cell = if split == TetSplit::Six { 6 } else { 5 };
    assert_eq!(mesh.node_count(), (x + 1) * (y + 1) * (z + 1));
    assert_eq!(mesh.tet_count(), per_cell * x * y * z);
    assert_eq!(mesh.edges().len(), expected_edges(n, split));
    let topo = mesh.topology();
    // Two triangles per boundary quad; a mismatch of diagonals between neighbouring cells
    // would leave interior faces unmatched and raise this count.
    assert_eq!(topo.boundary.len(), 4 * (x * y + y * z + z * x));
    assert_eq!(topo.non_manifold_faces, 0);
    let volume = size[0] * size[1] * size[2];
    assert_relative_eq!(mesh.volume(), volume, max_relative = 1e-12);
    // Divergence theorem over the outward boundary gives the volume only if every face points
    // out.
    assert_relative_eq!(topo.enclosed_volume(&mesh), volume, max_relative = 1e-12);
    assert!(mesh.tets().all(|(k, _)| mesh.tet_volume(k) > 0.0));
    assert_eq!(mesh.component_count(), 1);
}

#[test]
fn beam_spans_its_length_and_section() {
    let mesh = beam(0.1, 0.02, 0.03, 10, 2).unwrap();
    let (lo, hi) = mesh.bounds().unwrap();
    assert_relative_eq!(hi.x - lo.x, 0.1, max_relative = 1e-12);
    assert_relative_eq!(hi.y - lo.y, 0.02, max_relative = 1e-12);
    assert_relative_eq!(hi.z - lo.z, 0.03, max_relative = 1e-12);
    assert_eq!(mesh.tet_count(), 10 * 2 * 2 * 6);
}

#[test]
fn regular_tet_has_unit_quality_and_known_dihedral_angles() {
    let s = 8f64.sqrt();
    let p = [
        Point3::new(1.0, 1.0, 1.0) / s,
        Point3::new(1.0, -1.0, -1.0) / s,
        Point3::new(-1.0, -1.0, 1.0) / s,
        Point3::new(-1.0, 1.0, -1.0) / s,
    ];
    let q = tet_quality(&p);
    assert_relative_eq!(q.volume_length_ratio, 1.0, max_relative = 1e-12);
    let regular = (1.0f64 / 3.0).acos().to_degrees(); // 70.53 degrees
    assert_relative_eq!(q.min_dihedral_deg, regular, epsilon = 1e-9);
    assert_relative_eq!(q.max_dihedral_deg, regular, epsilon = 1e-9);
}

#[test]
fn kuhn_tets_have_dihedral_angles_of_45_60_and_90_degrees() {
    let mesh = BoxGrid::cube_cells([1, 1, 1], 1.0).build().unwrap();
    let q = mesh.quality().unwrap();
    assert_relative_eq!(q.min_dihedral_deg, 45.0, epsilon = 1e-9);
    assert_relative_eq!(q.max_dihedral_deg, 90.0, epsilon = 1e-9);
}

#[test]
fn sliver_has_small_dihedral_angle_and_low_quality() {
    // A nearly flat tet: apex 1e-3 above the base plane.
    let p = [
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(0.0, 1.0, 0.0),
        Point3::new(0.3, 0.3, 1e-3),
    ];
    let q = tet_quality(&p);
    assert!(q.volume_length_ratio > 0.0 && q.volume_length_ratio < 0.01);
    assert!(q.min_dihedral_deg < 1.0);
}

#[test]
fn from_arrays_reorients_inverted_tets_and_counts_them() {
    let pts = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
    ];
    // Second tet listed with negative orientation.
    let (mesh, flipped) = TetMesh::from_arrays(&pts, &[[0, 1, 2, 3], [1, 2, 4, 3]], None).unwrap();
    assert_eq!(flipped, 1);
    assert!(mesh.tets().all(|(k, _)| mesh.tet_volume(k) > 0.0));
}

#[rstest]
#[case::repeated_node(&[[0, 1, 1, 3]], "twice")]
#[case::zero_volume(&[[0, 1, 2, 4]], "zero volume")]
#[case::out_of_range(&[[0, 1, 2, 9]], "references node 9")]
fn from_arrays_rejects_bad_tets_with_a_reason(#[case] tets: &[[u32; 4]], #[case] reason: &str) {
    // Node 4 lies in the plane of nodes 0, 1, 2.
    let pts = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.5, 0.5, 0.0],
    ];
    match TetMesh::from_arrays(&pts, tets, None) {
        Err(Error::Mesh(msg)) => assert!(msg.contains(reason), "{msg}"),
        other => panic!("expected a mesh error mentioning {reason:?}, got {other:?}"),
    }
}

#[test]
fn removing_a_slab_of_tets_splits_the_box_into_two_components() {
    let mut mesh = BoxGrid::cube_cells([6, 2, 2], 1.0).build().unwrap();
    // Remove every tet of the middle layer of cells (2 < x < 3): the two halves then share no
    // node... except on the planes x = 2 and x = 3, which belong to different halves.
    let slab: Vec<_> = mesh
        .tets()
        .filter(|(_, t)| {
            let cx: f64 = t.nodes.iter().map(|k| mesh.rest(*k).x).sum::<f64>() / 4.0;
            cx > 2.0 && cx < 3.0
        })
        .map(|(k, _)| k)
        .collect();
    assert_eq!(slab.len(), 2 * 2 * 6);
    for k in slab {
        mesh.remove_tet(k);
    }
    let removed_nodes = mesh.remove_unused_nodes();
    assert_eq!(removed_nodes, 0, "the slab has no interior nodes");
    let (of_tet, count) = components(&mesh);
    assert_eq!(count, 2);
    // Tets left of the cut are all in one component, right of it in the other.
    let side = |k| {
        let t = mesh.tet(k).unwrap();
        t.nodes.iter().map(|n| mesh.rest(*n).x).sum::<f64>() / 4.0 < 2.5
    };
    for (k, _) in mesh.tets() {
        for (j, _) in mesh.tets() {
            assert_eq!(side(k) == side(j), of_tet[k] == of_tet[j]);
        }
    }
    // The boundary of each piece is closed: enclosed volume equals tet volume.
    let topo = mesh.topology();
    assert_relative_eq!(
        topo.enclosed_volume(&mesh),
        mesh.volume(),
        max_relative = 1e-12
    );
}

#[test]
fn tet_face_neighbours_are_symmetric() {
    let mesh = BoxGrid {
        cells: [3, 3, 2],
        size: [1.0, 1.0, 1.0],
        origin: [0.0; 3],
        split: TetSplit::Five,
    }
    .build()
    .unwrap();
    let topo = mesh.topology();
    let mut interior = 0;
    for (k, _) in mesh.tets() {
        for nb in topo.neighbours[k].iter().flatten() {
            assert!(topo.neighbours[*nb].contains(&Some(k)));
            interior += 1;
        }
    }
    // Every face is interior (counted from both sides) or on the boundary.
    assert_eq!(interior + topo.boundary.len(), 4 * mesh.tet_count());
}

#[test]
fn generators_refuse_empty_or_non_finite_boxes() {
    let bad = [
        BoxGrid::cube_cells([0, 1, 1], 1.0),
        BoxGrid {
            size: [f64::NAN, 1.0, 1.0],
            ..BoxGrid::cube_cells([1, 1, 1], 1.0)
        },
        BoxGrid {
            size: [-1.0, 1.0, 1.0],
            ..BoxGrid::cube_cells([1, 1, 1], 1.0)
        },
    ];
    for b in bad {
        assert!(matches!(b.build(), Err(Error::Mesh(_))), "{b:?}");
    }
}
