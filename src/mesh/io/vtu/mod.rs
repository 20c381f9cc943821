//! VTK XML unstructured grids (`.vtu`): reading here, writing in [`write_vtu`].
//!
//! The reader handles what ParaView, VTK, meshio and SOFA write: `ascii`, inline `binary`
//! (base64) and `appended` (raw or base64) arrays, optional zlib compression, UInt32 or UInt64
//! headers, either byte order, and several pieces (concatenated). Only the arrays a mesh needs
//! are decoded: `Points`, the three `Cells` arrays and one region-like `CellData` array.
//!
//! Sizes written in the file are never trusted for allocation: buffers grow only as real data is
//! decoded, and a zlib block may not claim more output than deflate can produce from its input.

mod write;

pub(crate) use write::{is_temp_of, replace_file, write_vtu_synced};
pub use write::{write_vtu, write_vtu_to, VtuEncoding, VtuOptions};

use std::borrow::Cow;
use std::io::Read;
use std::path::Path;

use base64::Engine;
use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;

use super::text::{parse_f64, parse_int};
use super::vtk_cells::{unsupported_message, CellKind, CellTally, UNSUPPORTED_HINT};
use super::{Format, RawMesh, RawTet, RawTriangle};
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

/// Converts byte positions to 1-based line numbers, moving forward only (XML events come in
/// file order), so that a file with many elements is still scanned once.
struct LineCounter<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: usize,
}

impl LineCounter<'_> {
    fn line_at(&mut self, pos: usize) -> usize {
        let pos = pos.min(self.bytes.len());
        if pos < self.pos {
            // Out of order (never for the event positions used): count from the start.
            return 1 + self.bytes[..pos].iter().filter(|&&b| b == b'\n').count();
        }
        self.line += self.bytes[self.pos..pos]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        self.pos = pos;
        self.line
    }
}

/// The element an XML event is nested in, as far as the reader cares.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Tag {
    VtkFile,
    Grid,
    Piece,
    Points,
    Cells,
    CellData,
    Other,
}

/// A `DataArray` whose content is being read: its description (if used) and where the text
/// starts.
struct OpenArray<'a> {
    desc: Option<(Tag, ArrayDesc<'a>)>,
    text_start: usize,
}

