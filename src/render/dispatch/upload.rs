//! Uploads: the scene in GPU layout, the uniform parameters, and every buffer the
//! kernel declares (and only those), checked against the device's buffer range.

use crate::accel::gpu_layout::*;
use crate::accel::{AccelBuffers, GpuImage};
use crate::error::{Error, Result};
use crate::gpu::bindings::*;
use crate::gpu::{BindingDesc, BindingKind, Buffer, Context, Kernel};
use crate::scene::{AlphaMode, ComplexIor, Light, Material, MaterialKind, Scene};
use glam::Vec3;
use std::sync::Arc;

/// Scene data in GPU layout.
#[derive(Debug, Clone)]
pub struct GpuScene {
    pub vertices: Vec<GpuVertex>,
    pub triangles: Vec<GpuTriangle>,
    pub spheres: Vec<GpuSphere>,
    /// Materials (`MATERIAL_ROWS` rows each) then lights (`LIGHT_ROWS` rows each).
    pub shading: Vec<[f32; 4]>,
}

impl GpuScene {
    /// Converts a validated scene. With instancing, every prototype's vertices and
    /// triangles come first (in prototype order), then the scene's own
    /// (src/accel/instance.rs).
    pub fn new(scene: &Scene) -> GpuScene {
        let mut vertices = Vec::new();
        let mut triangles = Vec::new();
        let protos = scene.instancing.iter().flat_map(|i| i.prototypes.iter().map(|p| &p.geometry));
        for g in protos.chain(std::iter::once(scene)) {
            let base = vertices.len() as u32;
            vertices.extend(gpu_vertices(g));
            triangles.extend(gpu_triangles(g, base));
        }
        let spheres = gpu_spheres(scene);
        let mut shading = shading_rows(scene);
        if scene.has_vertex_colors() {
            debug_assert_eq!(shading.len() as u32, vertex_color_table_row(scene));
            shading.extend(vertex_color_rows(scene));
        }
        GpuScene { vertices, triangles, spheres, shading }
    }
}

/// Materials (`MATERIAL_ROWS` rows each), lights (`LIGHT_ROWS` rows each), then with
/// cut-outs or blended panes the alpha section ([`alpha_rows`]). The vertex colour
/// section follows ([`vertex_color_rows`]).
fn shading_rows(scene: &Scene) -> Vec<[f32; 4]> {
    let rows = scene.materials.len() * MATERIAL_ROWS as usize + scene.lights.len() * LIGHT_ROWS as usize;
    let mut shading = Vec::with_capacity(rows);
    for m in &scene.materials {
        shading.extend(material_record(m).rows());
    }
    for l in &scene.lights {
        shading.extend(light_record(l).rows());
    }
    if scene.has_alpha() {
        debug_assert_eq!(shading.len() as u32, alpha_table_row(scene));
        let base = shading.len() as u32;
        shading.extend(alpha_rows(scene, base));
        debug_assert_eq!(shading.len() as u32 - base, alpha_section_rows(scene));
    }
    shading
}

/// The scene's `SPEC_ALPHA` bits (`ALPHA_*`).
pub fn alpha_spec(scene: &Scene) -> u32 {
    if !scene.has_alpha() {
        return 0;
    }
    let textures = if scene.alpha_textures().is_empty() { 0 } else { ALPHA_TEXTURES };
    let blend = if scene.materials.iter().any(|m| m.alpha_mode == AlphaMode::Blend) { ALPHA_BLEND } else { 0 };
    ALPHA_ON | textures | blend
}

/// The first shading row of the alpha section (`GpuParams::alpha_table`): after the
/// materials and lights; 0 in a scene without alpha.
pub fn alpha_table_row(scene: &Scene) -> u32 {
    if !scene.has_alpha() {
        return 0;
    }
    (scene.materials.len() * MATERIAL_ROWS as usize + scene.lights.len() * LIGHT_ROWS as usize) as u32
}

