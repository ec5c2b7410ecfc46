//! The shading tables both integrators read beyond the materials and lights
//! ([`super::upload`] writes those): the emitter table (a power-proportional CDF over
//! the area lights), the texture table and its texels, the environment map's texels
//! and its sampling distribution. Each is a run of extra rows appended to the shading
//! buffer (layout in `shaders/common/path.glsl`), so that no kernel binds a buffer
//! more for them; [`Extras::set_tables`] writes where each starts into the parameters.

use glam::Vec3;

use crate::accel::gpu_layout::GpuParams;
use crate::error::Result;
use crate::gpu::bindings::*;
use crate::scene::{Material, Scene};

/// Luminance of linear Rec. 709 RGB (the kernel's `luminance`).
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// One area light: a primitive (global numbering: triangles, then spheres) and its
/// emitted power up to a constant factor (luminance x area x sides).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Emitter {
    pub prim: u32,
    pub power: f32,
}

fn sides(m: &Material) -> f32 {
    if m.two_sided {
        2.0
    } else {
        1.0
    }
}

/// Every primitive that emits (non-zero luminance of emission, non-zero area), with
/// the power the kernel's `emitter_power` computes for it: with an emission texture,
/// the emission's luminance times the texture's mean luminance.
///
/// Numbers are those of the kernel's primitive buffers: with instancing, the scene's
/// own triangles come after every prototype's (which cannot emit).
pub fn emitters(scene: &Scene) -> Vec<Emitter> {
    emitters_with(scene, &emission_means(scene))
}

/// Per texture, the mean luminance it scales an emission by ([`Texture::mean_luminance`]),
/// once for every texture a material emits through; 0 for the others.
///
/// [`Texture::mean_luminance`]: crate::scene::Texture::mean_luminance
fn emission_means(scene: &Scene) -> Vec<f32> {
    let emitting: std::collections::BTreeSet<u32> = scene.materials.iter().filter_map(|m| m.maps.emission).collect();
    let mean = |(k, t): (usize, &crate::scene::Texture)| {
        if emitting.contains(&(k as u32)) {
            t.mean_luminance()
        } else {
            0.0
        }
    };
    scene.textures.iter().enumerate().map(mean).collect()
}

/// [`emitters`] with the emission textures' means.
fn emitters_with(scene: &Scene, means: &[f32]) -> Vec<Emitter> {
    let mut out = Vec::new();
    let stored = scene.stored_triangles() as u32;
    let first_own = stored - scene.triangles.len() as u32;
    let emits = |m: u32| {
        let m = &scene.materials[m as usize];
        let map = m.maps.emission.map_or(1.0, |t| means.get(t as usize).copied().unwrap_or(0.0));
        let l = luminance(m.emission) * map;
        (l > 0.0 && l.is_finite()).then(|| l * sides(m))
    };
    for (k, t) in scene.triangles.iter().enumerate() {
        if let Some(l) = emits(scene.tri_material[k]) {
            let [a, b, c] = t.map(|i| scene.positions[i as usize]);
            let area = 0.5 * (b - a).cross(c - a).length();
            if area > 0.0 && area.is_finite() {
                out.push(Emitter { prim: first_own + k as u32, power: l * area });
            }
        }
    }
    let nt = stored;
    for (k, s) in scene.spheres.iter().enumerate() {
        if let Some(l) = emits(s.material) {
            let area = 4.0 * std::f32::consts::PI * s.radius * s.radius;
            if area > 0.0 && area.is_finite() {
                out.push(Emitter { prim: nt + k as u32, power: l * area });
            }
        }
    }
    out
}

/// The emitter table rows: (prim bits, CDF at its start, probability, 0), and the
/// total power. The CDF is summed in f64 and each probability is the difference of
/// consecutive CDF values as f32, so that sampling and its pdf agree exactly.
pub fn emitter_rows(list: &[Emitter]) -> (Vec<[f32; 4]>, f32) {
    let total: f64 = list.iter().map(|e| f64::from(e.power)).sum();
    let mut rows = Vec::with_capacity(list.len());
    let mut acc = 0f64;
    for (k, e) in list.iter().enumerate() {
        let start = (acc / total) as f32;
        acc += f64::from(e.power);
        let end = if k + 1 == list.len() { 1.0 } else { (acc / total) as f32 };
        rows.push([f32::from_bits(e.prim), start, end - start, 0.0]);
    }
    (rows, total as f32)
}

/// Texture table rows then texels (4 per row, 0x00BBGGRR), given the first row the
/// section starts at. Returns (rows, table base row).
fn texture_rows(scene: &Scene, base: u32, means: &[f32]) -> Vec<[f32; 4]> {
    let n = scene.textures.len() as u32;
    let mut rows: Vec<[f32; 4]> = Vec::new();
    let mut next = base + n;
    let mut texel_rows: Vec<[f32; 4]> = Vec::new();
    for (t, &mean) in scene.textures.iter().zip(means) {
        // w: the mean luminance an emission texture scales its power by (`emitters`).
        // y: the width, and the wrap modes above it (at most 24 bits of width: the
        // float bits are never an infinity or NaN).
        let [wu, wv] = t.wrap.map(|w| w as u32);
        let width = t.width | wu << TEXTURE_WRAP_U_SHIFT | wv << TEXTURE_WRAP_V_SHIFT;
        rows.push([f32::from_bits(next), f32::from_bits(width), f32::from_bits(t.height), mean]);
        let words: Vec<u32> =
            t.texels.iter().map(|p| u32::from(p[0]) | u32::from(p[1]) << 8 | u32::from(p[2]) << 16).collect();
        texel_rows.extend(word_rows(&words));
        next = base + n + texel_rows.len() as u32;
    }
    rows.extend(texel_rows);
    rows
}

