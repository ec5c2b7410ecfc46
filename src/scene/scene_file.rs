//! The TOML scene format (keys are a contract; see README "Scene files").
//! Unknown keys are errors; every error names the file and line.
//!
//! Bounds (docs/limits.md): the file is at most [`limits::MAX_TEXT_FILE_BYTES`]; each
//! distinct mesh file is loaded once however many `[[mesh]]` tables name it, and the
//! scene's total triangles and vertices (every table counted) are checked against
//! [`limits::MAX_TRIANGLES`] / [`limits::MAX_VERTICES`] before the scene is assembled.
//! Texture and environment images go through [`super::images`] (size and texel caps);
//! each texture file is read once however many materials name it.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

use glam::Vec3;
use serde::Deserialize;
use toml::Spanned;

use super::images::{load_environment, load_texture};
use super::limits::{self, FileKind};
use super::mesh::{AlphaMode, ComplexIor, Material, MaterialKind, MeshData, DEFAULT_ALPHA_CUTOFF};
use super::{load_mesh, Camera, Light, Scene, SceneBuilder, Sphere};
use crate::error::{Error, Result};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    camera: Option<Spanned<CameraDef>>,
    film: Option<Spanned<FilmDef>>,
    render: Option<Spanned<RenderDef>>,
    #[serde(default)]
    mesh: Vec<Spanned<MeshDef>>,
    #[serde(default)]
    sphere: Vec<Spanned<SphereDef>>,
    #[serde(default)]
    material: Vec<Spanned<MaterialDef>>,
    #[serde(default)]
    light: Vec<Spanned<LightDef>>,
    #[serde(default)]
    instance: Vec<Spanned<InstanceDef>>,
    environment: Option<Spanned<EnvironmentDef>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EnvironmentDef {
    file: String,
    #[serde(default)]
    rotation: f32,
    #[serde(default = "one")]
    intensity: f32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraDef {
    eye: [f32; 3],
    look_at: [f32; 3],
    #[serde(default = "default_up")]
    up: [f32; 3],
    #[serde(default = "default_vfov")]
    vfov: f32,
}
fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}
fn default_vfov() -> f32 {
    45.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FilmDef {
    width: u32,
    height: u32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RenderDef {
    background: Option<[f32; 3]>,
    ambient: Option<f32>,
    max_depth: Option<u32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshDef {
    file: String,
    scale: Option<Scale>,
    /// Axis x, y, z and an angle in degrees, about an axis through the origin.
    rotate: Option<[f32; 4]>,
    translate: Option<[f32; 3]>,
    /// 16 numbers, row-major, last row 0 0 0 1; instead of scale, rotate and translate.
    matrix: Option<Vec<f32>>,
    material: Option<Spanned<String>>,
    /// The name `[[instance]]` tables draw it by.
    name: Option<String>,
    /// Stored once and drawn only by `[[instance]]` tables (needs `name`).
    #[serde(default)]
    instanced: bool,
}

/// One placement of an instanced mesh: its transform keys are a mesh's.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InstanceDef {
    mesh: String,
    scale: Option<Scale>,
    rotate: Option<[f32; 4]>,
    translate: Option<[f32; 3]>,
    matrix: Option<Vec<f32>>,
}

fn one() -> f32 {
    1.0
}

/// A uniform scale or one per axis.
#[derive(Deserialize, Clone, Copy)]
#[serde(untagged)]
enum Scale {
    Uniform(f32),
    Axes([f32; 3]),
}

/// The mesh table's transform: `matrix`, or scale, then rotate, then translate.
fn mesh_transform(d: &MeshDef) -> std::result::Result<glam::Affine3A, String> {
    transform_of(d.scale, d.rotate, d.translate, d.matrix.as_deref())
}

/// `matrix`, or scale, then rotate, then translate.
fn transform_of(
    scale: Option<Scale>,
    rotate: Option<[f32; 4]>,
    translate: Option<[f32; 3]>,
    matrix: Option<&[f32]>,
) -> std::result::Result<glam::Affine3A, String> {
    if let Some(m) = matrix {
        if scale.is_some() || rotate.is_some() || translate.is_some() {
            return Err("give either matrix or scale / rotate / translate, not both".into());
        }
        if m.len() != 16 {
            return Err(format!("matrix needs 16 numbers (row-major 4x4), got {}", m.len()));
        }
        if m.iter().any(|v| !v.is_finite()) {
            return Err("matrix has a non-finite number".into());
        }
        if m[12..16] != [0.0, 0.0, 0.0, 1.0] {
            return Err("matrix's last row must be 0 0 0 1 (an affine transform)".into());
        }
        let cols = glam::Mat4::from_cols_array(&[
            m[0], m[4], m[8], m[12], m[1], m[5], m[9], m[13], m[2], m[6], m[10], m[14], m[3], m[7], m[11], m[15],
        ]);
        return check_transform(glam::Affine3A::from_mat4(cols));
    }
    let scale = match scale.unwrap_or(Scale::Uniform(1.0)) {
        Scale::Uniform(s) => Vec3::splat(s),
        Scale::Axes(a) => v3(a),
    };
    let rotation = match rotate {
        None => glam::Quat::IDENTITY,
        Some([x, y, z, deg]) => {
            let axis = Vec3::new(x, y, z);
            if !(axis.is_finite() && deg.is_finite()) {
                return Err("rotate needs a finite axis and angle".into());
            }
            let axis = axis.try_normalize().ok_or("rotate needs a non-zero axis [x, y, z, degrees]")?;
            glam::Quat::from_axis_angle(axis, deg.to_radians())
        }
    };
    let translate = v3(translate.unwrap_or_default());
    if !(scale.is_finite() && translate.is_finite()) {
        return Err("scale and translate must be finite".into());
    }
    check_transform(glam::Affine3A::from_scale_rotation_translation(scale, rotation, translate))
}

/// Refuses a singular or non-finite transform.
fn check_transform(t: glam::Affine3A) -> std::result::Result<glam::Affine3A, String> {
    let det = t.matrix3.determinant();
    if !(det.is_finite() && t.translation.is_finite()) || det == 0.0 {
        return Err(format!("the transform is singular or not finite (determinant {det})"));
    }
    Ok(t)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SphereDef {
    center: [f32; 3],
    radius: f32,
    material: Option<Spanned<String>>,
    /// Uniform scale of centre and radius (about the origin), before `translate`.
    scale: Option<f32>,
    translate: Option<[f32; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialDef {
    name: String,
    #[serde(rename = "type")]
    kind: MaterialKind,
    color: Option<[f32; 3]>,
    specular: Option<[f32; 3]>,
    shininess: Option<f32>,
    ior: Option<f32>,
    emission: Option<[f32; 3]>,
    #[serde(default)]
    two_sided: bool,
    absorption: Option<[f32; 3]>,
    texture: Option<String>,
    emission_texture: Option<String>,
    roughness: Option<f32>,
    eta: Option<[f32; 3]>,
    k: Option<[f32; 3]>,
    metallic: Option<f32>,
    alpha_mode: Option<AlphaModeDef>,
    alpha_cutoff: Option<Spanned<f32>>,
    opacity: Option<Spanned<f32>>,
}

#[derive(Deserialize, Clone, Copy, PartialEq)]
#[serde(rename_all = "lowercase")]
enum AlphaModeDef {
    Opaque,
    Mask,
    Blend,
}

#[derive(Deserialize)]
#[serde(rename_all = "lowercase")]
enum LightKind {
    Directional,
    Point,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightDef {
    #[serde(rename = "type")]
    kind: LightKind,
    direction: Option<[f32; 3]>,
    radiance: Option<[f32; 3]>,
    position: Option<[f32; 3]>,
    intensity: Option<[f32; 3]>,
}

/// What is wrong with an alpha key, at the key's span where it has one.
type KeyError = (Option<std::ops::Range<usize>>, String);

/// A material's `alpha_mode`, `alpha_cutoff` (MASK only, default 0.5) and `opacity`
/// (default 1), each checked.
fn alpha_of(d: &MaterialDef) -> std::result::Result<(AlphaMode, f32), KeyError> {
    let mode = d.alpha_mode.unwrap_or(AlphaModeDef::Opaque);
    let opacity = match &d.opacity {
        None => 1.0,
        Some(o) if mode == AlphaModeDef::Opaque => {
            return Err((
                Some(o.span()),
                "opacity needs alpha_mode = \"mask\" or \"blend\" (an opaque surface ignores it)".into(),
            ))
        }
        Some(o) if !(0.0..=1.0).contains(o.get_ref()) => {
            return Err((Some(o.span()), format!("opacity must be in [0, 1], got {}", o.get_ref())))
        }
        Some(o) => *o.get_ref(),
    };
    let cutoff = match &d.alpha_cutoff {
        None => DEFAULT_ALPHA_CUTOFF,
        Some(c) if mode != AlphaModeDef::Mask => {
            return Err((Some(c.span()), "alpha_cutoff needs alpha_mode = \"mask\"".into()))
        }
        Some(c) if !(0.0..=1.0).contains(c.get_ref()) => {
            return Err((Some(c.span()), format!("alpha_cutoff must be in [0, 1], got {}", c.get_ref())))
        }
        Some(c) => *c.get_ref(),
    };
    Ok(match mode {
        AlphaModeDef::Opaque => (AlphaMode::Opaque, 1.0),
        AlphaModeDef::Blend => (AlphaMode::Blend, opacity),
        AlphaModeDef::Mask => (AlphaMode::Mask { cutoff }, opacity),
    })
}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

/// A key given to a material type that has no use for it (so that a typo of type
/// does not pass silently): roughness outside conductor, dielectric and pbr, eta and k
/// outside conductor, metallic outside pbr.
fn misplaced_key(d: &MaterialDef) -> Option<String> {
    let microfacet = matches!(d.kind, MaterialKind::Conductor | MaterialKind::Dielectric | MaterialKind::Pbr);
    if d.roughness.is_some() && !microfacet {
        return Some("roughness is for type = \"conductor\", \"dielectric\" or \"pbr\"".into());
    }
    if d.metallic.is_some() && d.kind != MaterialKind::Pbr {
        return Some("metallic is for type = \"pbr\"".into());
    }
    if (d.eta.is_some() || d.k.is_some()) && d.kind != MaterialKind::Conductor {
        return Some("eta and k are for type = \"conductor\" (a dielectric's index is ior)".into());
    }
    None
}

fn v3(a: [f32; 3]) -> Vec3 {
    Vec3::from_array(a)
}

/// Loads a TOML scene file; mesh paths are relative to it.
pub fn load(path: &Path) -> Result<Scene> {
    let bytes = limits::read_file(path, FileKind::SceneFile)?;
    let text = String::from_utf8(bytes).map_err(|e| {
        let line = line_of(&String::from_utf8_lossy(e.as_bytes()), e.utf8_error().valid_up_to());
        Error::parse(path, line, "the scene file is not valid UTF-8 text")
    })?;
    let file: SceneFile = toml::from_str(&text).map_err(|e| {
        let line = e.span().map(|s| line_of(&text, s.start)).unwrap_or(1);
        Error::parse(path, line, e.message().trim().to_string())
    })?;
    let at = |span: std::ops::Range<usize>, msg: String| Error::parse(path, line_of(&text, span.start), msg);
    let dir: PathBuf = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut b = SceneBuilder::new(&path.display().to_string());
    for (count, max, what) in [
        (file.material.len(), limits::MAX_MATERIALS, "[[material]] tables"),
        (file.sphere.len(), limits::MAX_SPHERES, "[[sphere]] tables"),
    ] {
        if count as u64 > max {
            return Err(Error::invalid(path, format!("{count} {what}; at most {max} are supported")));
        }
    }

    // Name -> index; SceneBuilder::find_material is a linear search.
    let mut names: HashMap<String, u32> = HashMap::new();
    // Texture file -> index into the scene's textures: each file is read once.
    let mut textures: HashMap<PathBuf, u32> = HashMap::new();
    for m in &file.material {
        let d = m.get_ref();
        if names.contains_key(&d.name) {
            return Err(at(m.span(), format!("material '{}' is defined twice", d.name)));
        }
        let base = Material::lambert(&d.name, Vec3::splat(0.7));
        let default_color = match d.kind {
            MaterialKind::Lambert | MaterialKind::Phong | MaterialKind::Pbr => base.color,
            _ => Vec3::ONE,
        };
        if let Some(what) = misplaced_key(d) {
            return Err(at(m.span(), format!("material '{}': {what}", d.name)));
        }
        let complex_ior = match (d.eta, d.k) {
            (Some(eta), Some(k)) => Some(ComplexIor { eta: v3(eta), k: v3(k) }),
            (None, None) => None,
            _ => {
                return Err(at(
                    m.span(),
                    format!("material '{}': a conductor's eta and k go together (or give color alone)", d.name),
                ))
            }
        };
        let mat = Material {
            kind: d.kind,
            color: d.color.map(v3).unwrap_or(default_color),
            specular: d.specular.map(v3).unwrap_or(if d.kind == MaterialKind::Phong {
                Vec3::splat(0.5)
            } else {
                Vec3::ZERO
            }),
            shininess: d.shininess.unwrap_or(32.0),
            ior: d.ior.unwrap_or(1.5),
            emission: d.emission.map(v3).unwrap_or(if d.kind == MaterialKind::Emissive {
                Vec3::ONE
            } else {
                Vec3::ZERO
            }),
            two_sided: d.two_sided,
            absorption: d.absorption.map(v3).unwrap_or(Vec3::ZERO),
            roughness: d.roughness.unwrap_or(if d.kind == MaterialKind::Pbr { 0.5 } else { 0.0 }),
            complex_ior,
            metallic: d.metallic.unwrap_or(0.0),
            dielectric_f0: Vec3::splat(super::mesh::dielectric_f0(d.ior.unwrap_or(1.5))),
            ..base
        };
        let bad = !(mat.color.is_finite()
            && mat.specular.is_finite()
            && mat.emission.is_finite()
            && mat.shininess.is_finite()
            && mat.ior.is_finite());
        if bad || mat.ior <= 0.0 {
            return Err(at(m.span(), format!("material '{}' has a non-finite value or ior <= 0", d.name)));
        }
        if !(mat.absorption.is_finite() && mat.absorption.min_element() >= 0.0) {
            return Err(at(
                m.span(),
                format!("material '{}': absorption must be three finite numbers >= 0 (per unit length)", d.name),
            ));
        }
        if let Some(what) = mat.microfacet_error() {
            return Err(at(m.span(), format!("material '{}': {what}", d.name)));
        }
        let mut mat = mat;
        if d.emission_texture.is_some() && mat.emission == Vec3::ZERO {
            return Err(at(
                m.span(),
                format!("material '{}': emission_texture multiplies `emission`, which is zero", d.name),
            ));
        }
        let mut load = |key: &str, file: &str| -> Result<u32> {
            let tex_path = dir.join(file);
            if let Some(&i) = textures.get(&tex_path) {
                return Ok(i);
            }
            let tex =
                load_texture(&tex_path).map_err(|e| at(m.span(), format!("material '{}': {key}: {e}", d.name)))?;
            b.scene.textures.push(tex);
            let i = b.scene.textures.len() as u32 - 1;
            textures.insert(tex_path, i);
            Ok(i)
        };
        mat.texture = d.texture.as_deref().map(|t| load("texture", t)).transpose()?;
        (mat.alpha_mode, mat.opacity) =
            alpha_of(d).map_err(|(span, e)| at(span.unwrap_or(m.span()), format!("material '{}': {e}", d.name)))?;
        mat.maps.emission = d.emission_texture.as_deref().map(|t| load("emission_texture", t)).transpose()?;
        let index = b.material(mat);
        names.insert(d.name.clone(), index);
    }
    // An unknown name is reported at its own line, not its table's.
    let lookup = |name: &Option<Spanned<String>>| -> Result<Option<u32>> {
        match name {
            None => Ok(None),
            Some(n) => names.get(n.get_ref()).copied().map(Some).ok_or_else(|| {
                at(n.span(), format!("unknown material '{}' (define it in a [[material]] table)", n.get_ref()))
            }),
        }
    };

    // Every mesh file once, then the totals, then the scene.
    let mut loaded: HashMap<PathBuf, Rc<MeshData>> = HashMap::new();
    let mut meshes = Vec::with_capacity(file.mesh.len());
    let (mut triangles, mut vertices, mut materials) = (0u64, 0u64, b.scene.materials.len() as u64);
    for m in &file.mesh {
        let d = m.get_ref();
        let mat = lookup(&d.material)?;
        let transform = mesh_transform(d).map_err(|e| at(m.span(), format!("mesh '{}': {e}", d.file)))?;
        let mesh_path = dir.join(&d.file);
        let mesh = match loaded.get(&mesh_path) {
            Some(mesh) => Rc::clone(mesh),
            None => {
                let mesh = Rc::new(load_mesh(&mesh_path).map_err(|e| match e {
                    Error::Io { path, cause } if cause.kind() == std::io::ErrorKind::NotFound => {
                        at(m.span(), format!("mesh file '{}' not found ({})", d.file, path.display()))
                    }
                    other => other,
                })?);
                loaded.insert(mesh_path, Rc::clone(&mesh));
                mesh
            }
        };
        if let Some(msg) = mesh.texture_uv_error(mat.and_then(|i| b.scene.materials.get(i as usize))) {
            return Err(at(m.span(), format!("mesh file '{}': {msg}", d.file)));
        }
        triangles += mesh.triangles.len() as u64;
        vertices += mesh.positions.len() as u64;
        if mat.is_none() {
            materials += mesh.materials.len() as u64;
        }
        if let Some(what) = limits::totals_error(triangles, vertices) {
            return Err(at(
                m.span(),
                format!(
                    "[[mesh]] table {} ('{}', {} triangles, {} vertices) brings the scene to {what}: \
                     use fewer or smaller meshes",
                    meshes.len() + 1,
                    d.file,
                    mesh.triangles.len(),
                    mesh.positions.len()
                ),
            ));
        }
        if materials > limits::MAX_MATERIALS {
            return Err(at(
                m.span(),
                format!(
                    "the scene would have more than {} materials (mesh files' materials count once per [[mesh]] \
                     table); give the tables a 'material' or use fewer meshes",
                    limits::MAX_MATERIALS
                ),
            ));
        }
        if d.instanced && d.name.is_none() {
            return Err(at(
                m.span(),
                format!("mesh '{}': instanced = true needs a name for [[instance]] tables", d.file),
            ));
        }
        if let Some(n) = &d.name {
            if file.mesh[..meshes.len()].iter().any(|o| o.get_ref().name.as_ref() == Some(n)) {
                return Err(at(m.span(), format!("mesh name '{n}' is used twice")));
            }
        }
        meshes.push((mesh, transform, mat, d.instanced.then(|| d.name.clone()).flatten()));
    }
    drop(loaded);
    // Name -> prototype index.
    let mut prototypes: HashMap<String, u32> = HashMap::new();
    for (mesh, transform, mat, proto) in meshes {
        match proto {
            Some(name) => {
                let k = b.prototype(&name, &mesh, &transform, mat);
                prototypes.insert(name, k);
            }
            None => b.mesh_transformed(&mesh, &transform, mat),
        }
    }
    if file.instance.len() > super::instance::MAX_INSTANCES {
        return Err(Error::invalid(
            path,
            format!(
                "{} [[instance]] tables; at most {} are supported",
                file.instance.len(),
                super::instance::MAX_INSTANCES
            ),
        ));
    }
    for i in &file.instance {
        let d = i.get_ref();
        let Some(&k) = prototypes.get(&d.mesh) else {
            let hint = if file.mesh.iter().any(|m| m.get_ref().name.as_ref() == Some(&d.mesh)) {
                format!("mesh '{}' is drawn as it is; give it instanced = true to draw it by instances", d.mesh)
            } else {
                format!("no [[mesh]] is named '{}'", d.mesh)
            };
            return Err(at(i.span(), format!("instance: {hint}")));
        };
        let t = transform_of(d.scale, d.rotate, d.translate, d.matrix.as_deref())
            .map_err(|e| at(i.span(), format!("instance of '{}': {e}", d.mesh)))?;
        b.instance(k, t);
    }
    for s in &file.sphere {
        let d = s.get_ref();
        let mat = lookup(&d.material)?.unwrap_or(0);
        let k = d.scale.unwrap_or(1.0);
        if !(k.is_finite() && k != 0.0) {
            return Err(at(s.span(), "sphere scale must be a finite, non-zero number (uniform)".into()));
        }
        let c = v3(d.center) * k + v3(d.translate.unwrap_or_default());
        let r = d.radius * k.abs();
        if !(c.is_finite() && r.is_finite() && d.radius > 0.0 && r > 0.0) {
            return Err(at(s.span(), "sphere needs a finite center and a finite radius > 0".into()));
        }
        b.scene.spheres.push(Sphere { center: c, radius: r, material: mat });
    }
    for l in &file.light {
        let d = l.get_ref();
        let light = match d.kind {
            LightKind::Directional => {
                if d.position.is_some() || d.intensity.is_some() {
                    return Err(at(
                        l.span(),
                        "a directional light takes direction and radiance, not position/intensity".into(),
                    ));
                }
                let dir =
                    d.direction.map(v3).ok_or_else(|| at(l.span(), "directional light needs direction".into()))?;
                Light::Directional { direction: dir, radiance: d.radiance.map(v3).unwrap_or(Vec3::ONE) }
            }
            LightKind::Point => {
                if d.direction.is_some() || d.radiance.is_some() {
                    return Err(at(
                        l.span(),
                        "a point light takes position and intensity, not direction/radiance".into(),
                    ));
                }
                let p = d.position.map(v3).ok_or_else(|| at(l.span(), "point light needs position".into()))?;
                Light::Point { position: p, intensity: d.intensity.map(v3).unwrap_or(Vec3::ONE) }
            }
        };
        let ok = match light {
            Light::Directional { direction, radiance } => {
                direction.is_finite() && direction.length_squared() > 0.0 && radiance.is_finite()
            }
            Light::Point { position, intensity } => position.is_finite() && intensity.is_finite(),
        };
        if !ok {
            return Err(at(l.span(), "light values must be finite (and a direction non-zero)".into()));
        }
        b.scene.lights.push(light);
    }
    if let Some(se) = &file.environment {
        let e = se.get_ref();
        let env = load_environment(&dir.join(&e.file), e.rotation, e.intensity)
            .map_err(|err| at(se.span(), format!("[environment]: {err}")))?;
        b.scene.environment = Some(env);
    }
    if let Some(sf) = &file.film {
        let f = sf.get_ref();
        let max = super::MAX_FILM_SIDE;
        if f.width == 0 || f.height == 0 || f.width > max || f.height > max {
            return Err(at(
                sf.span(),
                format!("image size {}x{} is invalid: each side must be 1..={max}", f.width, f.height),
            ));
        }
        b.scene.width = f.width;
        b.scene.height = f.height;
    }
    if let Some(sr) = &file.render {
        let r = sr.get_ref();
        let finite = r.background.is_none_or(|bg| v3(bg).is_finite()) && r.ambient.is_none_or(f32::is_finite);
        if !finite {
            return Err(at(sr.span(), "render background and ambient must be finite".into()));
        }
        if let Some(bg) = r.background {
            b.scene.background = v3(bg);
        }
        if let Some(a) = r.ambient {
            b.scene.ambient = a;
        }
        if let Some(d) = r.max_depth {
            b.scene.max_depth = d;
        }
    }
    match &file.camera {
        Some(sc) => {
            let c = sc.get_ref();
            let cam = Camera { eye: v3(c.eye), look_at: v3(c.look_at), up: v3(c.up), vfov: c.vfov };
            cam.check().map_err(|m| at(sc.span(), m))?;
            b.scene.camera = cam;
        }
        None => {
            let mut bounds = crate::math::Aabb::EMPTY;
            for p in &b.scene.positions {
                bounds.grow(*p);
            }
            for s in &b.scene.spheres {
                bounds.grow(s.center - Vec3::splat(s.radius));
                bounds.grow(s.center + Vec3::splat(s.radius));
            }
            if !bounds.is_empty() && bounds.min.is_finite() && bounds.max.is_finite() {
                b.scene.camera = super::framed_camera(&bounds, 45.0);
            }
        }
    }
    // An environment map lights the scene too: no default light then.
    if b.scene.lights.is_empty()
        && file.light.is_empty()
        && b.scene.environment.is_none()
        && !b.scene.materials.iter().any(|m| m.emission != Vec3::ZERO)
    {
        b.scene.lights.push(super::default_light());
    }
    b.finish().map_err(|e| match e {
        Error::Scene { msg, .. } => Error::invalid(path, msg),
        other => other,
    })
}
