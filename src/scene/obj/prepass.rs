//! The pre-pass over the OBJ text (module docs, step 2): checks what `tobj` does not
//! check or reports without a line, and rewrites what it mishandles, line for line.

use std::collections::HashSet;
use std::fmt::Write as _;
use std::path::Path;

use glam::Vec3;

use crate::error::{Error, Result};
use crate::scene::limits::{self, FileKind};

/// `usemtl` target written for an empty `usemtl`: no MTL can define a name with a NUL, so
/// `tobj` finds no such material and the faces get the default material.
const NO_MATERIAL: &str = "\u{0}no material";

/// Output of [`prepass`].
pub(super) struct Prepass {
    /// The rewritten OBJ text, line for line with the input.
    pub(super) text: String,
    /// Whether the file has any `mtllib` or `usemtl` line.
    pub(super) mentions_materials: bool,
}

/// Names (singular, plural) of the three kinds of face reference, indexed like `v/vt/vn`.
const REF_KINDS: [(&str, &str); 3] =
    [("vertex", "vertices"), ("texture coordinate", "texture coordinates"), ("normal", "normals")];

/// [`prepass_in`] for an OBJ file whose libraries would be beside it.
#[cfg(test)]
fn prepass(path: &Path, text: &str) -> Result<Prepass> {
    prepass_in(path, path.parent().unwrap_or(Path::new("")), text)
}

/// Checks and rewrites the OBJ text (see the module docs, step 2); `dir` is where
/// `mtllib` names are resolved. Also checks the element counts against the scene limits
/// and that each material library is a regular file of bounded size, before any of them
/// is read.
pub(super) fn prepass_in(path: &Path, dir: &Path, text: &str) -> Result<Prepass> {
    let keyword = |line: &str| line.split_whitespace().next().unwrap_or_default().to_string();
    // Totals of v, vt, vn: positive face references may point forward.
    let mut totals = [0u64; 3];
    // Vertices with a colour (three values after the coordinates): kept only when every
    // vertex has one, which is what `tobj` can read.
    let mut colored = 0u64;
    for line in text.split('\n') {
        match keyword(line).as_str() {
            "v" => {
                totals[0] += 1;
                colored += u64::from(line.split_whitespace().count() == 7);
            }
            "vt" => totals[1] += 1,
            "vn" => totals[2] += 1,
            _ => {}
        }
    }

    if totals[0] > limits::MAX_VERTICES {
        return Err(Error::invalid(
            path,
            format!("the file has {} vertices; at most {} are supported", totals[0], limits::MAX_VERTICES),
        ));
    }

    let colors = colored > 0 && colored == totals[0];
    let mut out = String::with_capacity(text.len());
    let mut so_far = [0u64; 3];
    let mut triangles = 0u64;
    let mut libraries: HashSet<&str> = HashSet::new();
    let mut mentions_materials = false;
    for (i, raw) in text.split('\n').enumerate() {
        let line_no = i + 1;
        if i > 0 {
            out.push('\n');
        }
        let line = raw.trim_end_matches('\r');
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                so_far[0] += 1;
                let (p, rgb) = parse_vertex(path, line_no, so_far[0], words)?;
                let _ = write!(out, "v {} {} {}", p.x, p.y, p.z);
                if let Some(c) = rgb.filter(|_| colors) {
                    let _ = write!(out, " {} {} {}", c.x, c.y, c.z);
                }
            }
            Some("vt") => {
                so_far[1] += 1;
                let vals: Vec<&str> = words.collect();
                if vals.len() == 1 {
                    let _ = write!(out, "{line} 0");
                } else {
                    out.push_str(line);
                }
            }
            Some("vn") => {
                so_far[2] += 1;
                out.push_str(line);
            }
            Some("f") => {
                let mut count = 0usize;
                for token in words {
                    check_face_ref(path, line_no, token, so_far, totals)?;
                    count += 1;
                }
                if count >= 3 {
                    out.push_str(line);
                    triangles += count as u64 - 2;
                    if triangles > limits::MAX_TRIANGLES {
                        return Err(Error::parse(
                            path,
                            line_no,
                            format!("the file has more than {} triangles, the most supported", limits::MAX_TRIANGLES),
                        ));
                    }
                }
            }
            Some("l") => {}
            Some("usemtl") => {
                mentions_materials = true;
                let name = line.trim_start().get("usemtl".len()..).unwrap_or_default().trim();
                let name = if name.is_empty() { NO_MATERIAL } else { name };
                let _ = write!(out, "usemtl {name}");
            }
            Some("mtllib") => {
                mentions_materials = true;
                // tobj takes the rest of the line, spaces included, as one file name.
                let name = line.split_once(' ').unwrap_or_default().1.trim();
                if libraries.insert(name) {
                    if libraries.len() > limits::MAX_MTLLIBS {
                        return Err(Error::parse(
                            path,
                            line_no,
                            format!("more than {} distinct material libraries (mtllib)", limits::MAX_MTLLIBS),
                        ));
                    }
                    match limits::check_file(&dir.join(name), FileKind::MaterialLibrary) {
                        // Missing or unreadable: only its materials are lost (module docs).
                        Ok(_) | Err(Error::Io { .. }) => {}
                        Err(Error::Invalid { msg, .. }) => {
                            return Err(Error::parse(path, line_no, format!("mtllib '{name}' {msg}")))
                        }
                        Err(e) => return Err(e),
                    }
                }
                out.push_str(line);
            }
            _ => out.push_str(line),
        }
    }
    Ok(Prepass { text: out, mentions_materials })
}

