//! Scenes: flat triangle lists and analytic spheres with materials, lights, camera
//! and film, validated once when built. Sources: a TOML scene file, a mesh file
//! (OBJ, PLY, OFF; auto-framed camera), or a built-in scene (`builtin:NAME`).

#![forbid(unsafe_code)]

pub mod alpha;
#[allow(missing_docs)] // scene parts with their fields explained in docs/ and the README; not the stable API
pub mod builtin;
#[allow(missing_docs)] // scene parts with their fields explained in docs/ and the README; not the stable API
pub mod camera;
pub mod colors;
pub mod gltf;
pub mod images;
#[allow(missing_docs)] // scene parts with their fields explained in docs/ and the README; not the stable API
pub mod instance;
pub mod limits;
#[allow(missing_docs)] // scene parts with their fields explained in docs/ and the README; not the stable API
pub mod mesh;
pub mod obj;
pub mod off;
pub mod ply;
pub mod procedural;
pub mod scene_file;

use std::path::Path;

use glam::{Vec2, Vec3, Vec4};

use colors::clamp_colors;

pub use camera::{Camera, CameraBasis};
pub use images::{load_environment, load_texture};
pub use instance::{Instance, Instancing, Prototype};
pub use mesh::{
    AlphaMode, ComplexIor, Environment, Maps, Material, MaterialKind, MeshData, Texture, Wrap, DEFAULT_ALPHA_CUTOFF,
};

use crate::error::{Error, Result};
use crate::math::Aabb;

/// An analytic sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// The centre.
    pub center: Vec3,
    /// The radius (positive).
    pub radius: f32,
    /// Index into [`Scene::materials`].
    pub material: u32,
}

/// A light source.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Light {
    /// Light travelling along `direction` (unit) with the given radiance.
    Directional {
        /// The direction light travels (unit).
        direction: Vec3,
        /// Radiance (RGB).
        radiance: Vec3,
    },
    /// A point light; irradiance falls off as intensity / distance².
    Point {
        /// Where it is.
        position: Vec3,
        /// Intensity (RGB).
        intensity: Vec3,
    },
}

/// Primitives (triangles + spheres) a scene may hold, exclusive.
pub const MAX_PRIMS: usize = 1 << 30;

/// Largest image side accepted.
pub const MAX_FILM_SIDE: u32 = 16384;

/// A material's map textures (metallic-roughness, normal, emission) are 16-bit fields
/// (`MAT_MAP_SHIFT`) of words the shading buffer holds as float bits: their indices
/// stay below this, so that index + 1 in the upper field never makes the word's
/// exponent all ones (an infinity or NaN, which a driver might rewrite).
pub const MAX_MAP_INDEX: u32 = 0x7F7F;

/// A validated scene.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Where it came from (file path or `builtin:NAME`), for messages.
    pub name: String,
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals; `Vec3::ZERO` where a vertex has none.
    pub normals: Vec<Vec3>,
    /// Triangles as three indices into `positions`; primitive `k` is triangle `k`.
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex texture coordinates: empty, or one per position (`Vec2::ZERO` where
    /// a vertex has none).
    pub uvs: Vec<glam::Vec2>,
    /// Per-vertex colours (linear RGBA in [0, 1]) that multiply the base colour and
    /// the alpha: empty, or one per position (white where a vertex has none).
    pub colors: Vec<glam::Vec4>,
    /// Per-triangle material index.
    pub tri_material: Vec<u32>,
    /// Spheres; sphere `k` is primitive `triangles.len() + k`.
    pub spheres: Vec<Sphere>,
    /// Index 0 is always the default grey Lambert material.
    pub materials: Vec<Material>,
    /// Point and directional lights.
    pub lights: Vec<Light>,
    /// The camera renders look through.
    pub camera: Camera,
    /// Image width renders default to.
    pub width: u32,
    /// Image height renders default to.
    pub height: u32,
    /// Texture images; `Material::texture` and `Material::maps` index this.
    pub textures: Vec<Texture>,
    /// Radiance of rays that leave the scene.
    pub background: Vec3,
    /// An environment map lighting the scene from every direction; replaces
    /// `background` for rays that leave the scene (path integrator).
    pub environment: Option<Environment>,
    /// Fraction of the albedo added as ambient light to Lambert and Phong surfaces.
    pub ambient: f32,
    /// Longest path followed (camera ray + mirror/glass bounces), 1..=MAX_PATH_DEPTH.
    pub max_depth: u32,
    /// Zero-area triangles (kept; never hit).
    pub degenerate_triangles: usize,
    /// What the scene's files have that arbor does not read (glTF extensions), each
    /// once; the command line prints them as warnings.
    pub warnings: Vec<String>,
    /// Meshes stored once and drawn by instances ([`instance`]); `triangles` holds
    /// only the scene's own.
    pub instancing: Option<Instancing>,
}

