//! Reader for Gmsh `.msh` files: version 1 (`$NOD`/`$ELM`), 2.2 and 4.1, ASCII and binary.
//!
//! Tetrahedra become [`RawTet`]s with the physical group as region; triangles are kept as tagged
//! surface elements; lines, points and quadrangles are ignored with one note per kind. Higher
//! order tets and triangles keep their corner nodes (Gmsh lists corners first). Hexahedra,
//! prisms and pyramids are refused: lancet simulates tetrahedra only.
//!
//! The record layouts of ASCII and binary files are the same sequence of values (binary only
//! fixes their widths), so the 4.1 sections and the 2.2 nodes are read once through the
//! `Source` trait, with an ASCII source that knows lines and a binary one that knows byte
//! offsets. Every count read from the file is untrusted: buffers are sized by what the remaining
//! bytes could hold, never by the declared count alone.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use std::str::SplitAsciiWhitespace;

use super::text::{parse_f64, parse_int, Bin, Lines};
use super::{Format, IdMap, RawMesh, RawTet, RawTriangle};
use crate::error::{Error, Location, Result};

/// Hint for files that need to be exported again in a supported version.
const REEXPORT_HINT: &str = "save the mesh as gmsh 4.1 or 2.2, e.g. \
                             `gmsh model.msh -save -format msh41 -o model41.msh`";

/// Parse a Gmsh file (any supported version, ASCII or binary).
pub fn parse(bytes: &[u8], path: &Path) -> Result<RawMesh> {
    let mut lines = Lines::new(path, bytes, None);
    let first = match lines.next_line() {
        Some(l) => l?,
        None => {
            return Err(Error::parse(
                path,
                Location::Line(lines.line().max(1)),
                None,
                "the file is empty",
                "a gmsh file starts with $MeshFormat (or $NOD for gmsh 1)",
            ))
        }
    };
    let header = match first {
        "$MeshFormat" => read_header(&mut lines)?,
        // Gmsh 1 has no header: the file starts with its node section.
        "$NOD" => Header::V1,
        other => {
            return Err(lines.error(
                None,
                format!("expected $MeshFormat or $NOD, found {:?}", clip(other)),
                "this does not look like a gmsh .msh file; check the file and its extension",
            ))
        }
    };
    let mut reader = Reader::new(path, header);
    if header == Header::V1 {
        reader.section(&mut lines, "$NOD")?;
    }
    while let Some(line) = lines.next_line() {
        let line = line?;
        if !line.starts_with('$') {
            return Err(lines.error(
                None,
                format!("expected a section such as $Nodes, found {:?}", clip(line)),
                "text outside sections; the counts of the previous section may be wrong",
            ));
        }
        reader.section(&mut lines, line)?;
    }
    Ok(reader.finish())
}

/// The format version and encoding given by the file's header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Header {
    /// Gmsh 1: ASCII only, no header.
    V1,
    /// Gmsh 2.x (read as 2.2).
    V2 { binary: Option<Endian> },
    /// Gmsh 4.1; binary files give the width of `size_t` (4 or 8).
    V4 { binary: Option<(Endian, usize)> },
}

/// Byte order of a binary file, from its check integer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Endian {
    /// Whether values are big-endian (the check integer read backwards).
    big: bool,
}

impl Header {
    /// The format reported to the caller.
    fn format(self) -> Format {
        match self {
            Header::V1 => Format::Gmsh1,
            Header::V2 { binary } => Format::Gmsh22 {
                binary: binary.is_some(),
            },
            Header::V4 { binary } => Format::Gmsh41 {
                binary: binary.is_some(),
            },
        }
    }
}

/// Read the `$MeshFormat` section after its opening line.
fn read_header(lines: &mut Lines) -> Result<Header> {
    let line = lines.expect_line("the version line of $MeshFormat")?;
    let toks: Vec<&str> = line.split_ascii_whitespace().collect();
    if toks.len() != 3 {
        return Err(lines.error(
            None,
            format!(
                "expected `version file-type data-size`, found {:?}",
                clip(line)
            ),
            "the $MeshFormat line should read like `4.1 0 8`",
        ));
    }
    let version = lines.f64(toks[0], "version", None)?;
    let file_type: i32 = lines.int(toks[1], "file-type", None)?;
    let data_size: usize = lines.int(toks[2], "data-size", None)?;
    if file_type != 0 && file_type != 1 {
        return Err(lines.error(
            None,
            format!("file-type {file_type} is neither 0 (ascii) nor 1 (binary)"),
            "fix the $MeshFormat line",
        ));
    }
    let binary = file_type == 1;
    // Versions are written as decimals; compare tenths so that `2.2` and `2.20` agree.
    let tenths = (version * 10.0).round();
    let header = if (20.0..=22.0).contains(&tenths) {
        let endian = binary.then(|| read_endian(lines)).transpose()?;
        if binary && data_size != 8 {
            return Err(lines.error(
                None,
                format!("binary gmsh 2 with data-size {data_size} is not supported (needs 8)"),
                REEXPORT_HINT,
            ));
        }
        Header::V2 { binary: endian }
    } else if tenths == 41.0 {
        if binary && data_size != 4 && data_size != 8 {
            return Err(lines.error(
                None,
                format!("data-size {data_size} is not a size_t width (4 or 8)"),
                "fix the $MeshFormat line or export the file again",
            ));
        }
        let endian = binary.then(|| read_endian(lines)).transpose()?;
        Header::V4 {
            binary: endian.map(|e| (e, data_size)),
        }
    } else {
        return Err(lines.error(
            None,
            format!(
                "unsupported gmsh format version {}; lancet reads versions 1, 2.2 and 4.1",
                toks[0]
            ),
            REEXPORT_HINT,
        ));
    };
    expect_end(lines, "$EndMeshFormat", "$MeshFormat")?;
    Ok(header)
}

