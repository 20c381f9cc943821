//! The TetGen, Medit, Vega and legacy VTK readers: real meshes, round trips through small
//! test-only writers and error messages (corrupt input: `io_formats_robust.rs`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use lancet::mesh::generate::BoxGrid;
use lancet::mesh::io::{self, tetgen, LoadedMesh};
use lancet::{Error, TetMesh};
use rstest::rstest;

// ---------------------------------------------------------------------------------------------
// Real meshes

/// The folder of real meshes, or `None` (with the reason printed) when the variable is unset.
fn mesh_dir() -> Option<PathBuf> {
    match std::env::var_os("LANCET_MESH_DIR") {
        Some(d) => Some(PathBuf::from(d)),
        None => {
            eprintln!("skipped: LANCET_MESH_DIR is not set, so the real meshes cannot be found");
            None
        }
    }
}

/// Read a real mesh, or `None` when the folder is not configured.
fn real(rel: &str) -> Option<LoadedMesh> {
    let path = mesh_dir()?.join(rel);
    Some(io::read(&path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display())))
}

#[rstest]
#[case::medit_square_beam("polyfem-data/square_beam.mesh", 739, 2886, 4071, 894, 40000.0, 1e-9)]
#[case::tetgen_armadillo_via_node(
    "positionbaseddynamics/armadillo_4k.node",
    1180,
    3717,
    5947,
    2102,
    1.8596,
    1e-4
)]
#[case::tetgen_armadillo_via_ele(
    "positionbaseddynamics/armadillo_4k.ele",
    1180,
    3717,
    5947,
    2102,
    1.8596,
    1e-4
)]
#[case::vega_torus("vegafem/torus-easy.veg", 20186, 97878, 125587, 15044, 6569.28, 1e-4)]
#[case::vtk_legacy_cylinder(
    "sofa/cylinderPDMS12724Vol.vtk",
    3668,
    12724,
    19103,
    5424,
    1.0159e-5,
    1e-4
)]
fn real_mesh_has_the_independently_counted_nodes_tets_edges_faces_and_volume(
    #[case] rel: &str,
    #[case] nodes: usize,
    #[case] tets: usize,
    #[case] edges: usize,
    #[case] boundary: usize,
    #[case] volume: f64,
    #[case] rel_tol: f64,
) {
    let Some(loaded) = real(rel) else { return };
    let m = &loaded.mesh;
    assert_eq!(m.node_count(), nodes, "nodes");
    assert_eq!(m.tet_count(), tets, "tets");
    assert_eq!(m.edges().len(), edges, "edges");
    assert_eq!(m.topology().boundary.len(), boundary, "boundary faces");
    let v = m.volume();
    assert!(
        ((v - volume) / volume).abs() < rel_tol,
        "volume {v} vs {volume}"
    );
    assert_eq!(
        loaded.report.reoriented, 0,
        "all tets are positive in file order"
    );
    assert_eq!(loaded.report.dropped_nodes, 0);
}

#[test]
fn medit_square_beam_with_an_empty_triangles_section_reads_without_surface_triangles() {
    let Some(loaded) = real("polyfem-data/square_beam.mesh") else {
        return;
    };
    assert!(loaded.surface.is_empty());
    assert_eq!(loaded.report.format, io::Format::Medit);
}

#[test]
fn tetgen_armadillo_reads_the_same_mesh_via_the_node_and_the_ele_file() {
    let (Some(a), Some(b)) = (
        real("positionbaseddynamics/armadillo_4k.node"),
        real("positionbaseddynamics/armadillo_4k.ele"),
    ) else {
        return;
    };
    assert_eq!(positions(&a.mesh), positions(&b.mesh));
    assert_eq!(tet_tuples(&a.mesh), tet_tuples(&b.mesh));
    assert!(a.report.path.ends_with("armadillo_4k.ele"));
    assert!(a.report.notes.iter().any(|n| n.contains("starts at 0")));
}

#[test]
fn vega_torus_reports_the_material_line_of_the_file() {
    let Some(loaded) = real("vegafem/torus-easy.veg") else {
        return;
    };
    // The file says: `ENU, 1000, 1000000000, 0.45` (density, Young's modulus, Poisson ratio).
    let m = loaded.report.material.expect("material");
    assert_eq!(m.density, 1000.0);
    assert_eq!(m.youngs_modulus, 1e9);
    assert_eq!(m.poisson_ratio, 0.45);
    // `*REGION allElements, defaultMaterial`: every tet in region 1.
    assert_eq!(loaded.mesh.regions(), vec![(1, 97878)]);
}

