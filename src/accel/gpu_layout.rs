//! Every struct the shaders read, declared once in Rust. Each has a twin in
//! `shaders/common/layout.glsl` (std430 for storage, std140 for the uniform block)
//! with byte offsets in comments; `tests/it/gpu_layout.rs` proves on the device that
//! the two agree by copying every field back through a probe kernel.
//!
//! Rules: 4-byte scalars in 16-byte groups, no bool, no `Vec3A`, sizes asserted at
//! compile time.

use bytemuck::{Pod, Zeroable};

use crate::gpu::bindings::*;
use crate::scene::Scene;

/// One vertex: position and shading normal, interleaved so that one storage buffer
/// holds both. `normal[3]` is 1.0 when the normal is valid, 0.0 when the triangle
/// should use its geometric normal.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuVertex {
    /// bytes 0..12 position, 12..16 texture coordinate u (0 without UVs)
    pub position: [f32; 4],
    /// bytes 16..28 shading normal (zero: the vertex has none), 28..32 texture
    /// coordinate v
    pub normal: [f32; 4],
}

/// One triangle: three vertex indices and the material index.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct GpuTriangle {
    /// `[v0, v1, v2, material]`
    pub v: [u32; 4],
}

/// One analytic sphere.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuSphere {
    /// bytes 0..12 centre, 12..16 radius
    pub center_radius: [f32; 4],
    /// bytes 16..20 material index, 20..32 unused (0)
    pub material: [u32; 4],
}

/// The vertices of one mesh `g` in GPU layout: positions, shading normals and texture
/// coordinates (0 where the mesh has none; a vertex without a normal gets the zero one). The render and the GPU build upload the
/// same words, so a tree built on the device is traced over the build's buffers.
pub fn gpu_vertices(g: &Scene) -> impl Iterator<Item = GpuVertex> + '_ {
    g.positions.iter().enumerate().map(move |(k, p)| {
        let uv = g.uvs.get(k).copied().unwrap_or(glam::Vec2::ZERO);
        let n = g.normals.get(k).copied().unwrap_or(glam::Vec3::ZERO);
        GpuVertex { position: [p.x, p.y, p.z, uv.x], normal: [n.x, n.y, n.z, uv.y] }
    })
}

/// The triangles of one mesh `g` in GPU layout, their vertex indices offset by `base`.
pub fn gpu_triangles(g: &Scene, base: u32) -> impl Iterator<Item = GpuTriangle> + '_ {
    g.triangles
        .iter()
        .zip(&g.tri_material)
        .map(move |(t, m)| GpuTriangle { v: [t[0] + base, t[1] + base, t[2] + base, *m] })
}

/// The analytic spheres of `scene` in GPU layout.
pub fn gpu_spheres(scene: &Scene) -> Vec<GpuSphere> {
    scene
        .spheres
        .iter()
        .map(|s| GpuSphere {
            center_radius: [s.center.x, s.center.y, s.center.z, s.radius],
            material: [s.material, 0, 0, 0],
        })
        .collect()
}

/// One material record: `MATERIAL_ROWS` vec4 rows of the shading buffer, as words
/// named in src/gpu/bindings.rs (`MAT_W_*`, with the table of which kind uses which).
/// Written through [`GpuMaterial::set`] and its siblings by the one encoder per kind
/// (`material_record` in src/render/dispatch/upload.rs); read by `material_at` in
/// shaders/common/bsdf.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMaterial {
    pub words: [f32; (MATERIAL_ROWS * 4) as usize],
}

/// One light record: `LIGHT_ROWS` vec4 rows of the shading buffer, after all
/// materials, as words named `LIGHT_W_*` in src/gpu/bindings.rs.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLight {
    pub words: [f32; (LIGHT_ROWS * 4) as usize],
}

/// Setters shared by the material and light records: a word as a float, as uint bits,
/// and three words from a vector (a `_RGB` word opens a row).
macro_rules! record_setters {
    ($t:ty) => {
        impl $t {
            /// Word `w` holds `v`.
            pub fn set(&mut self, w: u32, v: f32) -> &mut Self {
                self.words[w as usize] = v;
                self
            }
            /// Word `w` holds the bits of `v` (read with `floatBitsToUint`).
            pub fn set_bits(&mut self, w: u32, v: u32) -> &mut Self {
                self.set(w, f32::from_bits(v))
            }
            /// Words `w..w + 3` hold `v` (`w` is a `_RGB` word).
            pub fn set_rgb(&mut self, w: u32, v: glam::Vec3) -> &mut Self {
                self.words[w as usize..w as usize + 3].copy_from_slice(&v.to_array());
                self
            }
            /// The record as shading rows.
            pub fn rows(&self) -> impl Iterator<Item = [f32; 4]> + '_ {
                self.words.chunks_exact(4).map(|r| [r[0], r[1], r[2], r[3]])
            }
        }
    };
}
record_setters!(GpuMaterial);
record_setters!(GpuLight);

