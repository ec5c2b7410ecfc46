//! Object File Format (OFF) loader, ascii only: `OFF`, `COFF`, `NOFF`, `CNOFF`, `STOFF`...
//!
//! # Format
//!
//! ```text
//! [ST][C][N]OFF [nv nf ne]       header keyword; the counts may follow on the same line
//! nv nf [ne]                     counts (ne, the edge count, is ignored)
//! x y z [nx ny nz] [colour] [s t]    nv vertex lines; normals when the keyword has N
//! n i0 i1 ... i(n-1) [colour]    nf face lines; 0-based vertex indices
//! ```
//!
//! `#` starts a comment that runs to the end of the line; blank lines are ignored anywhere.
//! Each vertex and each face is one line, so the optional trailing colours (any number of
//! values) and texture coordinates are simply ignored. Faces are triangulated as fans
//! `(i0, ik, ik+1)`; faces with fewer than three vertices are skipped (their indices are
//! still checked). Anything after the last face is ignored. The `4OFF` / `nOFF`
//! (higher-dimensional) variants and binary OFF are rejected.
//!
//! Errors carry the 1-based line of the offending token. Vertex and face numbers in
//! messages are 0-based, the numbering face indices use.

use std::path::Path;

use glam::Vec3;

use crate::error::{Error, Result};
use crate::scene::limits::{self, FileKind};
use crate::scene::mesh::{normalize_all, push_fan, MeshData};

/// Upper bound on what a header count may pre-allocate; larger counts grow as data arrives.
const MAX_PREALLOC: usize = 1 << 20;

/// Loads the OFF file at `path`. `materials` and `tri_material` stay empty.
pub fn load(path: &Path) -> Result<MeshData> {
    let bytes = limits::read_file(path, FileKind::Mesh)?;
    parse(path, &String::from_utf8_lossy(&bytes))
}

/// Non-blank lines with comments removed, as `(1-based line number, tokens)`.
struct Lines<'a> {
    inner: std::iter::Enumerate<std::str::Split<'a, char>>,
    /// Number of the last line looked at; once exhausted, the number of the last line of the
    /// file (the empty line after a final newline counts), which is where EOF errors point.
    line: usize,
}

impl<'a> Lines<'a> {
    fn new(text: &'a str) -> Self {
        Lines { inner: text.split('\n').enumerate(), line: 0 }
    }

    fn next_tokens(&mut self) -> Option<(usize, std::str::SplitWhitespace<'a>)> {
        for (i, raw) in self.inner.by_ref() {
            self.line = i + 1;
            let content = raw.split('#').next().unwrap_or_default();
            let tokens = content.split_whitespace();
            if tokens.clone().next().is_some() {
                return Some((self.line, tokens));
            }
        }
        None
    }
}

/// Which optional vertex fields the header keyword announces.
struct Variant {
    normals: bool,
}

fn parse_keyword(path: &Path, line: usize, keyword: &str) -> Result<Variant> {
    let bad = || {
        Error::parse(
            path,
            line,
            format!("not an OFF file: expected a header such as 'OFF', 'COFF' or 'NOFF', found '{keyword}'"),
        )
    };
    let Some(mut prefix) = keyword.strip_suffix("OFF") else {
        return Err(bad());
    };
    prefix = prefix.strip_prefix("ST").unwrap_or(prefix);
    prefix = prefix.strip_prefix('C').unwrap_or(prefix);
    let normals = prefix.starts_with('N');
    prefix = prefix.strip_prefix('N').unwrap_or(prefix);
    match prefix {
        "" => Ok(Variant { normals }),
        "4" | "n" | "4n" => {
            Err(Error::parse(path, line, format!("'{keyword}': only three-dimensional OFF is supported")))
        }
        _ => Err(bad()),
    }
}