/// Builds a scene piece by piece; `finish` validates.
#[derive(Debug, Clone)]
pub struct SceneBuilder {
    /// The scene so far.
    pub scene: Scene,
}

impl SceneBuilder {
    /// An empty scene with default settings and the default material.
    pub fn new(name: &str) -> Self {
        SceneBuilder {
            scene: Scene {
                name: name.to_string(),
                positions: Vec::new(),
                normals: Vec::new(),
                uvs: Vec::new(),
                colors: Vec::new(),
                triangles: Vec::new(),
                tri_material: Vec::new(),
                spheres: Vec::new(),
                materials: vec![Material::lambert("default", Vec3::splat(0.7))],
                textures: Vec::new(),
                environment: None,
                lights: Vec::new(),
                camera: Camera { eye: Vec3::new(0.0, 0.0, 3.0), look_at: Vec3::ZERO, up: Vec3::Y, vfov: 45.0 },
                width: 512,
                height: 512,
                background: Vec3::new(0.05, 0.06, 0.08),
                ambient: 0.05,
                max_depth: 8,
                degenerate_triangles: 0,
                warnings: Vec::new(),
                instancing: None,
            },
        }
    }

    /// Adds a material and returns its index.
    pub fn material(&mut self, m: Material) -> u32 {
        self.scene.materials.push(m);
        (self.scene.materials.len() - 1) as u32
    }

    /// Index of the material named `name`, if any.
    pub fn find_material(&self, name: &str) -> Option<u32> {
        self.scene.materials.iter().position(|m| m.name == name).map(|i| i as u32)
    }

    /// Appends a mesh transformed by `scale` then `translate`. `material` overrides the
    /// mesh's own materials (and its textures); without either, triangles get the
    /// default material.
    ///
    /// Texture coordinates: `scene.uvs` stays empty until a mesh with UVs arrives, and
    /// from then on holds one per position (`Vec2::ZERO` for vertices of meshes without
    /// them, earlier ones included). Vertex colours likewise (white where a mesh has
    /// none). The mesh's textures join `scene.textures` (one with
    /// the same name and wrap modes as a texture already there is that texture) and its
    /// materials' texture indices are remapped.
    pub fn mesh(&mut self, mesh: &MeshData, scale: f32, translate: Vec3, material: Option<u32>) {
        let t = glam::Affine3A::from_scale_rotation_translation(Vec3::splat(scale), glam::Quat::IDENTITY, translate);
        self.mesh_transformed(mesh, &t, material);
    }

