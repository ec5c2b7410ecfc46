//! Reading the PLY body: a cursor over ascii lines or binary bytes that reads one typed
//! value at a time and turns a failed read into an error at its line or byte offset.

use std::path::Path;

use super::header::Scalar;
use crate::error::Error;

/// Why reading a value failed; turned into an [`Error`] with context by [`Body::error`].
#[derive(Debug)]
pub(super) enum Fault {
    /// No more records (ascii) or bytes (binary).
    EndOfData,
    /// Ascii record line ended before all properties were read.
    EndOfLine,
    /// Ascii token that is not a number of the expected kind.
    BadToken(String),
}

/// Position in the body: an ascii line cursor or a binary byte cursor.
pub(super) enum Body<'a> {
    Ascii {
        lines: std::str::Split<'a, char>,
        /// Line number of the current record (1-based, counted in the whole file).
        line: usize,
        tokens: std::str::SplitWhitespace<'a>,
    },
    Binary {
        bytes: &'a [u8],
        pos: usize,
        big_endian: bool,
    },
}

impl<'a> Body<'a> {
    /// Moves to the next record. Ascii: next non-blank line.
    pub(super) fn begin_record(&mut self) -> std::result::Result<(), Fault> {
        match self {
            Body::Ascii { lines, line, tokens } => loop {
                let Some(next) = lines.next() else {
                    return Err(Fault::EndOfData);
                };
                *line += 1;
                let t = next.split_whitespace();
                if t.clone().next().is_some() {
                    *tokens = t;
                    return Ok(());
                }
            },
            Body::Binary { .. } => Ok(()),
        }
    }

    /// Ascii: true when the current record line has values left.
    pub(super) fn has_extra_values(&self) -> bool {
        match self {
            Body::Ascii { tokens, .. } => tokens.clone().next().is_some(),
            Body::Binary { .. } => false,
        }
    }

    /// Reads one value of type `ty` as f64 (exact for every integer type).
    pub(super) fn scalar(&mut self, ty: Scalar) -> std::result::Result<f64, Fault> {
        match self {
            Body::Ascii { tokens, .. } => {
                let tok = tokens.next().ok_or(Fault::EndOfLine)?;
                parse_ascii_value(tok, ty).ok_or_else(|| Fault::BadToken(tok.to_string()))
            }
            Body::Binary { bytes, pos, big_endian } => {
                let start = *pos;
                let end = start.checked_add(ty.size()).ok_or(Fault::EndOfData)?;
                let raw = bytes.get(start..end).ok_or(Fault::EndOfData)?;
                let v = decode_binary(raw, ty, *big_endian).ok_or(Fault::EndOfData)?;
                *pos = end;
                Ok(v)
            }
        }
    }

    /// Skips `n` list items of type `ty`.
    pub(super) fn skip(&mut self, n: u64, ty: Scalar) -> std::result::Result<(), Fault> {
        match self {
            Body::Ascii { .. } => {
                for _ in 0..n {
                    self.scalar(ty)?;
                }
                Ok(())
            }
            Body::Binary { bytes, pos, .. } => {
                let len = n.checked_mul(ty.size() as u64).ok_or(Fault::EndOfData)?;
                let end = u64::try_from(*pos)
                    .ok()
                    .and_then(|p| p.checked_add(len))
                    .filter(|&e| e <= bytes.len() as u64)
                    .ok_or(Fault::EndOfData)?;
                *pos = usize::try_from(end).map_err(|_| Fault::EndOfData)?;
                Ok(())
            }
        }
    }

    /// Bytes left in a binary body (None for ascii).
    pub(super) fn binary_remaining(&self) -> Option<u64> {
        match self {
            Body::Binary { bytes, pos, .. } => Some(bytes.len().saturating_sub(*pos) as u64),
            Body::Ascii { .. } => None,
        }
    }

    /// Current position: the record's line (ascii) or the next byte's offset (binary).
    pub(super) fn location(&self) -> usize {
        match self {
            Body::Ascii { line, .. } => *line,
            Body::Binary { pos, .. } => *pos,
        }
    }

    /// An error at `location` (see [`Body::location`]): `path:line: msg` for ascii bodies,
    /// `path: msg (at byte offset N)` for binary ones.
    pub(super) fn error_at(&self, path: &Path, location: usize, msg: impl std::fmt::Display) -> Error {
        match self {
            Body::Ascii { .. } => Error::parse(path, location, msg.to_string()),
            Body::Binary { .. } => Error::invalid(path, format!("{msg} (at byte offset {location})")),
        }
    }

    /// An error at the current position. A failed read does not advance, so after a
    /// [`Fault`] this is where the unreadable value starts.
    pub(super) fn error(&self, path: &Path, msg: impl std::fmt::Display) -> Error {
        self.error_at(path, self.location(), msg)
    }

    /// Turns a [`Fault`] met while reading `what` into an [`Error`].
    pub(super) fn fault(&self, path: &Path, fault: Fault, what: &str) -> Error {
        match fault {
            Fault::EndOfData => match self {
                Body::Ascii { .. } => self.error(path, format!("file ends before {what}")),
                Body::Binary { bytes, .. } => {
                    self.error(path, format!("file is truncated: it ends ({} bytes) before {what}", bytes.len()))
                }
            },
            Fault::EndOfLine => self.error(path, format!("line ends before {what}")),
            Fault::BadToken(tok) => self.error(path, format!("'{tok}' is not a valid value for {what}")),
        }
    }
}

/// Parses an ascii token as a value of type `ty`. Integer types take integers (a float
/// token with no fractional part is tolerated); float types take any float syntax Rust
/// accepts, including `nan` and `inf` (rejected later for coordinates).
fn parse_ascii_value(tok: &str, ty: Scalar) -> Option<f64> {
    if ty.is_integer() {
        if let Ok(i) = tok.parse::<i64>() {
            return Some(i as f64);
        }
        let f = tok.parse::<f64>().ok()?;
        (f.is_finite() && f.fract() == 0.0).then_some(f)
    } else {
        tok.parse::<f64>().ok()
    }
}

/// Decodes one binary value; `raw` must be exactly `ty.size()` bytes.
fn decode_binary(raw: &[u8], ty: Scalar, big_endian: bool) -> Option<f64> {
    macro_rules! num {
        ($t:ty) => {{
            let a = raw.try_into().ok()?;
            if big_endian {
                <$t>::from_be_bytes(a) as f64
            } else {
                <$t>::from_le_bytes(a) as f64
            }
        }};
    }
    Some(match ty {
        Scalar::I8 => num!(i8),
        Scalar::U8 => num!(u8),
        Scalar::I16 => num!(i16),
        Scalar::U16 => num!(u16),
        Scalar::I32 => num!(i32),
        Scalar::U32 => num!(u32),
        Scalar::F32 => num!(f32),
        Scalar::F64 => num!(f64),
    })
}