/// Finds the face behind a tobj index error raised at `flush_line` (1-based), where a
/// group ended: the first face before it with a positive index beyond the entries defined
/// by then (tobj resolves a group's faces when the group ends, so a face may only point
/// forward to entries defined before its group ends). Returns its line and a message.
pub(super) fn find_late_reference(text: &str, flush_line: usize) -> Option<(usize, String)> {
    let mut defined = [0u64; 3];
    let lines: Vec<&str> = text.split('\n').take(flush_line.saturating_sub(1)).collect();
    for line in &lines {
        match line.split_whitespace().next() {
            Some("v") => defined[0] += 1,
            Some("vt") => defined[1] += 1,
            Some("vn") => defined[2] += 1,
            _ => {}
        }
    }
    for (i, line) in lines.iter().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some("f") {
            continue;
        }
        for token in words {
            for (k, part) in token.split('/').enumerate() {
                let (Ok(index), Some(&(_, kinds)), Some(&n)) = (part.parse::<i64>(), REF_KINDS.get(k), defined.get(k))
                else {
                    continue;
                };
                if index > 0 && index.unsigned_abs() > n && n > 0 {
                    let kind = REF_KINDS.get(k).map_or("vertex", |r| r.0);
                    return Some((
                        i + 1,
                        format!(
                            "face references {kind} {index}, but only {n} {kinds} are defined when its group ends at \
                             line {flush_line}; define them before the next 'o', 'g' or 'usemtl' line"
                        ),
                    ));
                }
            }
        }
    }
    None
}

/// Parses the values after `v`: `x y z`, optionally `w` (4 values) or colours (more);
/// the position, and the colour `r g b` when there are exactly six values.
fn parse_vertex<'a>(
    path: &Path,
    line: usize,
    number: u64,
    words: impl Iterator<Item = &'a str>,
) -> Result<(Vec3, Option<Vec3>)> {
    let vals: Vec<&str> = words.collect();
    let num = |tok: &str| {
        tok.parse::<f32>().map_err(|_| Error::parse(path, line, format!("vertex {number}: '{tok}' is not a number")))
    };
    let [x, y, z] = match vals.get(..3) {
        Some(&[x, y, z]) => [num(x)?, num(y)?, num(z)?],
        _ => {
            return Err(Error::parse(path, line, format!("vertex {number} has {} coordinates; expected 3", vals.len())))
        }
    };
    let mut p = Vec3::new(x, y, z);
    if let [_, _, _, w] = vals[..] {
        let w = num(w)?;
        if w == 0.0 {
            return Err(Error::parse(path, line, format!("vertex {number} has w = 0")));
        }
        p /= w;
    }
    if !p.is_finite() {
        return Err(Error::parse(path, line, format!("vertex {number} has a non-finite coordinate")));
    }
    let rgb = match vals[..] {
        [_, _, _, r, g, b] => Some(Vec3::new(num(r)?, num(g)?, num(b)?)),
        _ => None,
    };
    Ok((p, rgb))
}