/// Read the binary integer 1 that follows the version line of a binary file.
fn read_endian(lines: &mut Lines) -> Result<Endian> {
    let mut bin = Bin::new(lines.path(), lines.bytes(), lines.byte_pos(), false);
    let one = bin.i32("the endianness check of $MeshFormat")?;
    let endian = if one == 1 {
        Endian { big: false }
    } else if one.swap_bytes() == 1 {
        Endian { big: true }
    } else {
        return Err(Error::parse(
            lines.path(),
            Location::Byte(lines.byte_pos() as u64),
            None,
            format!("the endianness check reads {one}, not 1"),
            "the binary header is damaged; export the file again",
        ));
    };
    lines.seek(bin.pos);
    Ok(endian)
}

/// The closing line of a section, for its opening line (`$Nodes` -> `$EndNodes`,
/// Gmsh 1 `$NOD` -> `$ENDNOD`).
fn end_marker(section: &str) -> String {
    let name = &section[1..];
    if name.bytes().all(|b| !b.is_ascii_lowercase()) {
        format!("$END{name}")
    } else {
        format!("$End{name}")
    }
}

/// The next content line must be `marker`; say precisely what is wrong otherwise.
fn expect_end(lines: &mut Lines, marker: &str, section: &str) -> Result<()> {
    match lines.next_line() {
        None => Err(Error::parse(
            lines.path(),
            Location::Line(lines.line().max(1)),
            None,
            format!("file ends before {marker}"),
            "the file is truncated; export it again",
        )),
        Some(line) => {
            let line = line?;
            if line == marker {
                Ok(())
            } else if line.starts_with('$') {
                Err(lines.error(
                    None,
                    format!("missing {marker}: found {} first", clip(line)),
                    format!("close the {section} section with {marker}"),
                ))
            } else {
                Err(lines.error(
                    None,
                    format!(
                        "expected {marker}, found {:?}: {section} has more rows than it declares",
                        clip(line)
                    ),
                    "fix the count at the start of the section",
                ))
            }
        }
    }
}

/// After a binary block ending at `pos`, the section must close with `marker` (possibly after
/// a newline); otherwise the declared counts do not match the data.
fn expect_end_binary(lines: &mut Lines, pos: usize, marker: &str) -> Result<()> {
    let bytes = lines.bytes();
    let rest = bytes.get(pos..).unwrap_or_default();
    let skip = rest
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(rest.len());
    let after = &rest[skip..];
    let closes = after.starts_with(marker.as_bytes())
        && matches!(after.get(marker.len()), None | Some(b'\r' | b'\n'));
    if !closes {
        return Err(Error::parse(
            lines.path(),
            Location::Byte(pos as u64),
            None,
            format!("binary data does not end where the counts say: expected {marker}"),
            "the declared counts do not match the data; export the file again",
        ));
    }
    lines.seek(pos);
    lines.next_line();
    Ok(())
}

/// Skip a section the reader does not need, up to its closing line; works on binary sections
/// too because it searches bytes, not text lines.
fn skip_section(lines: &mut Lines, section: &str) -> Result<()> {
    let marker = end_marker(section);
    let bytes = lines.bytes();
    let start = lines.byte_pos();
    let mut from = start;
    while let Some(off) = find(&bytes[from..], marker.as_bytes()) {
        let at = from + off;
        let line_start = at == start || bytes[at - 1] == b'\n';
        let line_end = matches!(bytes.get(at + marker.len()), None | Some(b'\r' | b'\n'));
        if line_start && line_end {
            lines.seek(at);
            lines.next_raw();
            return Ok(());
        }
        from = at + 1;
    }
    Err(lines.error(
        None,
        format!("section {section} has no {marker}"),
        "the file is truncated; export it again",
    ))
}

/// Position of `needle` in `hay`.
fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// A line shortened for messages (binary junk can be long).
fn clip(s: &str) -> String {
    s.chars().take(40).collect()
}

/// How many items of at least `item_bytes` bytes each the rest of the input could hold: the
/// capacity to reserve for a declared count, so that a corrupt count cannot exhaust memory.
fn capacity(count: u64, bytes_left: usize, item_bytes: usize) -> usize {
    let room = bytes_left / item_bytes.max(1);
    count.min(room as u64) as usize
}

