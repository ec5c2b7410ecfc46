//! glTF 2.0 (`.gltf` with external or embedded buffers, `.glb`) through the `gltf`
//! crate: the default scene's node hierarchy flattened into world-space triangles,
//! its materials mapped to arbor's, the first camera, and KHR_lights_punctual lights.
//!
//! Materials map as follows:
//! - transmission (KHR_materials_transmission) of 0.5 or more: a rough dielectric of
//!   the material's roughness factor, tinted by the base colour, with
//!   KHR_materials_ior's index (default 1.5);
//! - otherwise arbor's metallic-roughness material (`MaterialKind::Pbr`, the
//!   specification's appendix B): base colour (factor and texture), metallic and
//!   roughness factors times the metallicRoughness texture's blue and green channels,
//!   the normal texture and its scale; KHR_materials_ior and KHR_materials_specular
//!   (factor and colour factor) set the dielectric layer's F0 and weight;
//! - the emissive factor times KHR_materials_emissive_strength, times the emissive
//!   texture (sRGB) where there is one, is the emission (an area light); `doubleSided`
//!   makes it emit from both sides.
//!
//! KHR_texture_transform is applied to a primitive's texture coordinates at load, one
//! transform a material: its base colour texture's (else its metallic-roughness or
//! emissive texture's); the normal texture takes the same.
//!
//! Not read, and named in the scene's warnings: textures of a texture-coordinate set
//! other than 0, KHR_materials_specular's textures, texture transforms that differ
//! between one material's textures. alphaMode MASK (with alphaCutoff) and BLEND are
//! read: cut-outs and blended panes (crate::scene::alpha); and COLOR_0, vertex colours
//! that multiply the base colour and its alpha (crate::scene::colors). The
//! occlusion texture is not read either: a path tracer computes its own occlusion.
//!
//! A mesh that two or more nodes draw becomes an instanced mesh, one instance per node
//! (`scene::instance`), unless one of its materials emits (instances cannot be
//! lights); as the `file` of a TOML `[[mesh]]`, the whole file is one flat mesh.
//!
//! The base colour texture (texture coordinate set 0) becomes the albedo texture.
//! Triangle strips and fans are triangulated; points and lines are an error naming
//! the mesh. Spot lights are treated as point lights (their cone is ignored). Skins,
//! morph targets, animations and Draco compression are not read.

#![forbid(unsafe_code)]

use std::path::Path;

use glam::{Mat4, Vec2, Vec3, Vec4};

use super::mesh::{AlphaMode, MeshData, Texture, Wrap, DEFAULT_ALPHA_CUTOFF};
use super::{Camera, Light, Material, MaterialKind};
use crate::error::{Error, Result};

/// What a glTF file holds for arbor.
#[derive(Debug, Clone, Default)]
pub struct GltfScene {
    /// Every triangle of the scene in world space, with its materials and textures.
    pub mesh: MeshData,
    /// The first camera in the node hierarchy and its aspect ratio, if any.
    pub camera: Option<(Camera, Option<f32>)>,
    /// KHR_lights_punctual lights.
    pub lights: Vec<Light>,
    /// Meshes drawn by several nodes, in their own coordinates: (name, mesh whose
    /// `tri_material` indexes `mesh.materials`; it has no materials of its own).
    pub prototypes: Vec<(String, MeshData)>,
    /// (prototype, object-to-world transform) of each node drawing one.
    pub instances: Vec<(u32, glam::Affine3A)>,
    /// What the file has that arbor does not read (the extensions it uses), for a
    /// warning.
    pub warnings: Vec<String>,
}

