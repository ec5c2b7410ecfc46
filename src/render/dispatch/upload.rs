//! Uploads: the scene in GPU layout, the uniform parameters, and every buffer the
//! kernel declares (and only those), checked against the device's buffer range.

use crate::accel::gpu_layout::*;
use crate::accel::{AccelBuffers, GpuImage};
use crate::error::{Error, Result};
use crate::gpu::bindings::*;
use crate::gpu::{BindingDesc, BindingKind, Buffer, Context, Kernel};
use crate::scene::{ComplexIor, Light, MaterialKind, Scene};
use glam::Vec3;
use std::sync::Arc;

/// Scene data in GPU layout.
#[derive(Debug, Clone)]
pub struct GpuScene {
    pub vertices: Vec<GpuVertex>,
    pub triangles: Vec<GpuTriangle>,
    pub spheres: Vec<GpuSphere>,
    /// Materials (4 rows each) then lights (2 rows each).
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
        GpuScene { vertices, triangles, spheres, shading: shading_rows(scene) }
    }
}

/// Materials (4 rows each) then lights (2 rows each).
fn shading_rows(scene: &Scene) -> Vec<[f32; 4]> {
    let mut shading = Vec::with_capacity(scene.materials.len() * 4 + scene.lights.len() * 2);
    for m in &scene.materials {
        // A conductor keeps eta in the specular row and k in the absorption row; it and
        // the dielectric keep GGX alpha where Phong keeps its exponent.
        let (specular, shininess, absorption) = match (m.kind, m.complex_ior) {
            (MaterialKind::Conductor, ior) => {
                let c = ior.unwrap_or(ComplexIor { eta: Vec3::ONE, k: Vec3::ZERO });
                (c.eta, m.alpha(), c.k)
            }
            (MaterialKind::Dielectric, _) => (Vec3::ZERO, m.alpha(), m.absorption),
            // Metallic-roughness: roughness itself (its texture multiplies it first).
            (MaterialKind::Pbr, _) => {
                (Vec3::new(m.metallic, m.specular_weight, m.maps.normal_scale), m.roughness, m.dielectric_f0)
            }
            _ => (m.specular, m.shininess, m.absorption),
        };
        let ior = match m.kind {
            MaterialKind::Pbr => f32::from_bits(map_word(m)),
            _ => m.ior,
        };
        // The kind, and the emission texture + 1 from MAT_MAP_SHIFT.
        let kind = m.kind as u32 | m.maps.emission.map_or(0, |t| t + 1) << MAT_MAP_SHIFT;
        let g = GpuMaterial {
            color_kind: [m.color.x, m.color.y, m.color.z, f32::from_bits(kind)],
            specular: [specular.x, specular.y, specular.z, shininess],
            emission_ior: [m.emission.x, m.emission.y, m.emission.z, ior],
            absorption_flags: [absorption.x, absorption.y, absorption.z, f32::from_bits(material_flags(m))],
        };
        shading.extend([g.color_kind, g.specular, g.emission_ior, g.absorption_flags]);
    }
    for l in &scene.lights {
        let g = match *l {
            Light::Directional { direction: d, radiance: r } => {
                GpuLight { position_or_direction: [d.x, d.y, d.z, 0.0], radiance: [r.x, r.y, r.z, 0.0] }
            }
            Light::Point { position: p, intensity: i } => {
                GpuLight { position_or_direction: [p.x, p.y, p.z, 1.0], radiance: [i.x, i.y, i.z, 0.0] }
            }
        };
        shading.extend([g.position_or_direction, g.radiance]);
    }
    shading
}

/// The flags word of material row 3 (shaders/common/layout.glsl).
fn material_flags(m: &crate::scene::Material) -> u32 {
    let sides = if m.two_sided { MAT_FLAG_TWO_SIDED } else { 0 };
    let schlick = if m.kind == MaterialKind::Conductor && m.complex_ior.is_none() { MAT_FLAG_SCHLICK } else { 0 };
    let tex = m.texture.map_or(0, |t| (t + 1) << MAT_TEXTURE_SHIFT);
    sides | schlick | tex
}

