//! Writing a [`TetMesh`] and its current positions as a `.vtu` file for ParaView.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use base64::Engine;
use nalgebra::Point3;

use crate::error::{Error, Result};
use crate::mesh::quality::tet_quality;
use crate::mesh::TetMesh;

/// Uncompressed size of a zlib block; VTK's default, so readers size their buffers as usual.
const ZLIB_BLOCK: usize = 32 * 1024;

/// How the arrays of a written `.vtu` are encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum VtuEncoding {
    /// Decimal text: readable and diffable, large and slow to read. Floats are written with
    /// the shortest representation that reads back to the same bits.
    Ascii,
    /// Base64 inside each `<DataArray>`: valid XML throughout, a third larger than raw.
    Binary,
    /// Raw little-endian bytes in an `<AppendedData>` section after the XML.
    ///
    /// The default: ParaView reads each array with one read straight into memory, with no
    /// base64 decoding and no inflating, so this is the fastest to open and to write. Float64
    /// positions and displacements barely compress, so zlib saves little on simulation output.
    #[default]
    AppendedRaw,
    /// Like [`VtuEncoding::AppendedRaw`], compressed with zlib in 32 KiB blocks: smaller on
    /// disk (mostly the connectivity), slower to write and open.
    AppendedZlib,
}

/// Options of [`write_vtu`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct VtuOptions {
    /// How arrays are encoded.
    pub encoding: VtuEncoding,
}

/// Element data of an array to write.
enum Data {
    F64(Vec<f64>),
    I64(Vec<i64>),
    I32(Vec<i32>),
    U8(Vec<u8>),
}