#[test]
fn vtk_cylinder_skips_its_unrelated_cell_data_block_with_a_note() {
    let Some(loaded) = real("sofa/cylinderPDMS12724Vol.vtk") else {
        return;
    };
    assert_eq!(loaded.mesh.regions(), vec![(0, 12724)]);
    assert!(
        loaded.report.notes.iter().any(|n| n.contains("dataset")),
        "{:?}",
        loaded.report.notes
    );
}

// ---------------------------------------------------------------------------------------------
// Test-only writers

/// A 2x2x2-cell box, 48 tets.
fn source() -> TetMesh {
    BoxGrid::cube_cells([2, 2, 2], 0.1).build().unwrap()
}

/// Node positions, and tets as dense node indices with their region tags.
type Arrays = (Vec<[f64; 3]>, Vec<([u32; 4], i32)>);

/// Points and tets (dense indices) of a mesh, with region tags.
fn arrays(m: &TetMesh) -> Arrays {
    let dense = m.dense_nodes();
    let pts = dense
        .keys
        .iter()
        .map(|&k| m.rest(k).coords.into())
        .collect();
    let tets = m
        .tets()
        .map(|(_, t)| (t.nodes.map(|k| dense.index[k]), t.region))
        .collect();
    (pts, tets)
}

pub(crate) fn write_tetgen(m: &TetMesh, base: u32) -> (String, String) {
    let (pts, tets) = arrays(m);
    let mut node = format!("# test mesh\n{} 3 0 0\n", pts.len());
    for (i, p) in pts.iter().enumerate() {
        writeln!(node, "{} {:e} {:e} {:e}", i as u32 + base, p[0], p[1], p[2]).unwrap();
    }
    let mut ele = format!("{} 4 1\n", tets.len());
    for (i, (t, r)) in tets.iter().enumerate() {
        let [a, b, c, d] = t.map(|n| n + base);
        writeln!(ele, "{} {a} {b} {c} {d} {r}", i as u32 + base).unwrap();
    }
    (node, ele)
}

pub(crate) fn write_medit(m: &TetMesh) -> String {
    let (pts, tets) = arrays(m);
    // Counts on the next line, a comment, and skipped sections: all legal.
    let mut s = format!(
        "MeshVersionFormatted 2\n# comment\nDimension\n3\nVertices\n{}\n",
        pts.len()
    );
    for p in &pts {
        writeln!(s, "{:e} {:e} {:e} 0", p[0], p[1], p[2]).unwrap();
    }
    s += "Edges 1\n1 2 0\nCorners 2\n1 2\nTriangles 0\n";
    writeln!(s, "Tetrahedra {}", tets.len()).unwrap();
    for (t, r) in &tets {
        let [a, b, c, d] = t.map(|n| n + 1);
        writeln!(s, "{a} {b} {c} {d} {r}").unwrap();
    }
    s + "End\n"
}

pub(crate) fn write_vega(m: &TetMesh) -> String {
    let (pts, tets) = arrays(m);
    let mut s = format!("# vega\n*VERTICES\n{} 3 0 0\n", pts.len());
    for (i, p) in pts.iter().enumerate() {
        writeln!(s, "{} {:e} {:e} {:e}", i + 1, p[0], p[1], p[2]).unwrap();
    }
    writeln!(s, "\n*ELEMENTS\nTETS\n{} 4 0", tets.len()).unwrap();
    for (i, (t, _)) in tets.iter().enumerate() {
        let [a, b, c, d] = t.map(|n| n + 1);
        writeln!(s, "{} {a} {b} {c} {d}", i + 1).unwrap();
    }
    s + "\n*MATERIAL soft\nENU, 1100, 5000, 0.4\n\n*SET first\n1, 2,\n3\n\n*REGION\nfirst, soft\n"
}

