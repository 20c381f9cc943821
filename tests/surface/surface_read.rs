//! Reading render surfaces: the same sphere written as OBJ, binary and ASCII STL and binary
//! and ASCII PLY reads back as the same surface; polygons are triangulated and objects joined;
//! bad files give errors naming the file and what is wrong; no input panics.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use lancet::surface::read::{read_surface, read_surface_bytes, SurfaceFormat};
use lancet::surface::RenderSurface;
use lancet::Error;
use proptest::prelude::*;

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/surfaces/sphere.obj")
}

fn binary_stl(s: &RenderSurface) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend((s.triangles.len() as u32).to_le_bytes());
    for t in &s.triangles {
        b.extend([0f32; 3].iter().flat_map(|c| c.to_le_bytes()));
        for &v in t {
            for c in s.positions[v as usize] {
                b.extend((c as f32).to_le_bytes());
            }
        }
        b.extend([0u8; 2]);
    }
    b
}

fn ascii_stl(s: &RenderSurface) -> Vec<u8> {
    let mut o = String::from("solid sphere\n");
    for t in &s.triangles {
        o += "facet normal 0 0 0\nouter loop\n";
        for &v in t {
            let p = s.positions[v as usize];
            writeln!(
                o,
                "vertex {:e} {:e} {:e}",
                p[0] as f32, p[1] as f32, p[2] as f32
            )
            .unwrap();
        }
        o += "endloop\nendfacet\n";
    }
    o += "endsolid sphere\n";
    o.into_bytes()
}

fn ply(s: &RenderSurface, binary: bool) -> Vec<u8> {
    let format = if binary {
        "binary_little_endian"
    } else {
        "ascii"
    };
    let mut b = format!(
        "ply\nformat {format} 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
         property double z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        s.positions.len(),
        s.triangles.len()
    )
    .into_bytes();
    for p in &s.positions {
        if binary {
            b.extend(p.iter().flat_map(|c| c.to_le_bytes()));
        } else {
            b.extend(format!("{:?} {:?} {:?}\n", p[0], p[1], p[2]).into_bytes());
        }
    }
    for t in &s.triangles {
        if binary {
            b.push(3);
            b.extend(t.iter().flat_map(|&v| (v as i32).to_le_bytes()));
        } else {
            b.extend(format!("3 {} {} {}\n", t[0], t[1], t[2]).into_bytes());
        }
    }
    b
}

/// Each undirected edge of a closed, consistently oriented surface is used once each way.
fn closed_and_oriented(s: &RenderSurface) -> bool {
    let mut directed = std::collections::HashMap::new();
    for t in &s.triangles {
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    directed
        .iter()
        .all(|(&(a, b), &n)| n == 1 && directed.get(&(b, a)) == Some(&1))
}

/// The triangles as position triples, sorted: comparable across readers that number vertices
/// differently (STL merges repeated corners in its own order).
fn corner_sets(s: &RenderSurface, round: impl Fn(f64) -> f64) -> Vec<[[u64; 3]; 3]> {
    let mut v: Vec<[[u64; 3]; 3]> = s
        .triangles
        .iter()
        .map(|t| {
            let mut c = t.map(|i| s.positions[i as usize].map(|x| round(x).to_bits()));
            // Rotate so that the smallest corner comes first (keeps the orientation).
            let k = (0..3).min_by_key(|&k| c[k]).unwrap();
            c.rotate_left(k);
            c
        })
        .collect();
    v.sort();
    v
}

#[test]
fn every_format_reads_the_same_closed_sphere() {
    let obj = read_surface(fixture()).unwrap();
    assert_eq!((obj.positions.len(), obj.triangles.len()), (42, 80));
    assert!(
        closed_and_oriented(&obj),
        "the OBJ sphere is closed and oriented"
    );
    let dir = tempfile::tempdir().unwrap();
    let f32_round = |x: f64| x as f32 as f64;
    for (name, bytes, exact) in [
        ("binary.stl", binary_stl(&obj), false),
        ("ascii.stl", ascii_stl(&obj), false),
        ("ascii.ply", ply(&obj, false), true),
        ("binary.ply", ply(&obj, true), true),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let s = read_surface(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(s.triangles.len(), 80, "{name}");
        // STL repeats corners per triangle; the reader merges them back into 42 vertices.
        assert_eq!(s.positions.len(), 42, "{name}: shared vertices");
        assert!(closed_and_oriented(&s), "{name}: closed and oriented");
        let round = |x: f64| if exact { x } else { f32_round(x) };
        assert_eq!(
            corner_sets(&s, round),
            corner_sets(&obj, round),
            "{name}: the same triangles at the same places"
        );
    }
}

#[test]
fn polygons_are_triangulated_and_objects_joined() {
    let text = "o a\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n\
                o b\nv 0 0 1\nv 1 0 1\nv 0 1 1\nf 5/1/1 6/1/1 7/1/1\n";
    let s = read_surface_bytes(text.as_bytes(), SurfaceFormat::Obj, Path::new("two.obj")).unwrap();
    assert_eq!(s.positions.len(), 7);
    assert_eq!(s.triangles.len(), 3, "a quad is two triangles, plus one");
    // The second object's triangle names its own vertices, after the first object's.
    assert!(s.triangles.contains(&[4, 5, 6]), "{:?}", s.triangles);
    let quad: Vec<_> = s
        .triangles
        .iter()
        .filter(|t| t.iter().all(|&v| v < 4))
        .collect();
    assert_eq!(quad.len(), 2);
    let ply_quad = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
                    property float z\nelement face 1\nproperty list uchar uint vertex_index\n\
                    end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";
    let s =
        read_surface_bytes(ply_quad.as_bytes(), SurfaceFormat::Ply, Path::new("q.ply")).unwrap();
    assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3]]);
}

