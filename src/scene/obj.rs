//! Wavefront OBJ loader with MTL materials, built on `tobj`.
//!
//! # Pipeline
//!
//! 1. The file is read and decoded as text: UTF-8 (a BOM is skipped), UTF-16 with a BOM, and
//!    invalid UTF-8 replaced by U+FFFD (names only ever need to match each other).
//! 2. A pre-pass, one output line per input line so line numbers stay valid, checks what
//!    `tobj` either does not check or reports without a location, and rewrites what it
//!    mishandles:
//!    * `v x y z [w | r g b ...]`: coordinates must be numbers, `w` non-zero, the result
//!      finite; the line is rewritten as `v x/w y/w z/w` (colours dropped, so vertices with
//!      and without colours can mix).
//!    * `vt u`: the missing second texture coordinate is written as 0.
//!    * `f`: every `v[/vt[/vn]]` reference must be a non-zero integer inside the file's
//!      vertex / texture / normal lists (negative = relative to the entries so far). `vt` and
//!      `vn` references are only checked when the file has that kind of entry (`tobj`
//!      ignores them otherwise). Faces with fewer than three vertices are dropped.
//!    * `l` (polylines) are dropped; `p` (points) are ignored by `tobj` anyway.
//!    * `usemtl` with no name selects the default material.
//! 3. `tobj` parses the result with `triangulate` (fans) and `single_index` (one index per
//!    unique `v/vt/vn` combination). Its remaining errors get the line it stopped on.
//! 4. All models are concatenated into one [`MeshData`].
//!
//! # Materials
//!
//! `mtllib` files are resolved relative to the OBJ file. A missing or malformed MTL is
//! not an error: its materials are absent and the faces using them get the default grey
//! Lambert material. An MTL that is not a regular file (a FIFO, a device) or is larger
//! than [`limits::MAX_TEXT_FILE_BYTES`] is an error at its `mtllib` line. Each distinct
//! library is read once however often it is named, at most [`limits::MAX_MTLLIBS`] of
//! them, defining at most [`limits::MAX_MATERIALS`] materials in all. When the file uses no materials at all (no `mtllib`, no `usemtl`)
//! `materials` and `tri_material` are empty; otherwise every triangle has a material and
//! the default is appended to `materials` if some triangle needs it.
//!
//! MTL → [`Material`]:
//! * `Kd` → `color` (grey 0.8 when absent), `Ks` → `specular`, `Ns` → `shininess`,
//!   `Ni` → `ior` (when positive), `Ke` → `emission`.
//! * kind, first match wins: `Emissive` if `Ke` is non-zero; `Mirror` if `illum 3`, `Ks`
//!   bright (largest component ≥ 0.5) and `Kd` black or absent (then `color` = `Ks`, the
//!   reflectance tint); `Glass` if `illum` is 4, 6 or 7 or `d` < 1 (then `color` = `Tf`
//!   when given, the transmission tint); `Phong` if `Ks` is non-zero; otherwise `Lambert`.
//!
//! # Normals
//!
//! Per-vertex normals are returned only when every vertex of every model has one, all
//! non-zero and finite; they are normalised. Otherwise `normals` is `None`.
//!
//! # Texture coordinates and textures
//!
//! `uvs` is returned only when every vertex of every model has a `vt` (v = 0 at the bottom
//! of the image). `map_Kd` gives a material a texture ([`images::load_texture`]); only
//! materials some face uses are looked at. The file is found relative to the MTL file's
//! folder, else the OBJ file's, also trying `\` as a folder separator; each file is read
//! once. Options before the file name: `-s u [v [w]]` and `-o u [v [w]]` transform the
//! coordinates of the faces using that material (`uv * s + o`; `w` ignored); `-blendu`,
//! `-blendv`, `-boost`, `-texres`, `-bm`, `-cc` are ignored; `-clamp off`, `-mm 0 1` and
//! `-t 0 0 0` (the defaults) are accepted; any other option is an error naming the MTL
//! file, the material and the option. A texture that cannot be read or decoded is an
//! error naming the texture file, the material and the MTL file.

