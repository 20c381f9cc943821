//! Decoding a `.vtu` array's content: ASCII numbers, base64 and raw binary blocks, zlib
//! compression, headers of either width and byte order.

use std::borrow::Cow;
use std::io::Read;

use base64::Engine;

use super::super::text::{parse_f64, parse_int};
use super::{ArrayDesc, Decoded, Doc, Positions, Scalar, Source, Values, MAX_INFLATE_RATIO};
use crate::error::{Location, Result};

impl<'a> Doc<'a> {
    /// Decode an array's values; the piece's counts say it needs at most `max_values`, and
    /// compressed data declaring more is refused before it is inflated.
    pub(super) fn decode(&self, desc: &ArrayDesc, max_values: usize) -> Result<Decoded> {
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
        if !clean.len().is_multiple_of(4) {
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
        if !payload.len().is_multiple_of(size) {
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
