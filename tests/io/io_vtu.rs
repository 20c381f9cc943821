//! VTK XML `.vtu` reading and writing, and `.pvd` series.

use std::path::{Path, PathBuf};

use approx::assert_relative_eq;
use base64::Engine;
use lancet::mesh::generate::BoxGrid;
use lancet::mesh::io::pvd::PvdWriter;
use lancet::mesh::io::vtu::{write_vtu, write_vtu_to, VtuEncoding, VtuOptions};
use lancet::mesh::io::{read, read_bytes, LoadedMesh};
use lancet::{Location, TetMesh};
use proptest::prelude::*;
use rstest::rstest;

const ENCODINGS: [VtuEncoding; 4] = [
    VtuEncoding::Ascii,
    VtuEncoding::Binary,
    VtuEncoding::AppendedRaw,
    VtuEncoding::AppendedZlib,
];

/// The shared mesh directory, or `None` (with the reason printed) when it is not configured.
fn mesh_dir() -> Option<PathBuf> {
    match std::env::var_os("LANCET_MESH_DIR") {
        Some(d) => Some(PathBuf::from(d)),
        None => {
            eprintln!("skipped: LANCET_MESH_DIR is not set, so the real meshes are not available");
            None
        }
    }
}

fn tongue() -> Option<TetMesh> {
    let path = mesh_dir()?.join("sofa/volumetricTongue.vtu");
    Some(read(&path).expect("the tongue mesh reads").mesh)
}

/// A 3x2x2 box with three regions.
fn box_mesh() -> TetMesh {
    let mut mesh = BoxGrid::cube_cells([3, 2, 2], 0.1).build().unwrap();
    mesh.set_region_where(2, |c| c.x > 0.1);
    mesh.set_region_where(-5, |c| c.x > 0.2 && c.z < 0.1);
    mesh
}

fn parse_str(text: &str) -> lancet::Result<LoadedMesh> {
    read_bytes(text.as_bytes(), "vtu", Path::new("test.vtu"))
}

fn to_bytes(mesh: &TetMesh, positions: Option<&[[f64; 3]]>, encoding: VtuEncoding) -> Vec<u8> {
    let mut out = Vec::new();
    write_vtu_to(&mut out, mesh, positions, &VtuOptions { encoding }).unwrap();
    out
}

/// Rest positions in dense node order.
fn rest_positions(mesh: &TetMesh) -> Vec<[f64; 3]> {
    let dense = mesh.dense_nodes();
    dense
        .keys
        .iter()
        .map(|&k| {
            let p = mesh.rest(k);
            [p.x, p.y, p.z]
        })
        .collect()
}

/// Tets as dense node indices with their region, in storage order.
fn tets(mesh: &TetMesh) -> Vec<([u32; 4], i32)> {
    let dense = mesh.dense_nodes();
    mesh.tets()
        .map(|(_, t)| (t.nodes.map(|k| dense.index[k]), t.region))
        .collect()
}

/// Bit patterns, so that -0.0 and 0.0 (and every last bit) count as different.
fn bits(p: &[[f64; 3]]) -> Vec<[u64; 3]> {
    p.iter().map(|v| v.map(f64::to_bits)).collect()
}

fn assert_same_mesh(a: &TetMesh, b: &TetMesh) {
    assert_eq!(bits(&rest_positions(a)), bits(&rest_positions(b)));
    assert_eq!(tets(a), tets(b));
}

/// The values of the float array `name` in a file written with ascii or binary encoding.
fn float_array(file: &[u8], name: &str) -> Vec<f64> {
    let text = std::str::from_utf8(file).unwrap();
    let start = text.find(&format!("Name=\"{name}\"")).unwrap();
    let open = start + text[start..].find('>').unwrap() + 1;
    let close = open + text[open..].find("</DataArray>").unwrap();
    let body = text[open..close].trim();
    if text[start..open].contains("format=\"ascii\"") {
        return body
            .split_ascii_whitespace()
            .map(|t| t.parse().unwrap())
            .collect();
    }
    let bytes = base64::engine::general_purpose::STANDARD
        .decode(body)
        .unwrap();
    bytes[8..]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

#[test]
fn the_tongue_mesh_reads_with_its_known_counts_volume_and_angles() {
    let Some(mesh) = tongue() else { return };
    assert_eq!(mesh.node_count(), 2238);
    assert_eq!(mesh.tet_count(), 10980);
    assert_eq!(mesh.edges().len(), 14187);
    assert_eq!(mesh.topology().boundary.len(), 1940);
    assert_relative_eq!(mesh.volume(), 2.4484, max_relative = 1e-4);
    let q = mesh.quality().unwrap();
    assert!((q.min_dihedral_deg - 1.0).abs() < 0.05, "{q:?}");
    assert!((q.max_dihedral_deg - 178.5).abs() < 0.05, "{q:?}");
}

#[rstest]
fn writing_then_reading_a_box_gives_back_the_same_mesh(
    #[values(
        VtuEncoding::Ascii,
        VtuEncoding::Binary,
        VtuEncoding::AppendedRaw,
        VtuEncoding::AppendedZlib
    )]
    encoding: VtuEncoding,
) {
    let mesh = box_mesh();
    assert_eq!(mesh.regions().len(), 3);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.vtu");
    write_vtu(&path, &mesh, None, &VtuOptions { encoding }).unwrap();
    let back = read(&path).unwrap();
    assert_same_mesh(&mesh, &back.mesh);
    assert_eq!(back.report.reoriented, 0);
    assert_eq!(back.report.dropped_nodes, 0);
}