use std::cell::RefCell;
use std::collections::{BTreeSet, HashMap, HashSet};
use std::fmt::Write as _;
use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use crate::error::{Error, Result};
use crate::scene::images;
use crate::scene::limits::{self, FileKind};
use crate::scene::mesh::{Material, MaterialKind, MeshData, Texture};

/// Name and albedo of the material given to faces without a (loadable) material.
pub const DEFAULT_MATERIAL_NAME: &str = "default";
const DEFAULT_ALBEDO: f32 = 0.8;

/// `usemtl` target written for an empty `usemtl`: no MTL can define a name with a NUL, so
/// `tobj` finds no such material and the faces get the default material.
const NO_MATERIAL: &str = "\u{0}no material";

/// Loads the OBJ file at `path` and the MTL libraries it names.
pub fn load(path: &Path) -> Result<MeshData> {
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let pre = {
        let text = decode_text(limits::read_file(path, FileKind::Mesh)?);
        prepass_in(path, &dir, &text)?
    };

    // `..Default::default()` covers the fields tobj's optional features add.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let mut reader = LineCounter::new(pre.text.as_bytes());
    let libraries = RefCell::new(Libraries::default());
    // The pre-pass removes the inputs known to make tobj panic; this catches the rest.
    let parsed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        tobj::load_obj_buf(&mut reader, &options, |mtl| libraries.borrow_mut().load(&dir.join(mtl)))
    }));
    let libraries = libraries.into_inner();
    if let Some(e) = libraries.error {
        return Err(e);
    }
    let (models, materials) = match parsed {
        Ok(Ok(result)) => result,
        Ok(Err(e)) => return Err(tobj_error(path, &pre.text, e, reader.line())),
        Err(_) => {
            return Err(Error::invalid(
                path,
                format!("the OBJ parser (tobj) failed unexpectedly near line {}", reader.line()),
            ))
        }
    };
    // A failed MTL only loses its materials; faces using them fall back to the default.
    let tobj_materials = materials.unwrap_or_default();
    let mut materials: Vec<Material> = tobj_materials.iter().map(convert_material).collect();
    let uses_materials = pre.mentions_materials || !materials.is_empty();
    let (textures, uv_maps) = load_textures(path, &dir, &models, &tobj_materials, &libraries.origins, &mut materials)?;
    let mut mesh = assemble(path, &models, materials, uses_materials, &uv_maps)?;
    mesh.textures = textures;
    Ok(mesh)
}

/// A texture coordinate transform, `uv * .0 + .1` (`map_Kd -s` and `-o`).
type UvMap = (Vec2, Vec2);

/// A `map_Kd` value: the texture file and the transform of texture coordinates its
/// `-s` and `-o` options give (`uv * scale + offset`).
#[derive(Debug, Clone, PartialEq)]
struct TextureRef {
    file: String,
    scale: Vec2,
    offset: Vec2,
}

/// `map_Kd` options accepted without effect (the renderer samples one bilinear texel
/// set, repeating) and how many values each takes.
const IGNORED_MAP_OPTIONS: [(&str, usize); 6] =
    [("-blendu", 1), ("-blendv", 1), ("-boost", 1), ("-texres", 1), ("-bm", 1), ("-cc", 1)];

