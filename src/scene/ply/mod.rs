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
//!   (any numeric type; v = 0 at the bottom of the image, as in OBJ); vertex colours
//!   `red`, `green`, `blue` and optionally `alpha` (or the `diffuse_` names), which
//!   multiply the base colour: an integer type is sRGB-encoded over its range (255
//!   for `uchar`), as 8-bit PNG textures are; a float is linear in [0, 1]. Alpha is
//!   linear.
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

mod body;
mod header;

use std::borrow::Cow;
use std::path::Path;

use glam::{Vec2, Vec3, Vec4};

use crate::error::{Error, Result};
use crate::scene::limits::{self, FileKind};
use crate::scene::mesh::{normalize_all, push_fan, MeshData};

use body::Body;
use header::{parse_header, Element, Format, PropKind, Scalar};

/// Upper bound on what a header count may pre-allocate; larger counts grow as data arrives.
const MAX_PREALLOC: usize = 1 << 20;

/// Loads the PLY file at `path`. Materials are not read: `materials` and `tri_material`
/// stay empty.
pub fn load(path: &Path) -> Result<MeshData> {
    let bytes = limits::read_file(path, FileKind::Mesh)?;
    parse(path, &bytes)
}

/// What a property of the vertex element feeds.
#[derive(Clone, Copy)]
enum VertexSlot {
    Coord(usize),
    Normal(usize),
    Uv(usize),
    Color(usize),
    Ignore,
}

/// Names of the vertex colour channels, tried in this order (alpha optional).
const COLOR_NAMES: [[&str; 4]; 2] =
    [["red", "green", "blue", "alpha"], ["diffuse_red", "diffuse_green", "diffuse_blue", "diffuse_alpha"]];

/// A colour channel of type `ty` read as `v` into linear [0, 1]: an integer over its
/// type's range, sRGB-decoded unless it is alpha (`k` 3); a float as it is.
fn color_channel(ty: Scalar, v: f64, k: usize) -> f32 {
    let range = match ty {
        Scalar::U8 | Scalar::I8 => 255.0,
        Scalar::U16 | Scalar::I16 => 65535.0,
        Scalar::U32 | Scalar::I32 => 4_294_967_295.0,
        Scalar::F32 | Scalar::F64 => return v as f32,
    };
    let x = (v / range).clamp(0.0, 1.0) as f32;
    if k == 3 {
        x
    } else {
        crate::scene::colors::srgb_to_linear(x)
    }
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
    let mut colors: Vec<Vec4> = Vec::new();
    let mut has_colors = false;

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
            for names in COLOR_NAMES {
                let [r, g, b, a] = names;
                if let (Some(r), Some(g), Some(b)) =
                    (find_scalar(path, el, r)?, find_scalar(path, el, g)?, find_scalar(path, el, b)?)
                {
                    has_colors = true;
                    let alpha = find_scalar(path, el, a)?;
                    for (k, i) in [Some(r), Some(g), Some(b), alpha].into_iter().enumerate() {
                        if let Some(s) = i.and_then(|i| slots.get_mut(i)) {
                            *s = VertexSlot::Color(k);
                        }
                    }
                    colors.reserve(cap);
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
            let mut color = [1f32; 4];
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
                            Some(VertexSlot::Color(k)) => {
                                if let Some(c) = color.get_mut(*k) {
                                    *c = color_channel(ty, v, *k);
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
                if has_colors {
                    colors.push(Vec4::from_array(color));
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
    if has_colors && colors.len() == mesh.positions.len() {
        crate::scene::colors::clamp_colors(&mut colors);
        mesh.colors = Some(colors);
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::header::Scalar;
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
