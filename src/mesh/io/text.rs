//! Line-oriented reading shared by the text readers: line numbers for every token, numbers
//! checked for being finite, and errors that name the file, line and element.

use std::path::Path;
use std::str::FromStr;

use crate::error::{Error, Location, Result};

/// The UTF-8 encoding of U+FEFF, the byte-order mark.
const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

/// A cursor over the lines of a (mostly) text file, tracking 1-based line numbers and byte
/// offsets so that binary sections (Gmsh, VTK) can be read from the same position.
///
/// Cloning is cheap (a few words) and is how a reader peeks ahead.
#[derive(Clone)]
pub(crate) struct Lines<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    pos: usize,
    line: usize,
    /// Lines starting with this character (after leading white space) are skipped.
    comment: Option<u8>,
}

impl<'a> Lines<'a> {
    /// A cursor at the start of `bytes`, after a UTF-8 byte-order mark if the file starts with
    /// one (editors on Windows write it); `comment` marks comment lines to skip. Byte offsets
    /// stay offsets in the file.
    pub(crate) fn new(path: &'a Path, bytes: &'a [u8], comment: Option<u8>) -> Self {
        Lines {
            path,
            bytes,
            pos: if bytes.starts_with(UTF8_BOM) {
                UTF8_BOM.len()
            } else {
                0
            },
            line: 0,
            comment,
        }
    }

    /// The path, for messages.
    pub(crate) fn path(&self) -> &'a Path {
        self.path
    }

    /// 1-based number of the line last returned.
    pub(crate) fn line(&self) -> usize {
        self.line
    }

    /// Location of the line last returned.
    pub(crate) fn loc(&self) -> Location {
        Location::Line(self.line)
    }

    /// Byte offset of the start of the next line.
    pub(crate) fn byte_pos(&self) -> usize {
        self.pos
    }

    /// The whole input.
    pub(crate) fn bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// Continue after a binary block: move to `pos` and count the newlines skipped over so
    /// that later line numbers stay right.
    pub(crate) fn seek(&mut self, pos: usize) {
        let pos = pos.min(self.bytes.len());
        if pos > self.pos {
            self.line += self.bytes[self.pos..pos]
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
        }
        self.pos = pos;
    }

    /// The next raw line (without its end-of-line), whatever it holds; `None` at the end.
    pub(crate) fn next_raw(&mut self) -> Option<Result<&'a str>> {
        if self.pos >= self.bytes.len() {
            return None;
        }
        let rest = &self.bytes[self.pos..];
        let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
        let raw = &rest[..len];
        self.pos += (len + 1).min(rest.len());
        self.line += 1;
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        Some(std::str::from_utf8(raw).map_err(|_| {
            self.error(
                None,
                "line is not valid text (utf-8)",
                "the file may be binary or corrupted; check its format",
            )
        }))
    }

    /// The next line that is neither blank nor a comment, trimmed; `None` at the end.
    pub(crate) fn next_line(&mut self) -> Option<Result<&'a str>> {
        loop {
            let line = match self.next_raw()? {
                Ok(l) => l.trim(),
                Err(e) => return Some(Err(e)),
            };
            if line.is_empty() {
                continue;
            }
            if let Some(c) = self.comment {
                if line.as_bytes()[0] == c {
                    continue;
                }
            }
            return Some(Ok(line));
        }
    }

    /// The next content line without consuming it; `None` at the end.
    pub(crate) fn peek_line(&self) -> Option<Result<&'a str>> {
        self.clone().next_line()
    }

    /// The next content line, or an error saying the file ended before `what`.
    pub(crate) fn expect_line(&mut self, what: &str) -> Result<&'a str> {
        match self.next_line() {
            Some(r) => r,
            None => Err(Error::parse(
                self.path,
                Location::Unknown,
                None,
                format!("file ends before {what}"),
                "the file is truncated; export it again",
            )),
        }
    }

    /// An error at the current line.
    pub(crate) fn error(
        &self,
        element: Option<i64>,
        message: impl Into<String>,
        hint: impl Into<String>,
    ) -> Error {
        Error::parse(self.path, self.loc(), element, message, hint)
    }

    /// Parse `tok` as a finite float, naming `what` it is in the error.
    pub(crate) fn f64(&self, tok: &str, what: &str, element: Option<i64>) -> Result<f64> {
        parse_f64(tok, what, self.path, self.loc(), element)
    }

    /// Parse `tok` as an integer of type `T`, naming `what` it is in the error.
    pub(crate) fn int<T: FromStr>(&self, tok: &str, what: &str, element: Option<i64>) -> Result<T> {
        parse_int(tok, what, self.path, self.loc(), element)
    }
}