/// Parses a `map_Kd` value: options, then the file name (the rest of the line, spaces
/// included). `-s u [v [w]]` and `-o u [v [w]]` transform texture coordinates (w is
/// ignored); `-clamp off`, `-mm 0 1` and `-t 0 0 0` are the defaults; the options in
/// [`IGNORED_MAP_OPTIONS`] are ignored; any other option is an error naming it.
fn parse_map_kd(value: &str) -> std::result::Result<TextureRef, String> {
    let mut rest = value.trim();
    let mut tex = TextureRef { file: String::new(), scale: Vec2::ONE, offset: Vec2::ZERO };
    // Splits off the first word of `rest`.
    let word = |rest: &mut &str| -> Option<String> {
        let r = rest.trim_start();
        let end = r.find(char::is_whitespace).unwrap_or(r.len());
        let (w, tail) = r.split_at(end);
        *rest = tail.trim_start();
        (!w.is_empty()).then(|| w.to_string())
    };
    // Up to `max` numbers following an option.
    let numbers = |rest: &mut &str, max: usize| -> Vec<f32> {
        let mut out = Vec::new();
        while out.len() < max {
            let r = rest.trim_start();
            let end = r.find(char::is_whitespace).unwrap_or(r.len());
            match r.get(..end).and_then(|w| w.parse::<f32>().ok()) {
                Some(v) if end < r.len() => {
                    out.push(v);
                    *rest = r.get(end..).unwrap_or_default().trim_start();
                }
                _ => break, // the last word is the file name, even when it looks like a number
            }
        }
        out
    };
    while rest.starts_with('-') {
        let option = word(&mut rest).unwrap_or_default();
        let bad = |why: &str| Err(format!("map_Kd option '{option}' {why}"));
        match option.as_str() {
            "-s" | "-o" | "-t" => {
                let v = numbers(&mut rest, 3);
                let Some(&u) = v.first() else { return bad("needs 1 to 3 numbers") };
                if !v.iter().all(|x| x.is_finite()) {
                    return bad("needs finite numbers");
                }
                let uv = Vec2::new(u, v.get(1).copied().unwrap_or(if option == "-s" { 1.0 } else { 0.0 }));
                match option.as_str() {
                    "-s" => tex.scale = uv,
                    "-o" => tex.offset = uv,
                    _ if v.iter().all(|x| *x == 0.0) => {}
                    _ => return bad("(turbulence) is not supported; only -t 0 0 0"),
                }
            }
            "-mm" => {
                if numbers(&mut rest, 2) != [0.0, 1.0] {
                    return bad("(value range) is not supported; only -mm 0 1");
                }
            }
            "-clamp" => match word(&mut rest).as_deref() {
                Some("off") => {}
                _ => return bad("is not supported except as '-clamp off': textures repeat"),
            },
            _ => match IGNORED_MAP_OPTIONS.iter().find(|(name, _)| *name == option) {
                Some(&(_, n)) => {
                    for _ in 0..n {
                        if word(&mut rest).is_none() {
                            return bad("needs a value");
                        }
                    }
                }
                None => {
                    return bad("is not supported (supported: -s, -o, -blendu, -blendv, -boost, -texres, -bm, -cc, \
                         -clamp off, -mm 0 1, -t 0 0 0)")
                }
            },
        }
    }
    if rest.is_empty() {
        return Err("map_Kd names no file".into());
    }
    tex.file = rest.to_string();
    Ok(tex)
}

/// Where a `map_Kd` file is: relative to the MTL file's folder, else to the OBJ file's
/// folder, trying `\` as a folder separator too; the first candidate that exists, or the
/// first one (for its "not found" message).
fn resolve_texture(file: &str, mtl_dir: &Path, obj_dir: &Path) -> PathBuf {
    let mut candidates = vec![mtl_dir.join(file), obj_dir.join(file)];
    if std::path::MAIN_SEPARATOR == '/' && file.contains('\\') {
        let slashed = file.replace('\\', "/");
        candidates.push(mtl_dir.join(&slashed));
        candidates.push(obj_dir.join(&slashed));
    }
    candidates.iter().find(|c| c.exists()).unwrap_or(&candidates[0]).clone()
}