#[rstest]
fn writing_then_reading_the_tongue_gives_back_the_same_mesh(
    #[values(
        VtuEncoding::Ascii,
        VtuEncoding::Binary,
        VtuEncoding::AppendedRaw,
        VtuEncoding::AppendedZlib
    )]
    encoding: VtuEncoding,
) {
    let Some(mesh) = tongue() else { return };
    let bytes = to_bytes(&mesh, None, encoding);
    let back = read_bytes(&bytes, "vtu", Path::new("tongue.vtu")).unwrap();
    assert_same_mesh(&mesh, &back.mesh);
}

#[rstest]
fn deformed_positions_come_back_as_points_with_displacement_current_minus_rest(
    #[values(
        VtuEncoding::Ascii,
        VtuEncoding::Binary,
        VtuEncoding::AppendedRaw,
        VtuEncoding::AppendedZlib
    )]
    encoding: VtuEncoding,
) {
    let mesh = box_mesh();
    let rest = rest_positions(&mesh);
    // A shear with irrational-looking factors, so every digit of the output matters.
    let current: Vec<[f64; 3]> = rest
        .iter()
        .map(|p| [p[0] + 0.37 * p[2] * p[1], p[1] * 1.1, p[2] - 1e-7 / 3.0])
        .collect();
    let bytes = to_bytes(&mesh, Some(&current), encoding);
    let back = read_bytes(&bytes, "vtu", Path::new("deformed.vtu")).unwrap();
    assert_eq!(bits(&rest_positions(&back.mesh)), bits(&current));
    assert_eq!(tets(&back.mesh), tets(&mesh));
    if matches!(encoding, VtuEncoding::Ascii | VtuEncoding::Binary) {
        let expected: Vec<f64> = current
            .iter()
            .zip(&rest)
            .flat_map(|(c, r)| [c[0] - r[0], c[1] - r[1], c[2] - r[2]])
            .collect();
        let got = float_array(&bytes, "displacement");
        assert_eq!(got.len(), expected.len());
        for (g, e) in got.iter().zip(&expected) {
            assert_eq!(g.to_bits(), e.to_bits());
        }
        let rest_back = float_array(&bytes, "rest_position");
        assert_eq!(rest_back, rest.concat());
    }
}

#[test]
fn written_cell_data_holds_region_quality_and_volume() {
    let mesh = box_mesh();
    let bytes = to_bytes(&mesh, None, VtuEncoding::Ascii);
    let quality = float_array(&bytes, "quality");
    let volume = float_array(&bytes, "volume");
    let expected = mesh.tet_qualities();
    assert_eq!(quality.len(), mesh.tet_count());
    for ((q, v), e) in quality.iter().zip(&volume).zip(&expected) {
        assert_eq!(*q, e.volume_length_ratio);
        assert_eq!(*v, e.volume);
    }
    let text = String::from_utf8(bytes).unwrap();
    assert!(text.contains("Name=\"region\""));
}

#[test]
fn writing_leaves_no_temporary_file_and_replaces_the_destination() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.vtu");
    std::fs::write(&path, "old content").unwrap();
    write_vtu(&path, &box_mesh(), None, &VtuOptions::default()).unwrap();
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("out.vtu")]);
    read(&path).unwrap();
}

#[test]
fn writing_with_the_wrong_number_of_positions_fails_without_touching_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.vtu");
    let err = write_vtu(
        &path,
        &box_mesh(),
        Some(&[[0.0; 3]]),
        &VtuOptions::default(),
    )
    .unwrap_err();
    assert!(err.to_string().contains("positions given"), "{err}");
    assert!(!path.exists());
}

