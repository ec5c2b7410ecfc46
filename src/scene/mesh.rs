//! Triangle mesh data as the loaders produce it, before it joins a scene.

use crate::gpu::bindings::{
    MAT_CONDUCTOR, MAT_DIELECTRIC, MAT_EMISSIVE, MAT_GLASS, MAT_LAMBERT, MAT_MIRROR, MAT_PBR, MAT_PHONG,
};
use glam::Vec3;

/// How a surface scatters light. The numeric values are the GPU's material kind codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[repr(u32)]
pub enum MaterialKind {
    Lambert = MAT_LAMBERT,
    Phong = MAT_PHONG,
    Mirror = MAT_MIRROR,
    Glass = MAT_GLASS,
    Emissive = MAT_EMISSIVE,
    /// A metal: GGX microfacets, Fresnel from [`Material::complex_ior`] or, without
    /// it, Schlick's from `color` (docs/materials.md).
    Conductor = MAT_CONDUCTOR,
    /// Rough glass: GGX microfacets that reflect and refract (Walter et al. 2007).
    Dielectric = MAT_DIELECTRIC,
    /// glTF 2.0's metallic-roughness model: a GGX specular layer with Schlick's
    /// Fresnel over a Lambert base, blended with a metal of F0 `color` by
    /// [`Material::metallic`] (docs/materials.md).
    Pbr = MAT_PBR,
}

impl MaterialKind {
    /// The last kind (the GPU's kind bits run from 0 to this).
    pub const LAST: MaterialKind = MaterialKind::Pbr;
}

/// A conductor's complex index of refraction per RGB channel, eta + i k, relative to
/// the medium outside (air).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComplexIor {
    pub eta: Vec3,
    pub k: Vec3,
}

/// A material. `color` is the diffuse albedo (Lambert, Phong), the reflectance tint
/// (mirror; a conductor with a complex index), the reflectance at normal incidence
/// (a conductor without one) or the transmission tint (glass, dielectric).
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    pub name: String,
    pub kind: MaterialKind,
    pub color: Vec3,
    /// Phong specular colour.
    pub specular: Vec3,
    /// Phong exponent.
    pub shininess: f32,
    /// Index of refraction (glass, dielectric).
    pub ior: f32,
    /// Emitted radiance (emissive; also added for any kind where non-zero).
    pub emission: Vec3,
    /// Emission on both sides of the surface; otherwise only along the geometric
    /// normal (the side the triangle's winding faces, a sphere's outside).
    pub two_sided: bool,
    /// Glass, dielectric: Beer-Lambert absorption coefficient per unit length inside
    /// (0 = clear).
    pub absorption: Vec3,
    /// Conductor, dielectric: roughness in [0, 1], as glTF defines it (GGX alpha =
    /// roughness squared); see [`Material::is_smooth`].
    pub roughness: f32,
    /// Conductor: the complex index of refraction its Fresnel term follows; None for
    /// Schlick's approximation from `color`.
    pub complex_ior: Option<ComplexIor>,
    /// Diffuse albedo texture: an index into `Scene::textures` (the albedo multiplies
    /// `color`), or, in a `MeshData`, into `MeshData::textures`.
    pub texture: Option<u32>,
    /// Metallic-roughness: how metallic, in [0, 1] (1: a conductor of F0 `color`).
    pub metallic: f32,
    /// Metallic-roughness: the dielectric layer's reflectance at normal incidence,
    /// ((ior - 1) / (ior + 1))^2 (0.04 at 1.5) times KHR_materials_specular's colour,
    /// at most 1 per channel.
    pub dielectric_f0: Vec3,
    /// Metallic-roughness: the dielectric layer's weight (KHR_materials_specular's
    /// factor), in [0, 1].
    pub specular_weight: f32,
    /// Metallic-roughness: textures that modulate roughness and metallic, and bend
    /// the shading normal.
    pub maps: Maps,
    /// How the surface's alpha (`opacity` times the albedo texture's alpha) is read:
    /// opaque (ignored), a cut-out, or a blended pane (docs/materials.md, "Alpha").
    pub alpha_mode: AlphaMode,
    /// The alpha factor (glTF's baseColorFactor alpha), in [0, 1].
    pub opacity: f32,
}

/// How a surface's alpha is read (glTF's alphaMode).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum AlphaMode {
    /// Alpha is ignored (the default).
    #[default]
    Opaque,
    /// The surface is absent wherever its alpha is below `cutoff` (glTF's MASK and
    /// alphaCutoff, default 0.5).
    Mask {
        /// The alpha below which the surface is absent.
        cutoff: f32,
    },
    /// A ray meets the surface with probability alpha (arbor's reading of glTF's BLEND:
    /// stochastic transparency, which converges to the blended image).
    Blend,
}

/// glTF's default alphaCutoff.
pub const DEFAULT_ALPHA_CUTOFF: f32 = 0.5;