// Every named word lies in its record, and a three-word field fills lanes 0..2 of one
// row (the GLSL decoder reads it as `row.rgb`).
const _: () = {
    let material_rgb = [
        MAT_W_COLOR_RGB,
        MAT_W_SPECULAR_RGB,
        MAT_W_ETA_RGB,
        MAT_W_EMISSION_RGB,
        MAT_W_ABSORPTION_RGB,
        MAT_W_K_RGB,
        MAT_W_F0_RGB,
    ];
    let mut i = 0;
    while i < material_rgb.len() {
        assert!(material_rgb[i] % 4 == 0 && material_rgb[i] + 2 < MATERIAL_ROWS * 4);
        i += 1;
    }
    let material_words = [
        MAT_W_KIND,
        MAT_W_SHININESS,
        MAT_W_ALPHA,
        MAT_W_METALLIC,
        MAT_W_SPEC_WEIGHT,
        MAT_W_NORMAL_SCALE,
        MAT_W_ROUGHNESS,
        MAT_W_IOR,
        MAT_W_MAPS,
        MAT_W_FLAGS,
    ];
    let mut i = 0;
    while i < material_words.len() {
        assert!(material_words[i] < MATERIAL_ROWS * 4);
        i += 1;
    }
    let light_rgb = [LIGHT_W_POSITION_RGB, LIGHT_W_RADIANCE_RGB];
    let mut i = 0;
    while i < light_rgb.len() {
        assert!(light_rgb[i] % 4 == 0 && light_rgb[i] + 2 < LIGHT_ROWS * 4);
        i += 1;
    }
    assert!(LIGHT_W_IS_POINT < LIGHT_ROWS * 4);
};

/// Per-pixel output of the trace kernel.
///
/// The ray-batch kernel (`rays_*`, src/render/rays.rs) writes one per ray with other
/// meanings: `radiance` = (u, v, 0, 1 once the ray is complete), `normal_depth.w` = t
/// of the hit (the ray's tmax on a miss), `prim_cost` = (primitive or u32::MAX,
/// nodes, tests, 1 | bit 31 where the trace ran out of steps), `albedo_m2` = 0.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuPixel {
    /// bytes 0..12 summed radiance over the samples traced so far, 12..16 sample count
    pub radiance: [f32; 4],
    /// bytes 16..28 shading normal at the camera ray's hit (zero on a miss),
    /// 28..32 depth (t of the camera ray's hit, +inf on a miss)
    pub normal_depth: [f32; 4],
    /// bytes 32..36 primitive index (u32::MAX on a miss), 36..40 nodes visited,
    /// 40..44 primitives tested, all for sample 0's camera ray; 44..48 rays traced
    /// (bit 31: a trace ran out of steps)
    pub prim_cost: [u32; 4],
    /// bytes 48..60 albedo at sample 0's first hit, 60..64 summed squared luminance
    /// of the samples (for the variance estimate)
    pub albedo_m2: [f32; 4],
}

/// One ray of a ray batch (src/render/rays.rs): a uniform texel buffer of RGBA32UI
/// texels, two per ray, at `BINDING_RAYS` (`ray_at` in shaders/common/layout.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuRay {
    /// bytes 0..12 origin, 12..16 tmin
    pub origin_tmin: [f32; 4],
    /// bytes 16..28 direction (unit), 28..32 tmax (may be +inf)
    pub dir_tmax: [f32; 4],
}

