//! The Gmsh reader: real meshes, ascii/binary round trips of every supported version, the
//! errors users see for broken files, and robustness against arbitrary bytes.
#![cfg(feature = "formats")]

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use lancet::mesh::io::{self, gmsh, Format, LoadedMesh, RawMesh};
use lancet::Error;
use proptest::prelude::*;
use rstest::rstest;

use crate::gmsh_writers::{content, sample, write_v22, write_v41, TRI_TAG};

// ---------------------------------------------------------------------------------------------
// Helpers

/// The folder of real meshes, or `None` (with a message) when the environment does not give it.
fn mesh_dir() -> Option<PathBuf> {
    match std::env::var_os("LANCET_MESH_DIR") {
        Some(d) => Some(PathBuf::from(d)),
        None => {
            eprintln!("skipping: LANCET_MESH_DIR is not set, so the real meshes cannot be found");
            None
        }
    }
}

fn load(text: &[u8]) -> lancet::Result<LoadedMesh> {
    io::read_bytes(text, "msh", Path::new("test.msh"))
}

fn raw(bytes: &[u8]) -> RawMesh {
    gmsh::parse(bytes, Path::new("test.msh")).expect("the file should parse")
}

/// The Display of the parse error that loading `bytes` must give.
fn parse_error(bytes: &[u8]) -> String {
    match load(bytes) {
        Err(e @ Error::Parse(_)) => e.to_string(),
        Err(e) => panic!("expected a parse error, got {e}"),
        Ok(_) => panic!("expected a parse error, the file loaded"),
    }
}

/// A valid Gmsh 2.2 ascii file; line numbers matter to the error tests below.
const V22: &str = "\
$MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
4
1 0 0 0
2 1 0 0
3 0 1 0
4 0 0 1
$EndNodes
$Elements
1
1 4 2 1 1 1 2 3 4
$EndElements
";

/// A valid Gmsh 4.1 ascii file with sparse node tags.
const V41: &str = "\
$MeshFormat
4.1 0 8
$EndMeshFormat
$Entities
0 0 0 1
7 0 0 0 1 1 1 1 3 0
$EndEntities
$Nodes
1 4 10 40
3 7 0 4
10
20
30
40
0 0 0
1 0 0
0 1 0
0 0 1
$EndNodes
$Elements
1 1 5 5
3 7 4 1
5 10 20 30 40
$EndElements
";

/// A valid Gmsh 1 file.
const V1: &str = "\
$NOD
4
1 0 0 0
2 1 0 0
3 0 1 0
4 0 0 1
$ENDNOD
$ELM
2
1 4 5 1 4 1 2 3 4
2 1 5 1 2 1 2
$ENDELM
";

// ---------------------------------------------------------------------------------------------
// Real meshes

#[rstest]
#[case::liver("sofa/liver.msh", 181, 596, 914, 276, 36.561)]
#[case::liver2("sofa/liver2.msh", 507, 1493, 2429, 860, 1.1251)]
#[case::cubes_v22("polyfem-data/cubes_v22.msh", 7714, 32981, 44499, 7610, 2.09790)]
#[case::cubes_v41("polyfem-data/cubes_v41.msh", 7714, 32981, 44499, 7610, 2.09790)]
fn real_meshes_load_with_the_counts_and_volume_of_the_readme(
    #[case] file: &str,
    #[case] nodes: usize,
    #[case] tets: usize,
    #[case] edges: usize,
    #[case] boundary: usize,
    #[case] volume: f64,
) {
    let Some(dir) = mesh_dir() else { return };
    let loaded = io::read(dir.join(file)).unwrap();
    let mesh = &loaded.mesh;
    assert_eq!(mesh.node_count(), nodes);
    assert_eq!(mesh.tet_count(), tets);
    assert_eq!(mesh.edges().len(), edges);
    assert_eq!(mesh.topology().boundary.len(), boundary);
    // The README rounds volumes to five significant digits.
    let rel = (mesh.volume() - volume).abs() / volume;
    assert!(rel < 1e-4, "volume {} vs {volume}", mesh.volume());
    assert_eq!(loaded.report.reoriented, 0);
}