/// Loads the `map_Kd` textures of the materials the models use (each file once), sets
/// those materials' `texture`, and returns the textures and, per material, the texture
/// coordinate transform (`scale`, `offset`) of its `map_Kd` options.
fn load_textures(
    path: &Path,
    obj_dir: &Path,
    models: &[tobj::Model],
    tobj_materials: &[tobj::Material],
    origins: &[PathBuf],
    materials: &mut [Material],
) -> Result<(Vec<Texture>, Vec<Option<UvMap>>)> {
    let mut uv_maps = vec![None; tobj_materials.len()];
    let mut textures: Vec<Texture> = Vec::new();
    let mut by_path: HashMap<PathBuf, u32> = HashMap::new();
    let used: BTreeSet<usize> =
        models.iter().filter(|m| !m.mesh.indices.is_empty()).filter_map(|m| m.mesh.material_id).collect();
    for id in used {
        let (Some(tm), Some(material)) = (tobj_materials.get(id), materials.get_mut(id)) else { continue };
        let Some(value) = &tm.diffuse_texture else { continue };
        let mtl = origins.get(id).map_or(path, PathBuf::as_path);
        let tex = parse_map_kd(value).map_err(|msg| Error::invalid(mtl, format!("material '{}': {msg}", tm.name)))?;
        let mtl_dir = mtl.parent().unwrap_or(obj_dir);
        let file = resolve_texture(&tex.file, mtl_dir, obj_dir);
        let index = match by_path.get(&file) {
            Some(&i) => i,
            None => {
                let context = format!("texture of material '{}' (map_Kd in {})", tm.name, mtl.display());
                textures.push(images::load_texture(&file).map_err(|e| images::with_context(e, &context))?);
                let i = textures.len() as u32 - 1;
                by_path.insert(file, i);
                i
            }
        };
        material.texture = Some(index);
        if let Some(slot) = uv_maps.get_mut(id) {
            *slot = Some((tex.scale, tex.offset));
        }
    }
    Ok((textures, uv_maps))
}

/// The MTL libraries an OBJ file names, as tobj asks for them: each distinct path is
/// read once (bounded, see [`limits::read_file`]); the first hard error is kept for
/// [`load`] to return, since tobj only hears that the library failed.
#[derive(Default)]
struct Libraries {
    seen: HashSet<PathBuf>,
    materials: u64,
    /// The library each material came from, in tobj's order (it appends each library's
    /// materials as it reads them).
    origins: Vec<PathBuf>,
    error: Option<Error>,
}

impl Libraries {
    fn load(&mut self, path: &Path) -> tobj::MTLLoadResult {
        if self.error.is_some() || !self.seen.insert(path.to_path_buf()) {
            return Ok((Vec::new(), Default::default()));
        }
        if self.seen.len() > limits::MAX_MTLLIBS {
            self.error = Some(Error::invalid(
                path,
                format!("more than {} distinct material libraries in one OBJ file", limits::MAX_MTLLIBS),
            ));
            return Err(tobj::LoadError::OpenFileFailed);
        }
        let bytes = match limits::read_file(path, FileKind::MaterialLibrary) {
            Ok(b) => b,
            // A missing or unreadable library only loses its materials (module docs).
            Err(Error::Io { .. }) => return Err(tobj::LoadError::OpenFileFailed),
            Err(e) => {
                self.error = Some(e);
                return Err(tobj::LoadError::OpenFileFailed);
            }
        };
        let text = decode_text(bytes);
        let defined = text.lines().filter(|l| l.split_whitespace().next() == Some("newmtl")).count() as u64;
        self.materials += defined;
        if self.materials > limits::MAX_MATERIALS {
            self.error = Some(Error::invalid(
                path,
                format!(
                    "the OBJ file's material libraries define {} materials; at most {} are supported",
                    self.materials,
                    limits::MAX_MATERIALS
                ),
            ));
            return Err(tobj::LoadError::OpenFileFailed);
        }
        let parsed = parse_mtl(&text);
        if let Ok((mats, _)) = &parsed {
            self.origins.extend(std::iter::repeat_n(path.to_path_buf(), mats.len()));
        }
        parsed
    }
}

/// Turns a tobj error into an [`Error`]. Errors tobj raises while reading a line get that
/// line. Index errors are raised when a group ends (`o`, `g`, `usemtl`), at line `line`:
/// the face that caused it is found by [`find_late_reference`].
fn tobj_error(path: &Path, text: &str, e: tobj::LoadError, line: usize) -> Error {
    use tobj::LoadError as E;
    if matches!(e, E::FaceVertexOutOfBounds | E::FaceTexCoordOutOfBounds | E::FaceNormalOutOfBounds) {
        if let Some((face_line, msg)) = find_late_reference(text, line) {
            return Error::parse(path, face_line, msg);
        }
    }
    match e {
        E::FaceVertexOutOfBounds
        | E::FaceTexCoordOutOfBounds
        | E::FaceNormalOutOfBounds
        | E::FaceColorOutOfBounds
        | E::InvalidPolygon
        | E::InvalidLoadOptionConfig
        | E::GenericFailure
        | E::OpenFileFailed => Error::invalid(path, format!("invalid OBJ: {e}")),
        _ => Error::parse(path, line, format!("invalid OBJ: {e}")),
    }
}