pub(crate) fn write_vtk_ascii(m: &TetMesh) -> String {
    let (pts, tets) = arrays(m);
    let mut s = format!(
        "# vtk DataFile Version 4.2\ntest\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {} double\n",
        pts.len()
    );
    for p in &pts {
        writeln!(s, "{:e} {:e} {:e}", p[0], p[1], p[2]).unwrap();
    }
    writeln!(s, "CELLS {} {}", tets.len(), tets.len() * 5).unwrap();
    for (t, _) in &tets {
        writeln!(s, "4 {} {} {} {}", t[0], t[1], t[2], t[3]).unwrap();
    }
    writeln!(s, "CELL_TYPES {}", tets.len()).unwrap();
    for _ in &tets {
        s += "10\n";
    }
    write!(s, "CELL_DATA {}\nFIELD FieldData 2\n", tets.len()).unwrap();
    writeln!(s, "quality 1 {} float", tets.len()).unwrap();
    for _ in &tets {
        s += "0.5 ";
    }
    writeln!(s, "\nMaterialIds 1 {} int", tets.len()).unwrap();
    for (_, r) in &tets {
        write!(s, "{} ", r + 7).unwrap();
    }
    write!(s, "\nPOINT_DATA {}\nVECTORS disp float\n", pts.len()).unwrap();
    for _ in &pts {
        s += "0 0 0\n";
    }
    s
}

pub(crate) fn write_vtk_binary(m: &TetMesh) -> Vec<u8> {
    let (pts, tets) = arrays(m);
    let mut b = format!(
        "# vtk DataFile Version 3.0\ntest\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS {} float\n",
        pts.len()
    )
    .into_bytes();
    for p in &pts {
        for c in p {
            b.extend((*c as f32).to_be_bytes());
        }
    }
    b.extend(format!("\nCELLS {} {}\n", tets.len(), tets.len() * 5).bytes());
    for (t, _) in &tets {
        b.extend(4i32.to_be_bytes());
        for n in t {
            b.extend((*n as i32).to_be_bytes());
        }
    }
    b.extend(format!("\nCELL_TYPES {}\n", tets.len()).bytes());
    for _ in &tets {
        b.extend(10i32.to_be_bytes());
    }
    b.extend(
        format!(
            "\nCELL_DATA {}\nSCALARS region int 1\nLOOKUP_TABLE default\n",
            tets.len()
        )
        .bytes(),
    );
    for (_, r) in &tets {
        b.extend((r + 3).to_be_bytes());
    }
    b.push(b'\n');
    b
}

pub(crate) fn write_vtk51(m: &TetMesh) -> String {
    let (pts, tets) = arrays(m);
    let mut s = format!(
        "# vtk DataFile Version 5.1\ntest\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {} double\n",
        pts.len()
    );
    for p in &pts {
        // Nine values per line, as VTK writes them: rows wrap across points.
        write!(s, "{:e} {:e} {:e} ", p[0], p[1], p[2]).unwrap();
    }
    writeln!(s, "\nMETADATA\nINFORMATION 0\n").unwrap();
    writeln!(
        s,
        "CELLS {} {}\nOFFSETS vtktypeint64",
        tets.len() + 1,
        tets.len() * 4
    )
    .unwrap();
    for i in 0..=tets.len() {
        write!(s, "{} ", i * 4).unwrap();
    }
    s += "\nCONNECTIVITY vtktypeint64\n";
    for (t, _) in &tets {
        write!(s, "{} {} {} {} ", t[0], t[1], t[2], t[3]).unwrap();
    }
    writeln!(s, "\nCELL_TYPES {}", tets.len()).unwrap();
    for _ in &tets {
        s += "10\n";
    }
    s
}

/// Node positions, sorted, as exact bit patterns.
fn positions(m: &TetMesh) -> Vec<[u64; 3]> {
    let mut v: Vec<[u64; 3]> = m
        .nodes()
        .map(|(_, n)| [n.rest.x, n.rest.y, n.rest.z].map(f64::to_bits))
        .collect();
    v.sort();
    v
}

/// Tets as tuples of node positions (sorted), so that meshes with different node numbering
/// compare equal.
fn tet_tuples(m: &TetMesh) -> Vec<[[u64; 3]; 4]> {
    let mut v: Vec<[[u64; 3]; 4]> = m
        .tets()
        .map(|(_, t)| t.nodes.map(|k| m.rest(k).coords.map(f64::to_bits).into()))
        .collect();
    v.sort();
    v
}