#[test]
fn liver2_keeps_its_surface_triangles_and_notes_its_ignored_lines() {
    let Some(dir) = mesh_dir() else { return };
    let path = dir.join("sofa/liver2.msh");
    let loaded = io::read(&path).unwrap();
    assert_eq!(loaded.report.format, Format::Gmsh1);
    assert_eq!(loaded.surface.len(), 860);
    let notes = &loaded.report.notes;
    assert!(
        notes
            .iter()
            .any(|n| n == "ignored 71 line elements (type 1)"),
        "{notes:?}"
    );
    let raw = gmsh::parse(&std::fs::read(&path).unwrap(), &path).unwrap();
    assert_eq!(raw.point_ids.iter().min(), Some(&2));
    assert_eq!(raw.point_ids.iter().max(), Some(&1393));
}

#[test]
fn six_tetra_bad_reorients_its_inverted_tet_and_accepts_repeated_element_ids() {
    let Some(dir) = mesh_dir() else { return };
    let path = dir.join("sofa/6_tetra_bad.msh");
    let loaded = io::read(&path).unwrap();
    assert_eq!(loaded.report.format, Format::Gmsh22 { binary: false });
    assert_eq!(loaded.mesh.tet_count(), 6);
    // The six tets happen to use all 17 nodes of the file, so none is dropped.
    assert_eq!(loaded.mesh.node_count(), 17);
    assert_eq!(loaded.report.dropped_nodes, 0);
    assert_eq!(loaded.report.reoriented, 1);
    assert!(loaded.report.notes.iter().any(|n| n.contains("reoriented")));
    let raw = gmsh::parse(&std::fs::read(&path).unwrap(), &path).unwrap();
    assert!(raw.tets.iter().all(|t| t.id == 44));
}

/// Position bits of a node, to compare meshes whose node order differs.
type PosKey = [u64; 3];

fn pos_key(mesh: &lancet::TetMesh, k: lancet::NodeKey) -> PosKey {
    let p = mesh.rest(k);
    [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]
}

/// Each tet as its sorted corner positions and region, sorted: order-free identity of a mesh.
fn tet_set(mesh: &lancet::TetMesh) -> Vec<([PosKey; 4], i32)> {
    let mut v: Vec<_> = mesh
        .tets()
        .map(|(_, t)| {
            let mut c = t.nodes.map(|k| pos_key(mesh, k));
            c.sort();
            (c, t.region)
        })
        .collect();
    v.sort();
    v
}

#[test]
fn cubes_v22_and_v41_load_to_the_same_mesh_with_three_regions() {
    let Some(dir) = mesh_dir() else { return };
    let a = io::read(dir.join("polyfem-data/cubes_v22.msh")).unwrap();
    let b = io::read(dir.join("polyfem-data/cubes_v41.msh")).unwrap();
    assert_eq!(a.report.format, Format::Gmsh22 { binary: false });
    assert_eq!(b.report.format, Format::Gmsh41 { binary: false });
    let regions: Vec<i32> = a.mesh.regions().iter().map(|r| r.0).collect();
    assert_eq!(regions, [1, 2, 3]);
    assert_eq!(a.mesh.regions(), b.mesh.regions());
    // The 4.1 file lists nodes by entity block, so the order differs: compare positions as sets.
    let mut pa: Vec<PosKey> = a.mesh.nodes().map(|(k, _)| pos_key(&a.mesh, k)).collect();
    let mut pb: Vec<PosKey> = b.mesh.nodes().map(|(k, _)| pos_key(&b.mesh, k)).collect();
    pa.sort();
    pb.sort();
    pa.dedup();
    assert_eq!(pa.len(), 7714, "node positions are distinct");
    assert_eq!(pa, pb);
    assert_eq!(tet_set(&a.mesh), tet_set(&b.mesh));
}

// ---------------------------------------------------------------------------------------------
// Round trips

