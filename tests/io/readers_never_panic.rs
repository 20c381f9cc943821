//! No reader panics on any input: real mesh files truncated and with random bytes changed, and
//! arbitrary bytes, all come back as `Ok` or a clear `Err`.

use std::path::{Path, PathBuf};

use lancet::mesh::io::read_bytes;
use proptest::prelude::*;

/// Real meshes of every single-file format, with the extension that picks their reader.
const REAL: &[(&str, &str)] = &[
    ("sofa/liver.msh", "msh"),
    ("sofa/6_tetra_bad.msh", "msh"),
    ("polyfem-data/square_beam.mesh", "mesh"),
    ("sofa/cylinderPDMS12724Vol.vtk", "vtk"),
    ("sofa/volumetricTongue.vtu", "vtu"),
];

fn mesh_dir() -> Option<PathBuf> {
    std::env::var_os("LANCET_MESH_DIR").map(PathBuf::from)
}

/// The first `cap` bytes of each real file (large files are cut to keep cases fast; a cut file
/// is itself a truncation case).
fn real_files(cap: usize) -> Vec<(Vec<u8>, &'static str)> {
    let Some(dir) = mesh_dir() else {
        eprintln!("skipped real files: LANCET_MESH_DIR is not set");
        return Vec::new();
    };
    REAL.iter()
        .map(|(f, ext)| {
            let mut b = std::fs::read(dir.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
            b.truncate(cap);
            (b, *ext)
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    #[test]
    fn mangled_real_files_never_panic(
        which in 0usize..REAL.len(),
        cut in 0.0f64..1.0,
        flips in proptest::collection::vec((0.0f64..1.0, any::<u8>()), 0..8),
    ) {
        let files = real_files(64 * 1024);
        if let Some((bytes, ext)) = files.get(which) {
            let mut b = bytes.clone();
            for (at, byte) in flips {
                if !b.is_empty() {
                    let i = ((b.len() - 1) as f64 * at) as usize;
                    b[i] = byte;
                }
            }
            b.truncate(((b.len() as f64) * (0.5 + cut / 2.0)) as usize);
            let _ = read_bytes(&b, ext, Path::new("mangled"));
        }
    }

    #[test]
    fn arbitrary_bytes_never_panic_any_reader(
        bytes in proptest::collection::vec(any::<u8>(), 0..2048),
        ext in prop::sample::select(vec!["msh", "mesh", "veg", "vtk", "vtu"]),
    ) {
        let _ = read_bytes(&bytes, ext, Path::new("arbitrary"));
    }

    #[test]
    fn header_prefixed_garbage_never_panics(
        header in prop::sample::select(vec![
            ("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n", "msh"),
            ("$MeshFormat\n2.2 1 8\n", "msh"),
            ("$MeshFormat\n4.1 1 8\n", "msh"),
            ("$NOD\n", "msh"),
            ("MeshVersionFormatted 1\nDimension 3\n", "mesh"),
            ("*VERTICES\n", "veg"),
            ("# vtk DataFile Version 2.0\nx\nBINARY\nDATASET UNSTRUCTURED_GRID\n", "vtk"),
            ("<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece ", "vtu"),
        ]),
        tail in proptest::collection::vec(any::<u8>(), 0..1024),
    ) {
        let (h, ext) = header;
        let mut b = h.as_bytes().to_vec();
        b.extend(tail);
        let _ = read_bytes(&b, ext, Path::new("garbage"));
    }
}

#[test]
fn truncating_a_real_file_anywhere_gives_an_error_not_a_wrong_mesh() {
    // Cutting a valid file short must not silently load fewer elements.
    for (bytes, ext) in real_files(usize::MAX) {
        let full = read_bytes(&bytes, ext, Path::new("full")).expect("the full file reads");
        for frac in [0.1, 0.35, 0.6, 0.9] {
            let cut = &bytes[..(bytes.len() as f64 * frac) as usize];
            if let Ok(m) = read_bytes(cut, ext, Path::new("cut")) {
                panic!(
                    "{ext} file cut at {frac} read as a mesh of {} tets (full: {})",
                    m.mesh.tet_count(),
                    full.mesh.tet_count()
                );
            }
        }
    }
}