/// What lancet does with a Gmsh element type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// A tetrahedron (its first four nodes are the corners).
    Tet,
    /// A triangle (its first three nodes are the corners).
    Triangle,
    /// A volume element lancet cannot simulate.
    Solid,
    /// Points, lines, quadrangles: ignored.
    Other,
}

/// Node count, kind and name of a Gmsh element type; `None` for types lancet does not know.
fn element_type(t: i32) -> Option<(usize, Kind, &'static str)> {
    use Kind::*;
    Some(match t {
        1 => (2, Other, "line"),
        2 => (3, Triangle, "triangle"),
        3 => (4, Other, "quadrangle"),
        4 => (4, Tet, "tetrahedron"),
        5 => (8, Solid, "hexahedron"),
        6 => (6, Solid, "prism"),
        7 => (5, Solid, "pyramid"),
        8 => (3, Other, "3-node line"),
        9 => (6, Triangle, "6-node triangle"),
        10 => (9, Other, "9-node quadrangle"),
        11 => (10, Tet, "10-node tetrahedron"),
        12 => (27, Solid, "27-node hexahedron"),
        13 => (18, Solid, "18-node prism"),
        14 => (14, Solid, "14-node pyramid"),
        15 => (1, Other, "point"),
        16 => (8, Other, "8-node quadrangle"),
        17 => (20, Solid, "20-node hexahedron"),
        18 => (15, Solid, "15-node prism"),
        19 => (13, Solid, "13-node pyramid"),
        20 => (9, Triangle, "9-node triangle"),
        21 => (10, Triangle, "10-node triangle"),
        22 => (12, Triangle, "12-node triangle"),
        23 | 24 => (15, Triangle, "15-node triangle"),
        25 => (21, Triangle, "21-node triangle"),
        26 => (4, Other, "4-node line"),
        27 => (5, Other, "5-node line"),
        28 => (6, Other, "6-node line"),
        29 => (20, Tet, "20-node tetrahedron"),
        30 => (35, Tet, "35-node tetrahedron"),
        31 => (56, Tet, "56-node tetrahedron"),
        92 => (64, Solid, "64-node hexahedron"),
        93 => (125, Solid, "125-node hexahedron"),
        _ => return None,
    })
}

/// A stream of the values of one section, read record by record: an ASCII record is a line,
/// a binary record is just the next values.
trait Source {
    /// Start the next record, `what` naming it for messages.
    fn begin(&mut self, what: std::fmt::Arguments) -> Result<()>;
    /// An `int` (a token in ASCII, 4 bytes in binary).
    fn int(&mut self, what: &str, element: Option<i64>) -> Result<i64>;
    /// A `size_t` (a token in ASCII, the header's data-size in binary; Gmsh 4.1 only).
    fn size(&mut self, what: &str, element: Option<i64>) -> Result<u64>;
    /// A finite `double`.
    fn float(&mut self, what: &str, element: Option<i64>) -> Result<f64>;
    /// Values left in the current ASCII line; `None` for binary, where records have no end.
    fn left(&self) -> Option<usize>;
    /// End the record: an ASCII line must hold nothing more.
    fn end(&mut self, element: Option<i64>) -> Result<()>;
    /// Where the current record starts.
    fn loc(&self) -> Location;
    /// Bytes not read yet, to cap buffer sizes.
    fn bytes_left(&self) -> usize;
    /// An error at the current record.
    fn error(&self, element: Option<i64>, message: String, hint: &str) -> Error;

    /// An `int` that must fit `i32` (element types, region tags, entity tags).
    fn int32(&mut self, what: &str, element: Option<i64>) -> Result<i32> {
        let v = self.int(what, element)?;
        i32::try_from(v).map_err(|_| {
            self.error(
                element,
                format!("{what} {v} is out of range"),
                "fix the value",
            )
        })
    }

    /// A count or tag read as `size_t`, as a signed id.
    fn id(&mut self, what: &str, element: Option<i64>) -> Result<i64> {
        let v = self.size(what, element)?;
        i64::try_from(v).map_err(|_| {
            self.error(
                element,
                format!("{what} {v} is out of range"),
                "fix the value",
            )
        })
    }
}

/// [`Source`] over ASCII lines.
struct Ascii<'a, 'l> {
    lines: &'l mut Lines<'a>,
    toks: SplitAsciiWhitespace<'a>,
    /// The section being read, for messages.
    section: &'static str,
}

impl<'a, 'l> Ascii<'a, 'l> {
    /// A source reading the lines of `section` from the cursor's position.
    fn new(lines: &'l mut Lines<'a>, section: &'static str) -> Self {
        Ascii {
            lines,
            toks: "".split_ascii_whitespace(),
            section,
        }
    }

    /// The next value of the current line.
    fn token(&mut self, what: &str, element: Option<i64>) -> Result<&'a str> {
        self.toks.next().ok_or_else(|| {
            self.lines.error(
                element,
                format!("line ends before the {what}"),
                "the line has too few values; fix or remove it",
            )
        })
    }
}