// Hand-crafted files: two tets, (0,1,2,3) of volume 1/6 and (1,2,3,4) of volume 1/3, regions 3
// and 5 where given. Generated with Python's struct, base64 and zlib modules, independently of
// lancet's writer; the zlib ones use 8-byte blocks so that arrays span several blocks.
const U64_HEADER_FLOAT32: &str = "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\"><UnstructuredGrid><Piece NumberOfPoints=\"5\" NumberOfCells=\"2\"><CellData><DataArray type=\"Int32\" Name=\"region\" NumberOfComponents=\"1\" format=\"binary\">CAAAAAAAAAADAAAABQAAAA==</DataArray></CellData><Points><DataArray type=\"Float32\" Name=\"Points\" NumberOfComponents=\"3\" format=\"binary\">PAAAAAAAAAAAAAAAAAAAAAAAAAAAAIA/AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAIA/AACAPwAAgD8=</DataArray></Points><Cells><DataArray type=\"Int64\" Name=\"connectivity\" NumberOfComponents=\"1\" format=\"binary\">QAAAAAAAAAAAAAAAAAAAAAEAAAAAAAAAAgAAAAAAAAADAAAAAAAAAAEAAAAAAAAAAgAAAAAAAAADAAAAAAAAAAQAAAAAAAAA</DataArray><DataArray type=\"Int32\" Name=\"offsets\" NumberOfComponents=\"1\" format=\"binary\">CAAAAAAAAAAEAAAACAAAAA==</DataArray><DataArray type=\"UInt8\" Name=\"types\" NumberOfComponents=\"1\" format=\"binary\">AgAAAAAAAAAKCg==</DataArray></Cells></Piece></UnstructuredGrid></VTKFile>";
const BIG_ENDIAN: &str = "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"BigEndian\" header_type=\"UInt32\"><UnstructuredGrid><Piece NumberOfPoints=\"5\" NumberOfCells=\"2\"><CellData><DataArray type=\"Int32\" Name=\"region\" NumberOfComponents=\"1\" format=\"binary\">AAAACAAAAAMAAAAF</DataArray></CellData><Points><DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" format=\"binary\">AAAAeAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAD/wAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAP/AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA/8AAAAAAAAD/wAAAAAAAAP/AAAAAAAAA/8AAAAAAAAA==</DataArray></Points><Cells><DataArray type=\"Int64\" Name=\"connectivity\" NumberOfComponents=\"1\" format=\"binary\">AAAAQAAAAAAAAAAAAAAAAAAAAAEAAAAAAAAAAgAAAAAAAAADAAAAAAAAAAEAAAAAAAAAAgAAAAAAAAADAAAAAAAAAAQ=</DataArray><DataArray type=\"Int32\" Name=\"offsets\" NumberOfComponents=\"1\" format=\"binary\">AAAACAAAAAQAAAAI</DataArray><DataArray type=\"UInt8\" Name=\"types\" NumberOfComponents=\"1\" format=\"binary\">AAAAAgoK</DataArray></Cells></Piece></UnstructuredGrid></VTKFile>";
const ZLIB_SEPARATE_BASE64: &str = "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt32\" compressor=\"vtkZLibDataCompressor\"><UnstructuredGrid><Piece NumberOfPoints=\"5\" NumberOfCells=\"2\"><CellData><DataArray type=\"Int32\" Name=\"region\" NumberOfComponents=\"1\" format=\"binary\">AQAAAAgAAAAAAAAADgAAAA==eJxjZmBgYAViAAA0AAk=</DataArray></CellData><Points><DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" format=\"binary\">DwAAAAgAAAAAAAAACwAAAAsAAAALAAAADQAAAAsAAAALAAAACwAAAA0AAAALAAAACwAAAAsAAAANAAAADQAAAA0AAAANAAAAeJxjYIAAAAAIAAF4nGNggAAAAAgAAXicY2CAAAAACAABeJxjYACBD/YAAicBMHicY2CAAAAACAABeJxjYIAAAAAIAAF4nGNggAAAAAgAAXicY2AAgQ/2AAInATB4nGNggAAAAAgAAXicY2CAAAAACAABeJxjYIAAAAAIAAF4nGNgAIEP9gACJwEweJxjYACBD/YAAicBMHicY2AAgQ/2AAInATB4nGNgAIEP9gACJwEw</DataArray></Points><Cells><DataArray type=\"Int64\" Name=\"connectivity\" NumberOfComponents=\"1\" format=\"binary\">CAAAAAgAAAAAAAAACwAAAAsAAAALAAAACwAAAAsAAAALAAAACwAAAAsAAAA=eJxjYIAAAAAIAAF4nGNkgAAAABAAAnicY2KAAAAAGAADeJxjZoAAAAAgAAR4nGNkgAAAABAAAnicY2KAAAAAGAADeJxjZoAAAAAgAAR4nGNhgAAAACgABQ==</DataArray><DataArray type=\"Int32\" Name=\"offsets\" NumberOfComponents=\"1\" format=\"binary\">AQAAAAgAAAAAAAAADgAAAA==eJxjYWBg4ABiAABIAA0=</DataArray><DataArray type=\"UInt8\" Name=\"types\" NumberOfComponents=\"1\" format=\"binary\">AQAAAAgAAAACAAAACgAAAA==eJzj4gIAACAAFQ==</DataArray></Cells></Piece></UnstructuredGrid></VTKFile>";
const ZLIB_SINGLE_BASE64: &str = "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt32\" compressor=\"vtkZLibDataCompressor\"><UnstructuredGrid><Piece NumberOfPoints=\"5\" NumberOfCells=\"2\"><CellData><DataArray type=\"Int32\" Name=\"region\" NumberOfComponents=\"1\" format=\"binary\">AQAAAAgAAAAAAAAADgAAAHicY2ZgYGAFYgAANAAJ</DataArray></CellData><Points><DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" format=\"binary\">DwAAAAgAAAAAAAAACwAAAAsAAAALAAAADQAAAAsAAAALAAAACwAAAA0AAAALAAAACwAAAAsAAAANAAAADQAAAA0AAAANAAAAeJxjYIAAAAAIAAF4nGNggAAAAAgAAXicY2CAAAAACAABeJxjYACBD/YAAicBMHicY2CAAAAACAABeJxjYIAAAAAIAAF4nGNggAAAAAgAAXicY2AAgQ/2AAInATB4nGNggAAAAAgAAXicY2CAAAAACAABeJxjYIAAAAAIAAF4nGNgAIEP9gACJwEweJxjYACBD/YAAicBMHicY2AAgQ/2AAInATB4nGNgAIEP9gACJwEw</DataArray></Points><Cells><DataArray type=\"Int64\" Name=\"connectivity\" NumberOfComponents=\"1\" format=\"binary\">CAAAAAgAAAAAAAAACwAAAAsAAAALAAAACwAAAAsAAAALAAAACwAAAAsAAAB4nGNggAAAAAgAAXicY2SAAAAAEAACeJxjYoAAAAAYAAN4nGNmgAAAACAABHicY2SAAAAAEAACeJxjYoAAAAAYAAN4nGNmgAAAACAABHicY2GAAAAAKAAF</DataArray><DataArray type=\"Int32\" Name=\"offsets\" NumberOfComponents=\"1\" format=\"binary\">AQAAAAgAAAAAAAAADgAAAHicY2FgYOAAYgAASAAN</DataArray><DataArray type=\"UInt8\" Name=\"types\" NumberOfComponents=\"1\" format=\"binary\">AQAAAAgAAAACAAAACgAAAHic4+ICAAAgABU=</DataArray></Cells></Piece></UnstructuredGrid></VTKFile>";
const ZLIB_BIG_ENDIAN_U64: &str = "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"BigEndian\" header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\"><UnstructuredGrid><Piece NumberOfPoints=\"5\" NumberOfCells=\"2\"><CellData><DataArray type=\"Int32\" Name=\"region\" NumberOfComponents=\"1\" format=\"binary\">AAAAAAAAAAEAAAAAAAAACAAAAAAAAAAAAAAAAAAAABA=eJxjYGBgZmBgYAUAABwACQ==</DataArray></CellData><Points><DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" format=\"binary\">AAAAAAAAAA8AAAAAAAAACAAAAAAAAAAAAAAAAAAAAAsAAAAAAAAACwAAAAAAAAALAAAAAAAAAAwAAAAAAAAACwAAAAAAAAALAAAAAAAAAAsAAAAAAAAADAAAAAAAAAALAAAAAAAAAAsAAAAAAAAACwAAAAAAAAAMAAAAAAAAAAwAAAAAAAAADAAAAAAAAAAMeJxjYIAAAAAIAAF4nGNggAAAAAgAAXicY2CAAAAACAABeJyz/8AABgAIkAEweJxjYIAAAAAIAAF4nGNggAAAAAgAAXicY2CAAAAACAABeJyz/8AABgAIkAEweJxjYIAAAAAIAAF4nGNggAAAAAgAAXicY2CAAAAACAABeJyz/8AABgAIkAEweJyz/8AABgAIkAEweJyz/8AABgAIkAEweJyz/8AABgAIkAEw</DataArray></Points><Cells><DataArray type=\"Int64\" Name=\"connectivity\" NumberOfComponents=\"1\" format=\"binary\">AAAAAAAAAAgAAAAAAAAACAAAAAAAAAAAAAAAAAAAAAsAAAAAAAAADAAAAAAAAAAMAAAAAAAAAAwAAAAAAAAADAAAAAAAAAAMAAAAAAAAAAwAAAAAAAAADA==eJxjYIAAAAAIAAF4nGNgAANGAAAJAAJ4nGNgAAMmAAAKAAN4nGNgAANmAAALAAR4nGNgAANGAAAJAAJ4nGNgAAMmAAAKAAN4nGNgAANmAAALAAR4nGNgAAMWAAAMAAU=</DataArray><DataArray type=\"Int32\" Name=\"offsets\" NumberOfComponents=\"1\" format=\"binary\">AAAAAAAAAAEAAAAAAAAACAAAAAAAAAAAAAAAAAAAABA=eJxjYGBgYWBg4AAAACQADQ==</DataArray><DataArray type=\"UInt8\" Name=\"types\" NumberOfComponents=\"1\" format=\"binary\">AAAAAAAAAAEAAAAAAAAACAAAAAAAAAACAAAAAAAAAAo=eJzj4gIAACAAFQ==</DataArray></Cells></Piece></UnstructuredGrid></VTKFile>";
const APPENDED_BASE64: &str = "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt32\"><UnstructuredGrid><Piece NumberOfPoints=\"5\" NumberOfCells=\"2\"><Points><DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" format=\"appended\" offset=\"0\"/></Points><Cells><DataArray type=\"Int32\" Name=\"connectivity\" NumberOfComponents=\"1\" format=\"appended\" offset=\"168\"/><DataArray type=\"Int64\" Name=\"offsets\" NumberOfComponents=\"1\" format=\"appended\" offset=\"216\"/><DataArray type=\"UInt8\" Name=\"types\" NumberOfComponents=\"1\" format=\"appended\" offset=\"244\"/></Cells></Piece></UnstructuredGrid><AppendedData encoding=\"base64\">_eAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAPA/AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA8D8AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAADwPwAAAAAAAPA/AAAAAAAA8D8AAAAAAADwPw==IAAAAAAAAAABAAAAAgAAAAMAAAABAAAAAgAAAAMAAAAEAAAAEAAAAAQAAAAAAAAACAAAAAAAAAA=AgAAAAoK</AppendedData></VTKFile>";
const APPENDED_RAW_ZLIB_U64: &[u8] = b"<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\"><UnstructuredGrid><Piece NumberOfPoints=\"5\" NumberOfCells=\"2\"><Points><DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" format=\"appended\" offset=\"0\"/></Points><Cells><DataArray type=\"Int32\" Name=\"connectivity\" NumberOfComponents=\"1\" format=\"appended\" offset=\"321\"/><DataArray type=\"Int64\" Name=\"offsets\" NumberOfComponents=\"1\" format=\"appended\" offset=\"433\"/><DataArray type=\"UInt8\" Name=\"types\" NumberOfComponents=\"1\" format=\"appended\" offset=\"495\"/></Cells></Piece></UnstructuredGrid><AppendedData encoding=\"raw\">_\x0f\x00\x00\x00\x00\x00\x00\x00\x08\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x0b\x00\x00\x00\x00\x00\x00\x00\x0b\x00\x00\x00\x00\x00\x00\x00\x0b\x00\x00\x00\x00\x00\x00\x00\x0d\x00\x00\x00\x00\x00\x00\x00\x0b\x00\x00\x00\x00\x00\x00\x00\x0b\x00\x00\x00\x00\x00\x00\x00\x0b\x00\x00\x00\x00\x00\x00\x00\x0d\x00\x00\x00\x00\x00\x00\x00\x0b\x00\x00\x00\x00\x00\x00\x00\x0b\x00\x00\x00\x00\x00\x00\x00\x0b\x00\x00\x00\x00\x00\x00\x00\x0d\x00\x00\x00\x00\x00\x00\x00\x0d\x00\x00\x00\x00\x00\x00\x00\x0d\x00\x00\x00\x00\x00\x00\x00\x0d\x00\x00\x00\x00\x00\x00\x00x\x9cc`\x80\x00\x00\x00\x08\x00\x01x\x9cc`\x80\x00\x00\x00\x08\x00\x01x\x9cc`\x80\x00\x00\x00\x08\x00\x01x\x9cc`\x00\x81\x0f\xf6\x00\x02'\x010x\x9cc`\x80\x00\x00\x00\x08\x00\x01x\x9cc`\x80\x00\x00\x00\x08\x00\x01x\x9cc`\x80\x00\x00\x00\x08\x00\x01x\x9cc`\x00\x81\x0f\xf6\x00\x02'\x010x\x9cc`\x80\x00\x00\x00\x08\x00\x01x\x9cc`\x80\x00\x00\x00\x08\x00\x01x\x9cc`\x80\x00\x00\x00\x08\x00\x01x\x9cc`\x00\x81\x0f\xf6\x00\x02'\x010x\x9cc`\x00\x81\x0f\xf6\x00\x02'\x010x\x9cc`\x00\x81\x0f\xf6\x00\x02'\x010x\x9cc`\x00\x81\x0f\xf6\x00\x02'\x010\x04\x00\x00\x00\x00\x00\x00\x00\x08\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x0e\x00\x00\x00\x00\x00\x00\x00\x0e\x00\x00\x00\x00\x00\x00\x00\x0e\x00\x00\x00\x00\x00\x00\x00\x0e\x00\x00\x00\x00\x00\x00\x00x\x9cc````\x04b\x00\x00\x0c\x00\x02x\x9ccb```\x06b\x00\x00$\x00\x06x\x9ccd```\x02b\x00\x00\x18\x00\x04x\x9ccf```\x01b\x00\x000\x00\x08\x02\x00\x00\x00\x00\x00\x00\x00\x08\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x0b\x00\x00\x00\x00\x00\x00\x00\x0b\x00\x00\x00\x00\x00\x00\x00x\x9cca\x80\x00\x00\x00(\x00\x05x\x9c\xe3`\x80\x00\x00\x00H\x00\x09\x01\x00\x00\x00\x00\x00\x00\x00\x08\x00\x00\x00\x00\x00\x00\x00\x02\x00\x00\x00\x00\x00\x00\x00\x0a\x00\x00\x00\x00\x00\x00\x00x\x9c\xe3\xe2\x02\x00\x00 \x00\x15</AppendedData></VTKFile>";

