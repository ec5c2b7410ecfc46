//! The PLY header (module docs, "Format"): the body's encoding, the elements and their
//! typed properties.

use std::path::Path;

use crate::error::{Error, Result};

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    pub(super) fn from_name(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// Size in bytes in a binary body.
    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    pub(super) fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum PropKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
pub(super) struct Property {
    pub(super) name: String,
    pub(super) kind: PropKind,
}

#[derive(Debug, Clone)]
pub(super) struct Element {
    pub(super) name: String,
    pub(super) count: u64,
    pub(super) props: Vec<Property>,
    /// Header line of the `element` keyword (1-based).
    pub(super) line: usize,
}

impl Element {
    /// Smallest possible size of one record in a binary body (lists empty).
    pub(super) fn min_record_size(&self) -> u64 {
        self.props
            .iter()
            .map(|p| match p.kind {
                PropKind::Scalar(s) => s.size() as u64,
                PropKind::List { count, .. } => count.size() as u64,
            })
            .sum()
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Format {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

#[derive(Debug)]
pub(super) struct Header {
    pub(super) format: Format,
    pub(super) elements: Vec<Element>,
    /// Byte offset of the first body byte.
    pub(super) body_start: usize,
    /// Number of header lines, `end_header` included.
    pub(super) lines: usize,
}

/// Reads the header (module docs, "Format"): the body's format and the elements with
/// their properties, in file order.
pub(super) fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header> {
    if bytes.is_empty() {
        return Err(Error::parse(path, 1, "file is empty; expected 'ply' on the first line"));
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut pos = 0usize;
    let mut line_no = 0usize;
    while pos < bytes.len() {
        line_no += 1;
        let rest = bytes.get(pos..).unwrap_or_default();
        let (raw, next) = match rest.iter().position(|&b| b == b'\n') {
            Some(n) => (rest.get(..n).unwrap_or_default(), pos + n + 1),
            None => (rest, bytes.len()),
        };
        pos = next;
        let text = String::from_utf8_lossy(raw);
        let mut words = text.split_whitespace();
        let keyword = words.next();
        if line_no == 1 {
            if keyword != Some("ply") || words.next().is_some() {
                return Err(Error::parse(path, 1, "not a PLY file: the first line must be 'ply'"));
            }
            continue;
        }
        match keyword {
            None | Some("comment") | Some("obj_info") => {}
            Some("format") => {
                if format.is_some() {
                    return Err(Error::parse(path, line_no, "second 'format' line"));
                }
                let f = match words.next() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::BinaryLittleEndian,
                    Some("binary_big_endian") => Format::BinaryBigEndian,
                    Some(other) => {
                        return Err(Error::parse(
                            path,
                            line_no,
                            format!(
                                "unknown format '{other}'; expected ascii, binary_little_endian or binary_big_endian"
                            ),
                        ))
                    }
                    None => return Err(Error::parse(path, line_no, "'format' line names no format")),
                };
                if words.next().is_none() {
                    return Err(Error::parse(path, line_no, "'format' line has no version"));
                }
                format = Some(f);
            }
            Some("element") => {
                let (Some(name), Some(count)) = (words.next(), words.next()) else {
                    return Err(Error::parse(path, line_no, "expected 'element <name> <count>'"));
                };
                let count: u64 = count.parse().map_err(|_| {
                    Error::parse(
                        path,
                        line_no,
                        format!("element '{name}': count '{count}' is not a non-negative integer"),
                    )
                })?;
                if (name == "vertex" || name == "face") && elements.iter().any(|e| e.name == name) {
                    return Err(Error::parse(path, line_no, format!("second '{name}' element")));
                }
                elements.push(Element { name: name.to_string(), count, props: Vec::new(), line: line_no });
            }
            Some("property") => {
                let Some(element) = elements.last_mut() else {
                    return Err(Error::parse(path, line_no, "'property' before any 'element'"));
                };
                let type_error = |t: &str| Error::parse(path, line_no, format!("unknown property type '{t}'"));
                let kind = match words.next() {
                    Some("list") => {
                        let (Some(c), Some(i)) = (words.next(), words.next()) else {
                            return Err(Error::parse(
                                path,
                                line_no,
                                "expected 'property list <count type> <item type> <name>'",
                            ));
                        };
                        let count = Scalar::from_name(c).ok_or_else(|| type_error(c))?;
                        let item = Scalar::from_name(i).ok_or_else(|| type_error(i))?;
                        if !count.is_integer() {
                            return Err(Error::parse(
                                path,
                                line_no,
                                format!("list count type '{c}' is not an integer type"),
                            ));
                        }
                        PropKind::List { count, item }
                    }
                    Some(t) => PropKind::Scalar(Scalar::from_name(t).ok_or_else(|| type_error(t))?),
                    None => return Err(Error::parse(path, line_no, "'property' line has no type")),
                };
                let Some(name) = words.next() else {
                    return Err(Error::parse(path, line_no, "'property' line has no name"));
                };
                element.props.push(Property { name: name.to_string(), kind });
            }
            Some("end_header") => {
                let Some(format) = format else {
                    return Err(Error::parse(path, line_no, "header has no 'format' line"));
                };
                return Ok(Header { format, elements, body_start: pos, lines: line_no });
            }
            // Unknown keywords are tolerated like comments (see the module docs).
            Some(_) => {}
        }
    }
    Err(Error::parse(path, line_no, "header has no 'end_header' line"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use Scalar::*;

    #[test]
    fn all_type_names() {
        for (name, ty) in [
            ("char", I8),
            ("int8", I8),
            ("uchar", U8),
            ("uint8", U8),
            ("short", I16),
            ("int16", I16),
            ("ushort", U16),
            ("uint16", U16),
            ("int", I32),
            ("int32", I32),
            ("uint", U32),
            ("uint32", U32),
            ("float", F32),
            ("float32", F32),
            ("double", F64),
            ("float64", F64),
        ] {
            assert_eq!(Scalar::from_name(name), Some(ty));
        }
        assert_eq!(Scalar::from_name("int64"), None);
    }
}
