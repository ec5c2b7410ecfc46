//! Stanford PLY loader: `ascii`, `binary_little_endian` and `binary_big_endian` bodies.
//!
//! # Format
//!
//! ```text
//! ply
//! format <ascii|binary_little_endian|binary_big_endian> <version>
//! comment ... / obj_info ...              (anywhere in the header; ignored)
//! element <name> <count>
//! property <type> <name>                   (scalar)
//! property list <count type> <item type> <name>
//! ...
//! end_header
//! <body: each element's records in header order>
//! ```
//!
//! Types: `char`/`int8`, `uchar`/`uint8`, `short`/`int16`, `ushort`/`uint16`, `int`/`int32`,
//! `uint`/`uint32`, `float`/`float32`, `double`/`float64`. Binary values are packed with no
//! padding; a list is its count followed by that many items. In an ascii body every record is
//! one line of whitespace-separated values.
//!
//! # What is read
//!
//! * Element `vertex`: `x`, `y`, `z` (required, any numeric type), `nx`, `ny`, `nz`
//!   (normals, used only when all three are present) and texture coordinates: the first
//!   pair present of `u`/`v`, `s`/`t`, `texture_u`/`texture_v`, `texture_s`/`texture_t`
//!   (any numeric type; v = 0 at the bottom of the image, as in OBJ).
//! * Element `face`: the list property `vertex_indices` (or `vertex_index`), any count and
//!   index types. Polygons are triangulated as fans `(i0, ik, ik+1)`; faces with fewer than
//!   three vertices are skipped.
//! * Every other element and property is skipped, lists included, in both body encodings.
//!
//! Header lines with an unknown keyword are ignored like comments (Blender 2.4x wrote a
//! comment line without the `comment` keyword). Bytes after the last record are ignored.
//!
//! # Errors
//!
//! Ascii bodies report the 1-based line of the offending value; binary bodies report the
//! byte offset from the start of the file. Vertex and face numbers in messages are 0-based
//! record numbers, the same numbering face indices use.

use std::borrow::Cow;
use std::path::Path;

use glam::{Vec2, Vec3};

use crate::error::{Error, Result};
use crate::scene::limits::{self, FileKind};
use crate::scene::mesh::{normalize_all, push_fan, MeshData};

/// Upper bound on what a header count may pre-allocate; larger counts grow as data arrives.
const MAX_PREALLOC: usize = 1 << 20;