impl GltfScene {
    /// Every triangle in world space in one mesh: the instances' copies appended.
    pub fn into_mesh(self) -> MeshData {
        let mut out = self.mesh;
        out.warnings.extend(self.warnings);
        let had_normals = out.normals.is_some();
        let mut normals = out.normals.take().unwrap_or_else(|| vec![Vec3::ZERO; out.positions.len()]);
        let any_uvs = out.uvs.is_some() || self.prototypes.iter().any(|(_, p)| p.uvs.is_some());
        let mut uvs = out.uvs.take().unwrap_or_default();
        let any_colors = out.colors.is_some() || self.prototypes.iter().any(|(_, p)| p.colors.is_some());
        let mut colors = out.colors.take().unwrap_or_default();
        let mut any_normals = had_normals;
        for (k, t) in &self.instances {
            let p = &self.prototypes[*k as usize].1;
            let base = out.positions.len() as u32;
            out.positions.extend(p.positions.iter().map(|v| t.transform_point3(*v)));
            let nm = t.matrix3.inverse().transpose();
            match &p.normals {
                Some(ns) => {
                    any_normals = true;
                    normals.extend(ns.iter().map(|n| (nm * *n).try_normalize().unwrap_or(Vec3::ZERO)));
                }
                None => normals.extend(std::iter::repeat_n(Vec3::ZERO, p.positions.len())),
            }
            if any_uvs {
                uvs.resize(base as usize, Vec2::ZERO);
                if let Some(u) = &p.uvs {
                    uvs.extend_from_slice(u);
                }
            }
            if any_colors {
                colors.resize(base as usize, Vec4::ONE);
                if let Some(c) = &p.colors {
                    colors.extend_from_slice(c);
                }
            }
            let mirrored = t.matrix3.determinant() < 0.0;
            for tri in &p.triangles {
                let [a, b, c] = tri.map(|i| i + base);
                out.triangles.push(if mirrored { [a, c, b] } else { [a, b, c] });
            }
            out.tri_material.extend_from_slice(&p.tri_material);
        }
        out.normals = any_normals.then_some(normals);
        if any_uvs {
            uvs.resize(out.positions.len(), Vec2::ZERO);
            out.uvs = Some(uvs);
        }
        if any_colors {
            colors.resize(out.positions.len(), Vec4::ONE);
            out.colors = Some(colors);
        }
        out
    }
}

/// Deepest node hierarchy followed (a cycle or an absurd depth is an error).
const MAX_DEPTH: usize = 256;

/// Loads a `.gltf` or `.glb` file. Any problem is an error naming the file.
pub fn load(path: &Path) -> Result<GltfScene> {
    let bytes = super::limits::read_file(path, super::limits::FileKind::Mesh)?;
    let base = path.parent().unwrap_or(Path::new("."));
    let loaded = std::panic::catch_unwind(|| load_bytes(&bytes, base, &path.display().to_string()));
    match loaded {
        Ok(r) => r.map_err(|why| Error::invalid(path, why)),
        Err(_) => Err(Error::invalid(path, "glTF: the file is malformed (the reader failed)")),
    }
}

/// Extensions this loader reads; a file that uses others gets one warning naming them.
/// They are also the extensions a file may require (the others it might require, such
/// as Draco or meshopt, change what the buffers hold).
const READ: [&str; 6] = [
    "KHR_lights_punctual",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_emissive_strength",
    "KHR_materials_specular",
    "KHR_texture_transform",
];

