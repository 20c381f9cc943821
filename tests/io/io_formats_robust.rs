//! The TetGen, Medit, Vega and legacy VTK readers against arbitrary and corrupted input: any
//! result is fine, a panic is not.

use std::path::Path;

use super::io_formats::{
    write_medit, write_tetgen, write_vega, write_vtk51, write_vtk_ascii, write_vtk_binary, VTK_HEAD,
};
use lancet::mesh::generate::BoxGrid;
use lancet::mesh::io::{self, tetgen};
use proptest::prelude::*;

/// A valid small file of each format, as bytes (`tetgen` as `node|ele`).
fn valid(format: &str) -> Vec<u8> {
    let m = BoxGrid::cube_cells([1, 1, 1], 0.5).build().unwrap();
    match format {
        "tetgen" => {
            let (n, e) = write_tetgen(&m, 0);
            format!("{n}|{e}").into_bytes()
        }
        "mesh" => write_medit(&m).into_bytes(),
        "veg" => write_vega(&m).into_bytes(),
        "vtk" => write_vtk_ascii(&m).into_bytes(),
        "vtkbin" => write_vtk_binary(&m),
        "vtk51" => write_vtk51(&m).into_bytes(),
        _ => unreachable!(),
    }
}

/// Apply byte mutations and a truncation to `bytes`.
fn mutate(mut bytes: Vec<u8>, edits: &[(usize, u8)], cut: usize) -> Vec<u8> {
    for &(at, b) in edits {
        if !bytes.is_empty() {
            let i = at % bytes.len();
            bytes[i] = b;
        }
    }
    // Half of the cases keep the whole file, so that the edits are seen deep inside it.
    if cut % 2 == 1 {
        bytes.truncate(cut / 2 % (bytes.len() + 1));
    }
    bytes
}

/// Run a reader on bytes; any result is fine, a panic is not.
fn survive(format: &str, bytes: &[u8]) {
    let (ext, bytes) = match format {
        "vtkbin" | "vtk51" => ("vtk", bytes.to_vec()),
        "tetgen" if !bytes.contains(&b'|') => {
            let _ = tetgen::parse(bytes, bytes, Path::new("f.node"), Path::new("f.ele"));
            return;
        }
        "tetgen" => {
            let i = bytes.iter().position(|&b| b == b'|').unwrap();
            let _ = tetgen::parse(
                &bytes[..i],
                &bytes[i + 1..],
                Path::new("f.node"),
                Path::new("f.ele"),
            )
            .and_then(|r| r.finish(Path::new("f.ele")));
            return;
        }
        f => (f, bytes.to_vec()),
    };
    let _ = io::read_bytes(&bytes, ext, Path::new("f"));
}

fn edits() -> impl Strategy<Value = Vec<(usize, u8)>> {
    // Bias replacement bytes toward characters that change meaning in these formats.
    let byte = prop_oneof![
        any::<u8>(),
        prop::sample::select(b"0123456789-+.eE \n*,#|9".to_vec()),
    ];
    prop::collection::vec((any::<usize>(), byte), 0..6)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn tetgen_reader_never_panics_on_arbitrary_or_corrupted_input(
        junk in prop::collection::vec(any::<u8>(), 0..400),
        e in edits(),
        cut in any::<usize>(),
    ) {
        survive("tetgen", &junk);
        survive("tetgen", &mutate(valid("tetgen"), &e, cut));
    }

    #[test]
    fn medit_reader_never_panics_on_arbitrary_or_corrupted_input(
        junk in prop::collection::vec(any::<u8>(), 0..400),
        e in edits(),
        cut in any::<usize>(),
    ) {
        survive("mesh", &junk);
        survive("mesh", &mutate(valid("mesh"), &e, cut));
    }

    #[test]
    fn vega_reader_never_panics_on_arbitrary_or_corrupted_input(
        junk in prop::collection::vec(any::<u8>(), 0..400),
        e in edits(),
        cut in any::<usize>(),
    ) {
        survive("veg", &junk);
        survive("veg", &mutate(valid("veg"), &e, cut));
    }

    #[test]
    fn vtk_legacy_reader_never_panics_on_arbitrary_or_corrupted_input(
        junk in prop::collection::vec(any::<u8>(), 0..400),
        e in edits(),
        cut in any::<usize>(),
    ) {
        let mut headed = VTK_HEAD.as_bytes().to_vec();
        headed.extend(&junk);
        survive("vtk", &junk);
        survive("vtk", &headed);
        survive("vtk", &mutate(valid("vtk"), &e, cut));
        survive("vtkbin", &mutate(valid("vtkbin"), &e, cut));
        survive("vtk51", &mutate(valid("vtk51"), &e, cut));
    }
}