    /// Appends a mesh transformed by the affine `t` (non-singular): positions by `t`,
    /// normals by its inverse transpose; where `t` mirrors (negative determinant) each
    /// triangle's winding is reversed, so geometric normals keep facing out.
    pub fn mesh_transformed(&mut self, mesh: &MeshData, t: &glam::Affine3A, material: Option<u32>) {
        let s = &mut self.scene;
        for w in &mesh.warnings {
            if !s.warnings.contains(w) {
                s.warnings.push(w.clone());
            }
        }
        let base = s.positions.len() as u32;
        s.positions.extend(mesh.positions.iter().map(|p| t.transform_point3(*p)));
        let normal_matrix = t.matrix3.inverse().transpose();
        let mirrored = t.matrix3.determinant() < 0.0;
        match &mesh.normals {
            Some(n) if n.len() == mesh.positions.len() => {
                s.normals.extend(n.iter().map(|v| (normal_matrix * *v).try_normalize().unwrap_or(Vec3::ZERO)))
            }
            _ => s.normals.extend(std::iter::repeat_n(Vec3::ZERO, mesh.positions.len())),
        }
        match &mesh.uvs {
            Some(uv) if uv.len() == mesh.positions.len() => {
                s.uvs.resize(base as usize, Vec2::ZERO);
                s.uvs.extend_from_slice(uv);
            }
            _ if !s.uvs.is_empty() => s.uvs.resize(s.positions.len(), Vec2::ZERO),
            _ => {}
        }
        match &mesh.colors {
            Some(c) if c.len() == mesh.positions.len() => {
                s.colors.resize(base as usize, Vec4::ONE);
                s.colors.extend_from_slice(c);
            }
            _ if !s.colors.is_empty() => s.colors.resize(s.positions.len(), Vec4::ONE),
            _ => {}
        }
        let mat_base = s.materials.len() as u32;
        if material.is_none() {
            // Where each of the mesh's textures is in the scene.
            let mut remap = Vec::with_capacity(mesh.textures.len());
            for t in &mesh.textures {
                let at = match s.textures.iter().position(|old| old.name == t.name && old.wrap == t.wrap) {
                    Some(i) => i,
                    None => {
                        s.textures.push(t.clone());
                        s.textures.len() - 1
                    }
                };
                remap.push(at as u32);
            }
            // An index past the mesh's textures stays past the scene's: finish() reports it.
            s.materials.extend(
                mesh.materials.iter().map(|m| m.map_textures(|i| remap.get(i as usize).copied().unwrap_or(u32::MAX))),
            );
        }
        for (k, tri) in mesh.triangles.iter().enumerate() {
            let [a, b, c] = tri.map(|i| i + base);
            s.triangles.push(if mirrored { [a, c, b] } else { [a, b, c] });
            let m = match material {
                Some(m) => m,
                None if !mesh.materials.is_empty() => mat_base + mesh.tri_material.get(k).copied().unwrap_or(0),
                None => 0,
            };
            s.tri_material.push(m);
        }
    }