/// The rows of the alpha section ([`alpha_rows`]) of a scene with alpha.
fn alpha_section_rows(scene: &Scene) -> u32 {
    let textures = scene.alpha_textures();
    let alphas: usize = textures.iter().map(|&t| scene.textures[t as usize].texels.len().div_ceil(4).div_ceil(4)).sum();
    (scene.materials.len() + textures.len() + alphas) as u32
}

/// The first shading row of the vertex colour section (`GpuParams::vertex_color_table`):
/// after the materials, the lights and the alpha section; 0 without vertex colours.
pub fn vertex_color_table_row(scene: &Scene) -> u32 {
    if !scene.has_vertex_colors() {
        return 0;
    }
    let alpha = if scene.has_alpha() { alpha_section_rows(scene) } else { 0 };
    (scene.materials.len() * MATERIAL_ROWS as usize + scene.lights.len() * LIGHT_ROWS as usize) as u32 + alpha
}

/// The vertex colour section (its layout: shaders/common/colors.glsl): every stored
/// vertex's colour in the vertex buffer's order (prototypes first, then the scene's
/// own), two words each ([`crate::scene::colors::color_words`]); white for a mesh
/// without colours.
fn vertex_color_rows(scene: &Scene) -> Vec<[f32; 4]> {
    let protos = scene.instancing.iter().flat_map(|i| i.prototypes.iter().map(|p| &p.geometry));
    let mut words = Vec::new();
    for g in protos.chain(std::iter::once(scene)) {
        let color = |k: usize| g.colors.get(k).copied().unwrap_or(glam::Vec4::ONE);
        words.extend((0..g.positions.len()).flat_map(|k| crate::scene::colors::color_words(color(k))));
    }
    super::tables::word_rows(&words)
}

/// The alpha section from row `base` (its layout: shaders/common/alpha.glsl): a row per
/// material, a descriptor row per texture whose alpha is read ([`Scene::alpha_textures`]),
/// then those textures' alphas, four bytes a word. An opaque material's row reads as a
/// cut-out with cutoff 0, which every alpha passes.
fn alpha_rows(scene: &Scene, base: u32) -> Vec<[f32; 4]> {
    let textures = scene.alpha_textures();
    let descriptors = base + scene.materials.len() as u32;
    let mut rows = Vec::new();
    for m in &scene.materials {
        let cutoff = match m.alpha_mode {
            AlphaMode::Opaque => 0.0,
            AlphaMode::Mask { cutoff } => cutoff,
            AlphaMode::Blend => -1.0,
        };
        let opacity = if m.has_alpha() { m.opacity } else { 1.0 };
        let desc = m
            .texture
            .filter(|_| m.has_alpha())
            .and_then(|t| textures.iter().position(|&x| x == t))
            .map_or(0, |k| descriptors + k as u32);
        rows.push([opacity, cutoff, f32::from_bits(desc), 0.0]);
    }
    let mut alphas: Vec<[f32; 4]> = Vec::new();
    for &t in &textures {
        let tex = &scene.textures[t as usize];
        let [wu, wv] = tex.wrap.map(|w| w as u32);
        let first = descriptors + textures.len() as u32 + alphas.len() as u32;
        let width = tex.width | wu << TEXTURE_WRAP_U_SHIFT | wv << TEXTURE_WRAP_V_SHIFT;
        rows.push([f32::from_bits(first), f32::from_bits(width), f32::from_bits(tex.height), 0.0]);
        let words: Vec<u32> = tex
            .texels
            .chunks(4)
            .map(|c| c.iter().enumerate().fold(0, |w, (k, p)| w | u32::from(p[3]) << (8 * k)))
            .collect();
        alphas.extend(super::tables::word_rows(&words));
    }
    rows.extend(alphas);
    rows
}