impl Source for Ascii<'_, '_> {
    fn begin(&mut self, what: std::fmt::Arguments) -> Result<()> {
        let line = match self.lines.next_line() {
            Some(l) => l?,
            None => {
                return Err(Error::parse(
                    self.lines.path(),
                    Location::Line(self.lines.line().max(1)),
                    None,
                    format!("file ends before the {what} in {}", self.section),
                    "the file is truncated; export it again",
                ))
            }
        };
        if line.starts_with('$') {
            return Err(self.lines.error(
                None,
                format!(
                    "{} ends early: expected the {what}, found {}",
                    self.section,
                    clip(line)
                ),
                "the section has fewer rows than it declares; fix the count",
            ));
        }
        self.toks = line.split_ascii_whitespace();
        Ok(())
    }

    fn int(&mut self, what: &str, element: Option<i64>) -> Result<i64> {
        let tok = self.token(what, element)?;
        self.lines.int(tok, what, element)
    }

    fn size(&mut self, what: &str, element: Option<i64>) -> Result<u64> {
        let tok = self.token(what, element)?;
        parse_int(tok, what, self.lines.path(), self.lines.loc(), element)
    }

    fn float(&mut self, what: &str, element: Option<i64>) -> Result<f64> {
        let tok = self.token(what, element)?;
        parse_f64(tok, what, self.lines.path(), self.lines.loc(), element)
    }

    fn left(&self) -> Option<usize> {
        Some(self.toks.clone().count())
    }

    fn end(&mut self, element: Option<i64>) -> Result<()> {
        match self.toks.next() {
            None => Ok(()),
            Some(tok) => Err(self.lines.error(
                element,
                format!(
                    "unexpected extra value {:?} at the end of the line",
                    clip(tok)
                ),
                "remove it, or check the counts and columns of this row",
            )),
        }
    }

    fn loc(&self) -> Location {
        self.lines.loc()
    }

    fn bytes_left(&self) -> usize {
        self.lines
            .bytes()
            .len()
            .saturating_sub(self.lines.byte_pos())
    }

    fn error(&self, element: Option<i64>, message: String, hint: &str) -> Error {
        self.lines.error(element, message, hint)
    }
}

/// [`Source`] over binary data.
struct Binary<'a> {
    bin: Bin<'a>,
    path: &'a Path,
    /// Width of `size_t` (Gmsh 4.1 binary).
    size_t: usize,
    /// Start of the current record.
    start: usize,
}

impl<'a> Binary<'a> {
    /// A source reading binary values from the cursor's position.
    fn new(lines: &Lines<'a>, endian: Endian, size_t: usize) -> Self {
        let pos = lines.byte_pos();
        Binary {
            bin: Bin::new(lines.path(), lines.bytes(), pos, endian.big),
            path: lines.path(),
            size_t,
            start: pos,
        }
    }
}

impl Source for Binary<'_> {
    fn begin(&mut self, _what: std::fmt::Arguments) -> Result<()> {
        self.start = self.bin.pos;
        Ok(())
    }

    fn int(&mut self, what: &str, _element: Option<i64>) -> Result<i64> {
        Ok(self.bin.i32(what)?.into())
    }

    fn size(&mut self, what: &str, _element: Option<i64>) -> Result<u64> {
        if self.size_t == 4 {
            // A 4-byte size_t is unsigned: reinterpret the bits.
            Ok(u64::from(self.bin.i32(what)? as u32))
        } else {
            self.bin.u64(what)
        }
    }

    fn float(&mut self, what: &str, element: Option<i64>) -> Result<f64> {
        let at = self.bin.pos;
        let v = self.bin.f64(what)?;
        if !v.is_finite() {
            return Err(Error::parse(
                self.path,
                Location::Byte(at as u64),
                element,
                format!("{what} is {v}, not a finite number"),
                "replace NaN or infinite values with real coordinates",
            ));
        }
        Ok(v)
    }

    fn left(&self) -> Option<usize> {
        None
    }

    fn end(&mut self, _element: Option<i64>) -> Result<()> {
        Ok(())
    }

    fn loc(&self) -> Location {
        Location::Byte(self.start as u64)
    }

    fn bytes_left(&self) -> usize {
        self.bin.remaining()
    }

    fn error(&self, element: Option<i64>, message: String, hint: &str) -> Error {
        Error::parse(self.path, self.loc(), element, message, hint)
    }
}

/// Read a line holding one count (the first line of a Gmsh 1/2 node or element section).
fn read_count(lines: &mut Lines, section: &str) -> Result<u64> {
    let line = match lines.next_line() {
        Some(l) => l?,
        None => {
            return Err(Error::parse(
                lines.path(),
                Location::Line(lines.line().max(1)),
                None,
                format!("file ends before the count of {section}"),
                "the file is truncated; export it again",
            ))
        }
    };
    let mut toks = line.split_ascii_whitespace();
    match (toks.next(), toks.next()) {
        (Some(tok), None) if !tok.starts_with('$') => {
            lines.int(tok, &format!("count of {section}"), None)
        }
        _ => Err(lines.error(
            None,
            format!("expected the count of {section}, found {:?}", clip(line)),
            "the first line of the section gives the number of rows",
        )),
    }
}