/// Positions rounded to float precision, for the binary float32 file.
fn positions_f32(m: &TetMesh) -> Vec<[u32; 3]> {
    let mut v: Vec<[u32; 3]> = m
        .nodes()
        .map(|(_, n)| [n.rest.x, n.rest.y, n.rest.z].map(|c| (c as f32).to_bits()))
        .collect();
    v.sort();
    v
}

fn write_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A generated mesh written in `format` and read back.
fn round_trip(format: &str) -> LoadedMesh {
    let m = source();
    let bytes = match format {
        "tetgen0" | "tetgen1" => {
            let dir = tempfile::tempdir().unwrap();
            let (node, ele) = write_tetgen(&m, if format == "tetgen0" { 0 } else { 1 });
            write_file(dir.path(), "box.node", &node);
            write_file(dir.path(), "box.ele", &ele);
            return io::read(dir.path().join("box.ele")).unwrap();
        }
        "medit" => write_medit(&m).into_bytes(),
        "vega" => write_vega(&m).into_bytes(),
        "vtk42" => write_vtk_ascii(&m).into_bytes(),
        "vtkbin" => write_vtk_binary(&m),
        "vtk51" => write_vtk51(&m).into_bytes(),
        _ => unreachable!(),
    };
    let ext = match format {
        "medit" => "mesh",
        "vega" => "veg",
        _ => "vtk",
    };
    let path = PathBuf::from(format!("box.{ext}"));
    io::read_bytes(&bytes, ext, &path).unwrap_or_else(|e| panic!("{format}: {e}"))
}

#[rstest]
#[case::tetgen_zero_based("tetgen0")]
#[case::tetgen_one_based("tetgen1")]
#[case::medit("medit")]
#[case::vega("vega")]
#[case::vtk_legacy_ascii_4_2("vtk42")]
#[case::vtk_legacy_5_1_offsets_connectivity("vtk51")]
fn generated_box_written_in_a_format_reads_back_as_the_same_mesh(#[case] format: &str) {
    let src = source();
    let back = round_trip(format);
    assert_eq!(positions(&back.mesh), positions(&src));
    assert_eq!(tet_tuples(&back.mesh), tet_tuples(&src));
    assert!((back.mesh.volume() - src.volume()).abs() < 1e-15);
    assert_eq!(back.report.reoriented, 0);
}

#[test]
fn generated_box_written_as_big_endian_binary_vtk_reads_back_as_the_same_mesh() {
    let src = source();
    let back = round_trip("vtkbin");
    assert_eq!(back.report.format, io::Format::VtkLegacy { binary: true });
    // Coordinates went through float32; grid values of 0.1 steps survive to f32 precision.
    assert_eq!(positions_f32(&back.mesh), positions_f32(&src));
    assert_eq!(back.mesh.tet_count(), src.tet_count());
    assert!((back.mesh.volume() - src.volume()).abs() < 1e-7);
    assert_eq!(back.mesh.regions(), vec![(3, 48)]);
}

#[test]
fn region_tags_survive_the_round_trips_that_carry_them() {
    assert_eq!(round_trip("tetgen1").mesh.regions(), vec![(0, 48)]);
    assert_eq!(round_trip("medit").mesh.regions(), vec![(0, 48)]);
    // The FIELD array "MaterialIds" (value region + 7) is recognised; "quality" is skipped.
    let vtk = round_trip("vtk42");
    assert_eq!(vtk.mesh.regions(), vec![(7, 48)]);
    assert!(vtk.report.notes.iter().any(|n| n.contains("quality")));
    // Vega: the set lists elements 1..3, the only *REGION line gives them tag 1.
    let vega = round_trip("vega");
    assert_eq!(vega.mesh.regions(), vec![(0, 45), (1, 3)]);
    let m = vega.report.material.unwrap();
    assert_eq!(
        (m.density, m.youngs_modulus, m.poisson_ratio),
        (1100.0, 5000.0, 0.4)
    );
}

#[test]
fn tetgen_pair_with_a_missing_sibling_names_the_missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let (node, _) = write_tetgen(&source(), 0);
    let p = write_file(dir.path(), "lonely.node", &node);
    let err = io::read(&p).unwrap_err();
    assert!(matches!(err, Error::Io { .. }), "{err}");
    assert!(err.to_string().contains("lonely.ele"), "{err}");
}

