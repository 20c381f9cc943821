//! Reader for Gmsh `.msh` files: version 1 (`$NOD`/`$ELM`), 2.2 and 4.1, ASCII and binary.
//!
//! Tetrahedra become [`RawTet`](super::RawTet)s with the physical group as region; triangles
//! are kept as tagged surface elements; lines, points and quadrangles are ignored with one note
//! per kind. Higher order tets and triangles keep their corner nodes (Gmsh lists corners
//! first). Hexahedra, prisms and pyramids are refused: lancet simulates tetrahedra only.
//!
//! The record layouts of ASCII and binary files are the same sequence of values (binary only
//! fixes their widths), so the 4.1 sections and the 2.2 nodes are read once through the
//! `Source` trait, with an ASCII source that knows lines and a binary one that knows byte
//! offsets. Every count read from the file is untrusted: buffers are sized by what the remaining
//! bytes could hold, never by the declared count alone.
//!
//! Here: the header, the section loop and the element types; `source.rs` reads values (ASCII
//! or binary), `reader.rs` turns sections into the mesh.

mod reader;
mod source;

use std::path::Path;

use super::text::{Bin, Lines};
use super::{Format, RawMesh};
use crate::error::{Error, Location, Result};
use reader::Reader;
use source::Source;

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

/// Read a block of `n` records of at least `each` bytes with `read`. Where the bytes left cannot
/// hold them, the records are read from whatever follows, and the error they meet (a misread
/// tag or id, or the end of the data, which must come) would hide the cause: the cause is said
/// first, then where reading on failed. `each` is `None` for ASCII, whose lines say where
/// records end.
fn read_block<T>(
    src: &mut dyn Source,
    what: std::fmt::Arguments,
    n: u64,
    each: Option<u64>,
    read: impl FnOnce(&mut dyn Source) -> Result<T>,
) -> Result<T> {
    let left = src.bytes_left() as u64;
    let impossible = each.filter(|&e| n.saturating_mul(e) > left);
    read(src).map_err(|e| match (e, impossible) {
        (Error::Parse(mut p), Some(each)) => {
            p.message = format!(
                "{what}, impossible for the file size (at least {each} bytes each, {left} bytes \
                 left); reading on: {}",
                p.message
            );
            p.hint = "the count is wrong or the file is truncated; export the mesh again".into();
            Error::Parse(p)
        }
        (e, _) => e,
    })
}

/// The least bytes of a binary Gmsh 4.1 entity block's header (dimension, entity, and type or
/// parametric flag as ints, then a `size_t` count); `None` for ASCII.
fn block_header_bytes(src: &dyn Source) -> Option<u64> {
    src.size_width().map(|w| 12 + w as u64)
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