fn load_bytes(bytes: &[u8], base: &Path, name: &str) -> std::result::Result<GltfScene, String> {
    // A required extension arbor cannot read (Draco, meshopt, ...) would otherwise show
    // up as a confusing validation error about missing buffer views.
    if let Ok(g) = gltf::Gltf::from_slice_without_validation(bytes) {
        if let Some(ext) = g.document.extensions_required().find(|e| !READ.contains(e)) {
            return Err(format!("glTF: the file requires the extension {ext}, which arbor does not read"));
        }
    }
    if !bytes.starts_with(b"glTF") && bytes.iter().find(|b| !b.is_ascii_whitespace()) != Some(&b'{') {
        return Err(format!("glTF: neither binary glTF (a .glb starts with \"glTF\") nor glTF JSON: {}", sniff(bytes)));
    }
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice(bytes).map_err(|e| format!("glTF: {e}"))?;
    let buffers = gltf::import_buffers(&document, Some(base), blob).map_err(|e| {
        missing_uri(
            document.buffers().map(|b| b.source()).filter_map(|s| match s {
                gltf::buffer::Source::Uri(u) => Some(u),
                gltf::buffer::Source::Bin => None,
            }),
            base,
            "buffer",
        )
        .unwrap_or_else(|| format!("glTF buffers: {e}"))
    })?;
    let images = gltf::import_images(&document, Some(base), &buffers).map_err(|e| {
        missing_uri(
            document.images().filter_map(|i| match i.source() {
                gltf::image::Source::Uri { uri, .. } => Some(uri),
                gltf::image::Source::View { .. } => None,
            }),
            base,
            "image",
        )
        .unwrap_or_else(|| format!("glTF images: {e}"))
    })?;
    let mut out = GltfScene::default();
    let unread: Vec<&str> = document.extensions_used().filter(|e| !READ.contains(e)).collect();
    if !unread.is_empty() {
        out.warnings.push(format!("{name}: arbor does not read the glTF extension(s) {}", unread.join(", ")));
    }
    // Materials and textures: one arbor material per glTF material, then the default.
    let mut textures = Slots { images: &images, slot: Default::default(), file: name, unread: Vec::new() };
    for m in document.materials() {
        let mut mat = material(&m, &mut textures, &mut out.mesh.textures)?;
        // alphaMode: cut-outs and blended panes (the alpha is baseColorFactor's times
        // the base colour texture's).
        mat.alpha_mode = match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            gltf::material::AlphaMode::Mask => {
                AlphaMode::Mask { cutoff: m.alpha_cutoff().unwrap_or(DEFAULT_ALPHA_CUTOFF).clamp(0.0, 1.0) }
            }
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
        };
        if mat.has_alpha() {
            mat.opacity = m.pbr_metallic_roughness().base_color_factor()[3].clamp(0.0, 1.0);
        }
        out.mesh.materials.push(mat);
    }
    if !textures.unread.is_empty() {
        textures.unread.sort();
        textures.unread.dedup();
        out.warnings.push(format!("{name}: arbor does not read {}", textures.unread.join(", ")));
    }
    let default_material = out.mesh.materials.len() as u32;
    out.mesh.materials.push(Material::lambert("gltf default", Vec3::splat(0.8)));
    let roots: Vec<gltf::Node> = match document.default_scene().or_else(|| document.scenes().next()) {
        Some(s) => s.nodes().collect(),
        None => {
            // No scene: every node that is no other node's child.
            let mut child = vec![false; document.nodes().count()];
            for n in document.nodes() {
                for c in n.children() {
                    child[c.index()] = true;
                }
            }
            document.nodes().filter(|n| !child[n.index()]).collect()
        }
    };
    let mut attrs = Attributes::default();
    let mut stack: Vec<(gltf::Node, Mat4, usize)> = roots.into_iter().rev().map(|n| (n, Mat4::IDENTITY, 0)).collect();
    let mut visits = 0usize;
    // (mesh, world transform) of every node that draws one, in traversal order.
    let mut drawn: Vec<(gltf::Mesh, Mat4)> = Vec::new();
    while let Some((node, parent, depth)) = stack.pop() {
        visits += 1;
        if depth > MAX_DEPTH || visits > 1 << 20 {
            return Err(format!("node {}: the node hierarchy is deeper than {MAX_DEPTH} or has a cycle", node.index()));
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix());
        let world = parent * local;
        if !world.is_finite() {
            return Err(format!("node {}: its transform is not finite", node.index()));
        }
        if let Some(mesh) = node.mesh() {
            drawn.push((mesh, world));
        }
        if let Some(cam) = node.camera() {
            if out.camera.is_none() {
                if let gltf::camera::Projection::Perspective(p) = cam.projection() {
                    let eye = world.transform_point3(Vec3::ZERO);
                    let forward = world.transform_vector3(-Vec3::Z);
                    let up = world.transform_vector3(Vec3::Y);
                    let camera = Camera { eye, look_at: eye + forward, up, vfov: p.yfov().to_degrees() };
                    out.camera = Some((camera, p.aspect_ratio()));
                }
            }
        }
        if let Some(light) = node.light() {
            let power = Vec3::from(light.color()) * light.intensity();
            out.lights.push(match light.kind() {
                gltf::khr_lights_punctual::Kind::Directional => Light::Directional {
                    direction: world.transform_vector3(-Vec3::Z).try_normalize().unwrap_or(-Vec3::Z),
                    radiance: power,
                },
                _ => Light::Point { position: world.transform_point3(Vec3::ZERO), intensity: power },
            });
        }
        for c in node.children() {
            stack.push((c, world, depth + 1));
        }
    }
    // Meshes drawn by several nodes become prototypes, unless they emit light.
    let mut uses = vec![0usize; document.meshes().count()];
    for (m, _) in &drawn {
        uses[m.index()] += 1;
    }
    let emits = |m: &gltf::Mesh| {
        m.primitives().any(|p| {
            let k = p.material().index().map_or(default_material, |i| i as u32);
            out.mesh.materials[k as usize].emission != Vec3::ZERO
        })
    };
    let instanced: Vec<bool> = document.meshes().map(|m| uses[m.index()] >= 2 && !emits(&m)).collect();
    let mut proto_of: Vec<Option<u32>> = vec![None; uses.len()];
    for (mesh, world) in &drawn {
        // A singular transform (a node scaled to nothing, as files hide nodes) has no
        // inverse to move rays with: that copy is drawn flat, degenerate as it is.
        if !instanced[mesh.index()] || !super::instance::invertible(&glam::Affine3A::from_mat4(*world)) {
            add_mesh(mesh, world, &buffers, default_material, &mut out.mesh, &mut attrs)?;
            continue;
        }
        let k = match proto_of[mesh.index()] {
            Some(k) => k,
            None => {
                let mut p = MeshData::default();
                let mut pattrs = Attributes::default();
                add_mesh(mesh, &Mat4::IDENTITY, &buffers, default_material, &mut p, &mut pattrs)?;
                pattrs.finish(&mut p);
                let name = mesh.name().map_or_else(|| format!("mesh {}", mesh.index()), str::to_string);
                out.prototypes.push((name, p));
                let k = (out.prototypes.len() - 1) as u32;
                proto_of[mesh.index()] = Some(k);
                k
            }
        };
        out.instances.push((k, glam::Affine3A::from_mat4(*world)));
    }
    attrs.finish(&mut out.mesh);
    Ok(out)
}

