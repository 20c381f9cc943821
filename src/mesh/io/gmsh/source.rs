//! The values of a Gmsh section read record by record, from ASCII lines or binary bytes
//! through one [`Source`] trait, so that the 4.1 sections and the 2.2 nodes are read once for
//! both encodings.

use std::path::Path;
use std::str::SplitAsciiWhitespace;

use super::super::text::{parse_f64, parse_int, Bin, Lines};
use super::{clip, Endian};
use crate::error::{Error, Location, Result};

/// A stream of the values of one section, read record by record: an ASCII record is a line,
/// a binary record is just the next values.
pub(super) trait Source {
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
    /// The width of a `size_t` in binary sources; `None` for ASCII, whose records have no
    /// fixed size.
    fn size_width(&self) -> Option<usize>;
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
pub(super) struct Ascii<'a, 'l> {
    lines: &'l mut Lines<'a>,
    toks: SplitAsciiWhitespace<'a>,
    /// The section being read, for messages.
    section: &'static str,
}

impl<'a, 'l> Ascii<'a, 'l> {
    /// A source reading the lines of `section` from the cursor's position.
    pub(super) fn new(lines: &'l mut Lines<'a>, section: &'static str) -> Self {
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

    fn size_width(&self) -> Option<usize> {
        None
    }

    fn error(&self, element: Option<i64>, message: String, hint: &str) -> Error {
        self.lines.error(element, message, hint)
    }
}

/// [`Source`] over binary data.
pub(super) struct Binary<'a> {
    bin: Bin<'a>,
    path: &'a Path,
    /// Width of `size_t` (Gmsh 4.1 binary).
    size_t: usize,
    /// Start of the current record.
    start: usize,
}

impl<'a> Binary<'a> {
    /// A source reading binary values from the cursor's position.
    pub(super) fn new(lines: &Lines<'a>, endian: Endian, size_t: usize) -> Self {
        let pos = lines.byte_pos();
        Binary {
            bin: Bin::new(lines.path(), lines.bytes(), pos, endian.big),
            path: lines.path(),
            size_t,
            start: pos,
        }
    }
}

impl Binary<'_> {
    /// The byte the next value is read from.
    pub(super) fn pos(&self) -> usize {
        self.bin.pos
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

    fn size_width(&self) -> Option<usize> {
        Some(self.size_t)
    }

    fn error(&self, element: Option<i64>, message: String, hint: &str) -> Error {
        Error::parse(self.path, self.loc(), element, message, hint)
    }
}

/// The three coordinates of node `id`.
pub(super) fn read_point(src: &mut dyn Source, id: i64) -> Result<[f64; 3]> {
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
pub(super) fn unknown_binary_type(src: &dyn Source, etype: i32) -> Error {
    src.error(
        None,
        format!("unknown element type {etype} in a binary block; its size is unknown"),
        "export the mesh with only standard element types, or as ascii",
    )
}