/// A material's record: the words every kind has, then its kind's own (the table at
/// `MAT_W_COLOR_RGB` in src/gpu/bindings.rs; `material_at` in
/// shaders/common/bsdf.glsl decodes them).
pub fn material_record(m: &Material) -> GpuMaterial {
    let mut g = GpuMaterial::default();
    // The kind, and the emission texture + 1 from MAT_MAP_SHIFT.
    let kind = m.kind as u32 | m.maps.emission.map_or(0, |t| t + 1) << MAT_MAP_SHIFT;
    g.set_rgb(MAT_W_COLOR_RGB, m.color)
        .set_bits(MAT_W_KIND, kind)
        .set_rgb(MAT_W_EMISSION_RGB, m.emission)
        .set_bits(MAT_W_FLAGS, material_flags(m));
    match m.kind {
        MaterialKind::Conductor => encode_conductor(m, &mut g),
        MaterialKind::Dielectric => encode_dielectric(m, &mut g),
        MaterialKind::Pbr => encode_pbr(m, &mut g),
        MaterialKind::Lambert
        | MaterialKind::Phong
        | MaterialKind::Mirror
        | MaterialKind::Glass
        | MaterialKind::Emissive => encode_plain(m, &mut g),
    }
    g
}

/// Lambert, Phong, mirror, glass, emissive: Phong's specular colour and exponent, the
/// glass's index and absorption.
fn encode_plain(m: &Material, g: &mut GpuMaterial) {
    g.set_rgb(MAT_W_SPECULAR_RGB, m.specular)
        .set(MAT_W_SHININESS, m.shininess)
        .set(MAT_W_IOR, m.ior)
        .set_rgb(MAT_W_ABSORPTION_RGB, m.absorption);
}

/// A conductor: its complex index (eta, k; without one, eta 1 and k 0, and the flag
/// MAT_FLAG_SCHLICK takes Fresnel from the colour) and GGX alpha.
fn encode_conductor(m: &Material, g: &mut GpuMaterial) {
    let c = m.complex_ior.unwrap_or(ComplexIor { eta: Vec3::ONE, k: Vec3::ZERO });
    g.set_rgb(MAT_W_ETA_RGB, c.eta).set(MAT_W_ALPHA, m.alpha()).set(MAT_W_IOR, m.ior).set_rgb(MAT_W_K_RGB, c.k);
}

/// A dielectric: GGX alpha, index and absorption.
fn encode_dielectric(m: &Material, g: &mut GpuMaterial) {
    g.set_rgb(MAT_W_SPECULAR_RGB, Vec3::ZERO)
        .set(MAT_W_ALPHA, m.alpha())
        .set(MAT_W_IOR, m.ior)
        .set_rgb(MAT_W_ABSORPTION_RGB, m.absorption);
}

/// Metallic-roughness: metallic, the dielectric layer's weight and F0, the normal
/// map's scale, roughness itself (its texture multiplies it first, in the kernel) and
/// the map word.
fn encode_pbr(m: &Material, g: &mut GpuMaterial) {
    g.set(MAT_W_METALLIC, m.metallic)
        .set(MAT_W_SPEC_WEIGHT, m.specular_weight)
        .set(MAT_W_NORMAL_SCALE, m.maps.normal_scale)
        .set(MAT_W_ROUGHNESS, m.roughness)
        .set_bits(MAT_W_MAPS, map_word(m))
        .set_rgb(MAT_W_F0_RGB, m.dielectric_f0);
}

/// A light's record (`light_at` in shaders/common/layout.glsl decodes it).
pub fn light_record(l: &Light) -> GpuLight {
    let mut g = GpuLight::default();
    match *l {
        Light::Directional { direction, radiance } => g
            .set_rgb(LIGHT_W_POSITION_RGB, direction)
            .set(LIGHT_W_IS_POINT, 0.0)
            .set_rgb(LIGHT_W_RADIANCE_RGB, radiance),
        Light::Point { position, intensity } => g
            .set_rgb(LIGHT_W_POSITION_RGB, position)
            .set(LIGHT_W_IS_POINT, 1.0)
            .set_rgb(LIGHT_W_RADIANCE_RGB, intensity),
    };
    g
}