#[test]
fn tetgen_ten_node_tets_keep_their_corners_and_say_so() {
    let node = "5 3 0 1\n1 0 0 0 0\n2 1 0 0 0\n3 0 1 0 0\n4 0 0 1 0\n5 1 1 1 0\n";
    let ele = "1 10 1\n1 1 2 3 4 5 5 5 5 5 5 2.5\n";
    let raw = tetgen::parse(
        node.as_bytes(),
        ele.as_bytes(),
        Path::new("a.node"),
        Path::new("a.ele"),
    )
    .unwrap();
    assert_eq!(raw.tets[0].nodes, [0, 1, 2, 3]);
    assert_eq!(raw.tets[0].region, 3);
    assert!(raw.notes.iter().any(|n| n.contains("10-node")));
    assert!(raw.notes.iter().any(|n| n.contains("non-integer")));
}

#[test]
fn vtk_triangles_become_surface_elements_and_lines_are_ignored_with_a_note() {
    let s = "# vtk DataFile Version 2.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n\
             0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 3 12\n4 0 1 2 3\n3 0 2 1\n2 0 1\nCELL_TYPES 3\n10 5 3\n";
    let loaded = io::read_bytes(s.as_bytes(), "vtk", Path::new("t.vtk")).unwrap();
    assert_eq!(loaded.mesh.tet_count(), 1);
    assert_eq!(loaded.surface.len(), 1);
    assert!(loaded.report.notes.iter().any(|n| n.contains("ignored 1")));
}

#[test]
fn vtk_quadratic_triangles_are_kept_on_their_corners_like_the_vtu_reader_does() {
    let s = "# vtk DataFile Version 2.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n\
             0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 2 12\n4 0 1 2 3\n6 0 2 1 3 3 3\nCELL_TYPES 2\n10 22\n";
    let loaded = io::read_bytes(s.as_bytes(), "vtk", Path::new("t.vtk")).unwrap();
    assert_eq!(loaded.surface.len(), 1);
    let notes = loaded.report.notes.join("\n");
    assert!(
        notes.contains("read 1 quadratic triangle(s) on their 3 corners"),
        "{notes}"
    );
}

// ---------------------------------------------------------------------------------------------
// Errors

/// Parse `text` as `format` (`tetgen` takes `node|ele` split at the first `|`).
fn parse(format: &str, text: &[u8]) -> lancet::Result<()> {
    match format {
        "tetgen" => {
            let text = std::str::from_utf8(text).unwrap();
            let (node, ele) = text.split_once('|').unwrap();
            tetgen::parse(
                node.as_bytes(),
                ele.as_bytes(),
                Path::new("m.node"),
                Path::new("m.ele"),
            )
            .and_then(|r| r.finish(Path::new("m.ele")))
            .map(|_| ())
        }
        ext => io::read_bytes(text, ext, &PathBuf::from(format!("m.{ext}"))).map(|_| ()),
    }
}

const NODE4: &str = "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n";
const MEDIT_HEAD: &str =
    "MeshVersionFormatted 1\nDimension 3\nVertices 4\n0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n";
const VEGA_HEAD: &str = "*VERTICES\n4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n";
pub(crate) const VTK_HEAD: &str =
    "# vtk DataFile Version 2.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\n";