/// One unit tet, every array ascii, region 7 in `MaterialIds`. Line numbers are used below.
const ONE_TET_ASCII: &str = r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">
  <UnstructuredGrid>
    <Piece NumberOfPoints="4" NumberOfCells="1">
      <Points>
        <DataArray type="Float64" NumberOfComponents="3" format="ascii">
          0 0 0
          1 0 0
          0 1 0
          0 0 1
        </DataArray>
      </Points>
      <Cells>
        <DataArray type="Int64" Name="connectivity" format="ascii">
          0 1 2 3
        </DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii">
          4
        </DataArray>
        <DataArray type="UInt8" Name="types" format="ascii">
          10
        </DataArray>
      </Cells>
      <CellData>
        <DataArray type="Float32" Name="quality" format="ascii">
          0.5
        </DataArray>
        <DataArray type="Int32" Name="MaterialIds" format="ascii">
          7
        </DataArray>
      </CellData>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
"#;

/// Two pieces: a unit tet with a triangle, then a tet scaled by 2 (volume 8/6).
const TWO_PIECES: &str = r#"<VTKFile type="UnstructuredGrid" version="0.1">
<UnstructuredGrid>
<Piece NumberOfPoints="4" NumberOfCells="2">
<Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">0 0 0 1 0 0 0 1 0 0 0 1</DataArray></Points>
<Cells>
<DataArray type="Int32" Name="connectivity" format="ascii">0 1 2 3 0 1 2</DataArray>
<DataArray type="Int32" Name="offsets" format="ascii">4 7</DataArray>
<DataArray type="UInt8" Name="types" format="ascii">10 5</DataArray>
</Cells>
<CellData><DataArray type="Int32" Name="gmsh:physical" format="ascii">1 9</DataArray></CellData>
</Piece>
<Piece NumberOfPoints="5" NumberOfCells="2">
<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">9 9 9 0 0 0 2 0 0 0 2 0 0 0 2</DataArray></Points>
<Cells>
<DataArray type="Int32" Name="connectivity" format="ascii">0 1 2 3 4</DataArray>
<DataArray type="Int32" Name="offsets" format="ascii">1 5</DataArray>
<DataArray type="UInt8" Name="types" format="ascii">1 10</DataArray>
</Cells>
<CellData><DataArray type="Int32" Name="gmsh:physical" format="ascii">0 2</DataArray></CellData>
</Piece>
</UnstructuredGrid>
</VTKFile>
"#;