/// Environment texels as half floats, two texels per row (`packHalf2x16(r, g)`,
/// `packHalf2x16(b, 0)` each), values clamped to the largest half (65504).
fn env_texel_rows(texels: &[[f32; 3]]) -> Vec<[f32; 4]> {
    let h = |x: f32| u32::from(half::f16::from_f32(x.min(65504.0)).to_bits());
    let words: Vec<u32> = texels.iter().flat_map(|t| [h(t[0]) | h(t[1]) << 16, h(t[2])]).collect();
    word_rows(&words)
}

/// Environment texels as the kernel sees them (half precision), for building the
/// sampling distribution from exactly the values it looks up.
pub fn env_texels_as_seen(texels: &[[f32; 3]]) -> Vec<[f32; 3]> {
    let h = |x: f32| half::f16::from_f32(x.min(65504.0)).to_f32();
    texels.iter().map(|t| [h(t[0]), h(t[1]), h(t[2])]).collect()
}

/// Words packed 4 per row as their bits (the shading buffer is read as uint texels:
/// a word that reads as a NaN keeps its bits).
pub fn word_rows(words: &[u32]) -> Vec<[f32; 4]> {
    words
        .chunks(4)
        .map(|c| {
            let mut row = [0f32; 4];
            for (k, w) in c.iter().enumerate() {
                row[k] = f32::from_bits(*w);
            }
            row
        })
        .collect()
}

/// Floats packed 4 per row.
fn float_rows(values: &[f32]) -> Vec<[f32; 4]> {
    values
        .chunks(4)
        .map(|c| {
            let mut row = [0f32; 4];
            row[..c.len()].copy_from_slice(c);
            row
        })
        .collect()
}

/// What the path kernel reads beyond the Whitted scene data.
#[derive(Debug, Clone, Default)]
pub struct Extras {
    /// Rows appended to the shading buffer.
    pub rows: Vec<[f32; 4]>,
    /// First shading rows of the emitter table, the texture table, the environment
    /// map's texels and its distribution (0: none), as `GpuParams` names them.
    pub emitter_table: u32,
    pub texture_table: u32,
    pub env_texel_table: u32,
    pub env_distribution_table: u32,
    pub emitter_count: u32,
    pub total_power: f32,
    /// Environment map size (0 x 0 without one).
    pub env_size: (u32, u32),
}

impl Extras {
    /// Writes the tables' first rows and the emitters' total power into `p`.
    pub fn set_tables(&self, p: &mut GpuParams) {
        p.emitter_table = self.emitter_table;
        p.texture_table = self.texture_table;
        p.env_texel_table = self.env_texel_table;
        p.env_distribution_table = self.env_distribution_table;
        p.emitter_power = self.total_power;
    }
}

/// The extra shading rows for `scene`, whose Whitted rows number `base`: the emitter
/// and texture tables, and with `env` the environment map's.
pub fn extras(scene: &Scene, base: u32, env: bool) -> Result<Extras> {
    let mut ex = Extras::default();
    let means = emission_means(scene);
    let list = emitters_with(scene, &means);
    let mut next = base;
    if !list.is_empty() {
        let (rows, total) = emitter_rows(&list);
        ex.emitter_table = next;
        ex.emitter_count = list.len() as u32;
        ex.total_power = total;
        next += rows.len() as u32;
        ex.rows.extend(rows);
    }
    if !scene.textures.is_empty() {
        ex.texture_table = next;
        let rows = texture_rows(scene, next, &means);
        next += rows.len() as u32;
        ex.rows.extend(rows);
    }
    if let Some(env) = scene.environment.as_ref().filter(|_| env) {
        let seen = env_texels_as_seen(&env.texels);
        let rows = env_texel_rows(&env.texels);
        ex.env_texel_table = next;
        next += rows.len() as u32;
        ex.rows.extend(rows);
        let dist = env_distribution(env.width, env.height, &seen, env.intensity)?;
        let rows = float_rows(&dist);
        ex.env_distribution_table = next;
        ex.rows.extend(rows);
        ex.env_size = (env.width, env.height);
    }
    Ok(ex)
}

/// The environment's sampling distribution in the kernel's layout
/// ([`crate::render::integrators::envdist`]), from the texels as the kernel sees them.
fn env_distribution(w: u32, h: u32, texels: &[[f32; 3]], intensity: f32) -> Result<Vec<f32>> {
    let env = crate::scene::Environment {
        name: String::new(),
        width: w,
        height: h,
        texels: texels.to_vec(),
        rotation: 0.0,
        intensity,
    };
    Ok(crate::render::integrators::envdist::Distribution2D::from_environment(&env).gpu_rows())
}
