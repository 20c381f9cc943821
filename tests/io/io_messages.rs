//! What the readers say about bad input: a node named as a node, a count the file cannot
//! hold, what a file without tetrahedra holds instead, and a byte-order mark accepted.

use std::path::Path;

use lancet::mesh::io::vtu::{write_vtu_to, VtuOptions};
use lancet::mesh::io::{self, LoadedMesh};
use lancet::{Error, IdKind};

fn load(bytes: &[u8], ext: &str) -> lancet::Result<LoadedMesh> {
    io::read_bytes(bytes, ext, Path::new("test").with_extension(ext).as_path())
}

fn parse_error(bytes: &[u8], ext: &str) -> lancet::ParseError {
    match load(bytes, ext) {
        Err(Error::Parse(p)) => *p,
        Err(e) => panic!("expected a parse error, got {e}"),
        Ok(_) => panic!("expected a parse error, the file loaded"),
    }
}

/// One tet on four nodes, Gmsh 2.2 ASCII.
const ONE_TET: &str = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n\
                       3 0 1 0\n4 0 0 1\n$EndNodes\n$Elements\n1\n1 4 0 1 2 3 4\n$EndElements\n";

/// The same tet in Medit's format (vertex rows `x y z ref`, numbered from 1).
const ONE_TET_MEDIT: &str = "MeshVersionFormatted 2\nDimension 3\nVertices\n4\n0 0 0 0\n\
                             1 0 0 0\n0 1 0 0\n0 0 1 0\nTetrahedra\n1\n1 2 3 4 1\nEnd\n";

/// A bad coordinate of node 3 was reported as "element 3".
#[test]
fn a_bad_node_coordinate_names_the_node_not_an_element() {
    for (text, ext) in [
        (ONE_TET.replace("3 0 1 0", "3 0 y 0"), "msh"),
        (ONE_TET_MEDIT.replace("0 1 0 0", "0 y 0 0"), "mesh"),
    ] {
        let p = parse_error(text.as_bytes(), ext);
        assert_eq!(
            (p.element, p.id_kind),
            (Some(3), IdKind::Node),
            "{ext}: {p}"
        );
        let msg = p.to_string();
        assert!(msg.contains("node 3: "), "{ext}: {msg}");
        assert!(!msg.contains("element"), "{ext}: {msg}");
    }
    // An element's errors still name the element.
    let p = parse_error(
        ONE_TET.replace("1 4 0 1 2 3 4", "1 4 0 1 2 3 x").as_bytes(),
        "msh",
    );
    assert_eq!((p.element, p.id_kind), (Some(1), IdKind::Element), "{p}");
}

/// A binary Gmsh 2.2 file whose `$Nodes` declares 10^12 nodes, followed by four real ones: the
/// rows were read from what follows, and the error was about a misread node id. The error
/// (wherever reading stops) says first that the count is impossible.
#[test]
fn a_binary_node_count_the_file_cannot_hold_is_called_impossible() {
    let mut b = b"$MeshFormat\n2.2 1 8\n".to_vec();
    b.extend(1i32.to_le_bytes());
    b.extend(b"\n$EndMeshFormat\n$Nodes\n1000000000000\n");
    for (i, p) in [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ]
    .iter()
    .enumerate()
    {
        b.extend((i as i32 + 1).to_le_bytes());
        for c in p {
            b.extend(f64::to_le_bytes(*c));
        }
    }
    b.extend(b"\n$EndNodes\n$Elements\n1\n");
    for v in [4i32, 1, 2, 1, 0, 1, 2, 3, 4] {
        b.extend(v.to_le_bytes());
    }
    b.extend(b"\n$EndElements\n");
    let p = parse_error(&b, "msh");
    let msg = p.to_string();
    assert!(msg.contains("impossible for the file size"), "{msg}");
    assert!(msg.contains("1000000000000 nodes"), "{msg}");
    assert!(!msg.contains("defined twice"), "{msg}");
}

/// A file of surface triangles and an element of unknown type said only "the file contains
/// no tetrahedra", hiding what it held.
#[test]
fn a_file_without_tetrahedra_says_what_it_holds() {
    let text = ONE_TET.replace(
        "$Elements\n1\n1 4 0 1 2 3 4\n",
        "$Elements\n3\n1 2 0 1 2 3\n2 2 0 1 3 4\n3 99 0 1 2 3 4\n",
    );
    let msg = parse_error(text.as_bytes(), "msh").to_string();
    assert!(msg.contains("no tetrahedra"), "{msg}");
    assert!(msg.contains("2 surface triangles"), "{msg}");
    assert!(msg.contains("1 elements of unknown type 99"), "{msg}");
}

/// A UTF-8 byte-order mark (as editors on Windows save text) made a `.msh` fail on its first
/// line; the text readers skip it and read the same mesh.
#[test]
fn a_utf8_byte_order_mark_is_accepted() {
    let vtu = {
        let mesh = load(ONE_TET.as_bytes(), "msh").unwrap().mesh;
        let mut out = Vec::new();
        write_vtu_to(&mut out, &mesh, None, &VtuOptions::default()).unwrap();
        out
    };
    for (text, ext) in [
        (ONE_TET.as_bytes(), "msh"),
        (ONE_TET_MEDIT.as_bytes(), "mesh"),
        (&vtu[..], "vtu"),
    ] {
        let plain = load(text, ext).unwrap();
        let mut bom = b"\xEF\xBB\xBF".to_vec();
        bom.extend(text);
        let marked = load(&bom, ext).unwrap_or_else(|e| panic!("{ext}: {e}"));
        assert_eq!(marked.mesh.tet_count(), plain.mesh.tet_count(), "{ext}");
        assert_eq!(marked.mesh.volume(), plain.mesh.volume(), "{ext}");
    }
}