/// The three coordinates of node `id`.
fn read_point(src: &mut dyn Source, id: i64) -> Result<[f64; 3]> {
    Ok([
        src.float("x coordinate", Some(id))
            .map_err(Error::about_node)?,
        src.float("y coordinate", Some(id))
            .map_err(Error::about_node)?,
        src.float("z coordinate", Some(id))
            .map_err(Error::about_node)?,
    ])
}

/// Error for an element type whose size is unknown in a binary block, which then cannot be
/// skipped.
fn unknown_binary_type(src: &dyn Source, etype: i32) -> Error {
    src.error(
        None,
        format!("unknown element type {etype} in a binary block; its size is unknown"),
        "export the mesh with only standard element types, or as ascii",
    )
}

/// The state of one parse: what was read so far and what was skipped.
struct Reader<'a> {
    path: &'a Path,
    header: Header,
    raw: RawMesh,
    ids: IdMap,
    /// Elements ignored, per type, for one note each.
    ignored: BTreeMap<i32, usize>,
    /// Higher-order elements reduced to their corners, per type.
    corners_only: BTreeMap<i32, usize>,
    /// First physical tag of each Gmsh 4.1 entity, by (dimension, entity tag).
    physical: HashMap<(i32, i32), i32>,
    /// Node ids of the element being read (reused between elements).
    nodes: Vec<i64>,
}

impl<'a> Reader<'a> {
    /// An empty reader for a file with this header.
    fn new(path: &'a Path, header: Header) -> Self {
        Reader {
            path,
            header,
            raw: RawMesh::new(header.format()),
            ids: IdMap::default(),
            ignored: BTreeMap::new(),
            corners_only: BTreeMap::new(),
            physical: HashMap::new(),
            nodes: Vec::new(),
        }
    }

    /// Read the section opened by the line `name`.
    fn section(&mut self, lines: &mut Lines<'a>, name: &str) -> Result<()> {
        match (self.header, name) {
            (Header::V1, "$NOD") => self.nodes_v2(lines, "$NOD"),
            (Header::V1, "$ELM") => self.elements_ascii_v2(lines, "$ELM"),
            (Header::V2 { .. }, "$Nodes") => self.nodes_v2(lines, "$Nodes"),
            (Header::V2 { binary: None }, "$Elements") => {
                self.elements_ascii_v2(lines, "$Elements")
            }
            (Header::V2 { binary: Some(e) }, "$Elements") => self.elements_binary_v2(lines, e),
            (Header::V4 { .. }, "$Entities") => {
                self.with_source(lines, "$Entities", |r, src| r.entities_v4(src))
            }
            (Header::V4 { .. }, "$Nodes") => {
                self.with_source(lines, "$Nodes", |r, src| r.nodes_v4(src))
            }
            (Header::V4 { .. }, "$Elements") => {
                self.with_source(lines, "$Elements", |r, src| r.elements_v4(src))
            }
            // Names of physical groups: regions are numbered by tag, names are not needed.
            (_, "$PhysicalNames") => skip_section(lines, name),
            _ => {
                skip_section(lines, name)?;
                self.raw.notes.push(format!(
                    "skipped section {} (not needed for the mesh)",
                    clip(name)
                ));
                Ok(())
            }
        }
    }

    /// Run `read` over the data of section `name` (ASCII or binary as the header says), then
    /// check the section's closing line.
    fn with_source(
        &mut self,
        lines: &mut Lines<'a>,
        name: &'static str,
        read: impl FnOnce(&mut Self, &mut dyn Source) -> Result<()>,
    ) -> Result<()> {
        let binary = match self.header {
            Header::V2 { binary: Some(e) } => Some((e, 8)),
            Header::V4 { binary } => binary,
            _ => None,
        };
        let end = end_marker(name);
        match binary {
            Some((endian, size_t)) => {
                let mut src = Binary::new(lines, endian, size_t);
                read(self, &mut src)?;
                expect_end_binary(lines, src.bin.pos, &end)
            }
            None => {
                read(self, &mut Ascii::new(lines, name))?;
                expect_end(lines, &end, name)
            }
        }
    }

    /// Record point `p` with file id `id`.
    fn add_point(&mut self, id: i64, p: [f64; 3], loc: Location) -> Result<()> {
        let index = u32::try_from(self.raw.points.len()).map_err(|_| {
            Error::parse(
                self.path,
                loc,
                Some(id),
                "more nodes than lancet can index (2^32)",
                "split the mesh",
            )
        })?;
        self.ids.insert(id, index, self.path, loc)?;
        self.raw.points.push(p);
        self.raw.point_ids.push(id);
        Ok(())
    }

