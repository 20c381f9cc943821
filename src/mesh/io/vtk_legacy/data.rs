//! The values of a legacy VTK section: their type, and the ASCII or big-endian binary data
//! they are read from.

use super::super::text::{Bin, Tokens};
use crate::error::{Error, Location, Result};

/// A data type named in a VTK file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Scalar {
    Bit,
    /// Signed integer of this many bytes.
    Int(usize),
    /// Unsigned integer of this many bytes.
    UInt(usize),
    Float(usize),
    Str,
}

impl Scalar {
    /// The type named `name`, if VTK knows it.
    pub(super) fn parse(name: &str) -> Option<Scalar> {
        let s = match name.to_ascii_lowercase().as_str() {
            "bit" => Scalar::Bit,
            "char" | "vtktypeint8" => Scalar::Int(1),
            "unsigned_char" | "vtktypeuint8" => Scalar::UInt(1),
            "short" | "vtktypeint16" => Scalar::Int(2),
            "unsigned_short" | "vtktypeuint16" => Scalar::UInt(2),
            "int" | "vtktypeint32" => Scalar::Int(4),
            "unsigned_int" | "vtktypeuint32" => Scalar::UInt(4),
            "long" | "vtktypeint64" | "vtkidtype" => Scalar::Int(8),
            "unsigned_long" | "vtktypeuint64" => Scalar::UInt(8),
            "float" => Scalar::Float(4),
            "double" => Scalar::Float(8),
            "string" | "utf8_string" => Scalar::Str,
            _ => return None,
        };
        Some(s)
    }
}

/// Numbers from an ASCII token stream or a big-endian binary block.
pub(super) enum Data<'r, 'a> {
    Ascii(&'r mut Tokens<'a>),
    Binary(Bin<'a>),
}

impl Data<'_, '_> {
    /// Where the next (binary) or last (ASCII) value is.
    pub(super) fn loc(&self) -> Location {
        match self {
            Data::Ascii(t) => t.loc(),
            Data::Binary(b) => Location::Byte(b.pos as u64),
        }
    }

    /// An error at the current position.
    pub(super) fn error(&self, element: Option<i64>, msg: impl Into<String>, hint: &str) -> Error {
        match self {
            Data::Ascii(t) => t.error(element, msg, hint),
            Data::Binary(b) => b.error(element, msg, hint),
        }
    }

    /// One integer value of type `ty`.
    pub(super) fn int(&mut self, ty: Scalar, what: &str, element: Option<i64>) -> Result<i64> {
        match self {
            Data::Ascii(t) => t.int(what, element),
            Data::Binary(b) => match ty {
                Scalar::Int(4) => b.i32(what).map(i64::from),
                Scalar::Int(8) => b.i64(what),
                Scalar::Int(n) => Ok(be_int(b.take(n, what)?, true)),
                Scalar::UInt(8) => {
                    let v = b.u64(what)?;
                    i64::try_from(v).map_err(|_| {
                        b.pos -= 8;
                        b.error(element, format!("{what} {v} is too large"), "fix the value")
                    })
                }
                Scalar::UInt(n) => Ok(be_int(b.take(n, what)?, false)),
                _ => Err(b.error(
                    element,
                    format!("{what} must be stored as integers, not {ty:?}"),
                    "write the array as int or vtktypeint64",
                )),
            },
        }
    }

    /// One value of type `ty` as a float (finite).
    pub(super) fn float(&mut self, ty: Scalar, what: &str, element: Option<i64>) -> Result<f64> {
        if !matches!(ty, Scalar::Float(_)) && matches!(self, Data::Binary(_)) {
            return self.int(ty, what, element).map(|v| v as f64);
        }
        match self {
            Data::Ascii(t) => t.f64(what, element),
            Data::Binary(b) => {
                let start = b.pos;
                let v = match ty {
                    Scalar::Float(4) => b.f32(what)? as f64,
                    _ => b.f64(what)?,
                };
                if !v.is_finite() {
                    b.pos = start;
                    return Err(b.error(
                        element,
                        format!("{what} is {v}, not a finite number"),
                        "replace NaN or infinite values with real coordinates",
                    ));
                }
                Ok(v)
            }
        }
    }

    /// Skip `n` values of type `ty`.
    pub(super) fn skip(&mut self, ty: Scalar, n: usize, what: &str) -> Result<()> {
        match self {
            Data::Ascii(t) => {
                for _ in 0..n {
                    t.expect(what)?;
                }
                Ok(())
            }
            Data::Binary(b) => {
                let bytes = match ty {
                    Scalar::Bit => n.div_ceil(8),
                    Scalar::Int(s) | Scalar::UInt(s) | Scalar::Float(s) => {
                        n.checked_mul(s).ok_or_else(|| {
                            b.error(None, format!("{what}: size overflows"), "fix the count")
                        })?
                    }
                    Scalar::Str => {
                        return Err(b.error(
                            None,
                            format!("{what}: binary string arrays are not supported"),
                            "remove the array or write the file as ascii",
                        ))
                    }
                };
                b.take(bytes, what).map(|_| ())
            }
        }
    }
}

/// A big-endian integer of up to 8 bytes, sign-extended when `signed`.
fn be_int(bytes: &[u8], signed: bool) -> i64 {
    let mut v: i64 = if signed && bytes.first().is_some_and(|b| b & 0x80 != 0) {
        -1
    } else {
        0
    };
    for &b in bytes {
        v = (v << 8) | b as i64;
    }
    v
}