#[rstest]
#[case::uint64_header_and_float32_points(U64_HEADER_FLOAT32.as_bytes(), true)]
#[case::big_endian(BIG_ENDIAN.as_bytes(), true)]
#[case::zlib_header_and_data_encoded_separately(ZLIB_SEPARATE_BASE64.as_bytes(), true)]
#[case::zlib_in_one_base64_stream(ZLIB_SINGLE_BASE64.as_bytes(), true)]
#[case::zlib_big_endian_uint64_header(ZLIB_BIG_ENDIAN_U64.as_bytes(), true)]
#[case::appended_base64(APPENDED_BASE64.as_bytes(), false)]
#[case::appended_raw_zlib_uint64_header(APPENDED_RAW_ZLIB_U64, false)]
fn hand_crafted_binary_files_read_to_the_two_expected_tets(
    #[case] bytes: &[u8],
    #[case] has_regions: bool,
) {
    let loaded = read_bytes(bytes, "vtu", Path::new("crafted.vtu")).unwrap();
    let mesh = &loaded.mesh;
    assert_eq!(mesh.node_count(), 5);
    assert_eq!(mesh.tet_count(), 2);
    assert_relative_eq!(mesh.volume(), 0.5, max_relative = 1e-12);
    assert_eq!(
        rest_positions(mesh),
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 1.0, 1.0]
        ]
    );
    let t = tets(mesh);
    assert_eq!(t[0].0, [0, 1, 2, 3]);
    assert_eq!(t[1].0, [1, 2, 3, 4]);
    let regions: Vec<i32> = t.iter().map(|x| x.1).collect();
    assert_eq!(regions, if has_regions { vec![3, 5] } else { vec![0, 0] });
}