    /// Reserve room for `count` more points, at most what `bytes_left` could hold.
    fn reserve_points(&mut self, count: u64, bytes_left: usize) {
        // A node needs at least 8 bytes ("1 0 0 0\n" in ASCII, more in binary).
        let n = capacity(count, bytes_left, 8);
        self.raw.points.reserve(n);
        self.raw.point_ids.reserve(n);
    }

    /// Gmsh 1 `$NOD` and Gmsh 2 `$Nodes`: a count line, then `id x y z` rows (binary: int id
    /// and three doubles per node).
    fn nodes_v2(&mut self, lines: &mut Lines<'a>, name: &'static str) -> Result<()> {
        let count = read_count(lines, name)?;
        // A binary node is an int and three doubles. Rows of a count the rest of the file
        // cannot hold are read from whatever follows, and the error they meet (a misread id)
        // would hide the cause: it is said first.
        let row = 4 + 3 * 8;
        let left = lines.bytes().len().saturating_sub(lines.byte_pos()) as u64;
        let binary = matches!(self.header, Header::V2 { binary: Some(_) });
        let impossible = binary && count.saturating_mul(row) > left;
        self.with_source(lines, name, |r, src| {
            r.reserve_points(count, src.bytes_left());
            for i in 0..count {
                src.begin(format_args!("node {} of {count}", i + 1))?;
                let id = src.int("node id", None)?;
                let p = read_point(src, id)?;
                src.end(Some(id))?;
                r.add_point(id, p, src.loc())?;
            }
            Ok(())
        })
        .map_err(|e| match e {
            Error::Parse(mut p) if impossible => {
                p.message = format!(
                    "{name} declares {count} nodes, impossible for the file size (at least \
                     {row} bytes each, {left} bytes left); reading on: {}",
                    p.message
                );
                p.hint = "the count line is wrong or the file is truncated; export the mesh \
                          again"
                    .into();
                Error::Parse(p)
            }
            e => e,
        })
    }

    /// Gmsh 1 `$ELM` (`id type reg-phys reg-elem n nodes...`) and Gmsh 2 ASCII `$Elements`
    /// (`id type ntags tags... nodes...`); the first tag is the physical group, the region.
    fn elements_ascii_v2(&mut self, lines: &mut Lines<'a>, name: &'static str) -> Result<()> {
        let count = read_count(lines, name)?;
        let v1 = self.header == Header::V1;
        let mut src = Ascii::new(lines, name);
        for i in 0..count {
            src.begin(format_args!("element {} of {count}", i + 1))?;
            let id = src.int("element id", None)?;
            let etype = src.int32("element type", Some(id))?;
            let region = if v1 {
                let region = src.int32("physical region", Some(id))?;
                src.int("elementary region", Some(id))?;
                let declared = src.size("number of nodes", Some(id))?;
                let listed = src.left().unwrap_or(0);
                if declared != listed as u64 {
                    return Err(src.error(
                        Some(id),
                        format!("element declares {declared} nodes but lists {listed}"),
                        "fix the node count or the node list",
                    ));
                }
                region
            } else {
                let ntags = src.size("number of tags", Some(id))?;
                let mut region = 0;
                for t in 0..ntags {
                    let tag = src.int32("tag", Some(id))?;
                    if t == 0 {
                        region = tag;
                    }
                }
                region
            };
            self.element_nodes(&mut src, etype, id, false)?;
            src.end(Some(id))?;
            self.push_element(etype, id, region, src.loc())?;
        }
        expect_end(lines, &end_marker(name), name)
    }

    /// Gmsh 2 binary `$Elements`: a count line, then blocks of one element type, each with a
    /// header `type count ntags` and per element `id tags... nodes...`, all ints.
    fn elements_binary_v2(&mut self, lines: &mut Lines<'a>, endian: Endian) -> Result<()> {
        let count = read_count(lines, "$Elements")?;
        let mut src = Binary::new(lines, endian, 8);
        let mut read: u64 = 0;
        while read < count {
            src.begin(format_args!("element block header"))?;
            let etype = src.int32("element type", None)?;
            let follow = src.int("number of elements in the block", None)?;
            let ntags = src.int("number of tags", None)?;
            if element_type(etype).is_none() {
                return Err(unknown_binary_type(&src, etype));
            }
            if follow <= 0 || ntags < 0 || follow as u64 > count - read {
                return Err(src.error(
                    None,
                    format!(
                        "element block declares {follow} elements with {ntags} tags, \
                         but {} of the {count} elements remain",
                        count - read
                    ),
                    "the block header is damaged; export the file again",
                ));
            }
            for _ in 0..follow {
                src.begin(format_args!("element"))?;
                let id = src.int("element id", None)?;
                let mut region = 0;
                for t in 0..ntags {
                    let tag = src.int32("tag", Some(id))?;
                    if t == 0 {
                        region = tag;
                    }
                }
                self.element_nodes(&mut src, etype, id, false)?;
                self.push_element(etype, id, region, src.loc())?;
            }
            read += follow as u64;
        }
        expect_end_binary(lines, src.bin.pos, "$EndElements")
    }