/// The message of reading `text` as `format`, which must fail as a parse error.
fn message(text: &str, format: SurfaceFormat, name: &str) -> String {
    let e =
        read_surface_bytes(text.as_bytes(), format, Path::new(name)).expect_err("the file is bad");
    assert!(matches!(e, Error::Parse(_)), "{e:?}");
    e.to_string()
}

#[test]
fn bad_files_name_the_file_and_the_problem() {
    let m = message(
        "v 0 0 0\nv 1 0 0\nv 1 x 0\nf 1 2 3\n",
        SurfaceFormat::Obj,
        "organ.obj",
    );
    assert!(m.starts_with("organ.obj: line 3:"), "{m}");
    let m = message(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 9\n",
        SurfaceFormat::Obj,
        "organ.obj",
    );
    assert!(m.contains("organ.obj: line 4:"), "{m}");
    let m = message(
        "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n",
        SurfaceFormat::Obj,
        "n.obj",
    );
    assert!(
        m.contains("n.obj") && m.contains("vertex 2") && m.contains("finite"),
        "{m}"
    );
    let m = message("v 0 0 0\nv 1 0 0\n", SurfaceFormat::Obj, "points.obj");
    assert!(m.contains("no triangles"), "{m}");
    let m = message(&"x".repeat(100), SurfaceFormat::Stl, "short.stl");
    assert!(m.starts_with("short.stl:") && m.contains("stl"), "{m}");
    let header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                  property float z\n";
    let m = message(
        &format!("{header}end_header\n0 0 0\n1 0 0\n0 1 0\n"),
        SurfaceFormat::Ply,
        "p.ply",
    );
    assert!(m.contains("p.ply") && m.contains("`face` element"), "{m}");
    let faces = "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let m = message(
        &format!("{header}{faces}0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"),
        SurfaceFormat::Ply,
        "p.ply",
    );
    assert!(m.contains("element 0") && m.contains("below 3"), "{m}");
    let e = read_surface("organ.dae").unwrap_err();
    assert!(
        matches!(e, Error::Unsupported(_)) && e.to_string().contains(".obj"),
        "{e}"
    );
    let e = read_surface("/nonexistent/organ.obj").unwrap_err();
    assert!(
        matches!(e, Error::Io { .. }) && e.to_string().contains("organ.obj"),
        "{e}"
    );
}

const FORMATS: [SurfaceFormat; 3] = [SurfaceFormat::Obj, SurfaceFormat::Stl, SurfaceFormat::Ply];

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(
        bytes in proptest::collection::vec(any::<u8>(), 0..2048),
        which in 0usize..3,
    ) {
        let _ = read_surface_bytes(&bytes, FORMATS[which], Path::new("arbitrary"));
    }

    #[test]
    fn mangled_files_never_panic(
        which in 0usize..5,
        cut in 0.0f64..1.0,
        flips in proptest::collection::vec((0.0f64..1.0, any::<u8>()), 0..8),
    ) {
        let obj = read_surface(fixture()).unwrap();
        let (mut b, format) = match which {
            0 => (std::fs::read(fixture()).unwrap(), SurfaceFormat::Obj),
            1 => (binary_stl(&obj), SurfaceFormat::Stl),
            2 => (ascii_stl(&obj), SurfaceFormat::Stl),
            3 => (ply(&obj, false), SurfaceFormat::Ply),
            _ => (ply(&obj, true), SurfaceFormat::Ply),
        };
        for (at, byte) in flips {
            let i = ((b.len() - 1) as f64 * at) as usize;
            b[i] = byte;
        }
        b.truncate(((b.len() as f64) * (0.5 + cut / 2.0)) as usize);
        let _ = read_surface_bytes(&b, format, Path::new("mangled"));
    }
}