    /// Validates everything once and returns the scene.
    pub fn finish(self) -> Result<Scene> {
        let mut s = self.scene;
        let err = |msg: String| Error::scene(s.name.clone(), msg);
        if s.triangles.is_empty() && s.spheres.is_empty() && !s.has_instances() {
            return Err(err("the scene is empty: it has no triangles and no spheres".into()));
        }
        if s.width == 0 || s.height == 0 || s.width > MAX_FILM_SIDE || s.height > MAX_FILM_SIDE {
            return Err(err(format!(
                "image size {}x{} is invalid: each side must be 1..={MAX_FILM_SIDE}",
                s.width, s.height
            )));
        }
        if let Err(e) = s.camera.check() {
            return Err(err(e));
        }
        // The kd-tree builder packs a node-local primitive index into 30 bits.
        if s.triangles.len() + s.spheres.len() >= MAX_PRIMS {
            return Err(err(format!(
                "{} primitives: at most {} are supported",
                s.triangles.len() + s.spheres.len(),
                MAX_PRIMS - 1
            )));
        }
        if let Some(i) = s.positions.iter().position(|p| !p.is_finite()) {
            return Err(err(format!("vertex {i} has a non-finite coordinate")));
        }
        for n in &mut s.normals {
            if !n.is_finite() {
                *n = Vec3::ZERO;
            }
        }
        let nv = s.positions.len() as u32;
        for (k, t) in s.triangles.iter().enumerate() {
            if let Some(&bad) = t.iter().find(|&&i| i >= nv) {
                return Err(err(format!("triangle {k} references vertex {bad} but there are {nv} vertices")));
            }
        }
        let nm = s.materials.len() as u32;
        if let Some(k) = s.tri_material.iter().position(|&m| m >= nm) {
            return Err(err(format!("triangle {k} has material index {} of {nm}", s.tri_material[k])));
        }
        for (k, sp) in s.spheres.iter().enumerate() {
            if !(sp.center.is_finite() && sp.radius.is_finite() && sp.radius > 0.0) {
                return Err(err(format!("sphere {k} needs a finite centre and a finite radius > 0")));
            }
            if sp.material >= nm {
                return Err(err(format!("sphere {k} has material index {} of {nm}", sp.material)));
            }
        }
        for (k, m) in s.materials.iter().enumerate() {
            let ok = m.color.is_finite()
                && m.specular.is_finite()
                && m.emission.is_finite()
                && m.shininess.is_finite()
                && m.ior.is_finite();
            if !ok || m.ior <= 0.0 {
                return Err(err(format!("material {k} ('{}') has a non-finite value or ior <= 0", m.name)));
            }
            if !(m.absorption.is_finite() && m.absorption.min_element() >= 0.0) {
                return Err(err(format!("material {k} ('{}'): absorption must be finite and >= 0", m.name)));
            }
            if let Some(what) = m.microfacet_error() {
                return Err(err(format!("material {k} ('{}'): {what}", m.name)));
            }
            if let Some(t) = m.textures().find(|&t| t as usize >= s.textures.len()) {
                return Err(err(format!("material {k} ('{}') has texture index {t} of {}", m.name, s.textures.len())));
            }
            if [m.maps.metal_rough, m.maps.normal, m.maps.emission].into_iter().flatten().any(|t| t >= MAX_MAP_INDEX) {
                return Err(err(format!(
                    "material {k} ('{}'): a map's texture index is {MAX_MAP_INDEX} or more",
                    m.name
                )));
            }
        }
        for (k, t) in s.textures.iter().enumerate() {
            let size = limits::image_size_error(t.width, t.height, limits::MAX_TEXTURE_TEXELS);
            if let Some(msg) = size.or_else(|| {
                (t.texels.len() as u64 != u64::from(t.width) * u64::from(t.height))
                    .then(|| format!("{} texels for {}x{}", t.texels.len(), t.width, t.height))
            }) {
                return Err(err(format!("texture {k} ('{}'): {msg}", t.name)));
            }
        }
        if !s.uvs.is_empty() && s.uvs.len() != s.positions.len() {
            return Err(err(format!(
                "{} texture coordinates for {} vertices: there must be none or one per vertex",
                s.uvs.len(),
                s.positions.len()
            )));
        }
        for uv in &mut s.uvs {
            if !uv.is_finite() {
                *uv = Vec2::ZERO;
            }
        }
        if !s.colors.is_empty() && s.colors.len() != s.positions.len() {
            return Err(err(format!(
                "{} vertex colours for {} vertices: there must be none or one per vertex",
                s.colors.len(),
                s.positions.len()
            )));
        }
        clamp_colors(&mut s.colors);
        if let Some(env) = &s.environment {
            let size = limits::image_size_error(env.width, env.height, limits::MAX_ENVIRONMENT_TEXELS);
            let bad = size.or_else(|| {
                if env.texels.len() as u64 != u64::from(env.width) * u64::from(env.height) {
                    Some(format!("{} texels for {}x{}", env.texels.len(), env.width, env.height))
                } else if !env.texels.iter().flatten().all(|v| v.is_finite() && *v >= 0.0) {
                    Some("every texel must be finite and >= 0".into())
                } else if !(env.rotation.is_finite() && env.intensity.is_finite() && env.intensity >= 0.0) {
                    Some("rotation and intensity must be finite, intensity >= 0".into())
                } else {
                    None
                }
            });
            if let Some(msg) = bad {
                return Err(err(format!("environment '{}': {msg}", env.name)));
            }
        }
        for (k, l) in s.lights.iter_mut().enumerate() {
            match l {
                Light::Directional { direction, radiance } => {
                    let d = direction.try_normalize();
                    if d.is_none() || !radiance.is_finite() {
                        return Err(err(format!("light {k}: direction must be non-zero and finite, radiance finite")));
                    }
                    *direction = d.unwrap_or(Vec3::NEG_Y);
                }
                Light::Point { position, intensity } => {
                    if !position.is_finite() || !intensity.is_finite() {
                        return Err(err(format!("light {k}: position and intensity must be finite")));
                    }
                }
            }
        }
        if !(s.background.is_finite() && s.ambient.is_finite()) {
            return Err(err("background and ambient must be finite".into()));
        }
        if let Err(e) = instance::validate(&mut s) {
            return Err(Error::scene(s.name.clone(), e));
        }
        s.max_depth = s.max_depth.clamp(1, crate::gpu::bindings::MAX_PATH_DEPTH);
        s.degenerate_triangles = s.count_degenerate();
        Ok(s)
    }
}