/// Read the XML structure up to `<AppendedData>` (whose content is binary, not XML) or the end.
fn scan<'a>(bytes: &'a [u8], path: &'a Path) -> Result<Doc<'a>> {
    let mut reader = Reader::from_reader(bytes);
    let mut lines = LineCounter {
        bytes,
        pos: 0,
        line: 1,
    };
    let mut doc = Doc {
        path,
        bin: Binary::default(),
        pieces: Vec::new(),
        appended: None,
        appended_offsets: Vec::new(),
    };
    let mut stack: Vec<Tag> = Vec::new();
    let mut open: Option<OpenArray<'a>> = None;
    let mut seen_root = false;
    let mut seen_grid = false;
    let mut closed = false;
    loop {
        let before = reader.buffer_position() as usize;
        let event = match reader.read_event() {
            Ok(e) => e,
            Err(e) => {
                let line = lines.line_at(reader.error_position() as usize);
                return Err(Error::parse(
                    path,
                    Location::Line(line),
                    None,
                    format!("the xml is malformed: {e}"),
                    "the file is corrupted or truncated; export it again",
                ));
            }
        };
        let after = reader.buffer_position() as usize;
        match event {
            Event::Start(e) | Event::Empty(e) if open.is_some() => {
                let line = lines.line_at(before);
                return Err(Error::parse(
                    path,
                    Location::Line(line),
                    None,
                    format!(
                        "unexpected <{}> inside a <DataArray>",
                        String::from_utf8_lossy(e.name().as_ref())
                    ),
                    "a data array holds only numbers or base64 text",
                ));
            }
            Event::Start(ref e) | Event::Empty(ref e) => {
                let empty = matches!(event, Event::Empty(_));
                let line = lines.line_at(before);
                let attrs = attributes(e, path, line)?;
                let name = e.name();
                let name = name.as_ref();
                let parent = stack.last().copied();
                if parent.is_none() {
                    if seen_root {
                        return Err(Error::parse(
                            path,
                            Location::Line(line),
                            None,
                            "a second root element follows </VTKFile>",
                            "remove everything after </VTKFile>",
                        ));
                    }
                    seen_root = true;
                    doc.bin = root_settings(name, &attrs, path, line)?;
                    stack.push(Tag::VtkFile);
                    continue;
                }
                if name == b"AppendedData" {
                    doc.appended = appended_section(bytes, after, empty, &attrs, path, line)?;
                    break;
                }
                let tag = match (parent, name) {
                    (Some(Tag::VtkFile), b"UnstructuredGrid") => {
                        seen_grid = true;
                        Tag::Grid
                    }
                    (Some(Tag::Grid), b"Piece") => {
                        doc.pieces.push(piece_header(&attrs, path, line)?);
                        Tag::Piece
                    }
                    (Some(Tag::Piece), b"Points") => Tag::Points,
                    (Some(Tag::Piece), b"Cells") => Tag::Cells,
                    (Some(Tag::Piece), b"CellData") => Tag::CellData,
                    (Some(p), b"DataArray") => {
                        let array = doc.open_array(p, &attrs, line, after)?;
                        if empty {
                            doc.store_array(array, b"", 0)?;
                        } else {
                            open = Some(array);
                        }
                        continue;
                    }
                    _ => Tag::Other,
                };
                if !empty {
                    stack.push(tag);
                }
            }
            Event::End(ref e) => {
                if let Some(array) = open.take() {
                    let text = &bytes[array.text_start.min(before)..before];
                    let text_line = lines.line_at(array.text_start);
                    doc.store_array(array, text, text_line)?;
                    continue;
                }
                stack.pop();
                if stack.is_empty() && e.name().as_ref() == b"VTKFile" {
                    closed = true;
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    finish_scan(doc, seen_root, closed, seen_grid)
}

/// Check that the scan found a complete unstructured grid.
fn finish_scan(mut doc: Doc, seen_root: bool, closed: bool, seen_grid: bool) -> Result<Doc> {
    let path = doc.path;
    if !seen_root {
        return Err(Error::parse(
            path,
            Location::Line(1),
            None,
            "no <VTKFile> element found",
            "this is not a vtk xml file; check the file and its extension",
        ));
    }
    if doc.appended.is_none() && !closed {
        return Err(Error::parse(
            path,
            Location::Unknown,
            None,
            "file ends before </VTKFile>",
            "the file is truncated; export it again",
        ));
    }
    if !seen_grid || doc.pieces.is_empty() {
        return Err(Error::parse(
            path,
            Location::Unknown,
            None,
            "the file has no <UnstructuredGrid> with a <Piece>",
            "export the mesh as an unstructured grid (.vtu)",
        ));
    }
    doc.appended_offsets.sort_unstable();
    doc.appended_offsets.dedup();
    Ok(doc)
}

/// The attributes of an element as (name, unescaped value) pairs.
fn attributes(e: &BytesStart, path: &Path, line: usize) -> Result<Vec<(String, String)>> {
    let bad = |what: String| {
        Error::parse(
            path,
            Location::Line(line),
            None,
            format!("malformed attribute: {what}"),
            "fix the element's attributes",
        )
    };
    let mut out = Vec::new();
    for a in e.attributes() {
        let a = a.map_err(|e| bad(e.to_string()))?;
        let key = String::from_utf8_lossy(a.key.as_ref()).into_owned();
        let value = a.unescape_value().map_err(|e| bad(e.to_string()))?;
        out.push((key, value.into_owned()));
    }
    Ok(out)
}

/// The value of attribute `key`.
fn get<'v>(attrs: &'v [(String, String)], key: &str) -> Option<&'v str> {
    attrs.iter().find(|(k, _)| k == key).map(|(_, v)| v.trim())
}

/// Check the root element and read byte order, header type and compressor.
fn root_settings(
    name: &[u8],
    attrs: &[(String, String)],
    path: &Path,
    line: usize,
) -> Result<Binary> {
    let err = |msg: String, hint: &str| Error::parse(path, Location::Line(line), None, msg, hint);
    if name != b"VTKFile" {
        return Err(err(
            format!(
                "the root element is <{}>, not <VTKFile>",
                String::from_utf8_lossy(name)
            ),
            "this is not a vtk xml file; check the file and its extension",
        ));
    }
    match get(attrs, "type") {
        Some("UnstructuredGrid") => {}
        Some(t) => {
            return Err(err(
                format!("the file holds a vtk {t:?}, not an UnstructuredGrid"),
                "export the volume mesh as an unstructured grid (.vtu)",
            ))
        }
        None => {
            return Err(err(
                "<VTKFile> has no type attribute".into(),
                "add type=\"UnstructuredGrid\"",
            ))
        }
    }
    let big_endian = match get(attrs, "byte_order") {
        None | Some("LittleEndian") => false,
        Some("BigEndian") => true,
        Some(o) => {
            return Err(err(
                format!("unknown byte_order {o:?}"),
                "use \"LittleEndian\" or \"BigEndian\"",
            ))
        }
    };
    let header64 = match get(attrs, "header_type") {
        None | Some("UInt32") => false,
        Some("UInt64") => true,
        Some(h) => {
            return Err(err(
                format!("unknown header_type {h:?}"),
                "use \"UInt32\" or \"UInt64\"",
            ))
        }
    };
    let zlib = match get(attrs, "compressor") {
        None | Some("") => false,
        Some("vtkZLibDataCompressor") => true,
        Some(c) => {
            return Err(err(
                format!("compressor {c:?} is not supported"),
                "save the file again with zlib compression or none",
            ))
        }
    };
    Ok(Binary {
        big_endian,
        header64,
        zlib,
    })
}

/// Read `NumberOfPoints` and `NumberOfCells` of a `<Piece>`.
fn piece_header<'a>(attrs: &[(String, String)], path: &Path, line: usize) -> Result<Piece<'a>> {
    let count = |key: &str| -> Result<usize> {
        let v = get(attrs, key).ok_or_else(|| {
            Error::parse(
                path,
                Location::Line(line),
                None,
                format!("<Piece> has no {key} attribute"),
                "add the point and cell counts to the piece",
            )
        })?;
        parse_int(v, key, path, Location::Line(line), None)
    };
    Ok(Piece {
        points: count("NumberOfPoints")?,
        cells: count("NumberOfCells")?,
        line,
        ..Piece::default()
    })
}

/// Read the attributes of a `<DataArray>` that lancet uses (its content comes later).
fn array_header<'a>(attrs: &[(String, String)], path: &Path, line: usize) -> Result<ArrayDesc<'a>> {
    let err = |msg: String, hint: &str| Error::parse(path, Location::Line(line), None, msg, hint);
    let name = get(attrs, "Name").unwrap_or("").to_string();
    let ty = get(attrs, "type").unwrap_or("");
    let scalar = Scalar::from_name(ty).ok_or_else(|| {
        err(
            format!("data array {name:?} has unsupported type {ty:?}"),
            "use an integer or float type (Int32, Int64, UInt8, Float32, Float64, ...)",
        )
    })?;
    let components = match get(attrs, "NumberOfComponents") {
        None => 1,
        Some(c) => parse_int::<usize>(c, "NumberOfComponents", path, Location::Line(line), None)?,
    };
    if components == 0 {
        return Err(err(
            format!("data array {name:?} has 0 components"),
            "set NumberOfComponents to at least 1",
        ));
    }
    let source = match get(attrs, "format") {
        Some("ascii") => Source::Ascii { text: b"", line: 0 },
        Some("binary") => Source::Inline(b""),
        Some("appended") => {
            let off = get(attrs, "offset").ok_or_else(|| {
                err(
                    format!("appended data array {name:?} has no offset attribute"),
                    "add the offset of the array in <AppendedData>",
                )
            })?;
            Source::Appended(parse_int(off, "offset", path, Location::Line(line), None)?)
        }
        other => {
            return Err(err(
                format!("data array {name:?} has format {other:?}"),
                "use format \"ascii\", \"binary\" or \"appended\"",
            ))
        }
    };
    Ok(ArrayDesc {
        name,
        scalar,
        components,
        source,
        line,
    })
}

/// Locate the data of `<AppendedData>`, whose start tag ends at `after`.
fn appended_section<'a>(
    bytes: &'a [u8],
    after: usize,
    empty: bool,
    attrs: &[(String, String)],
    path: &Path,
    line: usize,
) -> Result<Option<Appended<'a>>> {
    let err = |msg: &str, hint: &str| Error::parse(path, Location::Line(line), None, msg, hint);
    let base64 = match get(attrs, "encoding") {
        Some("raw") => false,
        Some("base64") => true,
        _ => {
            return Err(err(
                "<AppendedData> needs encoding=\"raw\" or encoding=\"base64\"",
                "fix the encoding attribute",
            ))
        }
    };
    if empty {
        return Ok(None);
    }
    let rest = bytes.get(after..).unwrap_or(&[]);
    let skip = rest
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(rest.len());
    if rest.get(skip) != Some(&b'_') {
        return Err(err(
            "appended data does not start with '_'",
            "the data must follow an underscore marker; export the file again",
        ));
    }
    let start = after + skip + 1;
    let data = &bytes[start..];
    // Base64 text cannot contain '<', so the first one ends it; raw data may contain anything,
    // and is read only as far as its headers say.
    let end = if base64 {
        data.iter().position(|&b| b == b'<').unwrap_or(data.len())
    } else {
        data.len()
    };
    Ok(Some(Appended {
        base64,
        data,
        start,
        end,
    }))
}