#[test]
fn the_sample_written_as_gmsh_22_ascii_reads_back_exactly() {
    let s = sample();
    let r = raw(&write_v22(&s, None));
    assert_eq!(r.format, Format::Gmsh22 { binary: false });
    assert_eq!(r.points, s.points);
    assert_eq!(
        r.point_ids,
        s.ids.iter().map(|&i| i as i64).collect::<Vec<_>>()
    );
    let tets: Vec<([u32; 4], i32)> = s
        .tets
        .iter()
        .map(|t| (t.0.map(|i| i as u32), t.1))
        .collect();
    let read: Vec<([u32; 4], i32)> = r.tets.iter().map(|t| (t.nodes, t.region)).collect();
    assert_eq!(read, tets);
    assert_eq!(r.triangles.len(), s.tris.len());
    assert!(r.triangles.iter().all(|t| t.tag == TRI_TAG));
    assert_eq!(r.notes, ["ignored 1 line elements (type 1)"]);
    let loaded = load(&write_v22(&s, None)).unwrap();
    assert_eq!(loaded.mesh.tet_count(), 48);
    assert_eq!(loaded.surface.len(), 4);
}

#[rstest]
#[case::little_endian(false)]
#[case::big_endian(true)]
fn gmsh_22_binary_reads_to_the_same_raw_mesh_as_ascii(#[case] big: bool) {
    let s = sample();
    let ascii = raw(&write_v22(&s, None));
    let binary = raw(&write_v22(&s, Some(big)));
    assert_eq!(binary.format, Format::Gmsh22 { binary: true });
    assert_eq!(content(&binary), content(&ascii));
}

#[rstest]
#[case::size_t_8(8)]
#[case::size_t_4(4)]
fn gmsh_41_ascii_and_binary_read_to_the_same_raw_mesh_as_gmsh_22(#[case] size_t: usize) {
    let s = sample();
    let v22 = raw(&write_v22(&s, None));
    let ascii = raw(&write_v41(&s, None));
    let binary = raw(&write_v41(&s, Some(size_t)));
    assert_eq!(ascii.format, Format::Gmsh41 { binary: false });
    assert_eq!(binary.format, Format::Gmsh41 { binary: true });
    assert_eq!(content(&ascii), content(&v22));
    assert_eq!(content(&binary), content(&v22));
}

// ---------------------------------------------------------------------------------------------
// Small valid files

#[test]
fn gmsh_1_uses_the_physical_region_and_ignores_lines() {
    let loaded = load(V1.as_bytes()).unwrap();
    assert_eq!(loaded.report.format, Format::Gmsh1);
    assert_eq!(loaded.mesh.regions(), [(5, 1)]);
    assert_eq!(loaded.report.notes[0], "ignored 1 line elements (type 1)");
}

#[test]
fn gmsh_41_region_is_the_physical_tag_of_the_volume_entity_else_the_entity_tag() {
    let loaded = load(V41.as_bytes()).unwrap();
    assert_eq!(loaded.mesh.regions(), [(3, 1)]);
    let no_entities = V41.replace(
        "$Entities\n0 0 0 1\n7 0 0 0 1 1 1 1 3 0\n$EndEntities\n",
        "",
    );
    let loaded = load(no_entities.as_bytes()).unwrap();
    assert_eq!(loaded.mesh.regions(), [(7, 1)]);
}

#[test]
fn a_ten_node_tet_keeps_its_corners_with_a_note_about_the_dropped_mid_edge_nodes() {
    let nodes: String = (5..=10).map(|i| format!("{i} 0.{i} 0.1 0.1\n")).collect();
    let text = V22
        .replace("$Nodes\n4\n", "$Nodes\n10\n")
        .replace("$EndNodes", &format!("{nodes}$EndNodes"))
        .replace("1 4 2 1 1 1 2 3 4", "1 11 2 1 1 1 2 3 4 5 6 7 8 9 10");
    let loaded = load(text.as_bytes()).unwrap();
    assert_eq!(loaded.mesh.tet_count(), 1);
    assert_eq!(loaded.mesh.node_count(), 4);
    let notes = loaded.report.notes.join("\n");
    assert!(
        notes.contains("dropped the mid-edge nodes of 1 10-node tetrahedron"),
        "{notes}"
    );
}