/// Decodes a text file: UTF-16 (LE or BE) when it starts with a byte-order mark, otherwise
/// UTF-8 with an optional BOM and invalid sequences replaced. A file using lone `\r` line
/// ends (and no `\n`) gets `\n` ones.
fn decode_text(mut bytes: Vec<u8>) -> String {
    let utf16 = |big_endian: bool, body: &[u8]| {
        let units = body.chunks_exact(2).map(|c| match *c {
            [a, b] if big_endian => u16::from_be_bytes([a, b]),
            [a, b] => u16::from_le_bytes([a, b]),
            _ => 0xFFFD,
        });
        char::decode_utf16(units).map(|c| c.unwrap_or(char::REPLACEMENT_CHARACTER)).collect::<String>()
    };
    let utf8 = |bytes: Vec<u8>| {
        // Valid UTF-8 (the usual case) is used in place, without a copy.
        String::from_utf8(bytes).unwrap_or_else(|e| String::from_utf8_lossy(e.as_bytes()).into_owned())
    };
    let text = match bytes[..] {
        [0xFE, 0xFF, ..] => utf16(true, bytes.get(2..).unwrap_or_default()),
        [0xFF, 0xFE, ..] => utf16(false, bytes.get(2..).unwrap_or_default()),
        [0xEF, 0xBB, 0xBF, ..] => {
            bytes.drain(..3);
            utf8(bytes)
        }
        _ => utf8(bytes),
    };
    if text.contains('\r') && !text.contains('\n') {
        text.replace('\r', "\n")
    } else {
        text
    }
}

/// Output of [`prepass`].
struct Prepass {
    /// The rewritten OBJ text, line for line with the input.
    text: String,
    /// Whether the file has any `mtllib` or `usemtl` line.
    mentions_materials: bool,
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
fn prepass_in(path: &Path, dir: &Path, text: &str) -> Result<Prepass> {
    let keyword = |line: &str| line.split_whitespace().next().unwrap_or_default().to_string();
    // Totals of v, vt, vn: positive face references may point forward.
    let mut totals = [0u64; 3];
    for line in text.split('\n') {
        match keyword(line).as_str() {
            "v" => totals[0] += 1,
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
                let p = parse_vertex(path, line_no, so_far[0], words)?;
                let _ = write!(out, "v {} {} {}", p.x, p.y, p.z);
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
fn find_late_reference(text: &str, flush_line: usize) -> Option<(usize, String)> {
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

/// Parses the values after `v`: `x y z`, optionally `w` (4 values) or colours (more).
fn parse_vertex<'a>(path: &Path, line: usize, number: u64, words: impl Iterator<Item = &'a str>) -> Result<Vec3> {
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
    Ok(p)
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

/// A `BufRead` over the pre-pass text that knows which line `tobj` read last.
struct LineCounter<'a> {
    data: &'a [u8],
    pos: usize,
    newlines: usize,
    ends_with_newline: bool,
}

impl<'a> LineCounter<'a> {
    fn new(data: &'a [u8]) -> Self {
        LineCounter { data, pos: 0, newlines: 0, ends_with_newline: false }
    }

    /// 1-based number of the line most recently consumed (1 before any reading).
    fn line(&self) -> usize {
        if self.ends_with_newline {
            self.newlines
        } else {
            self.newlines + 1
        }
    }
}

impl Read for LineCounter<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let avail = self.fill_buf()?;
        let n = avail.len().min(buf.len());
        if let (Some(dst), Some(src)) = (buf.get_mut(..n), avail.get(..n)) {
            dst.copy_from_slice(src);
        }
        self.consume(n);
        Ok(n)
    }
}

impl BufRead for LineCounter<'_> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        Ok(self.data.get(self.pos..).unwrap_or_default())
    }

