//! A tet listed twice (Gmsh 2.2 repeats an element for each physical group it belongs to) is
//! kept once, with a note; it once doubled the tet's mass and stiffness.

use std::path::Path;

use lancet::mesh::io::read_bytes;

/// Two tets sharing a face; element 3 repeats element 1 under physical group 7.
const REPEATED: &str = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n\
1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n$EndNodes\n$Elements\n3\n\
1 4 2 1 1 1 2 3 4\n2 4 2 2 2 2 3 4 5\n3 4 2 7 7 4 3 2 1\n$EndElements\n";

#[test]
fn a_tet_listed_twice_is_kept_once_with_its_first_region_and_a_note() {
    let m = read_bytes(REPEATED.as_bytes(), "msh", Path::new("twice.msh")).unwrap();
    assert_eq!(m.mesh.tet_count(), 2);
    // The unit corner tet (1/6) plus the tet on (1,0,0), (0,1,0), (0,0,1), (1,1,1): 1/3.
    let volume = 1.0 / 6.0 + 1.0 / 3.0;
    assert!(
        (m.mesh.volume() - volume).abs() < 1e-12,
        "{}",
        m.mesh.volume()
    );
    let mut regions = m.mesh.regions();
    regions.sort();
    assert_eq!(regions, [(1, 1), (2, 1)]);
    let note = m
        .report
        .notes
        .iter()
        .find(|n| n.contains("duplicated"))
        .unwrap_or_else(|| panic!("{:?}", m.report.notes));
    assert!(note.contains("merged 1 duplicated tet"), "{note}");
    assert!(note.contains("element 3 repeats element 1"), "{note}");
}