/// The per-vertex attributes of the primitives added so far, gathered beside the
/// positions: normals (zero where a primitive has none), and UVs and colours once a
/// primitive has them (zero UVs, white, for the vertices of those without).
#[derive(Default)]
struct Attributes {
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    any_uvs: bool,
    colors: Vec<Vec4>,
    any_colors: bool,
}

impl Attributes {
    /// Into `out`, whose positions they describe.
    fn finish(mut self, out: &mut MeshData) {
        let n = out.positions.len();
        out.normals =
            (self.normals.len() == n && self.normals.iter().any(|v| *v != Vec3::ZERO)).then_some(self.normals);
        if self.any_uvs {
            self.uvs.resize(n, Vec2::ZERO);
            out.uvs = Some(self.uvs);
        }
        if self.any_colors {
            self.colors.resize(n, Vec4::ONE);
            out.colors = Some(self.colors);
        }
    }
}

/// Appends every primitive of `mesh`, transformed by `world`.
fn add_mesh(
    mesh: &gltf::Mesh,
    world: &Mat4,
    buffers: &[gltf::buffer::Data],
    default_material: u32,
    out: &mut MeshData,
    attrs: &mut Attributes,
) -> std::result::Result<(), String> {
    use gltf::mesh::Mode;
    let what = || match mesh.name() {
        Some(n) => format!("mesh {} ('{n}')", mesh.index()),
        None => format!("mesh {}", mesh.index()),
    };
    let m3 = glam::Mat3::from_mat4(*world);
    let normal_matrix = m3.inverse().transpose();
    let mirrored = m3.determinant() < 0.0;
    for prim in mesh.primitives() {
        let mode = prim.mode();
        if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            return Err(format!("{}: primitive {} draws {mode:?}, not triangles", what(), prim.index()));
        }
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        let positions: Vec<Vec3> = reader
            .read_positions()
            .ok_or_else(|| format!("{}: primitive {} has no POSITION", what(), prim.index()))?
            .map(Vec3::from)
            .collect();
        let n = positions.len() as u32;
        let base = out.positions.len() as u32;
        out.positions.extend(positions.iter().map(|p| world.transform_point3(*p)));
        match reader.read_normals() {
            Some(ns) => {
                let ns: Vec<Vec3> = ns.map(Vec3::from).collect();
                if ns.len() != positions.len() {
                    return Err(format!(
                        "{}: primitive {} has {} normals for {n} positions",
                        what(),
                        prim.index(),
                        ns.len()
                    ));
                }
                attrs.normals.extend(ns.iter().map(|v| (normal_matrix * *v).try_normalize().unwrap_or(Vec3::ZERO)));
            }
            None => attrs.normals.extend(std::iter::repeat_n(Vec3::ZERO, positions.len())),
        }
        if let Some(tc) = reader.read_tex_coords(0) {
            // In glTF's UV space (v down), then arbor's (v up).
            let t = uv_transform(&prim.material()).0;
            let tc: Vec<Vec2> = tc
                .into_f32()
                .map(|uv| {
                    let [u, v] = t.transform_point2(Vec2::from(uv)).to_array();
                    Vec2::new(u, 1.0 - v)
                })
                .collect();
            if tc.len() != positions.len() {
                return Err(format!("{}: primitive {} has {} UVs for {n} positions", what(), prim.index(), tc.len()));
            }
            attrs.uvs.resize(base as usize, Vec2::ZERO);
            attrs.uvs.extend(tc);
            attrs.any_uvs = true;
        }
        // COLOR_0: float, or normalized unsigned byte or short; RGB or RGBA; linear.
        if let Some(cs) = reader.read_colors(0) {
            let cs: Vec<Vec4> = cs.into_rgba_f32().map(Vec4::from).collect();
            if cs.len() != positions.len() {
                return Err(format!(
                    "{}: primitive {} has {} colours for {n} positions",
                    what(),
                    prim.index(),
                    cs.len()
                ));
            }
            attrs.colors.resize(base as usize, Vec4::ONE);
            attrs.colors.extend(cs);
            attrs.any_colors = true;
        }
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..n).collect(),
        };
        if let Some(&bad) = indices.iter().find(|&&i| i >= n) {
            return Err(format!("{}: primitive {} uses vertex {bad} of {n}", what(), prim.index()));
        }
        let mut tris: Vec<[u32; 3]> = Vec::new();
        match mode {
            Mode::Triangles => tris.extend(indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]])),
            Mode::TriangleStrip => {
                for k in 2..indices.len() {
                    let (a, b, c) = (indices[k - 2], indices[k - 1], indices[k]);
                    tris.push(if k % 2 == 0 { [a, b, c] } else { [b, a, c] });
                }
            }
            _ => {
                for k in 2..indices.len() {
                    tris.push([indices[0], indices[k - 1], indices[k]]);
                }
            }
        }
        let material = prim.material().index().map_or(default_material, |i| i as u32);
        for t in tris {
            let [a, b, c] = t.map(|i| i + base);
            out.triangles.push(if mirrored { [a, c, b] } else { [a, b, c] });
            out.tri_material.push(material);
        }
    }
    Ok(())
}