    fn consume(&mut self, amt: usize) {
        let end = self.pos.saturating_add(amt).min(self.data.len());
        let chunk = self.data.get(self.pos..end).unwrap_or_default();
        self.newlines += chunk.iter().filter(|&&b| b == b'\n').count();
        if let Some(&last) = chunk.last() {
            self.ends_with_newline = last == b'\n';
        }
        self.pos = end;
    }
}

/// The colour keywords tobj parses with a helper that panics on fewer than three numbers.
const MTL_COLOURS: [&str; 4] = ["Ka", "Kd", "Ks", "Ke"];

/// Loads an MTL file for tobj. tobj reads a colour from the first three tokens after the
/// keyword and panics when they all parse but are fewer than three. So: one number
/// (`Kd 0.5`, allowed by the MTL spec: grey) is expanded to three; none or two fail the
/// file; anything non-numeric (`Kd spectral ...`) is left for tobj to reject.
#[cfg(test)]
fn load_mtl(path: &Path) -> tobj::MTLLoadResult {
    let bytes = std::fs::read(path).map_err(|_| tobj::LoadError::OpenFileFailed)?;
    parse_mtl(&decode_text(bytes))
}

/// [`load_mtl`] for MTL text already read.
fn parse_mtl(text: &str) -> tobj::MTLLoadResult {
    let mut fixed = String::with_capacity(text.len());
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some(key) if MTL_COLOURS.contains(&key) => {
                let vals: Vec<&str> = words.take(3).collect();
                let numeric = vals.iter().all(|v| v.parse::<f32>().is_ok());
                match vals[..] {
                    [v] if numeric => {
                        let _ = write!(fixed, "{key} {v} {v} {v}");
                    }
                    [] | [_, _] if numeric => return Err(tobj::LoadError::MaterialParseError),
                    _ => fixed.push_str(line),
                }
            }
            // tobj takes a name or file as the line from a fixed offset: no indentation.
            _ => fixed.push_str(line.trim_start()),
        }
        fixed.push('\n');
    }
    std::panic::catch_unwind(|| tobj::load_mtl_buf(&mut fixed.as_bytes()))
        .unwrap_or(Err(tobj::LoadError::GenericFailure))
}

/// Clean colour: finite, non-negative components.
fn colour(c: Option<[f32; 3]>) -> Option<Vec3> {
    c.map(|[r, g, b]| Vec3::new(r, g, b)).filter(|v| v.is_finite()).map(|v| v.max(Vec3::ZERO))
}

/// An MTL colour stored as text in `unknown_param` (`Ke` in older tobj versions, `Tf`):
/// three numbers, or one for grey.
fn param_colour(value: Option<&String>) -> Option<Vec3> {
    let vals: Vec<f32> = value?.split_whitespace().map(str::parse).collect::<std::result::Result<_, _>>().ok()?;
    match vals[..] {
        [v] => colour(Some([v; 3])),
        [r, g, b] => colour(Some([r, g, b])),
        _ => None,
    }
}

/// Components at or below this count as zero ("black").
const BLACK: f32 = 1e-4;
/// A specular colour whose largest component reaches this is "bright" (mirror test).
const BRIGHT: f32 = 0.5;

/// Maps an MTL material to a [`Material`] (rules in the module docs).
fn convert_material(m: &tobj::Material) -> Material {
    let mut out = Material::lambert(&m.name, Vec3::splat(DEFAULT_ALBEDO));
    let kd = colour(m.diffuse);
    let ks = colour(m.specular).unwrap_or(Vec3::ZERO);
    let ke = colour(m.emissive).or_else(|| param_colour(m.unknown_param.get("Ke"))).unwrap_or(Vec3::ZERO);
    if let Some(kd) = kd {
        out.color = kd;
    }
    out.specular = ks;
    out.emission = ke;
    if let Some(ns) = m.shininess.filter(|s| s.is_finite() && *s >= 0.0) {
        out.shininess = ns;
    }
    if let Some(ni) = m.optical_density.filter(|n| n.is_finite() && *n > 0.0) {
        out.ior = ni;
    }
    let illum = m.illumination_model;
    let kd_black = kd.is_none_or(|c| c.max_element() <= BLACK);
    let translucent = m.dissolve.is_some_and(|d| d < 1.0);
    out.kind = if ke.max_element() > BLACK {
        MaterialKind::Emissive
    } else if illum == Some(3) && ks.max_element() >= BRIGHT && kd_black {
        out.color = ks;
        MaterialKind::Mirror
    } else if matches!(illum, Some(4 | 6 | 7)) || translucent {
        if let Some(tf) = param_colour(m.unknown_param.get("Tf")) {
            out.color = tf;
        }
        MaterialKind::Glass
    } else if ks.max_element() > BLACK {
        MaterialKind::Phong
    } else {
        MaterialKind::Lambert
    };
    out
}