/// The reflectance at normal incidence of a dielectric of index `ior` in air.
pub fn dielectric_f0(ior: f32) -> f32 {
    ((ior - 1.0) / (ior + 1.0)).powi(2)
}

/// A metallic-roughness material's textures (indices as [`Material::texture`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Maps {
    /// Linear texture whose green channel multiplies the roughness and blue the
    /// metallic factor (glTF's metallicRoughnessTexture).
    pub metal_rough: Option<u32>,
    /// Tangent-space normal map (linear, +x along u, +y along v).
    pub normal: Option<u32>,
    /// Scales the normal map's x and y.
    pub normal_scale: f32,
    /// sRGB texture that multiplies the emission (glTF's emissiveTexture).
    pub emission: Option<u32>,
}

impl Default for Maps {
    fn default() -> Self {
        Maps { metal_rough: None, normal: None, normal_scale: 1.0, emission: None }
    }
}

impl Material {
    /// A grey Lambertian material, the default for meshes without materials.
    pub fn lambert(name: &str, color: Vec3) -> Self {
        Material {
            name: name.to_string(),
            kind: MaterialKind::Lambert,
            color,
            specular: Vec3::ZERO,
            shininess: 1.0,
            ior: 1.5,
            emission: Vec3::ZERO,
            two_sided: false,
            absorption: Vec3::ZERO,
            roughness: 0.0,
            complex_ior: None,
            texture: None,
            metallic: 0.0,
            dielectric_f0: Vec3::splat(0.04),
            specular_weight: 1.0,
            maps: Maps::default(),
            alpha_mode: AlphaMode::Opaque,
            opacity: 1.0,
        }
    }

    /// Whether rays may pass through the surface (a cut-out or a blended pane).
    pub fn has_alpha(&self) -> bool {
        self.alpha_mode != AlphaMode::Opaque
    }

    /// Every texture this material reads: albedo, then its maps.
    pub fn textures(&self) -> impl Iterator<Item = u32> {
        [self.texture, self.maps.metal_rough, self.maps.normal, self.maps.emission].into_iter().flatten()
    }

    /// The same material with every texture index mapped by `f`.
    pub fn map_textures(&self, f: impl Fn(u32) -> u32) -> Material {
        let maps = Maps {
            metal_rough: self.maps.metal_rough.map(&f),
            normal: self.maps.normal.map(&f),
            emission: self.maps.emission.map(&f),
            ..self.maps
        };
        Material { texture: self.texture.map(&f), maps, ..self.clone() }
    }

    /// The GGX alpha of a conductor or dielectric: roughness squared.
    pub fn alpha(&self) -> f32 {
        self.roughness * self.roughness
    }

    /// What is out of range in the microfacet parameters (roughness in [0, 1]; a
    /// complex index with eta > 0 and k >= 0, finite), or None.
    pub fn microfacet_error(&self) -> Option<String> {
        if !(0.0..=1.0).contains(&self.roughness) {
            return Some(format!("roughness {} is outside [0, 1]", self.roughness));
        }
        if !(0.0..=1.0).contains(&self.metallic) || !(0.0..=1.0).contains(&self.specular_weight) {
            return Some(format!(
                "metallic {} and specular weight {} must lie in [0, 1]",
                self.metallic, self.specular_weight
            ));
        }
        let f0 = self.dielectric_f0;
        if !(f0.is_finite() && f0.min_element() >= 0.0 && f0.max_element() <= 1.0) {
            return Some(format!("the dielectric F0 {f0} must lie in [0, 1] per channel"));
        }
        if !self.maps.normal_scale.is_finite() {
            return Some(format!("the normal scale {} is not finite", self.maps.normal_scale));
        }
        let c = self.complex_ior?;
        let ok = c.eta.is_finite() && c.k.is_finite() && c.eta.min_element() > 0.0 && c.k.min_element() >= 0.0;
        (!ok).then(|| format!("eta {} must be > 0 and k {} >= 0, finite, per channel", c.eta, c.k))
    }

    /// Whether the GGX alpha is below `SMOOTH_ALPHA_BITS` (src/gpu/bindings.rs, the
    /// shaders' threshold too; 0.001, roughness 0.0316): a conductor is then a mirror
    /// of Fresnel reflectance and a dielectric smooth glass.
    pub fn is_smooth(&self) -> bool {
        self.alpha() < f32::from_bits(crate::gpu::bindings::SMOOTH_ALPHA_BITS)
    }

    /// Whether this material refracts as smooth glass does: glass, and a smooth
    /// dielectric ([`Material::is_smooth`]).
    pub fn is_smooth_glass(&self) -> bool {
        match self.kind {
            MaterialKind::Glass => true,
            MaterialKind::Dielectric => self.is_smooth(),
            _ => false,
        }
    }
}

