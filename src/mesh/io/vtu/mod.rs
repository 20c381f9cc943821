//! VTK XML unstructured grids (`.vtu`): reading here (the XML structure in `xml.rs`, array
//! content in `decode.rs`, a piece's points and cells in `piece.rs`), writing in [`write_vtu`].
//!
//! The reader handles what ParaView, VTK, meshio and SOFA write: `ascii`, inline `binary`
//! (base64) and `appended` (raw or base64) arrays, optional zlib compression, UInt32 or UInt64
//! headers, either byte order, and several pieces (concatenated). Only the arrays a mesh needs
//! are decoded: `Points`, the three `Cells` arrays and one region-like `CellData` array.
//!
//! Sizes written in the file are never trusted for allocation: buffers grow only as real data is
//! decoded, and a zlib block may not claim more output than deflate can produce from its input.

mod decode;
mod piece;
mod write;
mod xml;

use xml::scan;

pub(crate) use write::{is_temp_of, replace_file, write_vtu_synced};
pub use write::{write_vtu, write_vtu_to, VtuEncoding, VtuOptions};

use std::path::Path;

use super::vtk_cells::CellTally;
use super::{Format, RawMesh};
use crate::error::{Error, Location, Result};

/// Deflate cannot expand data more than about 1032:1; a block claiming more is corrupt (or
/// hostile), and refusing it bounds memory by the input size.
const MAX_INFLATE_RATIO: u64 = 1100;

/// `CellData` names taken as region tags, by priority (matched case-insensitively as substrings).
const REGION_NAMES: [&str; 6] = [
    "region",
    "material",
    "gmsh:physical",
    "physical",
    "cellentityids",
    "tag",
];

/// Parse a `.vtu` file into a [`RawMesh`]; `path` is used in messages only.
pub fn parse(bytes: &[u8], path: &Path) -> Result<RawMesh> {
    let doc = scan(bytes, path)?;
    let mut raw = RawMesh::new(Format::Vtu);
    let mut counts = CellTally::default();
    let mut region_names: Vec<String> = Vec::new();
    for piece in &doc.pieces {
        if let Some(name) = doc.add_piece(piece, &mut raw, &mut counts)? {
            if !region_names.contains(&name) {
                region_names.push(name);
            }
        }
    }
    counts.notes(&mut raw.notes);
    if doc.pieces.len() > 1 {
        raw.notes.push(format!(
            "read {} pieces and joined them into one mesh",
            doc.pieces.len()
        ));
    }
    for name in region_names {
        raw.notes
            .push(format!("region tags taken from cell data array {name:?}"));
    }
    Ok(raw)
}

/// Element types of `DataArray`s.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float32,
    Float64,
}

impl Scalar {
    fn from_name(s: &str) -> Option<Self> {
        Some(match s {
            "Int8" | "Char" => Scalar::Int8,
            "UInt8" | "UChar" => Scalar::UInt8,
            "Int16" => Scalar::Int16,
            "UInt16" => Scalar::UInt16,
            "Int32" => Scalar::Int32,
            "UInt32" => Scalar::UInt32,
            "Int64" => Scalar::Int64,
            "UInt64" => Scalar::UInt64,
            "Float32" => Scalar::Float32,
            "Float64" => Scalar::Float64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::Int8 | Scalar::UInt8 => 1,
            Scalar::Int16 | Scalar::UInt16 => 2,
            Scalar::Int32 | Scalar::UInt32 | Scalar::Float32 => 4,
            Scalar::Int64 | Scalar::UInt64 | Scalar::Float64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::Float32 | Scalar::Float64)
    }

    /// Whether an integer value fits this type (for ascii data, which carries no width).
    fn fits(self, v: i64) -> bool {
        let (lo, hi) = match self {
            Scalar::Int8 => (i8::MIN as i64, i8::MAX as i64),
            Scalar::UInt8 => (0, u8::MAX as i64),
            Scalar::Int16 => (i16::MIN as i64, i16::MAX as i64),
            Scalar::UInt16 => (0, u16::MAX as i64),
            Scalar::Int32 => (i32::MIN as i64, i32::MAX as i64),
            Scalar::UInt32 => (0, u32::MAX as i64),
            Scalar::UInt64 => (0, i64::MAX),
            _ => (i64::MIN, i64::MAX),
        };
        (lo..=hi).contains(&v)
    }
}

/// How binary data is laid out, from the `<VTKFile>` attributes.
#[derive(Debug, Clone, Copy, Default)]
struct Binary {
    big_endian: bool,
    header64: bool,
    zlib: bool,
}

impl Binary {
    fn header_size(self) -> usize {
        if self.header64 {
            8
        } else {
            4
        }
    }

