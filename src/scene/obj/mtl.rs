//! MTL material libraries (module docs, "Materials" and "Texture coordinates and
//! textures"): each library read once within the limits, MTL to [`Material`], and the
//! `map_Kd` textures with their options.

use std::collections::{BTreeSet, HashMap, HashSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use super::text::decode_text;
use crate::error::{Error, Result};
use crate::scene::images;
use crate::scene::limits::{self, FileKind};
use crate::scene::mesh::{Material, MaterialKind, Texture};

/// Name and albedo of the material given to faces without a (loadable) material.
pub const DEFAULT_MATERIAL_NAME: &str = "default";
const DEFAULT_ALBEDO: f32 = 0.8;

/// The material given to faces without a (loadable) material.
pub(super) fn default_material() -> Material {
    Material::lambert(DEFAULT_MATERIAL_NAME, Vec3::splat(DEFAULT_ALBEDO))
}

/// A texture coordinate transform, `uv * .0 + .1` (`map_Kd -s` and `-o`).
pub(super) type UvMap = (Vec2, Vec2);

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
pub(super) fn load_textures(
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
/// [`load`](super::load) to return, since tobj only hears that the library failed.
#[derive(Default)]
pub(super) struct Libraries {
    seen: HashSet<PathBuf>,
    materials: u64,
    /// The library each material came from, in tobj's order (it appends each library's
    /// materials as it reads them).
    pub(super) origins: Vec<PathBuf>,
    pub(super) error: Option<Error>,
}

impl Libraries {
    pub(super) fn load(&mut self, path: &Path) -> tobj::MTLLoadResult {
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
pub(super) fn convert_material(m: &tobj::Material) -> Material {
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

#[cfg(test)]
mod tests {
    use super::*;

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