impl Data {
    fn type_name(&self) -> &'static str {
        match self {
            Data::F64(_) => "Float64",
            Data::I64(_) => "Int64",
            Data::I32(_) => "Int32",
            Data::U8(_) => "UInt8",
        }
    }

    /// The values as little-endian bytes (the byte order declared in the file).
    fn le_bytes(&self) -> Vec<u8> {
        match self {
            Data::F64(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::I64(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::I32(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::U8(v) => v.clone(),
        }
    }

    /// Write the values as text, `per_line` to a line.
    fn write_ascii(&self, w: &mut dyn Write, per_line: usize) -> io::Result<()> {
        // `{:e}` prints the shortest digits that parse back to the same f64.
        match self {
            Data::F64(v) => ascii_lines(w, v, per_line, |w, x| write!(w, "{x:e}")),
            Data::I64(v) => ascii_lines(w, v, per_line, |w, x| write!(w, "{x}")),
            Data::I32(v) => ascii_lines(w, v, per_line, |w, x| write!(w, "{x}")),
            Data::U8(v) => ascii_lines(w, v, per_line, |w, x| write!(w, "{x}")),
        }
    }
}

fn ascii_lines<T>(
    w: &mut dyn Write,
    values: &[T],
    per_line: usize,
    mut one: impl FnMut(&mut dyn Write, &T) -> io::Result<()>,
) -> io::Result<()> {
    for chunk in values.chunks(per_line.max(1)) {
        w.write_all(b"          ")?;
        for (i, x) in chunk.iter().enumerate() {
            if i > 0 {
                w.write_all(b" ")?;
            }
            one(w, x)?;
        }
        w.write_all(b"\n")?;
    }
    Ok(())
}

/// A named array.
struct Array {
    name: &'static str,
    components: usize,
    data: Data,
}

impl Array {
    fn new(name: &'static str, components: usize, data: Data) -> Self {
        Array {
            name,
            components,
            data,
        }
    }
}

/// Everything written for one mesh, grouped as in the file.
struct Grid {
    points: usize,
    cells: usize,
    point_data: Vec<Array>,
    cell_data: Vec<Array>,
    coords: Array,
    cell_arrays: Vec<Array>,
}

/// Write `mesh` to `path` as a VTK XML unstructured grid.
///
/// `positions` are the current positions in [`TetMesh::dense_nodes`] order (`None`: the rest
/// positions). Points are the current positions; point data `displacement` (current − rest)
/// and `rest_position`; cell data `region`, `quality` (volume-length ratio) and `volume`
/// (signed), both of the current shape so that inverted tets show. Cells follow
/// [`TetMesh::tets`] order.
///
/// Non-finite positions (a diverged run) are written as they are so that they can be
/// inspected; lancet's own reader refuses such a file.
///
/// The file is written beside `path` under a temporary name and renamed over it, so an
/// interrupted write never leaves a partial file (nor a half-overwritten input mesh).
pub fn write_vtu(
    path: &Path,
    mesh: &TetMesh,
    positions: Option<&[[f64; 3]]>,
    opts: &VtuOptions,
) -> Result<()> {
    write_vtu_synced(path, mesh, positions, opts, true)
}

/// [`write_vtu`], syncing the file to disk before the rename only when `sync` is set: a
/// series syncs its frames in batches instead (see [`crate::mesh::io::pvd::PvdWriter`]).
pub(crate) fn write_vtu_synced(
    path: &Path,
    mesh: &TetMesh,
    positions: Option<&[[f64; 3]]>,
    opts: &VtuOptions,
    sync: bool,
) -> Result<()> {
    let grid = grid(mesh, positions)?;
    replace_file(path, sync, |w| write_grid(w, &grid, opts))
}

/// Write `mesh` as `.vtu` to any writer; see [`write_vtu`] for the content. I/O errors are
/// reported with the path `<writer>`.
pub fn write_vtu_to<W: Write>(
    w: &mut W,
    mesh: &TetMesh,
    positions: Option<&[[f64; 3]]>,
    opts: &VtuOptions,
) -> Result<()> {
    let grid = grid(mesh, positions)?;
    write_grid(w, &grid, opts).map_err(|e| Error::io("<writer>", e))
}

/// Write a file by writing a temporary file in the same directory (same file system, so the
/// rename is atomic) and renaming it over `path`; with `sync`, the temporary file is synced to
/// disk before the rename. Unsynced, the file is still whole or absent for any reader, and
/// after the process is killed (the system holds the written pages); only a crash of the
/// system itself can lose it.
pub(crate) fn replace_file(
    path: &Path,
    sync: bool,
    write: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> Result<()> {
    let tmp = temp_path(path);
    let result = (|| {
        let mut w = BufWriter::new(File::create(&tmp)?);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        if sync {
            file.sync_all()?;
        }
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        // Best effort: a leftover temporary file is only clutter.
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

/// `dir/.name.<pid>.tmp`: hidden, and distinct per process so parallel writers do not collide.
/// [`is_temp_of`] recognises them, so that the leftovers of a killed writer can be removed.
fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// Gather the arrays to write.
fn grid(mesh: &TetMesh, positions: Option<&[[f64; 3]]>) -> Result<Grid> {
    let dense = mesh.dense_nodes();
    let rest: Vec<[f64; 3]> = dense
        .keys
        .iter()
        .map(|&k| {
            let p = mesh.rest(k);
            [p.x, p.y, p.z]
        })
        .collect();
    let current = match positions {
        Some(p) if p.len() != rest.len() => {
            return Err(Error::Mesh(format!(
                "{} positions given for {} nodes; give one per node in dense_nodes() order",
                p.len(),
                rest.len()
            )))
        }
        Some(p) => p,
        None => &rest[..],
    };
    let displacement: Vec<f64> = current
        .iter()
        .zip(&rest)
        .flat_map(|(c, r)| [c[0] - r[0], c[1] - r[1], c[2] - r[2]])
        .collect();
    let n_tets = mesh.tet_count();
    let mut connectivity = Vec::with_capacity(4 * n_tets);
    let mut region = Vec::with_capacity(n_tets);
    let mut quality = Vec::with_capacity(n_tets);
    let mut volume = Vec::with_capacity(n_tets);
    for (_, tet) in mesh.tets() {
        let idx = tet.nodes.map(|k| dense.index[k]);
        connectivity.extend(idx.map(i64::from));
        let p = idx.map(|i| Point3::from(current[i as usize]));
        let q = tet_quality(&p);
        region.push(tet.region);
        quality.push(q.volume_length_ratio);
        volume.push(q.volume);
    }
    let offsets = (1..=n_tets as i64).map(|i| 4 * i).collect();
    Ok(Grid {
        points: rest.len(),
        cells: n_tets,
        point_data: vec![
            Array::new("displacement", 3, Data::F64(displacement)),
            Array::new("rest_position", 3, Data::F64(rest.concat())),
        ],
        cell_data: vec![
            Array::new("region", 1, Data::I32(region)),
            Array::new("quality", 1, Data::F64(quality)),
            Array::new("volume", 1, Data::F64(volume)),
        ],
        coords: Array::new("Points", 3, Data::F64(current.concat())),
        cell_arrays: vec![
            Array::new("connectivity", 1, Data::I64(connectivity)),
            Array::new("offsets", 1, Data::I64(offsets)),
            Array::new("types", 1, Data::U8(vec![10; n_tets])),
        ],
    })
}

/// Write the XML, and the appended section if the encoding has one.
fn write_grid(w: &mut dyn Write, g: &Grid, opts: &VtuOptions) -> io::Result<()> {
    let enc = opts.encoding;
    let compressor = if enc == VtuEncoding::AppendedZlib {
        " compressor=\"vtkZLibDataCompressor\""
    } else {
        ""
    };
    // UInt64 headers keep arrays over 4 GiB valid; every VTK since 6.2 reads them.
    writeln!(w, "<?xml version=\"1.0\"?>")?;
    writeln!(
        w,
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" \
         header_type=\"UInt64\"{compressor}>"
    )?;
    writeln!(w, "  <UnstructuredGrid>")?;
    writeln!(
        w,
        "    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">",
        g.points, g.cells
    )?;
    let mut appended: Vec<Vec<u8>> = Vec::new();
    let mut offset = 0usize;
    let sections: [(&str, &str, Vec<&Array>); 4] = [
        (
            "PointData",
            " Vectors=\"displacement\"",
            g.point_data.iter().collect(),
        ),
        (
            "CellData",
            " Scalars=\"region\"",
            g.cell_data.iter().collect(),
        ),
        ("Points", "", vec![&g.coords]),
        ("Cells", "", g.cell_arrays.iter().collect()),
    ];
    for (tag, attrs, arrays) in sections {
        writeln!(w, "      <{tag}{attrs}>")?;
        for a in arrays {
            write_array(w, a, enc, &mut appended, &mut offset)?;
        }
        writeln!(w, "      </{tag}>")?;
    }
    writeln!(w, "    </Piece>")?;
    writeln!(w, "  </UnstructuredGrid>")?;
    if !appended.is_empty() {
        w.write_all(b"  <AppendedData encoding=\"raw\">\n   _")?;
        for block in &appended {
            w.write_all(block)?;
        }
        w.write_all(b"\n  </AppendedData>\n")?;
    }
    writeln!(w, "</VTKFile>")
}

/// Write one `<DataArray>`; for appended encodings queue its block and advance `offset`.
fn write_array(
    w: &mut dyn Write,
    a: &Array,
    enc: VtuEncoding,
    appended: &mut Vec<Vec<u8>>,
    offset: &mut usize,
) -> io::Result<()> {
    let head = format!(
        "        <DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\"",
        a.data.type_name(),
        a.name,
        a.components
    );
    // Vectors one to a line, tets one to a line, scalars six to a line.
    let per_line = match (a.name, a.components) {
        ("connectivity", _) => 4,
        (_, 1) => 6,
        (_, c) => c,
    };
    match enc {
        VtuEncoding::Ascii => {
            writeln!(w, "{head} format=\"ascii\">")?;
            a.data.write_ascii(w, per_line)?;
            writeln!(w, "        </DataArray>")
        }
        VtuEncoding::Binary => {
            writeln!(w, "{head} format=\"binary\">")?;
            // Uncompressed inline data is one base64 stream of header and data, as VTK reads it.
            let data = a.data.le_bytes();
            let mut block = (data.len() as u64).to_le_bytes().to_vec();
            block.extend_from_slice(&data);
            let text = base64::engine::general_purpose::STANDARD.encode(&block);
            writeln!(w, "          {text}")?;
            writeln!(w, "        </DataArray>")
        }
        VtuEncoding::AppendedRaw | VtuEncoding::AppendedZlib => {
            writeln!(w, "{head} format=\"appended\" offset=\"{offset}\"/>")?;
            let data = a.data.le_bytes();
            let block = if enc == VtuEncoding::AppendedZlib {
                zlib_block(&data)?
            } else {
                let mut b = (data.len() as u64).to_le_bytes().to_vec();
                b.extend_from_slice(&data);
                b
            };
            *offset += block.len();
            appended.push(block);
            Ok(())
        }
    }
}

/// VTK's compressed layout: `[blocks, block size, last block size, compressed sizes...]`
/// (UInt64) followed by the zlib streams of the blocks.
fn zlib_block(data: &[u8]) -> io::Result<Vec<u8>> {
    let mut streams = Vec::new();
    for chunk in data.chunks(ZLIB_BLOCK) {
        // Fast compression: frames are written while the simulation waits.
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
        z.write_all(chunk)?;
        streams.push(z.finish()?);
    }
    let last = data.len() % ZLIB_BLOCK;
    let mut out = Vec::new();
    for word in [streams.len(), ZLIB_BLOCK, last] {
        out.extend_from_slice(&(word as u64).to_le_bytes());
    }
    for s in &streams {
        out.extend_from_slice(&(s.len() as u64).to_le_bytes());
    }
    for s in &streams {
        out.extend_from_slice(s);
    }
    Ok(out)
}

/// Whether `file_name` is a temporary file [`replace_file`] makes (by any process) while it
/// writes a file named `target`: `.<target>.<pid>.tmp`.
pub(crate) fn is_temp_of(file_name: &str, target: &str) -> bool {
    file_name
        .strip_prefix('.')
        .and_then(|r| r.strip_prefix(target))
        .and_then(|r| r.strip_prefix('.'))
        .and_then(|r| r.strip_suffix(".tmp"))
        .is_some_and(|pid| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
}