#[test]
fn an_ascii_tet_reads_with_its_region_from_a_material_array() {
    let loaded = parse_str(ONE_TET_ASCII).unwrap();
    assert_eq!(loaded.mesh.tet_count(), 1);
    assert_relative_eq!(loaded.mesh.volume(), 1.0 / 6.0);
    assert_eq!(loaded.mesh.regions(), vec![(7, 1)]);
    assert!(loaded
        .report
        .notes
        .iter()
        .any(|n| n.contains("MaterialIds")));
}

#[test]
fn several_pieces_are_joined_with_their_point_numbers_shifted() {
    let loaded = parse_str(TWO_PIECES).unwrap();
    let mesh = &loaded.mesh;
    assert_eq!(mesh.tet_count(), 2);
    // The point (9, 9, 9) of the second piece is used only by a vertex cell: dropped.
    assert_eq!(mesh.node_count(), 8);
    assert_eq!(loaded.report.dropped_nodes, 1);
    assert_relative_eq!(mesh.volume(), 1.0 / 6.0 + 8.0 / 6.0, max_relative = 1e-12);
    assert_eq!(mesh.regions(), vec![(1, 1), (2, 1)]);
    assert_eq!(loaded.surface.len(), 1);
    assert_eq!(loaded.surface[0].tag, 9);
    let notes = loaded.report.notes.join("\n");
    assert!(notes.contains("2 pieces"), "{notes}");
    assert!(notes.contains("vertex or line"), "{notes}");
}

#[test]
fn a_quadratic_tet_is_read_on_its_corners() {
    let text = ONE_TET_ASCII
        .replace("NumberOfPoints=\"4\"", "NumberOfPoints=\"10\"")
        .replace(
            "0 0 1\n",
            "0 0 1\n0.5 0 0 0.5 0.5 0 0 0.5 0 0 0 0.5 0.5 0 0.5 0 0.5 0.5\n",
        )
        .replace("0 1 2 3\n", "0 1 2 3 4 5 6 7 8 9\n")
        .replace("          4\n", "          10\n")
        .replace(
            "          10\n        </DataArray>\n      </Cells>",
            "          24\n        </DataArray>\n      </Cells>",
        );
    let loaded = parse_str(&text).unwrap();
    assert_eq!(loaded.mesh.node_count(), 4);
    assert_relative_eq!(loaded.mesh.volume(), 1.0 / 6.0);
    assert!(loaded.report.notes.iter().any(|n| n.contains("quadratic")));
}

/// A binary-inline unit tet built from pieces, for the binary error cases.
fn binary_tet(points_b64: &str) -> String {
    let enc = |bytes: Vec<u8>| {
        let mut b = (bytes.len() as u32).to_le_bytes().to_vec();
        b.extend(bytes);
        base64::engine::general_purpose::STANDARD.encode(b)
    };
    let conn: Vec<u8> = [0i32, 1, 2, 3]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    format!(
        "<VTKFile type=\"UnstructuredGrid\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n\
         <Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n<Points>\n\
         <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"binary\">{points_b64}</DataArray>\n\
         </Points>\n<Cells>\n\
         <DataArray type=\"Int32\" Name=\"connectivity\" format=\"binary\">{}</DataArray>\n\
         <DataArray type=\"Int32\" Name=\"offsets\" format=\"binary\">{}</DataArray>\n\
         <DataArray type=\"UInt8\" Name=\"types\" format=\"binary\">{}</DataArray>\n\
         </Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n",
        enc(conn),
        enc(4i32.to_le_bytes().to_vec()),
        enc(vec![10u8]),
    )
}

fn points_b64(last: f64) -> String {
    let p = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, last];
    let mut b = 96u32.to_le_bytes().to_vec();
    b.extend(p.iter().flat_map(|x: &f64| x.to_le_bytes()));
    base64::engine::general_purpose::STANDARD.encode(b)
}

#[test]
fn the_binary_tet_helper_is_itself_valid() {
    let loaded = parse_str(&binary_tet(&points_b64(1.0))).unwrap();
    assert_relative_eq!(loaded.mesh.volume(), 1.0 / 6.0);
}

/// Replace `from` by `to` in the ascii tet (which must contain it).
fn ascii_with(from: &str, to: &str) -> String {
    assert!(ONE_TET_ASCII.contains(from), "{from:?}");
    ONE_TET_ASCII.replacen(from, to, 1)
}