    /// The header word `i` of `data`, or `None` past its end.
    fn word(self, data: &[u8], i: usize) -> Option<u64> {
        let n = self.header_size();
        let start = i.checked_mul(n)?;
        let b = data.get(start..start.checked_add(n)?)?;
        let mut a = [0u8; 8];
        if self.big_endian {
            a[8 - n..].copy_from_slice(b);
            Some(u64::from_be_bytes(a))
        } else {
            a[..n].copy_from_slice(b);
            Some(u64::from_le_bytes(a))
        }
    }
}

/// Where an array's values are.
#[derive(Debug, Clone, Copy)]
enum Source<'a> {
    /// White-space separated numbers; `line` is the line the text starts on.
    Ascii { text: &'a [u8], line: usize },
    /// Base64 inside the element.
    Inline(&'a [u8]),
    /// At this offset in `<AppendedData>`.
    Appended(u64),
}

/// A `DataArray` element, not yet decoded.
#[derive(Debug, Clone)]
struct ArrayDesc<'a> {
    name: String,
    scalar: Scalar,
    components: usize,
    source: Source<'a>,
    /// Line of the `<DataArray>` tag.
    line: usize,
}

/// A `<Piece>` and the arrays lancet uses from it.
#[derive(Debug, Default)]
struct Piece<'a> {
    points: usize,
    cells: usize,
    line: usize,
    coords: Option<ArrayDesc<'a>>,
    connectivity: Option<ArrayDesc<'a>>,
    offsets: Option<ArrayDesc<'a>>,
    types: Option<ArrayDesc<'a>>,
    cell_data: Vec<ArrayDesc<'a>>,
}

/// The `<AppendedData>` section.
#[derive(Debug)]
struct Appended<'a> {
    base64: bool,
    /// Everything after the `_` marker.
    data: &'a [u8],
    /// File offset of `data[0]`.
    start: usize,
    /// End of the base64 text (the `</AppendedData>` tag or end of file), relative to `data`.
    end: usize,
}

/// The parsed XML structure: pieces with array descriptions, and where appended data lies.
#[derive(Debug)]
struct Doc<'a> {
    path: &'a Path,
    bin: Binary,
    pieces: Vec<Piece<'a>>,
    appended: Option<Appended<'a>>,
    /// Offsets of every appended array, sorted, to find where a base64 block ends.
    appended_offsets: Vec<u64>,
}

/// Decoded values of an array.
#[derive(Debug)]
enum Values {
    Int(Vec<i64>),
    Float(Vec<f64>),
}

impl Values {
    fn len(&self) -> usize {
        match self {
            Values::Int(v) => v.len(),
            Values::Float(v) => v.len(),
        }
    }
}

/// A decoded array: its values and where they were read.
#[derive(Debug)]
struct Decoded {
    values: Values,
    at: Positions,
}

/// Where the values of an array were read: the line of each value for ascii data, else the
/// array's location.
#[derive(Debug)]
struct Positions {
    lines: Option<Vec<u32>>,
    loc: Location,
}

impl Positions {
    /// Location of value `i`: its line for ascii data, else the array's location.
    fn loc_of(&self, i: usize) -> Location {
        match self.lines.as_ref().and_then(|l| l.get(i)) {
            Some(&line) => Location::Line(line as usize),
            None => self.loc,
        }
    }
}

impl Doc<'_> {
    /// An error at `loc` of this file.
    fn err(&self, loc: Location, element: Option<i64>, msg: String, hint: &str) -> Error {
        Error::parse(self.path, loc, element, msg, hint)
    }
}