/// Concatenates tobj's models into one mesh (see the module docs for materials and normals).
fn assemble(
    path: &Path,
    models: &[tobj::Model],
    mut materials: Vec<Material>,
    uses_materials: bool,
    uv_maps: &[Option<UvMap>],
) -> Result<MeshData> {
    let mut mesh = MeshData::default();
    let mut normals: Vec<Vec3> = Vec::new();
    let mut all_have_normals = true;
    let mut uvs: Vec<Vec2> = Vec::new();
    let mut all_have_uvs = true;
    let mut default_index = None;

    for model in models {
        let m = &model.mesh;
        let base = u32::try_from(mesh.positions.len()).map_err(|_| Error::invalid(path, "more than 2^32 vertices"))?;
        let count = m.positions.len() / 3;
        mesh.positions.extend(m.positions.chunks_exact(3).filter_map(|c| match *c {
            [x, y, z] => Some(Vec3::new(x, y, z)),
            _ => None,
        }));
        if m.normals.len() == m.positions.len() {
            normals.extend(m.normals.chunks_exact(3).filter_map(|c| match *c {
                [x, y, z] => Some(Vec3::new(x, y, z)),
                _ => None,
            }));
        } else if count > 0 {
            all_have_normals = false;
        }
        // tobj gives a model texture coordinates only for the vertices that have one.
        if m.texcoords.len() == 2 * count {
            let (scale, offset) =
                m.material_id.and_then(|id| uv_maps.get(id).copied().flatten()).unwrap_or((Vec2::ONE, Vec2::ZERO));
            uvs.extend(m.texcoords.chunks_exact(2).filter_map(|c| match *c {
                [u, v] => Some(Vec2::new(u, v) * scale + offset),
                _ => None,
            }));
        } else {
            all_have_uvs = false;
        }

        let material = if uses_materials {
            match m.material_id.filter(|&id| id < materials.len()).and_then(|id| u32::try_from(id).ok()) {
                Some(id) => Some(id),
                None => Some(*default_index.get_or_insert_with(|| {
                    materials.push(Material::lambert(DEFAULT_MATERIAL_NAME, Vec3::splat(DEFAULT_ALBEDO)));
                    materials.len() as u32 - 1
                })),
            }
        } else {
            None
        };

        for tri in m.indices.chunks(3) {
            let &[a, b, c] = tri else {
                return Err(Error::invalid(path, format!("model '{}' has a partial triangle", model.name)));
            };
            let mut t = [0u32; 3];
            for (dst, i) in t.iter_mut().zip([a, b, c]) {
                if i as usize >= count {
                    return Err(Error::invalid(
                        path,
                        format!("model '{}' references vertex {i} of {count}", model.name),
                    ));
                }
                *dst = base.checked_add(i).ok_or_else(|| Error::invalid(path, "more than 2^32 vertices"))?;
            }
            mesh.triangles.push(t);
            if let Some(mat) = material {
                mesh.tri_material.push(mat);
            }
        }
    }

    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::invalid(path, format!("vertex {i} has a non-finite coordinate")));
    }
    if all_have_normals && !mesh.positions.is_empty() && normals.len() == mesh.positions.len() {
        mesh.normals = normals
            .into_iter()
            .map(|n| {
                let len = n.length();
                (len.is_finite() && len > 0.0).then(|| n / len)
            })
            .collect();
    }
    if all_have_uvs && !mesh.positions.is_empty() && uvs.len() == mesh.positions.len() {
        mesh.uvs = Some(uvs);
    }
    if uses_materials {
        mesh.materials = materials;
    }
    Ok(mesh)
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

    #[test]
    fn line_counter_tracks_lines() {
        let mut r = LineCounter::new(b"a\nbb\n\nc");
        assert_eq!(r.line(), 1);
        let mut lines = Vec::new();
        let mut s = String::new();
        while r.read_line(&mut s).unwrap() > 0 {
            lines.push(r.line());
            s.clear();
        }
        assert_eq!(lines, [1, 2, 3, 4]);
    }

    #[test]
    fn decodes_boms_and_utf16() {
        let d = |b: &[u8]| decode_text(b.to_vec());
        assert_eq!(d(b"\xEF\xBB\xBFv 1"), "v 1");
        assert_eq!(d(b"\xFE\xFF\0v\0 \x001"), "v 1");
        assert_eq!(d(b"\xFF\xFEv\0 \x001\0"), "v 1");
        assert_eq!(d(b"a\rb"), "a\nb");
        assert_eq!(d(b"a\xFFb"), "a\u{FFFD}b");
    }

    #[test]
    fn mtl_colours_tobj_would_panic_on() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("m.mtl");
        for (text, ok) in [("newmtl a\nKd 0.25\n", true), ("newmtl a\nKd\n", false), ("newmtl a\nKs 1 2\n", false)] {
            std::fs::write(&file, text).unwrap();
            let result = load_mtl(&file);
            assert_eq!(result.is_ok(), ok, "{text:?}");
            if let Ok((mats, _)) = result {
                assert_eq!(mats[0].diffuse, Some([0.25; 3]));
            }
        }
    }

    fn mtl(f: impl FnOnce(&mut tobj::Material)) -> Material {
        let mut m = tobj::Material { name: "m".into(), ..Default::default() };
        f(&mut m);
        convert_material(&m)
    }

    #[test]
    fn material_kinds() {
        let m = mtl(|_| {});
        assert_eq!((m.kind, m.color), (MaterialKind::Lambert, Vec3::splat(0.8)));
        let m = mtl(|m| {
            m.diffuse = Some([0.1, 0.2, 0.3]);
            m.specular = Some([0.5; 3]);
            m.shininess = Some(40.0);
        });
        assert_eq!((m.kind, m.color, m.shininess), (MaterialKind::Phong, Vec3::new(0.1, 0.2, 0.3), 40.0));
        let m = mtl(|m| {
            m.unknown_param.insert("Ke".into(), "4 4 4".into());
            m.illumination_model = Some(7);
        });
        assert_eq!((m.kind, m.emission), (MaterialKind::Emissive, Vec3::splat(4.0)));
        let m = mtl(|m| m.emissive = Some([0.0, 1.0, 0.0]));
        assert_eq!(m.kind, MaterialKind::Emissive);
        let m = mtl(|m| {
            m.illumination_model = Some(3);
            m.diffuse = Some([0.0; 3]);
            m.specular = Some([0.9, 0.8, 0.7]);
        });
        assert_eq!((m.kind, m.color), (MaterialKind::Mirror, Vec3::new(0.9, 0.8, 0.7)));
        let m = mtl(|m| {
            m.illumination_model = Some(3);
            m.diffuse = Some([0.5; 3]);
            m.specular = Some([0.9; 3]);
        });
        assert_eq!(m.kind, MaterialKind::Phong, "illum 3 with a coloured Kd is not a mirror");
        let m = mtl(|m| {
            m.illumination_model = Some(6);
            m.optical_density = Some(1.33);
            m.unknown_param.insert("Tf".into(), "0.9".into());
        });
        assert_eq!((m.kind, m.ior, m.color), (MaterialKind::Glass, 1.33, Vec3::splat(0.9)));
        let m = mtl(|m| m.dissolve = Some(0.5));
        assert_eq!(m.kind, MaterialKind::Glass);
        let m = mtl(|m| {
            m.optical_density = Some(0.0);
            m.diffuse = Some([f32::NAN, 1.0, 1.0]);
        });
        assert_eq!((m.ior, m.color), (1.5, Vec3::splat(0.8)));
    }
}