#[rstest]
#[case::tetgen_truncated_node_file(
    "tetgen",
    "4 3 0 0\n1 0 0 0\n2 1 0 0\n|1 4 0\n1 1 2 3 4\n",
    "m.node: line 3",
    "declares 4 nodes but the file ends after 2"
)]
#[case::tetgen_non_numeric_coordinate(
    "tetgen",
    "2 3 0 0\n1 0 0 0\n2 1 zero 0\n|0 4 0\n",
    "line 3: node 2",
    "coordinate \"zero\" is not a number"
)]
#[case::tetgen_nan_coordinate(
    "tetgen",
    "2 3 0 0\n1 0 0 0\n2 1 nan 0\n|0 4 0\n",
    "line 3",
    "not a finite number"
)]
#[case::tetgen_undefined_node("tetgen", &format!("{NODE4}|1 4 0\n# c\n7 1 2 3 9\n"), "m.ele: line 3: element 7", "references node 9, which is not defined")]
#[case::tetgen_wrong_nodes_per_tet("tetgen", &format!("{NODE4}|1 6 0\n1 1 2 3 4 1 2\n"), "m.ele: line 1", "6 nodes per tet")]
#[case::tetgen_short_row("tetgen", &format!("{NODE4}|1 4 1\n1 1 2 3 4\n"), "line 2: element 1", "tet row has 5 values, expected 6")]
#[case::tetgen_more_rows_than_declared("tetgen", &format!("{NODE4}|1 4 0\n1 1 2 3 4\n2 1 2 3 4\n"), "m.ele: line 3", "declares 1 tets but more rows follow")]
#[case::tetgen_two_dimensional("tetgen", "3 2 0 0\n1 0 0\n|", "line 1", "dimension is 2")]
#[case::tetgen_repeated_node_is_caught_by_finish("tetgen", &format!("{NODE4}|1 4 0\n1 1 2 3 3\n"), "line 2: element 1", "uses node 3 twice")]
#[case::medit_dimension_two(
    "mesh",
    "MeshVersionFormatted 1\nDimension\n2\n",
    "line 3",
    "dimension is 2"
)]
#[case::medit_truncated_vertices(
    "mesh",
    "MeshVersionFormatted 1\nDimension 3\nVertices 3\n0 0 0 0\n1 0 0\n",
    "line 5",
    "the file ends after 1 of the 3 vertices declared at line 3"
)]
#[case::medit_non_numeric_vertex(
    "mesh",
    "MeshVersionFormatted 1\nDimension 3\nVertices 1\n0 x 0 0\n",
    "line 4: node 1",
    "coordinate \"x\" is not a number"
)]
#[case::medit_infinite_vertex(
    "mesh",
    "MeshVersionFormatted 1\nDimension 3\nVertices 1\n0 inf 0 0\n",
    "line 4",
    "not a finite number"
)]
#[case::medit_undefined_vertex("mesh", &format!("{MEDIT_HEAD}Tetrahedra 1\n1 2 3 9 0\nEnd\n"), "line 9: element 1", "references vertex 9, which is not defined")]
#[case::medit_hexahedra("mesh", &format!("{MEDIT_HEAD}Hexahedra\n1\n1 2 3 4 1 2 3 4 0\n"), "line 9", "unsupported element type (hexahedra)")]
#[case::medit_unknown_section("mesh", &format!("{MEDIT_HEAD}Foo 2\n"), "line 8", "unknown medit section \"Foo\"")]
#[case::medit_binary(
    "mesh",
    "\x01\x00\x00\x00\x02\x00\x00\x00",
    "byte 0",
    "binary medit files (.meshb) are not supported"
)]
#[case::vega_cubes("veg", &format!("{VEGA_HEAD}*ELEMENTS\nCUBIC\n1 8 0\n"), "line 8", "unsupported element type (cubes)")]
#[case::vega_include("veg", "*INCLUDE other.veg\n", "line 1", "*INCLUDE is not supported")]
#[case::vega_fewer_vertices_than_declared(
    "veg",
    "*VERTICES\n3 3 0 0\n1 0 0 0\n2 1 0 0\n*ELEMENTS\n",
    "line 5",
    "declares 3 vertices but only 2 rows follow"
)]
#[case::vega_undefined_node("veg", &format!("{VEGA_HEAD}*ELEMENTS\nTETS\n1 4 0\n1 1 2 3 99\n"), "line 10: element 1", "references node 99, which is not defined")]
#[case::vega_wrong_nodes_per_element("veg", &format!("{VEGA_HEAD}*ELEMENTS\nTET\n1 8 0\n"), "line 9", "8 nodes per element")]
#[case::vega_infinite_coordinate(
    "veg",
    "*VERTICES\n1 3 0 0\n1 0 -inf 0\n",
    "line 3: node 1",
    "not a finite number"
)]
#[case::vega_undefined_set("veg", &format!("{VEGA_HEAD}*ELEMENTS\nTET\n1 4 0\n1 1 2 3 4\n*REGION\nnosuch, mat\n"), "line 12", "set \"nosuch\", which is not defined")]
#[case::vega_unknown_section("veg", &format!("{VEGA_HEAD}*FOO\n"), "line 7", "unknown section *FOO")]
#[case::vtk_polydata(
    "vtk",
    "# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\n",
    "line 4",
    "dataset type POLYDATA is not supported"
)]
#[case::vtk_not_vtk("vtk", "hello\n", "line 1", "not a legacy vtk file")]
#[case::vtk_hexahedron("vtk", &format!("{VTK_HEAD}POINTS 8 float\n0 0 0 1 0 0 1 1 0 0 1 0\n0 0 1 1 0 1 1 1 1 0 1 1\nCELLS 1 9\n8 0 1 2 3 4 5 6 7\nCELL_TYPES 1\n12\n"), "line 9: element 1", "unsupported cell type 12 (hexahedron)")]
#[case::vtk_wedge("vtk", &format!("{VTK_HEAD}POINTS 6 float\n0 0 0 1 0 0 0 1 0\n0 0 1 1 0 1 0 1 1\nCELLS 1 7\n6 0 1 2 3 4 5\nCELL_TYPES 1\n13\n"), "line 9", "(wedge)")]
#[case::vtk_cells_size_mismatch("vtk", &format!("{VTK_HEAD}POINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 6\n4 0 1 2 3\nCELL_TYPES 1\n10\n"), "line 8", "declares size 6 but the 1 cell lists hold 5 values")]
#[case::vtk_non_numeric_point("vtk", &format!("{VTK_HEAD}POINTS 1 float\n0 0 abc\n"), "line 6: node 0", "coordinate \"abc\" is not a number")]
#[case::vtk_undefined_point("vtk", &format!("{VTK_HEAD}POINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n4 0 1 2 99\nCELL_TYPES 1\n10\n"), "line 8: element 1", "references point 99, which is not defined")]
#[case::vtk_wrong_point_count_for_tet("vtk", &format!("{VTK_HEAD}POINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 4\n3 0 1 2\nCELL_TYPES 1\n10\n"), "line 8: element 1", "cell of type 10 has 3 points, expected 4")]
#[case::vtk_more_points_than_declared("vtk", &format!("{VTK_HEAD}POINTS 1 float\n0 0 0\n1 1 1\n"), "line 7", "more values than declared")]
#[case::vtk_fewer_points_than_declared("vtk", &format!("{VTK_HEAD}POINTS 2 float\n0 0 0\n"), "end of file", "file ends before coordinate")]
#[case::vtk_cell_types_mismatch("vtk", &format!("{VTK_HEAD}POINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 2\n10 10\n"), "end of file", "cells lists 1 cells but cell_types lists 2")]
fn malformed_file_gives_a_parse_error_naming_the_place_and_the_problem(
    #[case] format: &str,
    #[case] text: &str,
    #[case] place: &str,
    #[case] message: &str,
) {
    let err = parse(format, text.as_bytes()).expect_err("must fail");
    assert!(err.as_parse().is_some(), "not a parse error: {err}");
    let shown = err.to_string();
    assert!(shown.contains(place), "{shown:?} lacks {place:?}");
    assert!(
        shown.to_lowercase().contains(&message.to_lowercase()),
        "{shown:?} lacks {message:?}"
    );
}