#[rstest]
#[case::not_xml("hello, world".into(), "no <VTKFile>", Location::Line(1), None)]
#[case::poly_data(
    ascii_with("UnstructuredGrid\" version", "PolyData\" version"),
    "not an UnstructuredGrid",
    Location::Line(2),
    None
)]
#[case::unknown_compressor(
    ascii_with("version=\"0.1\"", "compressor=\"vtkLZ4DataCompressor\""),
    "compressor \"vtkLZ4DataCompressor\"",
    Location::Line(2),
    None
)]
#[case::mismatched_tag(
    ascii_with("</Points>", "</Pointz>"),
    "malformed",
    Location::Line(12),
    None
)]
#[case::truncated(
    ONE_TET_ASCII[..ONE_TET_ASCII.find("</Piece>").unwrap()].into(),
    "ends before </VTKFile>", Location::Unknown, None
)]
#[case::nan_coordinate(
    ascii_with("0 0 1", "0 0 nan"),
    "not a finite number",
    Location::Line(10),
    Some(3)
)]
#[case::bad_number(
    ascii_with("1 0 0", "1 x 0"),
    "\"x\" is not a number",
    Location::Line(8),
    Some(1)
)]
#[case::short_points(ascii_with("0 0 1", "0 0"), "has 11 values", Location::Line(6), None)]
#[case::hexahedron(
    ascii_with("          10\n", "          12\n"),
    "hexahedron",
    Location::Line(15),
    Some(0)
)]
#[case::unknown_cell_type(
    ascii_with("          10\n", "          99\n"),
    "unknown vtk cell type 99",
    Location::Line(15),
    Some(0)
)]
#[case::negative_point(
    ascii_with("0 1 2 3", "0 1 2 -1"),
    "references point -1",
    Location::Line(15),
    Some(0)
)]
#[case::point_out_of_range(
    ascii_with("0 1 2 3", "0 1 2 4"),
    "references point 4",
    Location::Line(15),
    Some(0)
)]
#[case::float_connectivity(
    ascii_with("0 1 2 3", "0 1 2 3.5"),
    "not a valid integer",
    Location::Line(15),
    Some(3)
)]
#[case::offsets_not_increasing(
    ascii_with("          4\n", "          0\n"),
    "does not increase",
    Location::Line(18),
    Some(0)
)]
#[case::offsets_past_connectivity(
    ascii_with("          4\n", "          5\n"),
    "past the 4 connectivity",
    Location::Line(18),
    Some(0)
)]
#[case::connectivity_longer_than_offsets(
    ascii_with("0 1 2 3", "0 1 2 3 0"),
    "offsets end at 4",
    Location::Line(14),
    None
)]
#[case::wrong_cell_size(
    ascii_with("0 1 2 3", "0 1 2 3 0").replacen("          4\n", "          5\n", 1),
    "has 5 points, expected 4", Location::Line(15), Some(0)
)]
#[case::value_too_big_for_type(
    ascii_with("          10\n", "          300\n"),
    "does not fit",
    Location::Line(21),
    Some(0)
)]
#[case::missing_offsets(
    ascii_with("Name=\"offsets\"", "Name=\"offsetz\""),
    "no offsets array",
    Location::Line(4),
    None
)]
#[case::fractional_region(
    ascii_with("          7\n", "          7.5\n").replacen("Int32\" Name=\"MaterialIds", "Float64\" Name=\"MaterialIds", 1), "not a 32-bit integer", Location::Line(29), Some(0))]
#[case::repeated_node(
    ascii_with("0 1 2 3", "0 1 1 3"),
    "uses node 1 twice",
    Location::Line(15),
    Some(0)
)]
#[case::flat_tet(
    ascii_with("0 0 1\n", "1 1 0\n"),
    "zero volume",
    Location::Line(15),
    Some(0)
)]
#[case::appended_without_section(
    ascii_with(
        "format=\"ascii\">\n          0 1 2 3\n        </DataArray>",
        "format=\"appended\" offset=\"0\"/>"
    ),
    "no <AppendedData>",
    Location::Line(14),
    None
)]
#[case::truncated_base64(
    binary_tet(&points_b64(1.0)[..21]),
    "not a multiple of 4", Location::Line(5), None
)]
#[case::invalid_base64(
    binary_tet(&format!("*{}", &points_b64(1.0)[1..])),
    "invalid base64", Location::Line(5), None
)]
#[case::infinite_binary_coordinate(binary_tet(&points_b64(f64::INFINITY)), "non-finite value (inf)", Location::Line(5), Some(3))]
#[case::short_binary_block(
    binary_tet(&base64::engine::general_purpose::STANDARD.encode([200u8, 0, 0, 0, 1, 2, 3, 4])),
    "declares 200 bytes but only 4 follow", Location::Line(5), None
)]
fn bad_files_give_parse_errors_naming_the_problem_and_place(
    #[case] text: String,
    #[case] expected: &str,
    #[case] location: Location,
    #[case] element: Option<i64>,
) {
    let err = parse_str(&text).unwrap_err();
    let p = err
        .as_parse()
        .unwrap_or_else(|| panic!("not a parse error: {err}"));
    let shown = err.to_string();
    assert!(shown.contains(expected), "{shown}");
    assert!(shown.starts_with("test.vtu: "), "{shown}");
    assert_eq!(p.location, location, "{shown}");
    assert_eq!(p.element, element, "{shown}");
    assert!(!p.hint.is_empty(), "{shown}");
    // Messages start lowercase (names quoted from the file keep their case).
    assert!(
        p.message.starts_with(|c: char| !c.is_uppercase()),
        "{shown}"
    );
}

/// The appended raw zlib fixture with its first block header changed to claim `block` bytes.
#[test]
fn a_zlib_header_claiming_more_than_deflate_can_produce_is_refused() {
    let mut bytes = APPENDED_RAW_ZLIB_U64.to_vec();
    let start = bytes.windows(2).position(|w| w == b">_").unwrap() + 2;
    // Header: blocks, block size, last size (UInt64 each); claim 1 TB blocks.
    bytes[start + 8..start + 16].copy_from_slice(&(1u64 << 40).to_le_bytes());
    bytes[start + 16..start + 24].copy_from_slice(&0u64.to_le_bytes());
    let err = read_bytes(&bytes, "vtu", Path::new("bomb.vtu")).unwrap_err();
    let p = err.as_parse().unwrap();
    assert!(
        err.to_string().contains("more than zlib can produce"),
        "{err}"
    );
    assert!(
        matches!(p.location, Location::Byte(b) if b as usize >= start),
        "{err}"
    );
}