/// The flags word (`MAT_W_FLAGS`).
fn material_flags(m: &Material) -> u32 {
    let sides = if m.two_sided { MAT_FLAG_TWO_SIDED } else { 0 };
    let schlick = if m.kind == MaterialKind::Conductor && m.complex_ior.is_none() { MAT_FLAG_SCHLICK } else { 0 };
    let tex = m.texture.map_or(0, |t| (t + 1) << MAT_TEXTURE_SHIFT);
    sides | schlick | tex
}

/// A metallic-roughness material's map word (`MAT_W_MAPS`): metallic-roughness
/// texture + 1, normal texture + 1 from MAT_MAP_SHIFT (0: none).
fn map_word(m: &Material) -> u32 {
    let slot = |t: Option<u32>| t.map_or(0, |t| t + 1);
    slot(m.maps.metal_rough) | slot(m.maps.normal) << MAT_MAP_SHIFT
}

/// The buffers bound to one kernel, kept alive while it runs.
pub struct Bound {
    /// The uniform parameters.
    pub uniform: Buffer,
    /// Storage buffers in binding order (a structure kept on the device shares its own).
    pub storage: Vec<Arc<Buffer>>,
    /// Names of every bound buffer, uniform first (for the stats).
    pub names: Vec<String>,
    /// Index in `storage` of the pixel buffer.
    pixels: usize,
    /// Index in `storage` of the ray buffer (ray-batch kernels only).
    rays: Option<usize>,
    /// The binding of each of `storage`, in order.
    slots: Vec<u32>,
}

impl std::fmt::Debug for Bound {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bound").field("names", &self.names).finish_non_exhaustive()
    }
}

impl Bound {
    /// The pixel buffer (dispatch header, then one `GpuPixel` per pixel of a chunk).
    pub fn pixels(&self) -> &Buffer {
        &self.storage[self.pixels]
    }

    /// The ray buffer (one `GpuRay` per pixel of a chunk), where the kernel reads rays.
    pub fn rays(&self) -> Option<&Buffer> {
        self.rays.map(|k| &*self.storage[k])
    }

    /// The storage buffer bound at `binding`, if any.
    pub fn at(&self, binding: u32) -> Option<&Buffer> {
        self.slots.iter().position(|&b| b == binding).map(|k| &*self.storage[k])
    }
}

/// Creates and binds every buffer `bindings` declares: the uniform `params`, the
/// scene, the structure's `image`, a pixel buffer for `chunk_pixels` pixels and, for
/// the ray-batch kernels, an uninitialised ray buffer of as many rays.
pub fn bind_all(
    ctx: &Context,
    kernel: &mut Kernel,
    bindings: &[BindingDesc],
    params: &GpuParams,
    scene: &GpuScene,
    image: &GpuImage,
    chunk_pixels: u64,
) -> Result<Bound> {
    let _span = crate::timeline::span("upload", || "upload scene and structure");
    let uniform = ctx.upload_uniform("params", bytemuck::bytes_of(params))?;
    let mut storage: Vec<Arc<Buffer>> = Vec::new();
    let mut names = Vec::new();
    let mut pixels = None;
    let mut rays = None;
    let mut slots = Vec::new();
    for b in bindings {
        if b.kind == BindingKind::Uniform && b.binding == BINDING_PARAMS {
            ctx.bind(kernel, b.binding, &uniform)?;
            names.push("params".to_string());
            continue;
        }
        if b.kind == BindingKind::RayStructure {
            let tlas = image.ray_structure.ok_or_else(|| {
                Error::Failed(format!("the {} kernel traces the driver's structure, which was not built", image.family))
            })?;
            ctx.bind_ray_structure(kernel, b.binding, tlas)?;
            names.push(b.name.to_string());
            continue;
        }
        if let Some(kept) = built_geometry(b.binding, scene, image) {
            ctx.bind(kernel, b.binding, &kept)?;
            names.push(format!("{} (the build's)", b.name));
            storage.push(kept);
            slots.push(b.binding);
            continue;
        }
        let buf = match (b.binding, &image.buffers) {
            (BINDING_ACCEL_NODES, Some(AccelBuffers::Device { nodes, .. })) => Arc::clone(nodes),
            (BINDING_ACCEL_INDICES, Some(AccelBuffers::Device { indices, .. })) => Arc::clone(indices),
            _ => Arc::new(upload_one(ctx, b, scene, image, chunk_pixels)?),
        };
        match b.binding {
            BINDING_PIXELS => pixels = Some(storage.len()),
            BINDING_RAYS => rays = Some(storage.len()),
            _ => {}
        }
        ctx.bind(kernel, b.binding, &buf)?;
        names.push(b.name.to_string());
        storage.push(buf);
        slots.push(b.binding);
    }
    let pixels = pixels.ok_or_else(|| Error::Failed("no pixel buffer".into()))?;
    Ok(Bound { uniform, storage, names, pixels, rays, slots })
}