fn parse_count(path: &Path, line: usize, token: Option<&str>, what: &str) -> Result<u64> {
    let token = token.ok_or_else(|| {
        Error::parse(path, line, format!("expected the counts line 'vertices faces [edges]', missing the {what} count"))
    })?;
    token.parse().map_err(|_| Error::parse(path, line, format!("{what} count '{token}' is not a non-negative integer")))
}

/// Parses a whole OFF file held in memory.
fn parse(path: &Path, text: &str) -> Result<MeshData> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = Lines::new(text);

    let Some((header_line, mut tokens)) = lines.next_tokens() else {
        return Err(Error::parse(path, 1, "file is empty; expected an 'OFF' header"));
    };
    let variant = parse_keyword(path, header_line, tokens.next().unwrap_or_default())?;

    // Counts: the rest of the header line, or the next non-blank line.
    let (count_line, mut counts) = if tokens.clone().next().is_some() {
        (header_line, tokens)
    } else {
        lines.next_tokens().ok_or_else(|| {
            Error::parse(path, lines.line.max(1), "file ends before the counts line 'vertices faces [edges]'")
        })?
    };
    let nv = parse_count(path, count_line, counts.next(), "vertex")?;
    let nf = parse_count(path, count_line, counts.next(), "face")?;
    if nv > limits::MAX_VERTICES {
        return Err(Error::parse(
            path,
            count_line,
            format!("the file declares {nv} vertices; at most {} are supported", limits::MAX_VERTICES),
        ));
    }
    let cap = |n: u64| usize::try_from(n).unwrap_or(usize::MAX).min(MAX_PREALLOC);

    let mut mesh = MeshData::default();
    mesh.positions.reserve(cap(nv));
    let mut normals: Vec<Vec3> = Vec::new();
    if variant.normals {
        normals.reserve(cap(nv));
    }
    let per_vertex = if variant.normals { 6 } else { 3 };

    for v in 0..nv {
        let (line, mut tokens) = lines
            .next_tokens()
            .ok_or_else(|| Error::parse(path, lines.line.max(1), format!("file ends after {v} of {nv} vertices")))?;
        let mut vals = [0f32; 6];
        for (k, slot) in vals.iter_mut().take(per_vertex).enumerate() {
            let tok = tokens
                .next()
                .ok_or_else(|| Error::parse(path, line, format!("vertex {v} has {k} values; expected {per_vertex}")))?;
            *slot =
                tok.parse().map_err(|_| Error::parse(path, line, format!("vertex {v}: '{tok}' is not a number")))?;
        }
        let [x, y, z, nx, ny, nz] = vals;
        let p = Vec3::new(x, y, z);
        if !p.is_finite() {
            return Err(Error::parse(path, line, format!("vertex {v} has a non-finite coordinate")));
        }
        mesh.positions.push(p);
        if variant.normals {
            normals.push(Vec3::new(nx, ny, nz));
        }
    }

    mesh.triangles.reserve(cap(nf));
    let mut polygon: Vec<u32> = Vec::new();
    for f in 0..nf {
        let (line, mut tokens) = lines
            .next_tokens()
            .ok_or_else(|| Error::parse(path, lines.line.max(1), format!("file ends after {f} of {nf} faces")))?;
        let n_tok = tokens.next().unwrap_or_default();
        let n: u64 = n_tok.parse().map_err(|_| {
            Error::parse(path, line, format!("face {f}: vertex count '{n_tok}' is not a non-negative integer"))
        })?;
        polygon.clear();
        for k in 0..n {
            let tok = tokens.next().ok_or_else(|| {
                Error::parse(path, line, format!("face {f} declares {n} vertices but lists only {k}"))
            })?;
            let i: i64 = tok
                .parse()
                .map_err(|_| Error::parse(path, line, format!("face {f}: vertex index '{tok}' is not an integer")))?;
            let index = u32::try_from(i).ok().filter(|&i| u64::from(i) < nv).ok_or_else(|| {
                Error::parse(path, line, format!("face {f} references vertex {i} but the file has {nv} vertices"))
            })?;
            polygon.push(index);
        }
        // Remaining tokens are the optional face colour.
        push_fan(&mut mesh.triangles, &polygon);
        if mesh.triangles.len() as u64 > limits::MAX_TRIANGLES {
            return Err(Error::parse(
                path,
                line,
                format!("face {f}: the file has more than {} triangles, the most supported", limits::MAX_TRIANGLES),
            ));
        }
    }

    if variant.normals {
        mesh.normals = normalize_all(normals);
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_str(text: &str) -> Result<MeshData> {
        parse(Path::new("test.off"), text)
    }

    #[test]
    fn quad_and_pentagon_become_fans() {
        let m = parse_str(
            "OFF\n# a comment\n\n6 3 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n-1 1 0 # trailing comment\n-1 0 0\n\
             4 0 1 2 3\n5 0 2 3 4 5 0.5 0.5 0.5 1\n2 0 1\n",
        )
        .unwrap();
        assert_eq!(m.positions.len(), 6);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3], [0, 3, 4], [0, 4, 5]]);
        assert!(m.normals.is_none() && m.materials.is_empty() && m.tri_material.is_empty());
    }

    #[test]
    fn counts_on_header_line_and_colours_ignored() {
        let m =
            parse_str("COFF 3 1\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255\n3 0 1 2 255 255 255\n").unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn noff_normals_are_normalised() {
        let m = parse_str("NOFF\n3 1 0\n0 0 0 0 0 2\n1 0 0 0 3 0\n0 1 0 4 0 0\n3 0 1 2\n").unwrap();
        assert_eq!(m.normals.unwrap(), vec![Vec3::Z, Vec3::Y, Vec3::X]);
        let m = parse_str("CNOFF\n1 0\n0 0 0 0 0 0 1 1 1\n").unwrap();
        assert!(m.normals.is_none(), "zero-length normal means no normals");
    }

    #[test]
    fn errors_name_line() {
        for (text, line, want) in [
            ("", 1, "empty"),
            ("PLY\n", 1, "not an OFF file"),
            ("4OFF\n", 1, "three-dimensional"),
            ("OFF\n", 2, "counts line"),
            ("OFF\n3 x\n", 2, "face count 'x'"),
            ("OFF\n2 0\n0 0 0\n", 4, "file ends after 1 of 2 vertices"),
            ("OFF\n1 0\n0 zero 0\n", 3, "'zero' is not a number"),
            ("OFF\n1 0\n0 0\n", 3, "vertex 0 has 2 values"),
            ("OFF\n1 0\n0 inf 0\n", 3, "vertex 0 has a non-finite coordinate"),
            ("OFF\n1 1\n0 0 0\n3 0 0 5\n", 4, "face 0 references vertex 5 but the file has 1 vertices"),
            ("OFF\n1 1\n0 0 0\n3 0 0 -1\n", 4, "vertex -1"),
            ("OFF\n1 1\n0 0 0\n220\n", 4, "declares 220 vertices but lists only 0"),
            ("OFF\n1 2\n0 0 0\n3 0 0 0\n", 5, "file ends after 1 of 2 faces"),
            ("OFF\n99999999999 1\n", 2, "at most"),
        ] {
            let e = parse_str(text).unwrap_err();
            let msg = e.to_string();
            assert!(matches!(e, Error::Parse { line: l, .. } if l == line), "{msg}: want line {line}");
            assert!(msg.contains(want) && msg.contains("test.off"), "{msg} should contain {want}");
        }
    }

    #[test]
    fn empty_mesh_is_ok() {
        let m = parse_str("OFF\n0 0 0\n").unwrap();
        assert!(m.positions.is_empty() && m.triangles.is_empty());
    }

    #[test]
    fn huge_face_vertex_count_does_not_allocate() {
        let e = parse_str("OFF\n3 1\n0 0 0\n1 0 0\n0 1 0\n18446744073709551615 0 1 2\n").unwrap_err();
        assert!(e.to_string().contains("lists only 3"), "{e}");
    }
}