#[test]
fn binary_medit_file_by_extension_says_meshb_is_unsupported() {
    let err = io::read_bytes(b"\x01\x00\x00\x00", "meshb", Path::new("m.meshb")).unwrap_err();
    assert!(err.as_parse().is_some(), "{err}");
    assert!(
        err.to_string().contains(".meshb) are not supported"),
        "{err}"
    );
}

#[test]
fn medit_triangle_on_an_undefined_vertex_names_its_line() {
    let text = format!("{MEDIT_HEAD}Triangles\n1\n1 2 5 3\nTetrahedra 1\n1 2 3 4 1\nEnd\n");
    let err = parse("mesh", text.as_bytes()).unwrap_err();
    assert!(err.to_string().contains("line 10: element 1"), "{err}");
    assert!(err.to_string().contains("references vertex 5"), "{err}");
}

#[test]
fn vtk_attribute_blocks_of_every_kind_are_skipped_and_a_scalars_region_without_lookup_table_is_read(
) {
    let s = format!(
        "{VTK_HEAD}FIELD FieldData 1\nTIME 1 1 double\n0.5\nPOINTS 4 float\n\
         0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n\
         POINT_DATA 4\nNORMALS n float\n0 0 1 0 0 1 0 0 1 0 0 1\n\
         TEXTURE_COORDINATES uv 2 float\n0 0 1 0 0 1 1 1\nCOLOR_SCALARS c 3\n\
         1 0 0 1 0 0 1 0 0 1 0 0\nTENSORS t float\n{}\n\
         SCALARS temperature float 1\nLOOKUP_TABLE hot\n1 2 3 4\nLOOKUP_TABLE hot 2\n\
         0 0 0 1 1 1 1 1\nCELL_DATA 1\nSCALARS gmsh:physical int\n42\n",
        "0 ".repeat(36)
    );
    let loaded = io::read_bytes(s.as_bytes(), "vtk", Path::new("a.vtk")).unwrap();
    assert_eq!(loaded.mesh.regions(), vec![(42, 1)]);
    let skipped = loaded
        .report
        .notes
        .iter()
        .filter(|n| n.starts_with("skipped"))
        .count();
    assert_eq!(skipped, 7, "{:?}", loaded.report.notes);
}