/// The file's images as arbor textures, each converted once, when a material uses it.
struct Slots<'a> {
    images: &'a [gltf::image::Data],
    /// Per image and wrap (the texture's sampler), its texture index once converted.
    slot: std::collections::HashMap<(usize, [Wrap; 2]), u32>,
    file: &'a str,
    /// What materials have that is not read, for the warning.
    unread: Vec<String>,
}

impl Slots<'_> {
    /// The texture index of `info`'s image (None, with a note in `unread`, when it uses
    /// a texture-coordinate set other than 0).
    fn of(
        &mut self,
        info: Option<(gltf::Texture, u32)>,
        what: &str,
        textures: &mut Vec<Texture>,
    ) -> std::result::Result<Option<u32>, String> {
        let Some((tex, set)) = info else { return Ok(None) };
        if set != 0 {
            self.unread.push(format!("{what} textures of texture-coordinate set {set}"));
            return Ok(None);
        }
        let image = tex.source().index();
        let wrap = {
            use gltf::texture::WrappingMode;
            let sampler = tex.sampler();
            [sampler.wrap_s(), sampler.wrap_t()].map(|m| match m {
                WrappingMode::ClampToEdge => Wrap::Clamp,
                WrappingMode::MirroredRepeat => Wrap::Mirror,
                WrappingMode::Repeat => Wrap::Repeat,
            })
        };
        if let Some(&s) = self.slot.get(&(image, wrap)) {
            return Ok(Some(s));
        }
        let data = self.images.get(image).ok_or_else(|| format!("image {image} is missing"))?;
        textures.push(Texture { wrap, ..texture(data, &format!("{}#image{image}", self.file))? });
        let s = (textures.len() - 1) as u32;
        self.slot.insert((image, wrap), s);
        Ok(Some(s))
    }
}