/// The uniform block (std140: a `[f32; 3]` is a vec3, which the scalar after it
/// completes to 16 bytes). `ParamsBlock` in shaders/common/layout.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuParams {
    /// bytes 0..12: the camera's eye
    pub cam_eye: [f32; 3],
    /// bytes 12..16: tan(vfov / 2)
    pub tan_half_fov: f32,
    /// bytes 16..28: camera right (unit)
    pub cam_right: [f32; 3],
    /// bytes 28..32: width / height
    pub aspect: f32,
    /// bytes 32..44: camera up (unit)
    pub cam_up: [f32; 3],
    /// bytes 44..48: SPPM: the flux one unit of a photon deposit's fixed point stands
    /// for (0 for the other integrators)
    pub photon_unit: f32,
    /// bytes 48..60: camera forward (unit)
    pub cam_forward: [f32; 3],
    /// bytes 60..64: SPPM: the initial radius (0: from the pixel footprint)
    pub photon_radius: f32,
    /// bytes 64..76: the scene box's minimum
    pub scene_min: [f32; 3],
    /// bytes 76..80: SPPM: first shading row of the photon pass's light table
    pub photon_light_table: u32,
    /// bytes 80..92: the scene box's maximum
    pub scene_max: [f32; 3],
    /// bytes 92..96: SPPM: the rows of that table
    pub photon_lights: u32,
    /// bytes 96..100: the whole image's width in pixels
    pub width: u32,
    /// bytes 100..104: its height
    pub height: u32,
    /// bytes 104..108: stored triangles, which are primitives 0.. (spheres follow)
    pub triangle_count: u32,
    /// bytes 108..112: spheres
    pub sphere_count: u32,
    /// bytes 112..116: point and directional lights shaded. The kernels' light loops
    /// take their bound from the constant SPEC_LIGHTS, not from here.
    pub light_count: u32,
    /// bytes 116..120: materials (the light records follow them in the shading rows)
    pub material_count: u32,
    /// bytes 120..124: the render's seed
    pub seed: u32,
    /// bytes 124..128: SPPM: photons traced per iteration
    pub photon_count: u32,
    /// bytes 128..140: background radiance (a ray that leaves the scene)
    pub background: [f32; 3],
    /// bytes 140..144: Whitted's ambient factor (0 for the path integrator)
    pub ambient: f32,
    /// bytes 144..148: first shading row of the emitter table (area lights by power)
    pub emitter_table: u32,
    /// bytes 148..152: first shading row of the texture table
    pub texture_table: u32,
    /// bytes 152..156: first shading row of the environment map's texels
    pub env_texel_table: u32,
    /// bytes 156..160: first shading row of the environment map's sampling distribution
    pub env_distribution_table: u32,
    /// bytes 160..164: the environment map's intensity
    pub env_intensity: f32,
    /// bytes 164..168: its rotation about +y (radians)
    pub env_rotation: f32,
    /// bytes 168..172: the emitter table's total power
    pub emitter_power: f32,
    /// bytes 172..176: the alpha section's first shading row (`alpha_table` in
    /// shaders/common/alpha.glsl; 0 without alpha materials)
    pub alpha_table: u32,
    /// bytes 176..180: the vertex colour section's first shading row
    /// (shaders/common/colors.glsl; 0 without vertex colours)
    pub vertex_color_table: u32,
    /// bytes 180..192: unused (0), the block's last 16-byte row
    pub spare0: u32,
    pub spare1: u32,
    pub spare2: u32,
}

/// What one trace dispatch covers: the head of the pixel buffer (`dispatch_range`,
/// `dispatch_chunk`, `dispatch_window`, `dispatch_limits` in
/// shaders/common/layout.glsl), written by the host before each dispatch. Not push
/// constants: lavapipe compiles the kernel again for every new value of a push
/// constant its branches or loops depend on.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct GpuDispatch {
    /// bytes 0..4: first pixel of this dispatch (a resume list pass: first job);
    /// pixel indices count row-major inside the window
    pub first: u32,
    /// bytes 4..8: pixels (or jobs) it covers
    pub count: u32,
    /// bytes 8..12: first sample
    pub sample_begin: u32,
    /// bytes 12..16: end sample (exclusive)
    pub sample_end: u32,
    /// bytes 16..32: the part the kernel writes; copied back after every dispatch
    pub chunk: DispatchChunk,
    /// bytes 32..36: the window of the image being rendered (`--crop`, a tile
    /// shard): left column
    pub window_left: u32,
    /// bytes 36..40: the window's top row
    pub window_top: u32,
    /// bytes 40..44: the window's width
    pub window_width: u32,
    /// bytes 44..48: the sample at which pixels start from zero (`u32::MAX`: never, a
    /// resumed render continues from uploaded sums)
    pub zero_sample: u32,
    /// bytes 48..52: the steps (nodes + primitive tests) one trace may take before it
    /// stops and is resumed (`TREE_STEPS`; 0 for brute force, whose loops need no
    /// budget). Not a specialization constant: every budget would be a pipeline of
    /// its own (a render with `--trace-steps` next to one without compiled twice).
    pub trace_steps: u32,
    /// bytes 52..56: 0
    pub unused: u32,
    /// bytes 56..60: SPPM's photon pass: the photon map's size (visible points in the
    /// grid, or the kd-tree's nodes)
    pub map_size: u32,
    /// bytes 60..64: SPPM's photon pass: the grid's buckets
    pub map_buckets: u32,
}