/// A small binary VTK file: 4 points, one tet.
fn tiny_vtk_binary(coord: f32) -> Vec<u8> {
    let mut b =
        b"# vtk DataFile Version 3.0\nt\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n"
            .to_vec();
    for c in [
        0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, coord,
    ] {
        b.extend(c.to_be_bytes());
    }
    b.extend(b"\nCELLS 1 5\n");
    for v in [4i32, 0, 1, 2, 3] {
        b.extend(v.to_be_bytes());
    }
    b.extend(b"\nCELL_TYPES 1\n");
    b.extend(10i32.to_be_bytes());
    b.push(b'\n');
    b
}

#[test]
fn tiny_binary_vtk_reads_as_one_tet() {
    let loaded = io::read_bytes(&tiny_vtk_binary(1.0), "vtk", Path::new("t.vtk")).unwrap();
    assert_eq!(loaded.mesh.tet_count(), 1);
    assert!((loaded.mesh.volume() - 1.0 / 6.0).abs() < 1e-12);
}

#[test]
fn binary_vtk_with_a_nan_coordinate_names_its_byte_offset() {
    let err = parse("vtk", &tiny_vtk_binary(f32::NAN)).unwrap_err();
    let p = err.as_parse().expect("parse error");
    // The NaN is the 12th float after the POINTS line.
    let header = tiny_vtk_binary(1.0)
        .windows(6)
        .position(|w| w == b"float\n")
        .unwrap()
        + 6;
    assert_eq!(p.location, lancet::Location::Byte(header as u64 + 11 * 4));
    assert!(err.to_string().contains("not a finite number"), "{err}");
}

#[test]
fn truncated_binary_vtk_names_the_byte_where_data_ran_out() {
    let b = tiny_vtk_binary(1.0);
    let cut = &b[..100];
    let err = parse("vtk", cut).unwrap_err();
    let shown = err.to_string();
    assert!(err.as_parse().is_some());
    assert!(shown.contains("byte 97"), "{shown}");
    assert!(
        shown.contains("binary data ends before coordinate"),
        "{shown}"
    );
}

#[rstest]
#[case::quadratic_linear_wedge(31)]
#[case::biquadratic_quadratic_wedge(32)]
#[case::biquadratic_quadratic_hexahedron(33)]
#[case::triquadratic_pyramid(37)]
fn higher_order_volume_cells_are_refused_not_dropped(#[case] ty: u32) {
    // One tet and one higher-order volume cell: the volume cell must not vanish silently.
    let text = format!(
        "# vtk DataFile Version 4.2\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n\
         0 0 0\n1 0 0\n0 1 0\n0 0 1\nCELLS 2 10\n4 0 1 2 3\n4 0 1 2 3\nCELL_TYPES 2\n10\n{ty}\n"
    );
    let err = lancet::mesh::io::read_bytes(text.as_bytes(), "vtk", Path::new("hi.vtk"))
        .expect_err("a volume cell lancet cannot simulate is an error");
    assert!(
        err.to_string()
            .contains(&format!("unsupported cell type {ty}")),
        "{err}"
    );
}