    /// Gmsh 4.1 `$Entities`: only the first physical tag of each entity is kept (it is the
    /// region of the elements of that entity).
    fn entities_v4(&mut self, src: &mut dyn Source) -> Result<()> {
        src.begin(format_args!("entity counts"))?;
        let mut counts = [0u64; 4];
        for c in &mut counts {
            *c = src.size("entity count", None)?;
        }
        src.end(None)?;
        for (dim, &n) in (0i32..).zip(&counts) {
            for i in 0..n {
                src.begin(format_args!("entity {} of {n} of dimension {dim}", i + 1))?;
                let tag = src.int32("entity tag", None)?;
                // Points give a position, other entities a bounding box.
                let floats = if dim == 0 { 3 } else { 6 };
                for _ in 0..floats {
                    src.float("bounding box coordinate", None)?;
                }
                let nphys = src.size("number of physical tags", None)?;
                for p in 0..nphys {
                    let phys = src.int32("physical tag", None)?;
                    if p == 0 {
                        self.physical.insert((dim, tag), phys);
                    }
                }
                if dim > 0 {
                    let nbound = src.size("number of bounding entities", None)?;
                    for _ in 0..nbound {
                        src.int("bounding entity tag", None)?;
                    }
                }
                src.end(None)?;
            }
        }
        Ok(())
    }

    /// Gmsh 4.1 `$Nodes`: a header, then per entity block a header, the block's node tags,
    /// then their coordinates (plus parametric coordinates when flagged).
    fn nodes_v4(&mut self, src: &mut dyn Source) -> Result<()> {
        src.begin(format_args!("header of $Nodes"))?;
        let blocks = src.size("number of entity blocks", None)?;
        let declared = src.size("number of nodes", None)?;
        src.size("minimum node tag", None)?;
        src.size("maximum node tag", None)?;
        src.end(None)?;
        self.reserve_points(declared, src.bytes_left());
        let mut total: u64 = 0;
        let mut tags = Vec::new();
        for b in 0..blocks {
            src.begin(format_args!("header of node block {} of {blocks}", b + 1))?;
            let dim = src.int32("entity dimension", None)?;
            src.int32("entity tag", None)?;
            let parametric = src.int32("parametric flag", None)?;
            let n = src.size("number of nodes in the block", None)?;
            src.end(None)?;
            if !(0..=3).contains(&dim) || !(0..=1).contains(&parametric) {
                return Err(src.error(
                    None,
                    format!(
                        "node block has entity dimension {dim} and parametric flag \
                         {parametric}; expected 0..3 and 0 or 1"
                    ),
                    "the block header is damaged; export the file again",
                ));
            }
            // Parametric coordinates follow x y z: one per dimension of the entity.
            let extra = if parametric == 1 { dim } else { 0 };
            tags.clear();
            tags.reserve(capacity(n, src.bytes_left(), 2));
            for i in 0..n {
                src.begin(format_args!(
                    "tag of node {} of {n} in block {}",
                    i + 1,
                    b + 1
                ))?;
                tags.push(src.id("node tag", None)?);
                src.end(None)?;
            }
            for &tag in &tags {
                src.begin(format_args!("coordinates of node {tag}"))?;
                let p = read_point(src, tag)?;
                for _ in 0..extra {
                    src.float("parametric coordinate", Some(tag))?;
                }
                src.end(Some(tag))?;
                self.add_point(tag, p, src.loc())?;
            }
            total = total.saturating_add(n);
        }
        if total != declared {
            return Err(src.error(
                None,
                format!("the node blocks hold {total} nodes but the header declares {declared}"),
                "fix the count in the first line of $Nodes",
            ));
        }
        Ok(())
    }

    /// Gmsh 4.1 `$Elements`: a header, then per entity block a header (dimension, entity,
    /// type, count) and one `tag nodes...` record per element.
    fn elements_v4(&mut self, src: &mut dyn Source) -> Result<()> {
        src.begin(format_args!("header of $Elements"))?;
        let blocks = src.size("number of entity blocks", None)?;
        let declared = src.size("number of elements", None)?;
        src.size("minimum element tag", None)?;
        src.size("maximum element tag", None)?;
        src.end(None)?;
        let mut total: u64 = 0;
        for b in 0..blocks {
            src.begin(format_args!(
                "header of element block {} of {blocks}",
                b + 1
            ))?;
            let dim = src.int32("entity dimension", None)?;
            let entity = src.int32("entity tag", None)?;
            let etype = src.int32("element type", None)?;
            let n = src.size("number of elements in the block", None)?;
            src.end(None)?;
            if src.left().is_none() && element_type(etype).is_none() {
                return Err(unknown_binary_type(src, etype));
            }
            // The region is the entity's physical group; without one, the entity itself.
            let region = self.physical.get(&(dim, entity)).copied().unwrap_or(entity);
            for i in 0..n {
                src.begin(format_args!("element {} of {n} in block {}", i + 1, b + 1))?;
                let id = src.id("element tag", None)?;
                self.element_nodes(src, etype, id, true)?;
                src.end(Some(id))?;
                self.push_element(etype, id, region, src.loc())?;
            }
            total = total.saturating_add(n);
        }
        if total != declared {
            return Err(src.error(
                None,
                format!(
                    "the element blocks hold {total} elements but the header declares {declared}"
                ),
                "fix the count in the first line of $Elements",
            ));
        }
        Ok(())
    }