/// Bytes 16..32 of the dispatch header (`dispatch_chunk` in layout.glsl): what the
/// ring copies back after every dispatch (`gpu::COPY_BACK_BYTES`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct DispatchChunk {
    /// first pixel held by the pixel buffer (the chunk base)
    pub base: u32,
    /// 1 for a resumed part (its pixels continue uploaded sums)
    pub resumed: u32,
    /// the pass: `PASS_TRACE`, or a resume pass (shaders/common/resume.glsl)
    pub pass: u32,
    /// counted by the kernel: samples stopped (a trace pass) or jobs handed to the
    /// next list (a resume list pass); the host sets it to the list's split point
    /// before the second half of a split pass
    pub counter: u32,
}

/// Head of the grid's node buffer, before the cell starts. GLSL twin: the `GridCells`
/// block in shaders/accel/grid.glsl (`uvec4 grid_res; vec4 grid_cell;`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuGridHeader {
    /// bytes 0..12 cells per axis, 12..16 number of cells
    pub res: [u32; 4],
    /// bytes 16..28 cell size per axis, 28..32 unused
    pub cell: [f32; 4],
}

/// Head of the octree's node buffer, before the nodes. GLSL twin: the `OctNodes`
/// block in shaders/accel/octree.glsl (`vec4 oct_min; vec4 oct_max;`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuOctreeHeader {
    /// bytes 0..12 root cube minimum, 12..16 unused
    pub min: [f32; 4],
    /// bytes 16..28 root cube maximum, 28..32 unused
    pub max: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<GpuGridHeader>() == 32);
const _: () = assert!(std::mem::size_of::<GpuOctreeHeader>() == 32);
const _: () = assert!(std::mem::size_of::<GpuVertex>() == 32);
const _: () = assert!(std::mem::size_of::<GpuTriangle>() == 16);
const _: () = assert!(std::mem::size_of::<GpuSphere>() == 32);
const _: () = assert!(std::mem::size_of::<GpuMaterial>() == 64);
const _: () = assert!(std::mem::size_of::<GpuPixel>() == 64);
const _: () = assert!(std::mem::size_of::<GpuRay>() == 32);
const _: () = assert!(std::mem::size_of::<GpuParams>() == 192);
const _: () = assert!(std::mem::size_of::<GpuLight>() == 32);
/// Push constants of every GPU BVH build kernel (`BuildPush` in
/// shaders/build/common.glsl; the canonical-node layout is documented there).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuBuildPush {
    /// bytes 0..4 primitives
    pub n: u32,
    /// bytes 4..16 kernel-specific words a, b, c (see each build_*.comp)
    pub a: u32,
    pub b: u32,
    pub c: u32,
    /// bytes 16..20 SAH traversal cost, 20..24 intersection cost
    pub ct: f32,
    pub ci: f32,
    /// bytes 24..28 restructure only below cost x keep (treelet::KEEP_FACTOR)
    pub keep: f32,
    /// bytes 28..32 unused
    pub d: u32,
}

const _: () = assert!(std::mem::size_of::<GpuBuildPush>() == 32);
const _: () = assert!(std::mem::size_of::<GpuDispatch>() == 64);
const _: () = assert!(std::mem::offset_of!(GpuDispatch, chunk) == 16 && std::mem::size_of::<DispatchChunk>() == 16);
const _: () = assert!(std::mem::offset_of!(GpuDispatch, window_left) == 32);
const _: () = assert!(std::mem::offset_of!(GpuDispatch, trace_steps) == 48);
const _: () = assert!(std::mem::size_of::<DispatchChunk>() as u64 == crate::gpu::COPY_BACK_BYTES);

/// Bytes before the first [`GpuPixel`] of the pixel buffer: one [`GpuDispatch`].
pub const PIXEL_HEADER_BYTES: u64 = std::mem::size_of::<GpuDispatch>() as u64;