/// The geometry buffer at `binding` that a structure built on the device uploaded, if
/// it holds the words `scene` would upload (the same layout, written by the same
/// functions; a scene with instances, whose prototypes come first, never matches).
fn built_geometry(binding: u32, scene: &GpuScene, image: &GpuImage) -> Option<Arc<Buffer>> {
    let Some(AccelBuffers::Device { geometry, .. }) = &image.buffers else { return None };
    let (_, buf) = geometry.iter().find(|(b, _)| *b == binding)?;
    let bytes = match binding {
        BINDING_VERTICES => std::mem::size_of_val(scene.vertices.as_slice()),
        BINDING_TRIANGLES => std::mem::size_of_val(scene.triangles.as_slice()),
        BINDING_SPHERES => std::mem::size_of_val(scene.spheres.as_slice()),
        _ => return None,
    };
    (buf.size() == bytes as u64).then(|| Arc::clone(buf))
}

/// Creates the buffer of one binding of [`bind_all`] (uploading what the host has).
fn upload_one(ctx: &Context, b: &BindingDesc, scene: &GpuScene, image: &GpuImage, chunk_pixels: u64) -> Result<Buffer> {
    let kind = b.kind;
    Ok(match b.binding {
        BINDING_VERTICES => upload_checked(ctx, kind, "vertices", bytemuck::cast_slice(&scene.vertices))?,
        BINDING_TRIANGLES => upload_checked(ctx, kind, "triangles", bytemuck::cast_slice(&scene.triangles))?,
        BINDING_SPHERES => upload_checked(ctx, kind, "spheres", bytemuck::cast_slice(&scene.spheres))?,
        BINDING_SHADING => upload_checked(ctx, kind, "shading", bytemuck::cast_slice(&scene.shading))?,
        BINDING_ACCEL_NODES => match &image.buffers {
            Some(AccelBuffers::Host(nodes, _)) => upload_checked(ctx, kind, "accel_nodes", nodes)?,
            _ => return Err(Error::Failed(format!("the {} structure has no nodes", image.family))),
        },
        BINDING_ACCEL_INDICES => match &image.buffers {
            Some(AccelBuffers::Host(_, indices)) => {
                upload_checked(ctx, kind, "accel_indices", bytemuck::cast_slice(indices))?
            }
            _ => return Err(Error::Failed(format!("the {} structure has no indices", image.family))),
        },
        // Resumable families: the trace kernel never touches the pool (resume.rs).
        BINDING_RESUME => ctx.create_buffer("resume", 16, crate::gpu::BufferKind::Storage)?,
        BINDING_PIXELS => {
            let size = PIXEL_HEADER_BYTES + chunk_pixels * std::mem::size_of::<GpuPixel>() as u64;
            ctx.check_binding(kind, "pixels", size)?;
            let buf = ctx.create_buffer("pixels", size, crate::gpu::BufferKind::Storage)?;
            // Cleared here so that on a CPU device the first touch of its pages
            // (the kernel zeroing them) is not charged to the first trace.
            ctx.fill_zero(&buf)?;
            buf
        }
        BINDING_RAYS => {
            let size = chunk_pixels * std::mem::size_of::<GpuRay>() as u64;
            ctx.check_binding(kind, "rays", size)?;
            ctx.create_buffer("rays", size, crate::gpu::BufferKind::Storage)?
        }
        // SPPM (src/render/integrators/sppm.rs): each over the chunk's pixels, zeroed;
        // the map binding starts as a stand-in, replaced once a map is built.
        // The texel views of the points and records stand in until the integrator binds
        // the storage buffers' own. Sizes are whole 16-byte texels.
        BINDING_SPPM_POINTS
        | BINDING_SPPM_RECORDS
        | BINDING_SPPM_FLUX
        | BINDING_SPPM_GRID_HEADER
        | BINDING_SPPM_GRID_STARTS
        | BINDING_SPPM_MAP
        | BINDING_SPPM_POINT_TEXELS
        | BINDING_SPPM_RECORD_TEXELS => {
            let size = match b.binding {
                BINDING_SPPM_POINTS => chunk_pixels * 16,
                BINDING_SPPM_RECORDS => chunk_pixels * u64::from(SPPM_RECORD_ROWS) * 16,
                BINDING_SPPM_FLUX => (u64::from(SPPM_COUNTERS) + chunk_pixels * u64::from(SPPM_FLUX_WORDS)) * 4,
                BINDING_SPPM_GRID_HEADER => u64::from(PHOTON_HDR_WORDS) * 4,
                BINDING_SPPM_GRID_STARTS => (chunk_pixels + 1) * 4,
                _ => 32,
            }
            .next_multiple_of(16);
            ctx.check_binding(kind, b.name, size)?;
            let buf = ctx.create_buffer(b.name, size, crate::gpu::BufferKind::Storage)?;
            ctx.fill_zero(&buf)?;
            buf
        }
        other => return Err(Error::Failed(format!("trace kernel has unexpected binding {other}"))),
    })
}