    /// Read the node ids of element `id` of type `etype` into `self.nodes`: as many as the
    /// type has (ASCII lines must list exactly that many). `wide` ids are `size_t` (4.1).
    fn element_nodes(
        &mut self,
        src: &mut dyn Source,
        etype: i32,
        id: i64,
        wide: bool,
    ) -> Result<()> {
        let n = match (element_type(etype), src.left()) {
            (Some((n, _, name)), Some(listed)) if listed != n => {
                return Err(src.error(
                    Some(id),
                    format!("a {name} (type {etype}) has {n} nodes, but the line lists {listed}"),
                    "fix the node list or the element type",
                ))
            }
            (Some((n, _, _)), _) => n,
            // Unknown type in ASCII: take the rest of the line; the element is ignored.
            (None, Some(listed)) => listed,
            (None, None) => return Err(unknown_binary_type(src, etype)),
        };
        self.nodes.clear();
        for _ in 0..n {
            let node = if wide {
                src.id("node id", Some(id))?
            } else {
                src.int("node id", Some(id))?
            };
            self.nodes.push(node);
        }
        Ok(())
    }

    /// Keep, ignore or refuse the element whose nodes are in `self.nodes`.
    fn push_element(&mut self, etype: i32, id: i64, region: i32, loc: Location) -> Result<()> {
        let Some((n, kind, name)) = element_type(etype) else {
            *self.ignored.entry(etype).or_default() += 1;
            return Ok(());
        };
        match kind {
            Kind::Other => *self.ignored.entry(etype).or_default() += 1,
            Kind::Solid => {
                return Err(Error::parse(
                    self.path,
                    loc,
                    Some(id),
                    format!(
                        "unsupported element type {etype} ({name}); lancet simulates tetrahedra"
                    ),
                    "convert to tetrahedra, e.g. mesh the geometry again with \
                     `gmsh -3 model.geo -o model.msh` without recombination",
                ))
            }
            Kind::Tet => {
                let nodes = self.corners::<4>(id, loc)?;
                self.raw.tets.push(RawTet {
                    nodes,
                    region,
                    id,
                    location: loc,
                });
                if n > 4 {
                    *self.corners_only.entry(etype).or_default() += 1;
                }
            }
            Kind::Triangle => {
                let nodes = self.corners::<3>(id, loc)?;
                self.raw.triangles.push(RawTriangle { nodes, tag: region });
                if n > 3 {
                    *self.corners_only.entry(etype).or_default() += 1;
                }
            }
        }
        Ok(())
    }

    /// The point indices of the first `N` nodes of the current element (Gmsh lists the
    /// corners of every element first).
    fn corners<const N: usize>(&self, id: i64, loc: Location) -> Result<[u32; N]> {
        let mut out = [0u32; N];
        for (o, &node) in out.iter_mut().zip(&self.nodes) {
            *o = self.ids.get(node, self.path, loc, id)?;
        }
        Ok(out)
    }

    /// The raw mesh, with one note per kind of element ignored or simplified.
    fn finish(mut self) -> RawMesh {
        for (&t, n) in &self.ignored {
            self.raw.notes.push(match element_type(t) {
                Some((_, _, name)) => format!("ignored {n} {name} elements (type {t})"),
                None => format!("ignored {n} elements of unknown type {t}"),
            });
        }
        for (&t, n) in &self.corners_only {
            let Some((_, kind, name)) = element_type(t) else {
                continue;
            };
            let corners = if kind == Kind::Tet { 4 } else { 3 };
            let extra = if t == 11 || t == 9 {
                "mid-edge"
            } else {
                "higher-order"
            };
            self.raw.notes.push(format!(
                "dropped the {extra} nodes of {n} {name} elements (type {t}), \
                 keeping their {corners} corners"
            ));
        }
        self.raw
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn end_markers_follow_the_case_of_the_section_name() {
        assert_eq!(end_marker("$Nodes"), "$EndNodes");
        assert_eq!(end_marker("$NOD"), "$ENDNOD");
        assert_eq!(end_marker("$ELM"), "$ENDELM");
    }

    #[test]
    fn capacity_is_capped_by_the_bytes_left() {
        assert_eq!(capacity(u64::MAX, 80, 8), 10);
        assert_eq!(capacity(3, 80, 8), 3);
        assert_eq!(capacity(5, 80, 0), 5);
    }

    #[test]
    fn every_known_element_type_has_at_least_its_corners() {
        for t in 0..200 {
            if let Some((n, kind, _)) = element_type(t) {
                match kind {
                    Kind::Tet => assert!(n >= 4, "type {t}"),
                    Kind::Triangle => assert!(n >= 3, "type {t}"),
                    _ => assert!(n >= 1, "type {t}"),
                }
            }
        }
    }
}