/// A triangle mesh as read from a file: indexed triangles, optional per-vertex normals
/// and the materials its file declared (empty when the file has none).
#[derive(Debug, Clone, Default)]
pub struct MeshData {
    pub positions: Vec<Vec3>,
    /// Per-vertex normals, the same length as `positions`, when the file has them.
    pub normals: Option<Vec<Vec3>>,
    /// Vertex indices of each triangle (polygons already triangulated as fans).
    pub triangles: Vec<[u32; 3]>,
    /// Per-triangle index into `materials`; empty when `materials` is empty.
    pub tri_material: Vec<u32>,
    pub materials: Vec<Material>,
    /// Per-vertex texture coordinates, the same length as `positions`, when the file
    /// has them.
    pub uvs: Option<Vec<glam::Vec2>>,
    /// Per-vertex colours (linear RGBA, each in [0, 1]), the same length as
    /// `positions`, when the file has them (glTF's COLOR_0, PLY's red/green/blue): they
    /// multiply the base colour and the alpha.
    pub colors: Option<Vec<glam::Vec4>>,
    /// Texture images the materials name (`Material::texture` indexes this).
    pub textures: Vec<Texture>,
    /// What the file has that arbor does not read, for a warning (glTF extensions).
    pub warnings: Vec<String>,
}

/// A texture image: 8-bit RGBA texels as stored (sRGB-encoded colour), row 0 at the
/// top (v = 1 in texture space), sampled with bilinear filtering and `wrap`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Texture {
    /// The file it came from, for messages.
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// `width * height` texels, row-major.
    pub texels: Vec<[u8; 4]>,
    /// How coordinates outside [0, 1] read it, along u and v (glTF's sampler).
    pub wrap: [Wrap; 2],
}

/// How a texture is read outside [0, 1] (glTF's wrapS / wrapT).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Wrap {
    /// The texture tiles (the default).
    #[default]
    Repeat = 0,
    /// The edge texels stretch on.
    Clamp = 1,
    /// The texture tiles, every other copy mirrored.
    Mirror = 2,
}

impl Texture {
    /// The mean luminance of the texels read as sRGB colours (decoded as the kernels
    /// decode them): what an emission texture scales its material's power by when
    /// area lights are chosen.
    pub fn mean_luminance(&self) -> f32 {
        let linear: [f32; 256] = std::array::from_fn(|k| {
            let c = k as f32 / 255.0;
            if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }
        });
        let lum = |t: &[u8; 4]| {
            0.2126 * linear[usize::from(t[0])] + 0.7152 * linear[usize::from(t[1])] + 0.0722 * linear[usize::from(t[2])]
        };
        let sum: f64 = self.texels.iter().map(|t| f64::from(lum(t))).sum();
        if self.texels.is_empty() {
            0.0
        } else {
            (sum / self.texels.len() as f64) as f32
        }
    }
}

/// An equirectangular environment map: linear RGB radiance, row 0 at the top (the
/// +y pole), u = 0 at -z... see `render::integrators::envdist` for the exact direction mapping.
#[derive(Debug, Clone, PartialEq)]
pub struct Environment {
    /// The file it came from, for messages.
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// `width * height` texels, row-major, linear radiance (before `intensity`).
    pub texels: Vec<[f32; 3]>,
    /// Rotation about +y, degrees.
    pub rotation: f32,
    /// Multiplies every texel.
    pub intensity: f32,
}

impl MeshData {
    /// None when every material this mesh's triangles use (or `material`, an override
    /// used for all of them) can be textured: it has no texture, or the mesh has UVs.
    /// Otherwise what is wrong, naming the material.
    pub fn texture_uv_error(&self, material: Option<&Material>) -> Option<String> {
        if self.uvs.is_some() || self.triangles.is_empty() {
            return None;
        }
        let textured = match material {
            Some(m) => m.textures().next().is_some().then_some(m),
            None => self
                .tri_material
                .iter()
                .filter_map(|&i| self.materials.get(i as usize))
                .find(|m| m.textures().next().is_some()),
        };
        textured.map(|m| {
            format!(
                "material '{}' has a texture but the mesh has no texture coordinates (every vertex needs one)",
                m.name
            )
        })
    }
}

/// Appends the fan `(i0, ik, ik+1)` of a polygon; polygons with < 3 vertices add nothing.
pub(crate) fn push_fan(triangles: &mut Vec<[u32; 3]>, polygon: &[u32]) {
    if let Some((&first, rest)) = polygon.split_first() {
        for pair in rest.windows(2) {
            if let [b, c] = *pair {
                triangles.push([first, b, c]);
            }
        }
    }
}

/// Unit normals, or None when any normal is zero-length or not finite (the mesh is then
/// treated as having no normals).
pub(crate) fn normalize_all(normals: Vec<Vec3>) -> Option<Vec<Vec3>> {
    normals
        .into_iter()
        .map(|n| {
            let len = n.length();
            (len.is_finite() && len > 0.0).then(|| n / len)
        })
        .collect()
}