/// Checks one face reference `v`, `v/vt`, `v//vn` or `v/vt/vn` against the entries
/// defined so far (negative indices) and in the whole file (positive indices).
fn check_face_ref(path: &Path, line: usize, token: &str, so_far: [u64; 3], totals: [u64; 3]) -> Result<()> {
    let err = |msg: String| Error::parse(path, line, msg);
    for (k, part) in token.split('/').enumerate() {
        let (Some(&(kind, kinds)), Some(&total), Some(&before)) = (REF_KINDS.get(k), totals.get(k), so_far.get(k))
        else {
            return Err(err(format!("face vertex '{token}' has more than three '/'-separated indices")));
        };
        if part.is_empty() {
            if k == 0 {
                return Err(err(format!("face vertex '{token}' has no vertex index")));
            }
            continue;
        }
        let index: i64 =
            part.parse().map_err(|_| err(format!("face vertex '{token}': '{part}' is not an integer index")))?;
        if k > 0 && total == 0 {
            continue; // tobj ignores vt/vn references when the file has none of that kind.
        }
        if index == 0 {
            return Err(err(format!("face references {kind} 0; OBJ indices start at 1")));
        }
        if index > 0 && index.unsigned_abs() > total {
            return Err(err(format!("face references {kind} {index} but the file has {total} {kinds}")));
        }
        if index < 0 && index.unsigned_abs() > before {
            return Err(err(format!("face references {kind} {index} (relative) but only {before} {kinds} precede it")));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("test.obj")
    }

    #[test]
    fn prepass_rewrites_vertices_and_drops_lines() {
        let pre = prepass(p(), "v 1 2 3 0.5 0.5 0.5\nv 2 4 6 2\nl 1 2\nf 1 2\nf 1 2 -1\nusemtl\r\nvt 0.5").unwrap();
        let lines: Vec<&str> = pre.text.split('\n').collect();
        assert_eq!(lines, ["v 1 2 3", "v 1 2 3", "", "", "f 1 2 -1", &format!("usemtl {NO_MATERIAL}"), "vt 0.5 0"]);
        assert!(pre.mentions_materials);
    }

    #[test]
    fn prepass_errors_have_lines() {
        for (text, line, want) in [
            ("v 1 2 3\nv 1 x 3\n", 2, "vertex 2: 'x' is not a number"),
            ("v 1 2\n", 1, "vertex 1 has 2 coordinates"),
            ("\nv 1 2 3 0\n", 2, "w = 0"),
            ("v 1 nan 3\n", 1, "vertex 1 has a non-finite coordinate"),
            ("v 1 2 3\nv 1 2 3\nv 1 2 3\n# c\nf 1 2 99\n", 5, "face references vertex 99 but the file has 3 vertices"),
            ("v 1 2 3\nf 1 1 -2\nv 1 2 3\n", 2, "vertex -2 (relative) but only 1"),
            ("v 1 2 3\nf 0 1 1\n", 2, "vertex 0"),
            ("v 1 2 3\nvt 0 0\nf 1/2 1/1 1/1\n", 3, "texture coordinate 2"),
            ("v 1 2 3\nvn 0 0 1\nf 1//1 1//1 1//-7\n", 3, "normal -7"),
            ("v 1 2 3\nf 1/1/1/1 1 1\n", 2, "more than three"),
            ("v 1 2 3\nf a 1 1\n", 2, "'a' is not an integer"),
            ("v 1 2 3\nf /1 1 1\n", 2, "no vertex index"),
        ] {
            let e = prepass(p(), text).err().unwrap();
            let msg = e.to_string();
            assert!(matches!(e, Error::Parse { line: l, .. } if l == line), "{msg}: want line {line}");
            assert!(msg.contains(want), "{msg} should contain {want}");
        }
        // vt/vn references are ignored when the file has none of that kind.
        assert!(prepass(p(), "v 1 2 3\nf 1/5/5 1/5/5 1/5/5\n").is_ok());
    }
}