impl<'a> Doc<'a> {
    /// Start a `<DataArray>` under `parent`: note its appended offset, and read its attributes
    /// if it is one lancet uses.
    fn open_array(
        &mut self,
        parent: Tag,
        attrs: &[(String, String)],
        line: usize,
        text_start: usize,
    ) -> Result<OpenArray<'a>> {
        if let Some(off) = get(attrs, "offset").and_then(|o| o.parse().ok()) {
            self.appended_offsets.push(off);
        }
        let desc = match parent {
            Tag::Points | Tag::Cells | Tag::CellData => {
                Some((parent, array_header(attrs, self.path, line)?))
            }
            _ => None,
        };
        Ok(OpenArray { desc, text_start })
    }

    /// Attach a finished `<DataArray>` with content `text` to the current piece.
    fn store_array(
        &mut self,
        array: OpenArray<'a>,
        text: &'a [u8],
        text_line: usize,
    ) -> Result<()> {
        let Some((tag, mut desc)) = array.desc else {
            return Ok(());
        };
        match &mut desc.source {
            Source::Ascii { text: t, line } => {
                *t = text;
                *line = text_line;
            }
            Source::Inline(t) => *t = text,
            Source::Appended(_) => {}
        }
        let Some(piece) = self.pieces.last_mut() else {
            return Ok(());
        };
        match tag {
            Tag::Points => piece.coords = Some(desc),
            Tag::Cells => match desc.name.as_str() {
                "connectivity" => piece.connectivity = Some(desc),
                "offsets" => piece.offsets = Some(desc),
                "types" => piece.types = Some(desc),
                // faces/faceoffsets of polyhedra: not used.
                _ => {}
            },
            Tag::CellData => piece.cell_data.push(desc),
            _ => {}
        }
        Ok(())
    }

    fn err(&self, loc: Location, element: Option<i64>, msg: String, hint: &str) -> Error {
        Error::parse(self.path, loc, element, msg, hint)
    }

    /// Decode an array's values; the piece's counts say it needs at most `max_values`, and
    /// compressed data declaring more is refused before it is inflated.
    fn decode(&self, desc: &ArrayDesc, max_values: usize) -> Result<Decoded> {
        let tag_loc = Location::Line(desc.line);
        let cap = (max_values as u64).saturating_mul(desc.scalar.size() as u64);
        match desc.source {
            Source::Ascii { text, line } => self.decode_ascii(desc, text, line),
            Source::Inline(text) => {
                let bytes = self.base64(text, tag_loc, &desc.name)?;
                let payload = self.block(&bytes, &|_| tag_loc, cap)?;
                self.values(desc, &payload, tag_loc)
            }
            Source::Appended(off) => {
                let Some(app) = &self.appended else {
                    return Err(self.err(
                        tag_loc,
                        None,
                        format!(
                            "data array {:?} refers to appended data, but the file has no \
                             <AppendedData> section",
                            desc.name
                        ),
                        "the file is truncated or was not written completely",
                    ));
                };
                let off_usize = usize::try_from(off).unwrap_or(usize::MAX);
                let limit = if app.base64 { app.end } else { app.data.len() };
                if off_usize > limit {
                    return Err(self.err(
                        tag_loc,
                        None,
                        format!(
                            "data array {:?} has offset {off}, past the {limit} bytes of \
                             appended data",
                            desc.name
                        ),
                        "the file is truncated or the offset is wrong",
                    ));
                }
                let at = app.start + off_usize;
                if app.base64 {
                    // The block ends where the next array starts.
                    let end = self
                        .appended_offsets
                        .iter()
                        .find(|&&o| o > off)
                        .map_or(app.end, |&o| usize::try_from(o).unwrap_or(usize::MAX))
                        .min(app.end);
                    let loc = Location::Byte(at as u64);
                    let bytes = self.base64(&app.data[off_usize..end], loc, &desc.name)?;
                    let payload = self.block(&bytes, &|_| loc, cap)?;
                    self.values(desc, &payload, loc)
                } else {
                    let payload = self.block(
                        &app.data[off_usize..],
                        &|p| Location::Byte((at + p) as u64),
                        cap,
                    )?;
                    self.values(desc, &payload, Location::Byte(at as u64))
                }
            }
        }
    }

    /// Decode base64 text that may be one stream or several separately padded streams (VTK
    /// encodes the header of compressed data apart from the data).
    fn base64(&self, text: &[u8], loc: Location, name: &str) -> Result<Vec<u8>> {
        let clean: Vec<u8> = text
            .iter()
            .copied()
            .filter(|b| !b.is_ascii_whitespace())
            .collect();
        let bad = |msg: String| {
            self.err(
                loc,
                None,
                msg,
                "the base64 data is truncated or corrupted; export the file again",
            )
        };
        if clean.len() % 4 != 0 {
            return Err(bad(format!(
                "base64 data of array {name:?} has {} characters, not a multiple of 4",
                clean.len()
            )));
        }
        let mut out = Vec::with_capacity(clean.len() / 4 * 3);
        let mut seg = 0;
        for q in (0..clean.len()).step_by(4) {
            if clean[q + 3] == b'=' || q + 4 == clean.len() {
                base64::engine::general_purpose::STANDARD
                    .decode_vec(&clean[seg..q + 4], &mut out)
                    .map_err(|e| {
                        bad(format!(
                            "invalid base64 in array {name:?}: {}",
                            e.to_string().to_lowercase()
                        ))
                    })?;
                seg = q + 4;
            }
        }
        Ok(out)
    }

    /// The payload of a binary block: `[byte count] data`, or, compressed,
    /// `[blocks, block size, last block size, compressed sizes...] zlib blocks`.
    /// `at(p)` locates byte `p` of `data` for messages. Compressed data is inflated only if
    /// the sizes its header declares add up to no more than `cap` bytes (what the piece's
    /// counts need): blocks of zeros within zlib's ratio could otherwise inflate a small file
    /// into gigabytes before the counts are compared.
    fn block<'b>(
        &self,
        data: &'b [u8],
        at: &dyn Fn(usize) -> Location,
        cap: u64,
    ) -> Result<Cow<'b, [u8]>> {
        let hs = self.bin.header_size();
        let truncated = |p: usize, what: &str| {
            self.err(
                at(p.min(data.len())),
                None,
                format!("binary data ends inside {what}"),
                "the file is truncated; export it again",
            )
        };
        let word = |i: usize| {
            self.bin
                .word(data, i)
                .ok_or_else(|| truncated(i * hs, "the block header"))
        };
        if !self.bin.zlib {
            let n = word(0)?;
            let end = usize::try_from(n)
                .ok()
                .and_then(|n| n.checked_add(hs))
                .filter(|&e| e <= data.len());
            return match end {
                Some(end) => Ok(Cow::Borrowed(&data[hs..end])),
                None => Err(self.err(
                    at(hs),
                    None,
                    format!(
                        "the block header declares {n} bytes but only {} follow",
                        data.len() - hs
                    ),
                    "the file is truncated; export it again",
                )),
            };
        }
        let blocks = word(0)?;
        let block_size = word(1)?;
        let last_size = word(2)?;
        // The header must hold every compressed size before anything is allocated for them.
        let header_len = usize::try_from(blocks)
            .ok()
            .and_then(|b| b.checked_add(3))
            .and_then(|w| w.checked_mul(hs))
            .filter(|&l| l <= data.len())
            .ok_or_else(|| truncated(3 * hs, "the compression header"))?;
        // Every block's place and size is checked before anything is inflated.
        let mut chunks = Vec::new();
        let mut pos = header_len;
        for i in 0..blocks as usize {
            let csize = word(3 + i)?;
            let chunk = usize::try_from(csize)
                .ok()
                .and_then(|c| pos.checked_add(c))
                .and_then(|end| data.get(pos..end))
                .ok_or_else(|| truncated(pos, &format!("compressed block {i}")))?;
            let expected = if i + 1 == blocks as usize && last_size != 0 {
                last_size
            } else {
                block_size
            };
            if expected > csize.saturating_mul(MAX_INFLATE_RATIO).saturating_add(64) {
                return Err(self.err(
                    at(pos),
                    None,
                    format!(
                        "compressed block {i} claims {expected} bytes from {csize} compressed \
                         bytes, more than zlib can produce"
                    ),
                    "the compression header is corrupted; export the file again",
                ));
            }
            chunks.push((pos, chunk, expected));
            pos += chunk.len();
        }
        let declared = chunks
            .iter()
            .fold(0u64, |sum, &(_, _, e)| sum.saturating_add(e));
        if declared > cap {
            return Err(self.err(
                at(0),
                None,
                format!(
                    "the compressed data declares {declared} bytes, more than the {cap} bytes \
                     the piece's point and cell counts need"
                ),
                "the compression header or the counts in <Piece> are wrong; export the file \
                 again",
            ));
        }
        let mut out = Vec::new();
        // Bounded by `cap` above; an allocation that still fails is an error, not an abort.
        out.try_reserve_exact(declared as usize).map_err(|_| {
            self.err(
                at(0),
                None,
                format!("not enough memory to inflate {declared} bytes of compressed data"),
                "free memory, or split the mesh",
            )
        })?;
        for (i, (pos, chunk, expected)) in chunks.into_iter().enumerate() {
            let before = out.len();
            flate2::read::ZlibDecoder::new(chunk)
                .take(expected + 1)
                .read_to_end(&mut out)
                .map_err(|e| {
                    self.err(
                        at(pos),
                        None,
                        format!(
                            "compressed block {i} is not valid zlib data: {}",
                            e.to_string().to_lowercase()
                        ),
                        "the file is corrupted; export it again",
                    )
                })?;
            let got = (out.len() - before) as u64;
            if got != expected {
                return Err(self.err(
                    at(pos),
                    None,
                    format!(
                        "compressed block {i} inflates to {got} bytes, not the {expected} its \
                         header declares"
                    ),
                    "the file is corrupted; export it again",
                ));
            }
        }
        Ok(Cow::Owned(out))
    }

    /// Convert a binary payload to values of the array's type.
    fn values(&self, desc: &ArrayDesc, payload: &[u8], loc: Location) -> Result<Decoded> {
        let size = desc.scalar.size();
        if payload.len() % size != 0 {
            return Err(self.err(
                loc,
                None,
                format!(
                    "data array {:?} has {} bytes, not a whole number of {}-byte values",
                    desc.name,
                    payload.len(),
                    size
                ),
                "the data is corrupted; export the file again",
            ));
        }
        let big = self.bin.big_endian;
        let mut chunks = payload.chunks_exact(size).map(|c| {
            let mut a = [0u8; 8];
            a[..size].copy_from_slice(c);
            if big {
                a[..size].reverse();
            }
            a
        });
        let values = match desc.scalar {
            Scalar::Float32 => Values::Float(
                chunks
                    .by_ref()
                    .map(|a| f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64)
                    .collect(),
            ),
            Scalar::Float64 => Values::Float(chunks.by_ref().map(f64::from_le_bytes).collect()),
            s => {
                let mut v = Vec::with_capacity(payload.len() / size);
                for (i, a) in chunks.by_ref().enumerate() {
                    v.push(int_from_le(s, a).ok_or_else(|| {
                        self.err(
                            loc,
                            None,
                            format!(
                                "data array {:?} value {i} is too large for a 64-bit integer",
                                desc.name
                            ),
                            "fix the value",
                        )
                    })?);
                }
                Values::Int(v)
            }
        };
        if let Values::Float(v) = &values {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(self.err(
                    loc,
                    Some((i / desc.components) as i64),
                    format!(
                        "data array {:?} holds a non-finite value ({}) at index {i}",
                        desc.name, v[i]
                    ),
                    "replace NaN or infinite values with real numbers",
                ));
            }
        }
        Ok(Decoded {
            values,
            at: Positions { lines: None, loc },
        })
    }

    /// Parse white-space separated numbers, remembering the line of each.
    fn decode_ascii(&self, desc: &ArrayDesc, text: &[u8], first_line: usize) -> Result<Decoded> {
        let mut line = first_line;
        let mut lines = Vec::new();
        let mut ints = Vec::new();
        let mut floats = Vec::new();
        let what = format!("{} value", desc.name);
        let mut i = 0;
        while i < text.len() {
            if text[i].is_ascii_whitespace() {
                line += (text[i] == b'\n') as usize;
                i += 1;
                continue;
            }
            let start = i;
            while i < text.len() && !text[i].is_ascii_whitespace() {
                i += 1;
            }
            let loc = Location::Line(line);
            let element = Some((lines.len() / desc.components) as i64);
            let tok = std::str::from_utf8(&text[start..i]).map_err(|_| {
                self.err(
                    loc,
                    element,
                    format!("{what} is not valid text"),
                    "the file is corrupted; export it again",
                )
            })?;
            if desc.scalar.is_float() {
                floats.push(parse_f64(tok, &what, self.path, loc, element)?);
            } else {
                let v: i64 = parse_int(tok, &what, self.path, loc, element)?;
                if !desc.scalar.fits(v) {
                    return Err(self.err(
                        loc,
                        element,
                        format!("{what} {v} does not fit the array's type {:?}", desc.scalar),
                        "fix the value or the array's type",
                    ));
                }
                ints.push(v);
            }
            lines.push(line as u32);
        }
        let values = if desc.scalar.is_float() {
            Values::Float(floats)
        } else {
            Values::Int(ints)
        };
        Ok(Decoded {
            values,
            at: Positions {
                lines: Some(lines),
                loc: Location::Line(desc.line),
            },
        })
    }

    /// Decode an array a piece needs, checking its presence and component count.
    fn array(
        &self,
        desc: Option<&ArrayDesc>,
        what: &str,
        piece: &Piece,
        components: usize,
        max_values: usize,
    ) -> Result<Decoded> {
        let desc = desc.ok_or_else(|| {
            self.err(
                Location::Line(piece.line),
                None,
                format!("the piece has no {what} array"),
                "the file is incomplete; export it again",
            )
        })?;
        if desc.components != components {
            return Err(self.err(
                Location::Line(desc.line),
                None,
                format!(
                    "the {what} array has {} components; it needs {components}",
                    desc.components
                ),
                "fix NumberOfComponents",
            ));
        }
        self.decode(desc, max_values)
    }

    /// Decode an array a piece needs and check that it holds `len` tuples.
    fn required(
        &self,
        desc: Option<&ArrayDesc>,
        what: &str,
        piece: &Piece,
        len: usize,
        components: usize,
    ) -> Result<Decoded> {
        let d = self.array(
            desc,
            what,
            piece,
            components,
            len.saturating_mul(components),
        )?;
        if len.checked_mul(components) != Some(d.values.len()) {
            return Err(self.err(
                d.at.loc,
                None,
                format!(
                    "the {what} array has {} values, but the piece needs {len} x {components}",
                    d.values.len()
                ),
                "the counts in <Piece> and the data disagree; export the file again",
            ));
        }
        Ok(d)
    }

    /// The values of an integer array.
    fn ints(&self, d: Decoded, what: &str) -> Result<(Vec<i64>, Positions)> {
        match d.values {
            Values::Int(v) => Ok((v, d.at)),
            Values::Float(_) => Err(self.err(
                d.at.loc,
                None,
                format!("the {what} array holds floats; it must hold integers"),
                "write cell arrays with an integer type",
            )),
        }
    }

    /// Add a piece's points and cells to `raw`; returns the name of the region array used.
    fn add_piece(
        &self,
        piece: &Piece,
        raw: &mut RawMesh,
        counts: &mut CellTally,
    ) -> Result<Option<String>> {
        let base = raw.points.len();
        if base.saturating_add(piece.points) > u32::MAX as usize {
            return Err(self.err(
                Location::Line(piece.line),
                None,
                "the mesh has more points than lancet can index (2^32)".into(),
                "split the mesh",
            ));
        }
        if piece.points > 0 {
            let d = self.required(piece.coords.as_ref(), "Points", piece, piece.points, 3)?;
            let coords: Vec<f64> = match d.values {
                Values::Float(v) => v,
                Values::Int(v) => v.into_iter().map(|x| x as f64).collect(),
            };
            for (i, c) in coords.chunks_exact(3).enumerate() {
                raw.points.push([c[0], c[1], c[2]]);
                raw.point_ids.push((base + i) as i64);
            }
        }
        if piece.cells == 0 {
            return Ok(None);
        }
        let n = piece.cells;
        let offsets = self.required(piece.offsets.as_ref(), "offsets", piece, n, 1)?;
        let (offsets, offsets_d) = self.ints(offsets, "offsets")?;
        // The connectivity length is given by the last offset (checked below), which also
        // bounds what its data may inflate to.
        let conn_len = offsets
            .last()
            .map_or(0, |&o| usize::try_from(o).unwrap_or(0));
        let conn = self.array(
            piece.connectivity.as_ref(),
            "connectivity",
            piece,
            1,
            conn_len,
        )?;
        let (conn, conn_d) = self.ints(conn, "connectivity")?;
        let types = self.required(piece.types.as_ref(), "types", piece, n, 1)?;
        let (types, _) = self.ints(types, "types")?;
        let region = self.regions(piece)?;
        let cell_base = raw.tets.len() + raw.triangles.len();
        let mut prev = 0i64;
        for i in 0..n {
            let id = (cell_base + i) as i64;
            let end = offsets[i];
            if end <= prev || end as u64 > conn.len() as u64 {
                return Err(self.err(
                    offsets_d.loc_of(i),
                    Some(id),
                    format!(
                        "cell offset {end} does not increase from {prev} or lies past the \
                         {} connectivity entries",
                        conn.len()
                    ),
                    "offsets must increase and end at the connectivity length",
                ));
            }
            let start = prev as usize;
            prev = end;
            let cell = Cell {
                id,
                kind: types[i],
                nodes: &conn[start..end as usize],
                loc: conn_d.loc_of(start),
                region: region.as_ref().map_or(0, |(_, r)| r[i]),
            };
            self.add_cell(&cell, base, piece.points, raw, counts)?;
        }
        if prev as u64 != conn.len() as u64 {
            return Err(self.err(
                conn_d.loc,
                None,
                format!(
                    "the connectivity array has {} entries but the offsets end at {prev}",
                    conn.len()
                ),
                "the cell arrays disagree; export the file again",
            ));
        }
        Ok(region.map(|(name, _)| name))
    }

    /// The region tags of a piece's cells, from the first `CellData` array with a region-like
    /// name.
    fn regions(&self, piece: &Piece) -> Result<Option<(String, Vec<i32>)>> {
        let pick = REGION_NAMES.iter().find_map(|key| {
            piece
                .cell_data
                .iter()
                .find(|a| a.components == 1 && a.name.to_ascii_lowercase().contains(key))
        });
        let Some(desc) = pick else {
            return Ok(None);
        };
        let d = self.required(Some(desc), &desc.name, piece, piece.cells, 1)?;
        let as_i32 = |i: usize, v: f64| -> Result<i32> {
            if v.fract() == 0.0 && v >= i32::MIN as f64 && v <= i32::MAX as f64 {
                Ok(v as i32)
            } else {
                Err(self.err(
                    d.at.loc_of(i),
                    Some(i as i64),
                    format!(
                        "region tag {v} in array {:?} is not a 32-bit integer",
                        desc.name
                    ),
                    "region tags must be whole numbers",
                ))
            }
        };
        let tags = match &d.values {
            Values::Int(v) => v
                .iter()
                .enumerate()
                .map(|(i, &x)| as_i32(i, x as f64))
                .collect::<Result<Vec<_>>>()?,
            Values::Float(v) => v
                .iter()
                .enumerate()
                .map(|(i, &x)| as_i32(i, x))
                .collect::<Result<Vec<_>>>()?,
        };
        Ok(Some((desc.name.clone(), tags)))
    }

    /// Add one cell: tets and triangles are kept, vertices, lines and other surface cells are
    /// counted and skipped, other volume cells are an error.
    fn add_cell(
        &self,
        cell: &Cell,
        base: usize,
        points: usize,
        raw: &mut RawMesh,
        counts: &mut CellTally,
    ) -> Result<()> {
        let kind = CellKind::of(cell.kind);
        counts.record(kind);
        match kind {
            CellKind::VertexOrLine | CellKind::OtherSurface => return Ok(()),
            CellKind::Volume(_) | CellKind::Unknown => {
                return Err(self.err(
                    cell.loc,
                    Some(cell.id),
                    unsupported_message(cell.kind),
                    UNSUPPORTED_HINT,
                ))
            }
            _ => {}
        }
        if let Some(msg) = kind.wrong_points(cell.kind, cell.nodes.len()) {
            return Err(self.err(
                cell.loc,
                Some(cell.id),
                msg,
                "fix the offsets or the cell type",
            ));
        }
        if kind.corners() == 3 {
            let nodes = self.nodes::<3>(cell, base, points)?;
            raw.triangles.push(RawTriangle {
                nodes,
                tag: cell.region,
            });
        } else {
            let nodes = self.nodes::<4>(cell, base, points)?;
            raw.tets.push(RawTet {
                nodes,
                region: cell.region,
                id: cell.id,
                location: cell.loc,
            });
        }
        Ok(())
    }

    /// The first `N` point references of a cell, checked against the piece's points and
    /// shifted by the points of earlier pieces.
    fn nodes<const N: usize>(&self, cell: &Cell, base: usize, points: usize) -> Result<[u32; N]> {
        let mut out = [0u32; N];
        for (slot, &v) in out.iter_mut().zip(cell.nodes) {
            if v < 0 || v as u64 >= points as u64 {
                return Err(self.err(
                    cell.loc,
                    Some(cell.id),
                    format!("cell references point {v}, but the piece has {points} points"),
                    "point numbers in the connectivity start at 0 in each piece",
                ));
            }
            *slot = (base + v as usize) as u32;
        }
        Ok(out)
    }
}

/// An integer of type `s` from its little-endian bytes; `None` for a UInt64 beyond `i64`.
fn int_from_le(s: Scalar, a: [u8; 8]) -> Option<i64> {
    Some(match s {
        Scalar::Int8 => a[0] as i8 as i64,
        Scalar::UInt8 => a[0] as i64,
        Scalar::Int16 => i16::from_le_bytes([a[0], a[1]]) as i64,
        Scalar::UInt16 => u16::from_le_bytes([a[0], a[1]]) as i64,
        Scalar::Int32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as i64,
        Scalar::UInt32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as i64,
        Scalar::Int64 => i64::from_le_bytes(a),
        Scalar::UInt64 => i64::try_from(u64::from_le_bytes(a)).ok()?,
        Scalar::Float32 | Scalar::Float64 => return None,
    })
}

/// One cell as read, before it becomes a tet or triangle.
struct Cell<'c> {
    id: i64,
    kind: i64,
    nodes: &'c [i64],
    loc: Location,
    region: i32,
}