#[test]
fn unknown_sections_are_skipped_with_a_note_and_physical_names_silently() {
    let text = V22.replace(
        "$Nodes",
        "$PhysicalNames\n1\n3 1 \"liver\"\n$EndPhysicalNames\n$Foo\nbar\n$EndFoo\n$Nodes",
    );
    let loaded = load(text.as_bytes()).unwrap();
    assert_eq!(
        loaded.report.notes,
        ["skipped section $Foo (not needed for the mesh)"]
    );
}

#[test]
fn windows_line_ends_and_blank_lines_are_accepted() {
    let text = V22.replace('\n', "\r\n\r\n");
    assert_eq!(load(text.as_bytes()).unwrap().mesh.tet_count(), 1);
}

// ---------------------------------------------------------------------------------------------
// Errors

#[rstest]
#[case::nan_coordinate("2 1 0 0", "2 nan 0 0", "line 7", "not a finite number")]
#[case::infinite_coordinate("3 0 1 0", "3 0 inf 0", "line 8", "not a finite number")]
#[case::non_numeric_coordinate("3 0 1 0", "3 0 abc 0", "line 8", "\"abc\" is not a number")]
#[case::non_numeric_node_id("4 0 0 1", "x4 0 0 1", "line 9", "is not a valid integer")]
#[case::missing_coordinate("4 0 0 1", "4 0 0", "line 9", "line ends before the z coordinate")]
#[case::fewer_nodes_than_declared("$Nodes\n4", "$Nodes\n5", "line 10", "$Nodes ends early")]
#[case::more_nodes_than_declared("$Nodes\n4", "$Nodes\n3", "line 9", "more rows than it declares")]
#[case::missing_end_nodes("$EndNodes\n", "", "line 10", "missing $EndNodes")]
#[case::repeated_node_id("3 0 1 0", "2 0 1 0", "line 8", "node id 2 is defined twice")]
#[case::undefined_node("1 2 3 4\n", "1 2 3 9\n", "line 13", "references node 9")]
#[case::too_few_nodes("1 2 3 4\n", "1 2 3\n", "line 13", "has 4 nodes, but the line lists 3")]
#[case::too_many_nodes(
    "1 2 3 4\n",
    "1 2 3 4 1\n",
    "line 13",
    "has 4 nodes, but the line lists 5"
)]
#[case::more_elements_than_declared("$Elements\n1", "$Elements\n0", "line 13", "more rows")]
#[case::hexahedron(
    "1 4 2 1 1 1 2 3 4",
    "1 5 2 1 1 1 2 3 4 1 2 3 4",
    "line 13: element 1",
    "unsupported element type 5 (hexahedron)"
)]
#[case::prism(
    "1 4 2 1 1 1 2 3 4",
    "1 6 2 1 1 1 2 3 4 1 2",
    "line 13",
    "type 6 (prism)"
)]
#[case::version_3("2.2 0 8", "3.0 0 8", "line 2", "unsupported gmsh format version 3.0")]
#[case::version_4_0("2.2 0 8", "4 0 8", "line 2", "lancet reads versions 1, 2.2 and 4.1")]
#[case::bad_file_type("2.2 0 8", "2.2 2 8", "line 2", "file-type 2")]
#[case::missing_end_mesh_format("$EndMeshFormat\n", "", "line 3", "missing $EndMeshFormat")]
#[case::text_between_sections(
    "$Elements\n1",
    "junk\n$Elements\n1",
    "line 11",
    "expected a section"
)]
#[case::unclosed_unknown_section(
    "$Nodes\n4",
    "$Foo\n$Nodes\n4",
    "line 4",
    "section $Foo has no $EndFoo"
)]
fn a_broken_gmsh_22_file_gives_the_line_and_what_is_wrong(
    #[case] from: &str,
    #[case] to: &str,
    #[case] location: &str,
    #[case] message: &str,
) {
    assert!(V22.contains(from));
    let msg = parse_error(V22.replacen(from, to, 1).as_bytes());
    assert!(msg.contains(location), "{msg:?} lacks {location:?}");
    assert!(msg.contains(message), "{msg:?} lacks {message:?}");
    assert!(msg.contains("test.msh"), "{msg:?} names the file");
}