/// Binds the buffers of `bound` (bound by [`bind_all`] for the same `bindings`) to
/// another kernel of the variant, `replace` in place of the buffer at its binding, and
/// the driver's structure `tlas` where the variant traces one.
pub fn bind_again(
    ctx: &Context,
    kernel: &mut Kernel,
    bindings: &[BindingDesc],
    bound: &Bound,
    tlas: Option<&crate::gpu::RayStructure>,
    replace: (u32, &Buffer),
) -> Result<()> {
    for b in bindings {
        if b.kind == BindingKind::Uniform && b.binding == BINDING_PARAMS {
            ctx.bind(kernel, b.binding, &bound.uniform)?;
            continue;
        }
        if b.kind == BindingKind::RayStructure {
            let tlas = tlas.ok_or_else(|| Error::Failed(format!("binding {} has no ray structure", b.binding)))?;
            ctx.bind_ray_structure(kernel, b.binding, tlas)?;
            continue;
        }
        let buf = if b.binding == replace.0 { Some(replace.1) } else { bound.at(b.binding) };
        let buf = buf.ok_or_else(|| Error::Failed(format!("binding {} has no buffer", b.binding)))?;
        ctx.bind(kernel, b.binding, buf)?;
    }
    Ok(())
}

fn upload_checked(ctx: &Context, kind: BindingKind, name: &str, data: &[u8]) -> Result<Buffer> {
    ctx.check_binding(kind, name, data.len() as u64)?;
    ctx.upload_storage(name, data)
}
