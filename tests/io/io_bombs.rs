//! Files built to make a reader use far more memory than their size: they are refused before
//! the memory is taken.

use std::io::Write;
use std::path::Path;

use base64::Engine;
use lancet::mesh::io::read_bytes;

/// `data` as VTK compressed binary: the header (blocks, block size, last block size,
/// compressed sizes; UInt32) and the zlib blocks, in one base64 stream.
fn zlib_b64(data: &[u8], block: usize) -> String {
    let blocks: Vec<Vec<u8>> = data.chunks(block).map(compress).collect();
    zlib_b64_blocks(&blocks, block as u32, (data.len() % block) as u32)
}

fn compress(chunk: &[u8]) -> Vec<u8> {
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    z.write_all(chunk).unwrap();
    z.finish().unwrap()
}

fn zlib_b64_blocks(blocks: &[Vec<u8>], block: u32, last: u32) -> String {
    let mut bytes = Vec::new();
    for w in [blocks.len() as u32, block, last] {
        bytes.extend(w.to_le_bytes());
    }
    for b in blocks {
        bytes.extend((b.len() as u32).to_le_bytes());
    }
    for b in blocks {
        bytes.extend(b);
    }
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// A one-tet `.vtu` with compressed arrays; `points` replaces the Points array's data.
fn one_tet(points: &str, connectivity: &str) -> Vec<u8> {
    let ints = |v: &[i32]| {
        zlib_b64(
            &v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<_>>(),
            64,
        )
    };
    format!(
        r#"<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt32" compressor="vtkZLibDataCompressor">
<UnstructuredGrid><Piece NumberOfPoints="4" NumberOfCells="1">
<Points><DataArray type="Float64" Name="Points" NumberOfComponents="3" format="binary">{points}</DataArray></Points>
<Cells>
<DataArray type="Int32" Name="connectivity" NumberOfComponents="1" format="binary">{connectivity}</DataArray>
<DataArray type="Int32" Name="offsets" NumberOfComponents="1" format="binary">{}</DataArray>
<DataArray type="UInt8" Name="types" NumberOfComponents="1" format="binary">{}</DataArray>
</Cells></Piece></UnstructuredGrid></VTKFile>"#,
        ints(&[4]),
        zlib_b64(&[10], 64),
    )
    .into_bytes()
}

fn tet_points() -> String {
    let p: [f64; 12] = [0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1.];
    zlib_b64(
        &p.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<_>>(),
        64,
    )
}

fn tet_connectivity() -> String {
    let c: [i32; 4] = [0, 1, 2, 3];
    zlib_b64(
        &c.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<_>>(),
        64,
    )
}

/// The helper's file is itself valid: one tet.
#[test]
fn the_compressed_one_tet_file_reads() {
    let m = read_bytes(
        &one_tet(&tet_points(), &tet_connectivity()),
        "vtu",
        Path::new("t.vtu"),
    )
    .unwrap();
    assert_eq!(m.mesh.tet_count(), 1);
}

/// 64 blocks of a mebibyte of zeros each (a file of about 100 kB) for a piece whose four
/// points need 96 bytes: inflating it first once took 64 MiB here (and 2 GB for a 2.6 MB
/// file). It is refused from its header, naming both sizes, before anything is inflated.
#[test]
fn a_zlib_bomb_in_the_points_is_refused_before_it_is_inflated() {
    let block = 1usize << 20;
    let zeros = compress(&vec![0u8; block]);
    let bomb = zlib_b64_blocks(&vec![zeros; 64], block as u32, 0);
    let file = one_tet(&bomb, &tet_connectivity());
    assert!(file.len() < 200_000, "{} bytes", file.len());
    let err = read_bytes(&file, "vtu", Path::new("bomb.vtu")).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains(&format!("declares {} bytes", 64 * block)),
        "{msg}"
    );
    assert!(msg.contains("the 96 bytes"), "{msg}");
}

/// The blocks need not even be valid zlib: the sizes are compared first.
#[test]
fn oversized_compressed_data_is_refused_whatever_its_blocks_hold() {
    let garbage = vec![vec![0xAB_u8; 64]; 4];
    // Four blocks of 64 bytes declared for 16 bytes of connectivity.
    let conn = zlib_b64_blocks(&garbage, 64, 0);
    let err = read_bytes(&one_tet(&tet_points(), &conn), "vtu", Path::new("c.vtu")).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("declares 256 bytes"), "{msg}");
    assert!(msg.contains("the 16 bytes"), "{msg}");
}