/// The UV transform (KHR_texture_transform) of `m`'s textures, on glTF's (u, v): the
/// base colour texture's, else that of the first of the metallic-roughness and emissive
/// textures that has one; and whether those textures carry different ones (then the
/// first is used for all). The normal texture's is not read: it takes this one.
fn uv_transform(m: &gltf::Material) -> (glam::Affine2, bool) {
    let pbr = m.pbr_metallic_roughness();
    let infos = [pbr.base_color_texture(), pbr.metallic_roughness_texture(), m.emissive_texture()];
    let of = |i: &gltf::texture::Info| {
        i.texture_transform().map_or(glam::Affine2::IDENTITY, |t| {
            let (s, c) = t.rotation().sin_cos();
            // Rotation counter-clockwise in glTF's UV space, after the scale.
            let rotate = glam::Mat2::from_cols(Vec2::new(c, -s), Vec2::new(s, c));
            glam::Affine2::from_mat2_translation(
                rotate * glam::Mat2::from_diagonal(Vec2::from(t.scale())),
                Vec2::from(t.offset()),
            )
        })
    };
    let all: Vec<glam::Affine2> = infos.iter().flatten().map(of).collect();
    let first = all.first().copied().unwrap_or(glam::Affine2::IDENTITY);
    (first, all.iter().any(|t| *t != first))
}

/// An arbor material for a glTF material (the module docs give the mapping).
fn material(
    m: &gltf::Material,
    slots: &mut Slots,
    textures: &mut Vec<Texture>,
) -> std::result::Result<Material, String> {
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, _] = pbr.base_color_factor();
    let base = Vec3::new(r, g, b).clamp(Vec3::ZERO, Vec3::ONE);
    let rough = pbr.roughness_factor().clamp(0.0, 1.0);
    let transmission = m.transmission().map_or(0.0, |t| t.transmission_factor());
    let name = m.name().map_or_else(|| format!("gltf material {}", m.index().unwrap_or(0)), str::to_string);
    let mut out = Material::lambert(&name, base);
    out.roughness = rough;
    let ior = m.ior().unwrap_or(1.5);
    if transmission >= 0.5 {
        out.kind = MaterialKind::Dielectric;
        out.ior = ior;
    } else {
        out.kind = MaterialKind::Pbr;
        out.metallic = pbr.metallic_factor().clamp(0.0, 1.0);
        let (weight, colour) = m.specular().map_or((1.0, Vec3::ONE), |s| {
            if s.specular_texture().is_some() || s.specular_color_texture().is_some() {
                slots.unread.push("KHR_materials_specular textures".into());
            }
            (s.specular_factor(), Vec3::from(s.specular_color_factor()))
        });
        let f0 = super::mesh::dielectric_f0(ior.max(1.0));
        out.dielectric_f0 = (colour.max(Vec3::ZERO) * f0).min(Vec3::ONE);
        out.specular_weight = weight.clamp(0.0, 1.0);
        let mr = pbr.metallic_roughness_texture().map(|i| (i.texture(), i.tex_coord()));
        out.maps.metal_rough = slots.of(mr, "metallic-roughness", textures)?;
        if let Some(n) = m.normal_texture() {
            out.maps.normal = slots.of(Some((n.texture(), n.tex_coord())), "normal", textures)?;
            out.maps.normal_scale = if n.scale().is_finite() { n.scale() } else { 1.0 };
        }
    }
    out.emission = Vec3::from(m.emissive_factor()) * m.emissive_strength().unwrap_or(1.0);
    out.two_sided = m.double_sided();
    if out.emission != Vec3::ZERO {
        let emissive = m.emissive_texture().map(|i| (i.texture(), i.tex_coord()));
        out.maps.emission = slots.of(emissive, "emissive", textures)?;
    }
    let base_tex = pbr.base_color_texture().map(|i| (i.texture(), i.tex_coord()));
    out.texture = slots.of(base_tex, "base colour", textures)?;
    if uv_transform(m).1 {
        slots.unread.push("KHR_texture_transform differing between one material's textures (the first is used)".into());
    }
    Ok(out)
}