/// A metallic-roughness material's map word (row 2, w): metallic-roughness texture
/// + 1, normal texture + 1 from MAT_MAP_SHIFT (0: none).
fn map_word(m: &crate::scene::Material) -> u32 {
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
            continue;
        }
        let buf = match (b.binding, &image.buffers) {
            (BINDING_ACCEL_NODES, Some(AccelBuffers::Device { nodes, .. })) => Arc::clone(nodes),
            (BINDING_ACCEL_INDICES, Some(AccelBuffers::Device { indices, .. })) => Arc::clone(indices),
            _ => Arc::new(upload_one(
                ctx,
                (b.binding, b.kind),
                scene,
                image,
                chunk_pixels,
                (&mut pixels, &mut rays),
                storage.len(),
            )?),
        };
        ctx.bind(kernel, b.binding, &buf)?;
        names.push(b.name.to_string());
        storage.push(buf);
    }
    let pixels = pixels.ok_or_else(|| Error::Failed("no pixel buffer".into()))?;
    Ok(Bound { uniform, storage, names, pixels, rays })
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

/// Creates the buffer of one binding of [`bind_all`] (uploading what the host has),
/// noting where the pixel and ray buffers are (`at`: its index in the storage list).
fn upload_one(
    ctx: &Context,
    (binding, kind): (u32, BindingKind),
    scene: &GpuScene,
    image: &GpuImage,
    chunk_pixels: u64,
    (pixels, rays): (&mut Option<usize>, &mut Option<usize>),
    at: usize,
) -> Result<Buffer> {
    Ok(match binding {
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
            check_range(ctx, kind, "pixels", size)?;
            *pixels = Some(at);
            let buf = ctx.create_buffer("pixels", size, crate::gpu::BufferKind::Storage)?;
            // Cleared here so that on a CPU device the first touch of its pages
            // (the kernel zeroing them) is not charged to the first trace.
            ctx.fill_zero(&buf)?;
            buf
        }
        BINDING_RAYS => {
            let size = chunk_pixels * std::mem::size_of::<GpuRay>() as u64;
            check_range(ctx, kind, "rays", size)?;
            *rays = Some(at);
            ctx.create_buffer("rays", size, crate::gpu::BufferKind::Storage)?
        }
        other => return Err(Error::Failed(format!("trace kernel has unexpected binding {other}"))),
    })
}

/// Binds the buffers of `bound` (bound by [`bind_all`] for the same `bindings`) to
/// another kernel of the variant, `replace` in place of the buffer at its binding.
pub fn bind_again(
    ctx: &Context,
    kernel: &mut Kernel,
    bindings: &[BindingDesc],
    bound: &Bound,
    replace: (u32, &Buffer),
) -> Result<()> {
    let mut storage = bound.storage.iter();
    for b in bindings {
        if b.kind == BindingKind::Uniform && b.binding == BINDING_PARAMS {
            ctx.bind(kernel, b.binding, &bound.uniform)?;
            continue;
        }
        let buf = storage.next().ok_or_else(|| Error::Failed(format!("binding {} has no buffer", b.binding)))?;
        ctx.bind(kernel, b.binding, if b.binding == replace.0 { replace.1 } else { buf })?;
    }
    Ok(())
}

/// Refuses, before it is created, a buffer larger than its binding allows
/// ([`Context::binding_limit`]: a texel view's limit for texel bindings, the storage
/// range for storage ones).
fn check_range(ctx: &Context, kind: BindingKind, name: &str, size: u64) -> Result<()> {
    let (limit, per) = ctx.binding_limit_named(kind);
    if size > limit {
        return Err(Error::BufferTooLarge { name: name.to_string(), size, limit, per });
    }
    Ok(())
}

fn upload_checked(ctx: &Context, kind: BindingKind, name: &str, data: &[u8]) -> Result<Buffer> {
    check_range(ctx, kind, name, data.len() as u64)?;
    ctx.upload_storage(name, data)
}