#[rstest]
#[case::truncated_in_nodes(8, "line 8", "file ends before the node 4 of 4 in $Nodes")]
#[case::truncated_before_elements_count(11, "line 11", "file ends before the count of $Elements")]
#[case::truncated_in_elements(12, "line 12", "file ends before the element 1 of 1")]
#[case::truncated_before_end(13, "line 13", "file ends before $EndElements")]
fn a_truncated_gmsh_22_file_says_where_it_ends(
    #[case] keep_lines: usize,
    #[case] location: &str,
    #[case] message: &str,
) {
    let text: String = V22
        .lines()
        .take(keep_lines)
        .map(|l| format!("{l}\n"))
        .collect();
    let msg = parse_error(text.as_bytes());
    assert!(msg.contains(location), "{msg:?} lacks {location:?}");
    assert!(msg.contains(message), "{msg:?} lacks {message:?}");
}

#[test]
fn an_empty_file_is_an_error_not_a_panic() {
    assert!(parse_error(b"").contains("the file is empty"));
    assert!(parse_error(b"hello\n").contains("expected $MeshFormat or $NOD"));
}

#[rstest]
#[case::node_count(
    "1 4 10 40",
    "1 5 10 40",
    "line 18",
    "blocks hold 4 nodes but the header declares 5"
)]
#[case::block_size("3 7 0 4", "3 7 0 3", "line 14", "line ends before the y coordinate")]
#[case::nan("0 1 0\n", "0 nan 0\n", "line 17", "y coordinate is nan")]
#[case::element_nodes(
    "5 10 20 30 40",
    "5 10 20 30",
    "line 23: element 5",
    "the line lists 3"
)]
#[case::element_count(
    "1 1 5 5",
    "1 2 5 5",
    "line 23",
    "hold 1 elements but the header declares 2"
)]
#[case::undefined_node("5 10 20 30 40", "5 10 20 30 41", "line 23", "references node 41")]
#[case::entity_line(
    "7 0 0 0 1 1 1 1 3 0",
    "7 0 0 0 1 1 1 1 3",
    "line 6",
    "line ends before"
)]
#[case::hexahedron(
    "3 7 4 1\n5 10 20 30 40",
    "3 7 5 1\n5 10 20 30 40 10 20 30 40",
    "line 23",
    "hexahedron"
)]
fn a_broken_gmsh_41_file_gives_the_line_and_what_is_wrong(
    #[case] from: &str,
    #[case] to: &str,
    #[case] location: &str,
    #[case] message: &str,
) {
    assert!(V41.contains(from));
    let msg = parse_error(V41.replacen(from, to, 1).as_bytes());
    assert!(msg.contains(location), "{msg:?} lacks {location:?}");
    assert!(msg.contains(message), "{msg:?} lacks {message:?}");
}

#[test]
fn a_gmsh_1_element_whose_node_count_disagrees_with_its_list_is_an_error() {
    let text = V1.replace("1 4 5 1 4 1 2 3 4", "1 4 5 1 3 1 2 3 4");
    let msg = parse_error(text.as_bytes());
    assert!(
        msg.contains("line 10: element 1: element declares 3 nodes but lists 4"),
        "{msg}"
    );
}

/// Byte offset of the first occurrence of `needle`.
fn offset_of(hay: &[u8], needle: &[u8]) -> usize {
    hay.windows(needle.len()).position(|w| w == needle).unwrap()
}