#[test]
fn truncated_raw_appended_data_is_reported_at_a_byte_offset() {
    let bytes = to_bytes(&box_mesh(), None, VtuEncoding::AppendedRaw);
    let cut = &bytes[..bytes.len() - 200];
    let err = read_bytes(cut, "vtu", Path::new("cut.vtu")).unwrap_err();
    let p = err.as_parse().unwrap();
    assert!(matches!(p.location, Location::Byte(_)), "{err}");
    assert!(err.to_string().contains("follow"), "{err}");
}

#[test]
fn negative_int64_connectivity_in_binary_data_is_caught() {
    let mesh = box_mesh();
    let mut bytes = to_bytes(&mesh, None, VtuEncoding::AppendedRaw);
    // The first connectivity value is the first Int64 after the connectivity block's header.
    let text = String::from_utf8_lossy(&bytes).into_owned();
    let tag = text.find("Name=\"connectivity\"").unwrap();
    let off: usize = text[tag..]
        .split("offset=\"")
        .nth(1)
        .unwrap()
        .split('"')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let data = text.find("<AppendedData encoding=\"raw\">").unwrap();
    let data = data + text[data..].find('_').unwrap() + 1;
    let at = data + off + 8;
    bytes[at..at + 8].copy_from_slice(&(-3i64).to_le_bytes());
    let err = read_bytes(&bytes, "vtu", Path::new("neg.vtu")).unwrap_err();
    let p = err.as_parse().unwrap();
    assert!(err.to_string().contains("references point -3"), "{err}");
    assert_eq!(p.element, Some(0));
}

#[test]
fn a_pvd_series_lists_every_frame_with_increasing_times() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = box_mesh();
    let rest = rest_positions(&mesh);
    let mut series = PvdWriter::new(dir.path(), "run", VtuOptions::default()).unwrap();
    assert_eq!(series.frames(), 0);
    let mut paths = Vec::new();
    for (i, t) in [0.0, 0.01, 0.02].into_iter().enumerate() {
        let current: Vec<[f64; 3]> = rest
            .iter()
            .map(|p| [p[0], p[1], p[2] + 0.01 * i as f64])
            .collect();
        paths.push(series.frame(t, &mesh, Some(&current)).unwrap());
        // The collection is complete after every frame.
        let pvd = std::fs::read_to_string(dir.path().join("run.pvd")).unwrap();
        assert_eq!(pvd.matches("<DataSet").count(), i + 1);
    }
    assert_eq!(series.frames(), 3);
    assert!(
        series.frame(0.02, &mesh, None).is_err(),
        "time must increase"
    );
    let pvd = std::fs::read_to_string(series.pvd_path()).unwrap();
    assert!(pvd.contains("type=\"Collection\""));
    let mut last = f64::NEG_INFINITY;
    for (i, ds) in pvd.split("<DataSet").skip(1).enumerate() {
        let attr = |name: &str| {
            ds.split(&format!("{name}=\""))
                .nth(1)
                .unwrap()
                .split('"')
                .next()
                .unwrap()
                .to_string()
        };
        let t: f64 = attr("timestep").parse().unwrap();
        assert!(t > last);
        last = t;
        let file = dir.path().join(attr("file"));
        assert_eq!(file, paths[i]);
        assert_eq!(
            file.file_name().unwrap(),
            format!("run_{i:06}.vtu").as_str()
        );
        let back = read(&file).unwrap();
        let z = rest_positions(&back.mesh)[0][2];
        assert_eq!(z, rest[0][2] + 0.01 * i as f64);
    }
}

#[test]
fn a_pvd_series_name_with_a_path_separator_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    assert!(PvdWriter::new(dir.path(), "a/b", VtuOptions::default()).is_err());
}

/// Valid files of every encoding, to mutate.
fn valid_files() -> Vec<Vec<u8>> {
    let mesh = BoxGrid::cube_cells([2, 1, 1], 0.1).build().unwrap();
    let mut files: Vec<Vec<u8>> = ENCODINGS
        .iter()
        .map(|&e| to_bytes(&mesh, None, e))
        .collect();
    files.extend(
        [
            U64_HEADER_FLOAT32,
            BIG_ENDIAN,
            ZLIB_SEPARATE_BASE64,
            ZLIB_BIG_ENDIAN_U64,
            APPENDED_BASE64,
            TWO_PIECES,
        ]
        .map(|s| s.as_bytes().to_vec()),
    );
    files.push(APPENDED_RAW_ZLIB_U64.to_vec());
    files
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = read_bytes(&bytes, "vtu", Path::new("fuzz.vtu"));
    }

    #[test]
    fn mutated_or_truncated_valid_files_never_panic(
        which in 0usize..11,
        cut in any::<prop::sample::Index>(),
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..6),
    ) {
        let files = valid_files();
        let mut bytes = files[which % files.len()].clone();
        for (at, b) in edits {
            let i = at.index(bytes.len());
            bytes[i] = b;
        }
        let _ = read_bytes(&bytes, "vtu", Path::new("fuzz.vtu"));
        let keep = cut.index(bytes.len() + 1);
        let _ = read_bytes(&bytes[..keep], "vtu", Path::new("fuzz.vtu"));
    }
}