/// Loads the PLY file at `path`. Materials are not read: `materials` and `tri_material`
/// stay empty.
pub fn load(path: &Path) -> Result<MeshData> {
    let bytes = limits::read_file(path, FileKind::Mesh)?;
    parse(path, &bytes)
}

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
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
    fn from_name(name: &str) -> Option<Scalar> {
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
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum PropKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
struct Property {
    name: String,
    kind: PropKind,
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: u64,
    props: Vec<Property>,
    /// Header line of the `element` keyword (1-based).
    line: usize,
}

impl Element {
    /// Smallest possible size of one record in a binary body (lists empty).
    fn min_record_size(&self) -> u64 {
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
enum Format {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

#[derive(Debug)]
struct Header {
    format: Format,
    elements: Vec<Element>,
    /// Byte offset of the first body byte.
    body_start: usize,
    /// Number of header lines, `end_header` included.
    lines: usize,
}

fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header> {
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

/// Why reading a value failed; turned into an [`Error`] with context by [`Body::error`].
#[derive(Debug)]
enum Fault {
    /// No more records (ascii) or bytes (binary).
    EndOfData,
    /// Ascii record line ended before all properties were read.
    EndOfLine,
    /// Ascii token that is not a number of the expected kind.
    BadToken(String),
}

/// Position in the body: an ascii line cursor or a binary byte cursor.
enum Body<'a> {
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
    fn begin_record(&mut self) -> std::result::Result<(), Fault> {
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
    fn has_extra_values(&self) -> bool {
        match self {
            Body::Ascii { tokens, .. } => tokens.clone().next().is_some(),
            Body::Binary { .. } => false,
        }
    }

    /// Reads one value of type `ty` as f64 (exact for every integer type).
    fn scalar(&mut self, ty: Scalar) -> std::result::Result<f64, Fault> {
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
    fn skip(&mut self, n: u64, ty: Scalar) -> std::result::Result<(), Fault> {
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
    fn binary_remaining(&self) -> Option<u64> {
        match self {
            Body::Binary { bytes, pos, .. } => Some(bytes.len().saturating_sub(*pos) as u64),
            Body::Ascii { .. } => None,
        }
    }

    /// Current position: the record's line (ascii) or the next byte's offset (binary).
    fn location(&self) -> usize {
        match self {
            Body::Ascii { line, .. } => *line,
            Body::Binary { pos, .. } => *pos,
        }
    }

    /// An error at `location` (see [`Body::location`]): `path:line: msg` for ascii bodies,
    /// `path: msg (at byte offset N)` for binary ones.
    fn error_at(&self, path: &Path, location: usize, msg: impl std::fmt::Display) -> Error {
        match self {
            Body::Ascii { .. } => Error::parse(path, location, msg.to_string()),
            Body::Binary { .. } => Error::invalid(path, format!("{msg} (at byte offset {location})")),
        }
    }

    /// An error at the current position. A failed read does not advance, so after a
    /// [`Fault`] this is where the unreadable value starts.
    fn error(&self, path: &Path, msg: impl std::fmt::Display) -> Error {
        self.error_at(path, self.location(), msg)
    }

    /// Turns a [`Fault`] met while reading `what` into an [`Error`].
    fn fault(&self, path: &Path, fault: Fault, what: &str) -> Error {
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

/// What a property of the vertex element feeds.
#[derive(Clone, Copy)]
enum VertexSlot {
    Coord(usize),
    Normal(usize),
    Uv(usize),
    Ignore,
}

/// Names of the texture coordinate pair on the vertex element, tried in this order.
const UV_NAMES: [[&str; 2]; 4] = [["u", "v"], ["s", "t"], ["texture_u", "texture_v"], ["texture_s", "texture_t"]];

fn find_scalar(path: &Path, el: &Element, name: &str) -> Result<Option<usize>> {
    match el.props.iter().position(|p| p.name == name) {
        None => Ok(None),
        Some(i) => match el.props.get(i).map(|p| p.kind) {
            Some(PropKind::Scalar(_)) => Ok(Some(i)),
            _ => Err(Error::parse(
                path,
                el.line,
                format!("property '{name}' of element '{}' must be a scalar, not a list", el.name),
            )),
        },
    }
}

/// Parses a whole PLY file held in memory.
fn parse(path: &Path, bytes: &[u8]) -> Result<MeshData> {
    let header = parse_header(path, bytes)?;
    let body_bytes = bytes.get(header.body_start..).unwrap_or_default();

    // Vertex count as the header declares it: face indices are checked against it, so
    // the element order in the file does not matter.
    let vertex_count = header.elements.iter().find(|e| e.name == "vertex").map_or(0, |e| e.count);
    if vertex_count > limits::MAX_VERTICES {
        return Err(Error::invalid(
            path,
            format!("the header declares {vertex_count} vertices; at most {} are supported", limits::MAX_VERTICES),
        ));
    }

    let ascii_text: Cow<str>;
    let mut body = match header.format {
        Format::Ascii => {
            ascii_text = String::from_utf8_lossy(body_bytes);
            Body::Ascii { lines: ascii_text.split('\n'), line: header.lines, tokens: "".split_whitespace() }
        }
        Format::BinaryLittleEndian | Format::BinaryBigEndian => {
            Body::Binary { bytes, pos: header.body_start, big_endian: header.format == Format::BinaryBigEndian }
        }
    };

    let mut mesh = MeshData::default();
    let mut normals: Vec<Vec3> = Vec::new();
    let mut has_normals = false;
    let mut uvs: Vec<Vec2> = Vec::new();
    let mut has_uvs = false;

    for el in &header.elements {
        if el.count == 0 {
            continue;
        }
        if let Some(remaining) = body.binary_remaining() {
            let needed = el.count.saturating_mul(el.min_record_size());
            if needed > remaining {
                return Err(body.error(
                    path,
                    format!(
                        "file is truncated: {} '{}' records need at least {needed} bytes but only {remaining} remain",
                        el.count, el.name
                    ),
                ));
            }
        }
        let cap = usize::try_from(el.count).unwrap_or(usize::MAX).min(MAX_PREALLOC);

        // Role of this element and where its interesting properties are.
        let mut slots = vec![VertexSlot::Ignore; el.props.len()];
        let mut face_list = None;
        let is_vertex = el.name == "vertex";
        let is_face = el.name == "face";
        if is_vertex {
            for (k, name) in ["x", "y", "z"].iter().enumerate() {
                let i = find_scalar(path, el, name)?
                    .ok_or_else(|| Error::parse(path, el.line, format!("element 'vertex' has no '{name}' property")))?;
                if let Some(s) = slots.get_mut(i) {
                    *s = VertexSlot::Coord(k);
                }
            }
            let n = [find_scalar(path, el, "nx")?, find_scalar(path, el, "ny")?, find_scalar(path, el, "nz")?];
            if let [Some(a), Some(b), Some(c)] = n {
                has_normals = true;
                for (k, i) in [a, b, c].into_iter().enumerate() {
                    if let Some(s) = slots.get_mut(i) {
                        *s = VertexSlot::Normal(k);
                    }
                }
                normals.reserve(cap);
            }
            for [un, vn] in UV_NAMES {
                if let (Some(a), Some(b)) = (find_scalar(path, el, un)?, find_scalar(path, el, vn)?) {
                    has_uvs = true;
                    for (k, i) in [a, b].into_iter().enumerate() {
                        if let Some(s) = slots.get_mut(i) {
                            *s = VertexSlot::Uv(k);
                        }
                    }
                    uvs.reserve(cap);
                    break;
                }
            }
            mesh.positions.reserve(cap);
        } else if is_face {
            let i = el.props.iter().position(|p| p.name == "vertex_indices" || p.name == "vertex_index").ok_or_else(
                || {
                    Error::parse(
                        path,
                        el.line,
                        "element 'face' has no 'vertex_indices' (or 'vertex_index') list property",
                    )
                },
            )?;
            if !matches!(el.props.get(i).map(|p| p.kind), Some(PropKind::List { .. })) {
                return Err(Error::parse(path, el.line, "property 'vertex_indices' of element 'face' must be a list"));
            }
            face_list = Some(i);
            mesh.triangles.reserve(cap);
        }

        if el.props.is_empty() {
            continue; // Records without properties occupy no bytes and no ascii values.
        }

        let mut indices: Vec<u32> = Vec::new();
        for rec in 0..el.count {
            let ctx = |prop: &str| format!("property '{prop}' of {} {rec}", el.name);
            body.begin_record().map_err(|f| body.fault(path, f, &format!("{} {rec} of {}", el.name, el.count)))?;
            let record_start = body.location();
            let mut coord = [0f64; 3];
            let mut normal = [0f64; 3];
            let mut uv = [0f64; 2];
            for (pi, prop) in el.props.iter().enumerate() {
                match prop.kind {
                    PropKind::Scalar(ty) => {
                        let v = body.scalar(ty).map_err(|f| body.fault(path, f, &ctx(&prop.name)))?;
                        match slots.get(pi) {
                            Some(VertexSlot::Coord(k)) => {
                                if let Some(c) = coord.get_mut(*k) {
                                    *c = v;
                                }
                            }
                            Some(VertexSlot::Normal(k)) => {
                                if let Some(c) = normal.get_mut(*k) {
                                    *c = v;
                                }
                            }
                            Some(VertexSlot::Uv(k)) => {
                                if let Some(c) = uv.get_mut(*k) {
                                    *c = v;
                                }
                            }
                            _ => {}
                        }
                    }
                    PropKind::List { count, item } => {
                        let at = body.location();
                        let n = body.scalar(count).map_err(|f| body.fault(path, f, &ctx(&prop.name)))?;
                        if n < 0.0 {
                            return Err(body.error_at(
                                path,
                                at,
                                format!("{} has negative length {n}", ctx(&prop.name)),
                            ));
                        }
                        let n = n as u64;
                        if face_list == Some(pi) {
                            indices.clear();
                            for _ in 0..n {
                                let at = body.location();
                                let v = body.scalar(item).map_err(|f| body.fault(path, f, &ctx(&prop.name)))?;
                                if !(v >= 0.0 && v < vertex_count as f64 && v.fract() == 0.0) {
                                    return Err(body.error_at(
                                        path,
                                        at,
                                        format!(
                                            "face {rec} references vertex {v} but the file has {vertex_count} vertices"
                                        ),
                                    ));
                                }
                                indices.push(v as u32);
                            }
                        } else {
                            body.skip(n, item).map_err(|f| body.fault(path, f, &ctx(&prop.name)))?;
                        }
                    }
                }
            }
            if body.has_extra_values() {
                return Err(body.error(
                    path,
                    format!("{} {rec} has more values than the header's {} properties", el.name, el.props.len()),
                ));
            }
            if is_vertex {
                let p = Vec3::new(coord[0] as f32, coord[1] as f32, coord[2] as f32);
                if !p.is_finite() {
                    return Err(body.error_at(path, record_start, format!("vertex {rec} has a non-finite coordinate")));
                }
                mesh.positions.push(p);
                if has_normals {
                    normals.push(Vec3::new(normal[0] as f32, normal[1] as f32, normal[2] as f32));
                }
                if has_uvs {
                    uvs.push(Vec2::new(uv[0] as f32, uv[1] as f32));
                }
            } else if face_list.is_some() {
                push_fan(&mut mesh.triangles, &indices);
                if mesh.triangles.len() as u64 > limits::MAX_TRIANGLES {
                    return Err(body.error_at(
                        path,
                        record_start,
                        format!(
                            "face {rec}: the file has more than {} triangles, the most supported",
                            limits::MAX_TRIANGLES
                        ),
                    ));
                }
            }
        }
    }

    if has_normals {
        mesh.normals = normalize_all(normals);
    }
    if has_uvs && uvs.len() == mesh.positions.len() {
        mesh.uvs = Some(uvs);
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("test.ply")
    }

    /// Header + binary body builder.
    fn binary(big_endian: bool, header_body: &str, values: &[(Scalar, f64)]) -> Vec<u8> {
        let fmt = if big_endian { "binary_big_endian" } else { "binary_little_endian" };
        let mut out = format!("ply\nformat {fmt} 1.0\n{header_body}end_header\n").into_bytes();
        for &(ty, v) in values {
            macro_rules! put {
                ($t:ty) => {{
                    let x = v as $t;
                    out.extend_from_slice(&if big_endian { x.to_be_bytes() } else { x.to_le_bytes() })
                }};
            }
            match ty {
                Scalar::I8 => put!(i8),
                Scalar::U8 => put!(u8),
                Scalar::I16 => put!(i16),
                Scalar::U16 => put!(u16),
                Scalar::I32 => put!(i32),
                Scalar::U32 => put!(u32),
                Scalar::F32 => put!(f32),
                Scalar::F64 => put!(f64),
            }
        }
        out
    }

    use Scalar::*;

    /// A quad (two triangles) with extra properties and a skipped list before the indices.
    fn quad_values() -> (String, Vec<(Scalar, f64)>) {
        let header = "comment test\n\
            element vertex 4\n\
            property double x\nproperty uchar red\nproperty float y\nproperty int16 z\n\
            property list uint8 float32 junk\n\
            element face 1\n\
            property list ushort int8 other\n\
            property list uint32 uint16 vertex_indices\n\
            property float32 quality\n";
        let mut v = Vec::new();
        for (i, (x, y, z)) in [(0., 0., 0.), (1., 0., 0.), (1., 1., 0.), (0., 1., 0.)].into_iter().enumerate() {
            v.extend([(F64, x), (U8, 255.0), (F32, y), (I16, z)]);
            // list of i+1 floats to skip
            v.push((U8, (i + 1) as f64));
            for _ in 0..=i {
                v.push((F32, 9.5));
            }
        }
        v.extend([(U16, 2.0), (I8, -1.0), (I8, -2.0)]);
        v.extend([(U32, 4.0), (U16, 0.0), (U16, 1.0), (U16, 2.0), (U16, 3.0)]);
        v.push((F32, 0.25));
        (header.to_string(), v)
    }

    #[test]
    fn binary_little_and_big_endian_agree() {
        let (h, v) = quad_values();
        for be in [false, true] {
            let m = parse(p(), &binary(be, &h, &v)).unwrap();
            assert_eq!(m.positions.len(), 4, "big endian: {be}");
            assert_eq!(m.positions[2], Vec3::new(1.0, 1.0, 0.0));
            assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
            assert!(m.normals.is_none());
            assert!(m.materials.is_empty() && m.tri_material.is_empty());
        }
    }

    #[test]
    fn ascii_skips_lists_and_unknown_properties() {
        let text = "ply\nformat ascii 1.0\nobj_info x\n\
            element vertex 3\nproperty list uchar int extra\nproperty float x\nproperty float y\nproperty float z\n\
            property float nx\nproperty float ny\nproperty float nz\n\
            element face 2\nproperty list uchar int vertex_index\nproperty list int double tail\n\
            end_header\n\
            2 7 7 0 0 0 0 0 2\n\
            0 1 0 0 0 1 0\n\
            \n\
            1 9 0 1 0 0 0 1\n\
            3 0 1 2 2 1.5 2.5\n\
            2 0 1 0\n";
        let m = parse(p(), text.as_bytes()).unwrap();
        assert_eq!(m.positions, vec![Vec3::ZERO, Vec3::X, Vec3::Y]);
        assert_eq!(m.triangles, vec![[0, 1, 2]]); // second face has 2 vertices: skipped
        assert_eq!(m.normals.unwrap()[0], Vec3::Z);
    }

    #[test]
    fn elements_in_any_order() {
        let text = "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar uint vertex_indices\n\
            element vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n\
            3 2 1 0\n0 0 0\n1 0 0\n0 1 0\n";
        let m = parse(p(), text.as_bytes()).unwrap();
        assert_eq!(m.triangles, vec![[2, 1, 0]]);
        assert_eq!(m.positions.len(), 3);
    }

    #[test]
    fn fan_triangulation() {
        let mut t = Vec::new();
        push_fan(&mut t, &[5, 6, 7, 8, 9]);
        assert_eq!(t, vec![[5, 6, 7], [5, 7, 8], [5, 8, 9]]);
        push_fan(&mut t, &[1, 2]);
        push_fan(&mut t, &[]);
        assert_eq!(t.len(), 3);
    }

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

    #[test]
    fn binary_negative_and_signed_values() {
        let header = "element vertex 1\nproperty char x\nproperty short y\nproperty int z\n";
        for be in [false, true] {
            let data = binary(be, header, &[(I8, -3.0), (I16, -300.0), (I32, -70000.0)]);
            let m = parse(p(), &data).unwrap();
            assert_eq!(m.positions, vec![Vec3::new(-3.0, -300.0, -70000.0)]);
        }
    }

    #[test]
    fn binary_truncated_reports_byte_offset() {
        let header = "element vertex 2\nproperty float x\nproperty float y\nproperty float z\n";
        let mut data = binary(false, header, &[(F32, 0.0); 6]);
        data.truncate(data.len() - 2);
        let e = parse(p(), &data).unwrap_err().to_string();
        assert!(e.contains("truncated") && e.contains("byte offset"), "{e}");

        // A list whose declared length runs past the end.
        let header = "element vertex 0\nproperty float x\nproperty float y\nproperty float z\n\
            element face 1\nproperty list uint uint vertex_indices\n";
        let data = binary(true, header, &[(U32, 4e9)]);
        let e = parse(p(), &data).unwrap_err().to_string();
        assert!(e.contains("byte offset"), "{e}");
    }

    #[test]
    fn huge_counts_do_not_allocate() {
        let header = "element vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\n";
        // Refused from the header's counts, before anything is allocated.
        let e = parse(p(), &binary(false, header, &[])).unwrap_err().to_string();
        assert!(e.contains("at most 33554432 are supported"), "{e}");
        let text = "ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n\
            property float z\nelement nothing 99999999999999\nend_header\n0 0 0\n";
        let e = parse(p(), text.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("at most 33554432 are supported"), "{e}");
    }

    #[test]
    fn ascii_errors_have_lines() {
        let base = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n\
            element face 1\nproperty list uchar int vertex_indices\nend_header\n";
        let cases = [
            ("0 0 0\n1 x 0\n3 0 1 1\n", 11, "'x'"),
            ("0 0 0\n1 1 0\n3 0 1 2\n", 12, "face 0 references vertex 2 but the file has 2 vertices"),
            ("0 0 0\n1 nan 0\n3 0 1 1\n", 11, "vertex 1 has a non-finite coordinate"),
            ("0 0 0\n1 1\n3 0 1 1\n", 11, "line ends"),
            ("0 0 0\n1 1 1 1\n3 0 1 1\n", 11, "more values"),
            ("0 0 0\n1 1 1\n", 12, "file ends"),
            ("0 0 0\n1 1 1\n3 0 1 -1\n", 12, "vertex -1"),
            ("0 0 0\n1 1 1\n-3 0 1 1\n", 12, "negative"),
        ];
        for (body, line, what) in cases {
            let e = parse(p(), format!("{base}{body}").as_bytes()).unwrap_err();
            let msg = e.to_string();
            assert!(matches!(e, Error::Parse { line: l, .. } if l == line), "{msg} (want line {line})");
            assert!(msg.contains(what), "{msg} should contain {what}");
        }
    }

    #[test]
    fn header_errors() {
        for (text, want) in [
            ("", "empty"),
            ("plx\n", "not a PLY"),
            ("ply\nformat ascii 1.0\nelement vertex 1\n", "end_header"),
            ("ply\nformat ebcdic 1.0\nend_header\n", "unknown format"),
            ("ply\nformat ascii 1.0\nproperty float x\nend_header\n", "before any"),
            ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n", "float128"),
            ("ply\nformat ascii 1.0\nelement vertex -1\nend_header\n", "count"),
            ("ply\nformat ascii 1.0\nelement face 1\nproperty list float int vertex_indices\nend_header\n", "integer"),
            ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n", "'y'"),
            ("ply\nformat ascii 1.0\nelement face 1\nproperty int vertex_indices\nend_header\n", "list"),
            ("ply\nelement vertex 0\nend_header\n", "format"),
        ] {
            let msg = parse(p(), text.as_bytes()).unwrap_err().to_string();
            assert!(msg.contains(want) && msg.contains("test.ply"), "{msg} should contain {want}");
        }
    }

    #[test]
    fn vertex_element_without_coordinates_is_rejected() {
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nelement face 1\n\
            property list uchar int vertex_indices\nend_header\n3 0 1 2\n";
        let e = parse(p(), text.as_bytes()).unwrap_err();
        assert!(matches!(e, Error::Parse { line: 3, .. }) && e.to_string().contains("'x'"), "{e}");
        // Elements without properties are skipped in binary bodies too.
        let header = "element junk 5\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n";
        let m = parse(p(), &binary(false, header, &[(F32, 1.0), (F32, 2.0), (F32, 3.0)])).unwrap();
        assert_eq!(m.positions, vec![Vec3::new(1.0, 2.0, 3.0)]);
    }

    #[test]
    fn zero_length_normal_drops_normals() {
        let text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n\
            property float nx\nproperty float ny\nproperty float nz\nend_header\n0 0 0 0 0 2\n0 0 0 0 0 0\n";
        let m = parse(p(), text.as_bytes()).unwrap();
        assert!(m.normals.is_none());
        assert!(m.triangles.is_empty());
    }

    #[test]
    fn crlf_header_and_binary_body() {
        let mut data = b"ply\r\nformat binary_little_endian 1.0\r\nelement vertex 1\r\nproperty float x\r\n\
            property float y\r\nproperty float z\r\nend_header\r\n"
            .to_vec();
        for v in [1f32, 2.0, 3.0] {
            data.extend_from_slice(&v.to_le_bytes());
        }
        let m = parse(p(), &data).unwrap();
        assert_eq!(m.positions, vec![Vec3::new(1.0, 2.0, 3.0)]);
    }
}