#[test]
fn a_nan_in_binary_coordinates_names_its_byte_offset() {
    let mut s = sample();
    s.points[3][1] = f64::NAN;
    let bytes = write_v22(&s, Some(false));
    let at = offset_of(&bytes, &f64::NAN.to_le_bytes());
    let msg = parse_error(&bytes);
    assert!(msg.contains(&format!("byte {at}")), "{msg}");
    assert!(
        msg.contains("y coordinate is NaN, not a finite number"),
        "{msg}"
    );
}

#[test]
fn truncated_binary_data_is_an_error_at_the_byte_where_it_ends() {
    let bytes = write_v22(&sample(), Some(false));
    let nodes = offset_of(&bytes, b"$Nodes\n27\n") + b"$Nodes\n27\n".len();
    // Cut inside the third node's coordinates.
    let cut = nodes + 2 * 28 + 10;
    let msg = parse_error(&bytes[..cut]);
    assert!(
        msg.contains("binary data ends before x coordinate"),
        "{msg}"
    );
    assert!(
        msg.contains(&format!("byte {}", nodes + 2 * 28 + 4)),
        "{msg}"
    );
    let v41 = write_v41(&sample(), Some(8));
    let msg = parse_error(&v41[..v41.len() - 40]);
    assert!(msg.contains("binary data ends before"), "{msg}");
}

#[test]
fn binary_counts_that_disagree_with_the_data_are_an_error() {
    let bytes = write_v22(&sample(), Some(false));
    let mut patched = bytes.clone();
    let at = offset_of(&patched, b"$Nodes\n27\n") + b"$Nodes\n".len();
    patched[at..at + 2].copy_from_slice(b"26");
    let msg = parse_error(&patched);
    assert!(
        msg.contains("binary data does not end where the counts say"),
        "{msg}"
    );
    assert!(msg.contains("expected $EndNodes"), "{msg}");
}

#[test]
fn a_bad_endianness_check_is_an_error() {
    let mut bytes = write_v22(&sample(), Some(false));
    let at = offset_of(&bytes, b"2.2 1 8\n") + 8;
    bytes[at] = 7;
    let msg = parse_error(&bytes);
    assert!(msg.contains(&format!("byte {at}")), "{msg}");
    assert!(msg.contains("endianness check reads 7"), "{msg}");
}

#[test]
fn an_unknown_element_type_in_binary_cannot_be_skipped_and_is_an_error() {
    let mut bytes = write_v22(&sample(), Some(false));
    let at = offset_of(&bytes, b"$Elements\n53\n") + b"$Elements\n53\n".len();
    bytes[at..at + 4].copy_from_slice(&77i32.to_le_bytes());
    let msg = parse_error(&bytes);
    assert!(msg.contains(&format!("byte {at}")), "{msg}");
    assert!(msg.contains("unknown element type 77"), "{msg}");
}

#[test]
fn a_huge_declared_count_fails_cleanly_without_allocating_it() {
    let text = V22.replace("$Nodes\n4", "$Nodes\n18446744073709551615");
    assert!(parse_error(text.as_bytes()).contains("$Nodes ends early"));
    let mut bytes = write_v41(&sample(), Some(8));
    let at = offset_of(&bytes, b"$Nodes\n") + b"$Nodes\n".len();
    bytes[at + 8..at + 16].copy_from_slice(&u64::MAX.to_le_bytes());
    assert!(parse_error(&bytes).contains("the header declares 18446744073709551615"));
}

