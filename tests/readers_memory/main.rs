//! Every mesh reader under a memory cap: arbitrary bytes, and real and generated files of every
//! format truncated, with bytes changed and with counts made huge, never abort the process and
//! never take more memory than a small multiple of the file's size.
//!
//! Its own test binary because it counts allocations with a global allocator. Only the
//! thread that reads is counted (readers run on the calling thread), so tests running side by
//! side do not add to each other's peaks.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use lancet::mesh::generate::BoxGrid;
use lancet::mesh::io::vtu::{write_vtu_to, VtuEncoding, VtuOptions};
use lancet::mesh::io::{read_bytes, tetgen};
use lancet::mesh::TetMesh;
use proptest::prelude::*;

/// Counts, on a thread that asked for it, the bytes allocated now and their peak, and refuses
/// (the process then aborts) any allocation past a hard cap, so that a reader that tries to
/// take gigabytes fails the test instead of the machine.
struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static CURRENT: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

/// Far above any bound below, far below the machine's memory.
const HARD_CAP: isize = 1 << 30;

/// Count `delta` bytes more (or fewer) on this thread; false if that passes the hard cap.
fn count(delta: isize) -> bool {
    COUNTING
        .try_with(|on| {
            if !on.get() {
                return true;
            }
            let now = CURRENT.with(|c| c.get()) + delta;
            if delta > 0 && now > HARD_CAP {
                return false;
            }
            CURRENT.with(|c| c.set(now));
            PEAK.with(|p| p.set(p.get().max(now)));
            true
        })
        .unwrap_or(true)
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !count(layout.size() as isize) {
            return std::ptr::null_mut();
        }
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        count(-(layout.size() as isize));
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if !count(new_size as isize - layout.size() as isize) {
            return std::ptr::null_mut();
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Run `read` and return the most bytes it held at once (on this thread).
fn peak_of(read: impl FnOnce()) -> usize {
    CURRENT.with(|c| c.set(0));
    PEAK.with(|p| p.set(0));
    COUNTING.with(|on| on.set(true));
    read();
    COUNTING.with(|on| on.set(false));
    PEAK.with(|p| p.get()).max(0) as usize
}

/// Most bytes a reader may hold at once: `PER_BYTE` times the file's size plus `FIXED` (tables
/// and maps that start at a fixed size). A reader builds a mesh of what the file holds, never
/// of what its header declares, so its memory follows the file's size.
const PER_BYTE: usize = 32;
const FIXED: usize = 64 << 10;
/// A compressed `.vtu` inflates to more than its size: to at most what its pieces' declared
/// point and cell counts need (this many bytes per point or cell covers every array lancet
/// reads), and never more than zlib's largest ratio (1032 to 1) allows.
const PER_DECLARED: usize = 256;
const PER_COMPRESSED_BYTE: usize = 1100;

/// The bound for `bytes` read by the reader of `ext`.
fn bound(bytes: &[u8], ext: &str) -> usize {
    let inflated = if ext == "vtu" && contains(bytes, b"vtkZLibDataCompressor") {
        (PER_COMPRESSED_BYTE * bytes.len()).min(PER_DECLARED.saturating_mul(declared(bytes)))
    } else {
        0
    };
    PER_BYTE * bytes.len() + FIXED + inflated
}

/// The points and cells the pieces of a `.vtu` declare, summed (saturating).
fn declared(bytes: &[u8]) -> usize {
    let text = String::from_utf8_lossy(bytes);
    ["NumberOfPoints=\"", "NumberOfCells=\""]
        .iter()
        .flat_map(|attr| text.split(attr).skip(1))
        .filter_map(|rest| rest.split('"').next()?.trim().parse::<usize>().ok())
        .fold(0usize, usize::saturating_add)
}

/// Read `bytes` with the reader of `ext` (`node`: a TetGen pair, the `.node` half given, the
/// `.ele` half `ele`), under the bound; the result itself may be a mesh or an error.
fn read_within_bound(bytes: &[u8], ext: &str, ele: &[u8]) -> Result<(), String> {
    let len = bytes.len() + ele.len();
    let peak = peak_of(|| {
        let _ = if ext == "node" {
            tetgen::parse(bytes, ele, Path::new("m.node"), Path::new("m.ele"))
                .and_then(|raw| raw.finish(Path::new("m.node")))
        } else {
            read_bytes(bytes, ext, Path::new("mutated"))
        };
    });
    let limit = bound(bytes, ext) + PER_BYTE * ele.len();
    if std::env::var_os("READERS_MEMORY_VERBOSE").is_some() {
        eprintln!(
            "{ext}: {len} bytes, peak {peak} ({:.1} per byte)",
            peak as f64 / len.max(1) as f64
        );
    }
    if peak > limit {
        return Err(format!(
            "{ext} of {len} bytes held {peak} bytes at once; the bound is {limit}"
        ));
    }
    Ok(())
}

fn contains(hay: &[u8], needle: &[u8]) -> bool {
    hay.windows(needle.len()).any(|w| w == needle)
}

/// A file to mutate: its bytes, the extension that picks its reader, and for a TetGen pair the
/// `.ele` half (kept as it is).
#[derive(Debug, Clone)]
struct Seed {
    name: String,
    bytes: Vec<u8>,
    ext: &'static str,
    ele: Vec<u8>,
}

fn seed(name: &str, bytes: Vec<u8>, ext: &'static str) -> Seed {
    Seed {
        name: name.into(),
        bytes,
        ext,
        ele: Vec::new(),
    }
}

/// Files of every format the readers take: the real meshes when `LANCET_MESH_DIR` is set
/// (cut to 64 KiB, itself a truncation), and a small generated box written in each format.
fn seeds() -> &'static [Seed] {
    static SEEDS: OnceLock<Vec<Seed>> = OnceLock::new();
    SEEDS.get_or_init(read_seeds)
}

fn read_seeds() -> Vec<Seed> {
    let mut v = generated();
    let Some(dir) = std::env::var_os("LANCET_MESH_DIR").map(PathBuf::from) else {
        eprintln!("real meshes skipped: LANCET_MESH_DIR is not set");
        return v;
    };
    let read = |f: &str| {
        let mut b = std::fs::read(dir.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        b.truncate(64 * 1024);
        b
    };
    for (f, ext) in [
        ("sofa/liver.msh", "msh"),
        ("sofa/6_tetra_bad.msh", "msh"),
        ("polyfem-data/cubes_v41.msh", "msh"),
        ("polyfem-data/square_beam.mesh", "mesh"),
        ("sofa/cylinderPDMS12724Vol.vtk", "vtk"),
        ("sofa/volumetricTongue.vtu", "vtu"),
        ("vegafem/torus-easy.veg", "veg"),
    ] {
        v.push(seed(f, read(f), ext));
    }
    v.push(Seed {
        name: "armadillo".into(),
        bytes: read("positionbaseddynamics/armadillo_4k.node"),
        ext: "node",
        ele: read("positionbaseddynamics/armadillo_4k.ele"),
    });
    v
}

/// A 2 x 2 x 2 box (27 nodes, 48 tets) in every format: Gmsh 1, 2.2 (ASCII and binary) and
/// 4.1, Medit, Vega, TetGen, VTK legacy (ASCII and binary) and `.vtu` in each encoding.
fn generated() -> Vec<Seed> {
    let m = BoxGrid::cube_cells([2; 3], 0.01).build().unwrap();
    let (pts, tets) = arrays(&m);
    let mut v = Vec::new();

    let mut s = format!("$NOD\n{}\n", pts.len());
    for (i, p) in pts.iter().enumerate() {
        writeln!(s, "{} {:e} {:e} {:e}", i + 1, p[0], p[1], p[2]).unwrap();
    }
    writeln!(s, "$ENDNOD\n$ELM\n{}", tets.len()).unwrap();
    for (i, t) in tets.iter().enumerate() {
        let [a, b, c, d] = t.map(|n| n + 1);
        writeln!(s, "{} 4 1 1 4 {a} {b} {c} {d}", i + 1).unwrap();
    }
    v.push(seed("gmsh 1", (s + "$ENDELM\n").into_bytes(), "msh"));

    for binary in [false, true] {
        let mut b = format!("$MeshFormat\n2.2 {} 8\n", binary as u8).into_bytes();
        if binary {
            b.extend(1i32.to_le_bytes());
            b.push(b'\n');
        }
        b.extend(format!("$EndMeshFormat\n$Nodes\n{}\n", pts.len()).bytes());
        for (i, p) in pts.iter().enumerate() {
            if binary {
                b.extend((i as i32 + 1).to_le_bytes());
                p.iter().for_each(|c| b.extend(c.to_le_bytes()));
            } else {
                b.extend(format!("{} {:e} {:e} {:e}\n", i + 1, p[0], p[1], p[2]).bytes());
            }
        }
        b.extend(format!("$EndNodes\n$Elements\n{}\n", tets.len()).bytes());
        if binary {
            // One block: element type 4 (tet), count, two tags.
            [4, tets.len() as i32, 2]
                .iter()
                .for_each(|x| b.extend(x.to_le_bytes()));
        }
        for (i, t) in tets.iter().enumerate() {
            let [a, bb, c, d] = t.map(|n| n as i32 + 1);
            if binary {
                [i as i32 + 1, 1, 1, a, bb, c, d]
                    .iter()
                    .for_each(|x| b.extend(x.to_le_bytes()));
            } else {
                b.extend(format!("{} 4 2 1 1 {a} {bb} {c} {d}\n", i + 1).bytes());
            }
        }
        b.extend(b"$EndElements\n");
        v.push(seed(&format!("gmsh 2.2 binary {binary}"), b, "msh"));
    }

    let n = pts.len();
    let mut s = format!(
        "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 0 1\n1 0 0 0 1 1 1 0 0\n\
         $EndEntities\n$Nodes\n1 {n} 1 {n}\n3 1 0 {n}\n"
    );
    (1..=n).for_each(|i| writeln!(s, "{i}").unwrap());
    pts.iter()
        .for_each(|p| writeln!(s, "{:e} {:e} {:e}", p[0], p[1], p[2]).unwrap());
    let t = tets.len();
    writeln!(s, "$EndNodes\n$Elements\n1 {t} 1 {t}\n3 1 4 {t}").unwrap();
    for (i, tet) in tets.iter().enumerate() {
        let [a, b, c, d] = tet.map(|n| n + 1);
        writeln!(s, "{} {a} {b} {c} {d}", i + 1).unwrap();
    }
    v.push(seed("gmsh 4.1", (s + "$EndElements\n").into_bytes(), "msh"));

    let mut s = format!("MeshVersionFormatted 2\nDimension 3\nVertices\n{n}\n");
    pts.iter()
        .for_each(|p| writeln!(s, "{:e} {:e} {:e} 0", p[0], p[1], p[2]).unwrap());
    writeln!(s, "Tetrahedra {t}").unwrap();
    for tet in &tets {
        let [a, b, c, d] = tet.map(|n| n + 1);
        writeln!(s, "{a} {b} {c} {d} 1").unwrap();
    }
    v.push(seed("medit", (s + "End\n").into_bytes(), "mesh"));

    let mut s = format!("*VERTICES\n{n} 3 0 0\n");
    for (i, p) in pts.iter().enumerate() {
        writeln!(s, "{} {:e} {:e} {:e}", i + 1, p[0], p[1], p[2]).unwrap();
    }
    writeln!(s, "*ELEMENTS\nTETS\n{t} 4 0").unwrap();
    for (i, tet) in tets.iter().enumerate() {
        let [a, b, c, d] = tet.map(|n| n + 1);
        writeln!(s, "{} {a} {b} {c} {d}", i + 1).unwrap();
    }
    v.push(seed("vega", s.into_bytes(), "veg"));

    let mut node = format!("{n} 3 0 0\n");
    for (i, p) in pts.iter().enumerate() {
        writeln!(node, "{} {:e} {:e} {:e}", i + 1, p[0], p[1], p[2]).unwrap();
    }
    let mut ele = format!("{t} 4 0\n");
    for (i, tet) in tets.iter().enumerate() {
        let [a, b, c, d] = tet.map(|n| n + 1);
        writeln!(ele, "{} {a} {b} {c} {d}", i + 1).unwrap();
    }
    v.push(Seed {
        name: "tetgen".into(),
        bytes: node.into_bytes(),
        ext: "node",
        ele: ele.into_bytes(),
    });

    for binary in [false, true] {
        let mut b = format!(
            "# vtk DataFile Version 2.0\nbox\n{}\nDATASET UNSTRUCTURED_GRID\nPOINTS {n} double\n",
            if binary { "BINARY" } else { "ASCII" }
        )
        .into_bytes();
        for p in &pts {
            if binary {
                p.iter().for_each(|c| b.extend(c.to_be_bytes()));
            } else {
                b.extend(format!("{:e} {:e} {:e}\n", p[0], p[1], p[2]).bytes());
            }
        }
        b.extend(format!("\nCELLS {t} {}\n", 5 * t).bytes());
        for tet in &tets {
            if binary {
                b.extend(4i32.to_be_bytes());
                tet.iter().for_each(|&x| b.extend((x as i32).to_be_bytes()));
            } else {
                b.extend(format!("4 {} {} {} {}\n", tet[0], tet[1], tet[2], tet[3]).bytes());
            }
        }
        b.extend(format!("\nCELL_TYPES {t}\n").bytes());
        for _ in 0..t {
            if binary {
                b.extend(10i32.to_be_bytes());
            } else {
                b.extend(b"10\n");
            }
        }
        v.push(seed(&format!("vtk binary {binary}"), b, "vtk"));
    }

    for encoding in [
        VtuEncoding::Ascii,
        VtuEncoding::Binary,
        VtuEncoding::AppendedRaw,
        VtuEncoding::AppendedZlib,
    ] {
        let mut b = Vec::new();
        write_vtu_to(&mut b, &m, None, &VtuOptions { encoding }).unwrap();
        v.push(seed(&format!("vtu {encoding:?}"), b, "vtu"));
    }
    for s in &v {
        assert!(
            read_whole(s),
            "{}: the unmutated seed must read as a mesh",
            s.name
        );
    }
    v
}

fn read_whole(s: &Seed) -> bool {
    if s.ext == "node" {
        tetgen::parse(&s.bytes, &s.ele, Path::new("a.node"), Path::new("a.ele"))
            .and_then(|r| r.finish(Path::new("a.node")))
            .is_ok()
    } else {
        read_bytes(&s.bytes, s.ext, Path::new("seed")).is_ok()
    }
}

/// Positions and tets (as dense node indices) of a mesh.
fn arrays(m: &TetMesh) -> (Vec<[f64; 3]>, Vec<[u32; 4]>) {
    let dense = m.dense_nodes();
    let pts = dense
        .keys
        .iter()
        .map(|&k| {
            let p = m.rest(k);
            [p.x, p.y, p.z]
        })
        .collect();
    let tets = m
        .tets()
        .map(|(_, t)| t.nodes.map(|k| dense.index[k]))
        .collect();
    (pts, tets)
}

/// A change to a file: a byte set, a cut, or a huge number written over a digit (a count a
/// header declares, or an id).
#[derive(Debug, Clone)]
enum Mutation {
    Set(f64, u8),
    Cut(f64),
    Huge(f64, &'static str),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        4 => (0.0f64..1.0, any::<u8>()).prop_map(|(at, b)| Mutation::Set(at, b)),
        1 => (0.0f64..1.0).prop_map(Mutation::Cut),
        3 => (
            0.0f64..1.0,
            prop::sample::select(vec!["999999999999", "4294967295", "2147483647", "65536", "-1"])
        )
            .prop_map(|(at, n)| Mutation::Huge(at, n)),
    ]
}

fn mutate(bytes: &mut Vec<u8>, m: &Mutation) {
    let at = |f: f64, len: usize| ((len.saturating_sub(1)) as f64 * f) as usize;
    match *m {
        Mutation::Set(f, b) if !bytes.is_empty() => {
            let i = at(f, bytes.len());
            bytes[i] = b;
        }
        Mutation::Cut(f) => bytes.truncate(at(f, bytes.len())),
        Mutation::Huge(f, n) => {
            // The first digit at or after the place picked, replaced with the number.
            let start = at(f, bytes.len());
            if let Some(i) = (start..bytes.len()).find(|&i| bytes[i].is_ascii_digit()) {
                bytes.splice(i..=i, n.bytes());
            }
        }
        _ => {}
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_stay_within_the_memory_bound_of_every_reader(
        bytes in proptest::collection::vec(any::<u8>(), 0..4096),
        ext in prop::sample::select(vec!["msh", "mesh", "veg", "vtk", "vtu", "node"]),
    ) {
        let ele = bytes.clone();
        read_within_bound(&bytes, ext, &ele).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn mutated_files_of_every_format_stay_within_the_memory_bound(
        which in any::<prop::sample::Index>(),
        mutations in proptest::collection::vec(mutation(), 1..6),
    ) {
        let all = seeds();
        let s = which.get(all);
        let mut bytes = s.bytes.clone();
        for m in &mutations {
            mutate(&mut bytes, m);
        }
        read_within_bound(&bytes, s.ext, &s.ele)
            .map_err(|e| TestCaseError::fail(format!("{}: {e}", s.name)))?;
    }
}

/// The seeds themselves, read whole, stay within the bound too: the bound is what a valid
/// file needs, not only what a mangled one gets away with.
#[test]
fn whole_files_of_every_format_stay_within_the_memory_bound() {
    for s in seeds() {
        read_within_bound(&s.bytes, s.ext, &s.ele).unwrap_or_else(|e| panic!("{}: {e}", s.name));
    }
}

/// The check catches what it is for: a reader that sized a buffer from a declared count would
/// hold far more than the bound. (Stands in for such a reader: a vector sized from a count the
/// file declares.)
#[test]
fn the_bound_catches_an_allocation_sized_from_a_declared_count() {
    let declared: usize = "4000000".parse().unwrap();
    let peak = peak_of(|| {
        let v: Vec<[f64; 3]> = Vec::with_capacity(declared);
        std::hint::black_box(&v);
    });
    assert!(peak > bound(&[b'x'; 100], "msh"), "{peak}");
}

/// A `.vtu` whose four points come as 64 zlib blocks of a mebibyte of zeros each (a file of
/// about 100 kB): a reader that inflated before comparing with the declared counts held
/// 64 MiB for it (and aborted on a 16 MB file). It stays within the bound of its size.
#[test]
fn a_zlib_bomb_stays_within_the_bound() {
    use base64::Engine;
    use std::io::Write;
    let block = 1usize << 20;
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    z.write_all(&vec![0u8; block]).unwrap();
    let zeros = z.finish().unwrap();
    let mut points = Vec::new();
    for w in [64u32, block as u32, 0] {
        points.extend(w.to_le_bytes());
    }
    for _ in 0..64 {
        points.extend((zeros.len() as u32).to_le_bytes());
    }
    for _ in 0..64 {
        points.extend(&zeros);
    }
    let points = base64::engine::general_purpose::STANDARD.encode(points);
    let file = format!(
        r#"<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt32" compressor="vtkZLibDataCompressor">
<UnstructuredGrid><Piece NumberOfPoints="4" NumberOfCells="1">
<Points><DataArray type="Float64" Name="Points" NumberOfComponents="3" format="binary">{points}</DataArray></Points>
</Piece></UnstructuredGrid></VTKFile>"#
    );
    read_within_bound(file.as_bytes(), "vtu", &[]).unwrap();
}