impl Scene {
    /// Loads a scene from `builtin:NAME`, a `.toml` scene file, or a mesh file.
    pub fn load(source: &str) -> Result<Scene> {
        let _span = crate::timeline::span("load", || format!("load scene {source}"));
        if let Some(name) = source.strip_prefix("builtin:") {
            return builtin::load(name);
        }
        let path = Path::new(source);
        let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase()).unwrap_or_default();
        match ext.as_str() {
            "toml" => scene_file::load(path),
            "gltf" | "glb" => Self::from_gltf(source, &gltf::load(path)?).map_err(|e| match e {
                Error::Scene { msg, .. } => Error::invalid(path, msg),
                other => other,
            }),
            "obj" | "ply" | "off" => {
                let mesh = load_mesh(path)?;
                // Messages start with the file name, like every other file error.
                Self::from_mesh(source, &mesh).map_err(|e| match e {
                    Error::Scene { msg, .. } => Error::invalid(path, msg),
                    other => other,
                })
            }
            _ => Err(Error::invalid(
                path,
                "unknown scene type: expected a .toml scene file, a .obj/.ply/.off mesh, a .gltf/.glb scene, or builtin:default|cornell|caustic|blob:N",
            )),
        }
    }

    /// A scene of one mesh with the camera framed on its bounding box (eye on +z of
    /// the box centre looking down -z, vfov 45°, the bounding sphere fitting the
    /// image height) and one directional light.
    pub fn from_mesh(name: &str, mesh: &MeshData) -> Result<Scene> {
        if let Some(msg) = mesh.texture_uv_error(None) {
            return Err(Error::scene(name, msg));
        }
        let mut b = SceneBuilder::new(name);
        b.mesh(mesh, 1.0, Vec3::ZERO, None);
        let mut bounds = Aabb::EMPTY;
        for p in &b.scene.positions {
            bounds.grow(*p);
        }
        if !bounds.is_empty() && bounds.min.is_finite() && bounds.max.is_finite() {
            b.scene.camera = framed_camera(&bounds, 45.0);
        }
        b.scene.lights.push(default_light());
        b.finish()
    }

    /// A scene from a glTF file: its triangles, materials and lights; its first camera
    /// (film 512 pixels high, as wide as the camera's aspect ratio asks), else one framed
    /// on the scene box; one default directional light when it has no light and
    /// nothing emits.
    pub fn from_gltf(name: &str, g: &gltf::GltfScene) -> Result<Scene> {
        if let Some(msg) = g.mesh.texture_uv_error(None) {
            return Err(Error::scene(name, msg));
        }
        let mut b = SceneBuilder::new(name);
        b.scene.warnings.extend(g.warnings.iter().cloned());
        let mat_base = b.scene.materials.len() as u32;
        b.mesh(&g.mesh, 1.0, Vec3::ZERO, None);
        // Prototypes index the file's materials, which the mesh above brought in.
        for (pname, p) in &g.prototypes {
            let k = b.prototype(pname, p, &glam::Affine3A::IDENTITY, None);
            if let Some(inst) = b.scene.instancing.as_mut() {
                inst.prototypes[k as usize].geometry.tri_material =
                    p.tri_material.iter().map(|m| mat_base + m).collect();
            }
        }
        for (k, t) in &g.instances {
            b.instance(*k, *t);
        }
        match &g.camera {
            Some((camera, aspect)) => {
                b.scene.camera = *camera;
                if let Some(a) = aspect.filter(|a| a.is_finite() && *a > 0.0) {
                    b.scene.width = ((512.0 * a).round() as u32).clamp(1, MAX_FILM_SIDE);
                }
            }
            None => {
                let bounds = b.scene.bounds();
                if !bounds.is_empty() && bounds.min.is_finite() && bounds.max.is_finite() {
                    b.scene.camera = framed_camera(&bounds, 45.0);
                }
            }
        }
        b.scene.lights.extend(g.lights.iter().cloned());
        let emits = b.scene.materials.iter().any(|m| m.emission != Vec3::ZERO);
        if b.scene.lights.is_empty() && !emits {
            b.scene.lights.push(default_light());
        }
        b.finish()
    }

    /// The bounding box of every primitive, instances included.
    pub fn bounds(&self) -> Aabb {
        let own = self.own_bounds();
        match &self.instancing {
            None => own,
            Some(inst) => {
                inst.instances.iter().fold(own, |b, i| b.union(&i.world_bounds(&inst.prototypes[i.prototype as usize])))
            }
        }
    }

    /// The bounding box of the scene's own primitives (instances left out).
    pub fn own_bounds(&self) -> Aabb {
        use rayon::prelude::*;
        let tris = self
            .triangles
            .par_iter()
            .fold(
                || Aabb::EMPTY,
                |mut b, t| {
                    for &i in t {
                        b.grow(self.positions[i as usize]);
                    }
                    b
                },
            )
            .reduce(|| Aabb::EMPTY, |a, b| a.union(&b));
        let mut b = tris;
        for s in &self.spheres {
            b.grow(s.center - Vec3::splat(s.radius));
            b.grow(s.center + Vec3::splat(s.radius));
        }
        // The parallel reduction may meet -0 and +0 in either order: one sign of zero,
        // so the box is the same bits whatever the thread count.
        Aabb { min: b.min + Vec3::ZERO, max: b.max + Vec3::ZERO }
    }

    /// Zero-area triangles among the scene's own.
    pub fn count_degenerate(&self) -> usize {
        self.triangles
            .iter()
            .filter(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize]);
                (b - a).cross(c - a).length_squared() == 0.0
            })
            .count()
    }

    /// Number of primitives (triangles, then spheres).
    pub fn prim_count(&self) -> usize {
        self.triangles.len() + self.spheres.len()
    }
}

/// The light a mesh-only scene gets.
pub fn default_light() -> Light {
    Light::Directional { direction: Vec3::new(-1.0, -1.0, -1.0).normalize(), radiance: Vec3::splat(2.5) }
}

/// A camera on +z of the box centre, far enough that the bounding sphere fits.
pub fn framed_camera(bounds: &Aabb, vfov: f32) -> Camera {
    let c = bounds.center();
    let r = (bounds.extent().length() * 0.5).max(1e-20);
    let dist = r / (vfov.to_radians() * 0.5).sin();
    Camera { eye: c + Vec3::new(0.0, 0.0, dist), look_at: c, up: Vec3::Y, vfov }
}

/// Loads a mesh file by extension.
pub fn load_mesh(path: &Path) -> Result<MeshData> {
    let _span = crate::timeline::span("load", || format!("load mesh {}", path.display()));
    let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase()).unwrap_or_default();
    match ext.as_str() {
        "obj" => obj::load(path),
        "ply" => ply::load(path),
        "off" => off::load(path),
        "gltf" | "glb" => Ok(gltf::load(path)?.into_mesh()),
        _ => Err(Error::invalid(path, "unknown mesh type: expected .obj, .ply, .off, .gltf or .glb")),
    }
}