/// An 8-bit RGBA texture from a decoded glTF image.
fn texture(d: &gltf::image::Data, name: &str) -> std::result::Result<Texture, String> {
    use gltf::image::Format;
    let n = d.width as usize * d.height as usize;
    // 16-bit channels (native-endian words, as the image decoder gives them) rounded
    // to 8 bits: normal and metallic-roughness maps are often 16-bit PNGs.
    let narrowed: Vec<u8>;
    let (px, channels) = match d.format {
        Format::R8 => (&d.pixels[..], 1),
        Format::R8G8 => (&d.pixels[..], 2),
        Format::R8G8B8 => (&d.pixels[..], 3),
        Format::R8G8B8A8 => (&d.pixels[..], 4),
        Format::R16 | Format::R16G16 | Format::R16G16B16 | Format::R16G16B16A16 => {
            let to8 = |c: &[u8]| ((u32::from(u16::from_ne_bytes([c[0], c[1]])) * 255 + 32_767) / 65_535) as u8;
            narrowed = d.pixels.chunks_exact(2).map(to8).collect();
            let channels = match d.format {
                Format::R16 => 1,
                Format::R16G16 => 2,
                Format::R16G16B16 => 3,
                _ => 4,
            };
            (&narrowed[..], channels)
        }
        other => return Err(format!("{name}: image format {other:?} is not supported (8- and 16-bit images only)")),
    };
    let texels: Vec<[u8; 4]> = match channels {
        1 => px.iter().map(|&v| [v, v, v, 255]).collect(),
        2 => px.chunks_exact(2).map(|p| [p[0], p[0], p[0], p[1]]).collect(),
        3 => px.chunks_exact(3).map(|p| [p[0], p[1], p[2], 255]).collect(),
        _ => px.chunks_exact(4).map(|p| [p[0], p[1], p[2], p[3]]).collect(),
    };
    if texels.len() != n || n == 0 {
        return Err(format!("{name}: the image has {} texels for {}x{}", texels.len(), d.width, d.height));
    }
    Ok(Texture { name: name.to_string(), width: d.width, height: d.height, texels, ..Default::default() })
}

/// What a file that is not glTF looks like, from its first bytes.
fn sniff(bytes: &[u8]) -> String {
    let what = if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        "a JPEG image"
    } else if bytes.starts_with(b"\x89PNG") {
        "a PNG image"
    } else if bytes.starts_with(b"PK") {
        "a ZIP archive"
    } else if bytes.is_empty() {
        return "the file is empty".into();
    } else {
        "something else"
    };
    let head: Vec<String> = bytes.iter().take(4).map(|b| format!("{b:02X}")).collect();
    format!("it starts with the bytes {} ({what}?)", head.join(" "))
}

/// The first external file (`uris` relative to `base`, `data:` URIs skipped) that
/// cannot be read, as a message naming it: the glTF reader's own error does not.
fn missing_uri<'a>(uris: impl Iterator<Item = &'a str>, base: &Path, what: &str) -> Option<String> {
    uris.filter(|u| !u.starts_with("data:")).find_map(|u| {
        let path = base.join(percent_decode(u));
        std::fs::metadata(&path).err().map(|e| format!("glTF {what} {}: cannot read it: {e}", path.display()))
    })
}

/// `%XX` escapes of a relative URI decoded (file names with spaces are written `%20`).
fn percent_decode(u: &str) -> String {
    let b = u.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        if b[i] == b'%' && i + 2 < b.len() {
            if let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}
