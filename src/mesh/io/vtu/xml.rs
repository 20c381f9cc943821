//! The XML structure of a `.vtu` file read up to its appended data: the pieces, their
//! arrays' attributes and where each array's content lies.

use std::path::Path;

use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;

use super::super::text::parse_int;
use super::{Appended, ArrayDesc, Binary, Doc, Piece, Scalar, Source};
use crate::error::{Error, Location, Result};

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
pub(super) fn scan<'a>(bytes: &'a [u8], path: &'a Path) -> Result<Doc<'a>> {
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
}