/// A cursor over the white-space separated tokens of a text file, across lines, for formats
/// whose rows may wrap (Medit, VTK ASCII data). Text after a comment character on a line is
/// ignored. Errors name the line of the token last returned.
pub(crate) struct Tokens<'a> {
    lines: Lines<'a>,
    rest: std::str::SplitAsciiWhitespace<'a>,
    comment: Option<char>,
}

impl<'a> Tokens<'a> {
    /// Tokens of `lines`, from its current position.
    pub(crate) fn new(lines: Lines<'a>) -> Self {
        let comment = lines.comment.map(char::from);
        Tokens {
            lines,
            rest: "".split_ascii_whitespace(),
            comment,
        }
    }

    /// The underlying line cursor: use it only when no token of the current line is pending
    /// (see [`Tokens::line_done`]), for example to switch to a binary block.
    pub(crate) fn lines(&mut self) -> &mut Lines<'a> {
        &mut self.lines
    }

    /// Whether every token of the current line has been returned.
    pub(crate) fn line_done(&self) -> bool {
        self.rest.clone().next().is_none()
    }

    /// The tokens of the current line not yet returned (consumed).
    pub(crate) fn rest_of_line(&mut self) -> Vec<&'a str> {
        self.rest.by_ref().collect()
    }

    /// Location of the token last returned.
    pub(crate) fn loc(&self) -> Location {
        self.lines.loc()
    }

    /// The next token; `None` at the end of the input.
    pub(crate) fn next_token(&mut self) -> Option<Result<&'a str>> {
        loop {
            if let Some(t) = self.rest.next() {
                return Some(Ok(t));
            }
            let line = match self.lines.next_line()? {
                Ok(l) => l,
                Err(e) => return Some(Err(e)),
            };
            let line = match self.comment.and_then(|c| line.find(c)) {
                Some(i) => &line[..i],
                None => line,
            };
            self.rest = line.split_ascii_whitespace();
        }
    }

    /// The next token, or an error saying the file ended before `what`.
    pub(crate) fn expect(&mut self, what: &str) -> Result<&'a str> {
        match self.next_token() {
            Some(r) => r,
            None => Err(Error::parse(
                self.lines.path,
                Location::Unknown,
                None,
                format!("file ends before {what}"),
                "the file is truncated; export it again",
            )),
        }
    }

    /// The next token as a finite float.
    pub(crate) fn f64(&mut self, what: &str, element: Option<i64>) -> Result<f64> {
        let t = self.expect(what)?;
        self.lines.f64(t, what, element)
    }

    /// The next token as an integer of type `T`.
    pub(crate) fn int<T: FromStr>(&mut self, what: &str, element: Option<i64>) -> Result<T> {
        let t = self.expect(what)?;
        self.lines.int(t, what, element)
    }

    /// An error at the line of the token last returned.
    pub(crate) fn error(
        &self,
        element: Option<i64>,
        message: impl Into<String>,
        hint: impl Into<String>,
    ) -> Error {
        self.lines.error(element, message, hint)
    }
}