/// A binary block whose count the rest of the file cannot hold is read from whatever follows
/// until that fails; the error says the cause first (the block, its count, the bytes left),
/// then where reading on failed. It said only the symptom: a misread tag or an undefined node.
#[rstest]
#[case::gmsh41_nodes(b"$Nodes\n", 32, 12, "node block 1 of 2 declares 1000000 nodes")]
#[case::gmsh41_elements(
    b"$Elements\n",
    32,
    12,
    "element block 1 of 4 declares 1000000 elements"
)]
#[case::gmsh41_node_blocks(b"$Nodes\n", 0, 0, "$Nodes declares 1000000 entity blocks")]
#[case::gmsh41_element_blocks(b"$Elements\n", 0, 0, "$Elements declares 1000000 entity blocks")]
fn a_binary_block_larger_than_the_file_names_its_count(
    #[case] section: &[u8],
    #[case] record: usize,
    #[case] count_in_record: usize,
    #[case] expected: &str,
) {
    let mut bytes = write_v41(&sample(), Some(8));
    // The record's offset in the section (the section header is 32 bytes) and the count's in
    // the record.
    let count = offset_of(&bytes, section) + section.len() + record + count_in_record;
    bytes[count..count + 8].copy_from_slice(&1_000_000u64.to_le_bytes());
    let msg = parse_error(&bytes);
    assert!(
        msg.contains(&format!("{expected}, impossible for the file size")),
        "{msg}"
    );
    assert!(msg.contains("; reading on: "), "{msg}");
}

#[test]
fn a_gmsh22_binary_element_block_larger_than_the_file_names_its_count() {
    let mut bytes = write_v22(&sample(), Some(false));
    // The section's count raised too, so that the block passes the check against it (which
    // names the elements that remain) and is read on past the file's end.
    let count = offset_of(&bytes, b"$Elements\n") + b"$Elements\n".len();
    let at = offset_of(&bytes, b"$Elements\n53\n") + b"$Elements\n53\n".len();
    bytes.splice(count..at - 1, b"9000000".iter().copied());
    let at = offset_of(&bytes, b"$Elements\n9000000\n") + b"$Elements\n9000000\n".len();
    bytes[at + 4..at + 8].copy_from_slice(&9_000_000i32.to_le_bytes());
    let msg = parse_error(&bytes);
    assert!(msg.contains("; reading on: "), "{msg}");
    assert!(
        msg.contains("element block declares 9000000 elements"),
        "{msg}"
    );
    assert!(msg.contains("impossible for the file size"), "{msg}");
}

// ---------------------------------------------------------------------------------------------
// Robustness

/// Valid files of every encoding, to mutate.
fn seeds() -> Vec<Vec<u8>> {
    let s = sample();
    vec![
        V1.as_bytes().to_vec(),
        V22.as_bytes().to_vec(),
        V41.as_bytes().to_vec(),
        write_v22(&s, Some(false)),
        write_v22(&s, Some(true)),
        write_v41(&s, Some(8)),
        write_v41(&s, Some(4)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_bytes_never_panic(
        prefix in prop::sample::select(vec!["", "$MeshFormat\n2.2 1 8\n", "$MeshFormat\n4.1 1 8\n",
            "$MeshFormat\n4.1 0 8\n", "$NOD\n"]),
        bytes in prop::collection::vec(any::<u8>(), 0..512),
    ) {
        let mut input = prefix.as_bytes().to_vec();
        input.extend_from_slice(&bytes);
        let _ = io::read_bytes(&input, "msh", Path::new("fuzz.msh"));
    }

    #[test]
    fn mutated_or_truncated_valid_files_never_panic(
        seed in 0usize..7,
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..8),
        cut in any::<prop::sample::Index>(),
        truncate in any::<bool>(),
    ) {
        let mut input = seeds().swap_remove(seed);
        for (at, b) in edits {
            let i = at.index(input.len());
            input[i] = b;
        }
        if truncate {
            input.truncate(cut.index(input.len() + 1));
        }
        let _ = io::read_bytes(&input, "msh", Path::new("fuzz.msh"));
    }
}

#[test]
fn regions_of_the_sample_survive_loading() {
    let loaded = load(&write_v41(&sample(), Some(8))).unwrap();
    let regions: BTreeMap<i32, usize> = loaded.mesh.regions().into_iter().collect();
    assert_eq!(regions, BTreeMap::from([(10, 24), (20, 24)]));
    let tags: HashMap<i32, usize> = loaded.surface.iter().fold(HashMap::new(), |mut m, t| {
        *m.entry(t.tag).or_default() += 1;
        m
    });
    assert_eq!(tags, HashMap::from([(TRI_TAG, 4)]));
}