/// A capacity for `declared` items that the rest of the input (`remaining` bytes, at least
/// `min_item_bytes` per item) could actually hold, so that a corrupt count cannot make a
/// reader allocate gigabytes before it finds the file is short.
pub(crate) fn capped(declared: usize, remaining: usize, min_item_bytes: usize) -> usize {
    declared.min(remaining / min_item_bytes.max(1))
}

/// Split a line into white-space separated tokens.
pub(crate) fn tokens(line: &str) -> Vec<&str> {
    line.split_ascii_whitespace().collect()
}

/// Parse a finite float (Fortran-style `D` exponents accepted).
pub(crate) fn parse_f64(
    tok: &str,
    what: &str,
    path: &Path,
    loc: Location,
    element: Option<i64>,
) -> Result<f64> {
    let v: f64 = match tok.parse() {
        Ok(v) => v,
        Err(_) => match tok.replace(['D', 'd'], "e").parse() {
            Ok(v) => v,
            Err(_) => {
                return Err(Error::parse(
                    path,
                    loc,
                    element,
                    format!("{what} {tok:?} is not a number"),
                    "fix the value",
                ))
            }
        },
    };
    if !v.is_finite() {
        return Err(Error::parse(
            path,
            loc,
            element,
            format!("{what} is {tok}, not a finite number"),
            "replace NaN or infinite values with real coordinates",
        ));
    }
    Ok(v)
}

/// Parse an integer.
pub(crate) fn parse_int<T: FromStr>(
    tok: &str,
    what: &str,
    path: &Path,
    loc: Location,
    element: Option<i64>,
) -> Result<T> {
    tok.parse().map_err(|_| {
        Error::parse(
            path,
            loc,
            element,
            format!("{what} {tok:?} is not a valid integer"),
            "fix the value",
        )
    })
}

/// A cursor over a binary block, little- or big-endian, reporting byte offsets in errors.
pub(crate) struct Bin<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    /// Next byte to read.
    pub(crate) pos: usize,
    big_endian: bool,
}

impl<'a> Bin<'a> {
    /// A cursor at `pos` in `bytes`.
    pub(crate) fn new(path: &'a Path, bytes: &'a [u8], pos: usize, big_endian: bool) -> Self {
        Bin {
            path,
            bytes,
            pos,
            big_endian,
        }
    }

    /// Number of bytes after the cursor.
    pub(crate) fn remaining(&self) -> usize {
        self.bytes.len().saturating_sub(self.pos)
    }

    /// Take `n` bytes or fail with "truncated".
    pub(crate) fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
        match end {
            Some(end) => {
                let s = &self.bytes[self.pos..end];
                self.pos = end;
                Ok(s)
            }
            None => Err(Error::parse(
                self.path,
                Location::Byte(self.pos as u64),
                None,
                format!("binary data ends before {what}"),
                "the file is truncated; export it again",
            )),
        }
    }

    fn arr<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N, what)?);
        if self.big_endian {
            a.reverse();
        }
        Ok(a)
    }

    /// Read an `i32`.
    pub(crate) fn i32(&mut self, what: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.arr(what)?))
    }

    /// Read an `i64`.
    pub(crate) fn i64(&mut self, what: &str) -> Result<i64> {
        Ok(i64::from_le_bytes(self.arr(what)?))
    }

    /// Read a `u64`.
    pub(crate) fn u64(&mut self, what: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(self.arr(what)?))
    }

    /// Read an `f32`.
    pub(crate) fn f32(&mut self, what: &str) -> Result<f32> {
        Ok(f32::from_le_bytes(self.arr(what)?))
    }

    /// Read an `f64`.
    pub(crate) fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.arr(what)?))
    }

    /// Error at the current byte offset.
    pub(crate) fn error(
        &self,
        element: Option<i64>,
        message: impl Into<String>,
        hint: impl Into<String>,
    ) -> Error {
        Error::parse(
            self.path,
            Location::Byte(self.pos as u64),
            element,
            message,
            hint,
        )
    }
}
