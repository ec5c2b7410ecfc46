//! The path integrator (`shaders/common/path.glsl`): unidirectional path tracing with
//! next-event estimation toward point and directional lights, area lights (emissive
//! triangles and spheres) and the environment map, multiple importance sampling with
//! the power heuristic, Russian roulette, Beer-Lambert absorption in glass, textures.
//!
//! This module writes what the kernel reads beyond the scene: the emitter table
//! (power-proportional CDF), the texture table and texels, the environment's texels
//! and its sampling distribution, all as extra rows of the shading buffer (layout in
//! `shaders/common/path.glsl`), so that the kernel binds no buffer more than the
//! Whitted one; and it runs the dispatches progressively (whole sample waves), so that
//! a time budget, an interruption or a checkpoint always sees every pixel of a chunk
//! with the same number of samples.

use std::time::Instant;

use glam::Vec3;

use crate::accel::gpu_layout::GpuParams;
use crate::accel::Accel;
use crate::error::Result;
use crate::gpu::bindings::*;
use crate::gpu::Context;
use crate::render::dispatch::kernel::Entry;
use crate::render::dispatch::prepare::{Prepared, Request};
use crate::render::dispatch::readback::Steer;
use crate::render::dispatch::upload::GpuScene;
use crate::render::dispatch::{Next, Wave};
use crate::render::{Frame, RenderSettings, RenderStats};
use crate::scene::{Material, Scene};

/// Most pixels held on the device at once (64 bytes each).
const MAX_CHUNK_PIXELS: u64 = 1 << 21;

/// The depth from which Russian roulette may end a path (Mitsuba's default).
pub const RR_DEPTH: u32 = 5;

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
        for chunk in words.chunks(4) {
            let mut row = [0f32; 4];
            for (k, w) in chunk.iter().enumerate() {
                // The top byte is zero, so the bits are never a NaN.
                row[k] = f32::from_bits(*w);
            }
            texel_rows.push(row);
        }
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

/// Environment texels as the kernel sees them (half precision), for building the
/// sampling distribution from exactly the values it looks up.
pub fn env_texels_as_seen(texels: &[[f32; 3]]) -> Vec<[f32; 3]> {
    let h = |x: f32| half::f16::from_f32(x.min(65504.0)).to_f32();
    texels.iter().map(|t| [h(t[0]), h(t[1]), h(t[2])]).collect()
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
/// ([`crate::render::envdist`]), from the texels as the kernel sees them.
fn env_distribution(w: u32, h: u32, texels: &[[f32; 3]], intensity: f32) -> Result<Vec<f32>> {
    let env = crate::scene::Environment {
        name: String::new(),
        width: w,
        height: h,
        texels: texels.to_vec(),
        rotation: 0.0,
        intensity,
    };
    Ok(crate::render::envdist::Distribution2D::from_environment(&env).gpu_rows())
}

/// The scene's maximum depth, or the settings' override.
pub fn max_depth(scene: &Scene, settings: &RenderSettings) -> u32 {
    settings.max_depth.unwrap_or(scene.max_depth)
}

/// Shadow rays one path vertex may trace: one per point or directional light, one
/// toward an area light, one toward the environment map.
fn shadow_rays(scene: &Scene, ex: &Extras) -> u64 {
    scene.lights.len() as u64 + u64::from(ex.emitter_count > 0) + u64::from(ex.env_size.0 > 0)
}

/// Traces one sample may run, plus one whose share of the loop budget covers the
/// binary searches of light and environment sampling (at most 32 + 2 x 32 steps a
/// vertex).
pub fn traces_per_sample(scene: &Scene, settings: &RenderSettings, ex: &Extras) -> u64 {
    u64::from(max_depth(scene, settings)) * (1 + shadow_rays(scene, ex)) + 1
}

/// Rays one sample costs when sizing dispatches: a typical path of three segments.
fn rays_per_sample(scene: &Scene, settings: &RenderSettings, ex: &Extras) -> u64 {
    u64::from(max_depth(scene, settings).min(3)) * (1 + shadow_rays(scene, ex))
}

/// The integrator's specialization constants (the loop adds the shared ones).
fn specialization(scene: &Scene, settings: &RenderSettings, ex: &Extras) -> Vec<(u32, u32)> {
    vec![
        (SPEC_LIGHTS, scene.lights.len() as u32),
        (SPEC_MAX_DEPTH, max_depth(scene, settings)),
        (SPEC_DIFFUSE_PROBE, 0),
        (SPEC_EMITTERS, ex.emitter_count),
        (SPEC_ENV_WIDTH, ex.env_size.0),
        (SPEC_ENV_HEIGHT, ex.env_size.1.max(1)),
        (SPEC_TEXTURES, u32::from(!scene.textures.is_empty())),
        (SPEC_MIS, settings.mis.spec()),
        (SPEC_RR_DEPTH, RR_DEPTH),
    ]
}

/// The uniform parameters: the shared ones, every light, the extras' tables and the
/// environment's intensity and rotation (no ambient term).
fn params(scene: &Scene, settings: &RenderSettings, accel: &Accel, ex: &Extras) -> GpuParams {
    let (intensity, rotation) =
        scene.environment.as_ref().map_or((0.0, 0.0), |e| (e.intensity, e.rotation.to_radians()));
    let mut p =
        crate::render::dispatch::kernel::base_params(scene, (settings.width, settings.height), settings.seed, accel);
    p.light_count = scene.lights.len() as u32;
    ex.set_tables(&mut p);
    p.env_intensity = intensity;
    p.env_rotation = rotation;
    p
}

/// Called with the image so far at each checkpoint.
pub type CheckpointWriter<'a> = Box<dyn FnMut(&Frame) -> Result<()> + 'a>;

/// What a progressive render is told from outside: progress, interruption and
/// checkpoints.
pub struct Control<'a> {
    /// `(done, total)` pixel-samples after every dispatch.
    pub progress: Box<dyn FnMut(u64, u64) + 'a>,
    /// Polled after every sample wave: true stops the render; the image so far is
    /// returned.
    pub interrupted: Box<dyn Fn() -> bool + 'a>,
    /// Every so many seconds (checked after each wave), the image so far.
    pub checkpoint: Option<(f64, CheckpointWriter<'a>)>,
}

impl std::fmt::Debug for Control<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Control").field("checkpoint", &self.checkpoint.as_ref().map(|c| c.0)).finish_non_exhaustive()
    }
}

impl<'a> Control<'a> {
    /// Progress only: never interrupted, no checkpoints.
    pub fn progress_only(progress: impl FnMut(u64, u64) + 'a) -> Control<'a> {
        Control { progress: Box::new(progress), interrupted: Box::new(|| false), checkpoint: None }
    }
}

/// Renders `scene` with an already built structure.
pub fn render_with(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    accel: &Accel,
    control: Control<'_>,
) -> Result<(Frame, RenderStats)> {
    settings.check()?;
    let Control { mut progress, interrupted, checkpoint } = control;
    let mut gs = GpuScene::new(scene);
    let ex = extras(scene, gs.shading.len() as u32, true)?;
    gs.shading.extend_from_slice(&ex.rows);
    let request = Request {
        entry: Entry::Path,
        traces: traces_per_sample(scene, settings, &ex),
        rays_per_sample: rays_per_sample(scene, settings, &ex),
        spec: specialization(scene, settings, &ex),
        params: params(scene, settings, accel, &ex),
        scene: gs,
        extra_bindings: Vec::new(),
        chunk_most: MAX_CHUNK_PIXELS,
        fit: None,
    };
    let prep = Prepared::new(ctx, scene, &settings.loop_settings(), accel, request)?;
    let mut sizer = prep.sizer(settings.spp);
    // Short waves keep a time budget, an interruption and checkpoints responsive.
    if settings.time_budget.is_some() || checkpoint.is_some() {
        sizer.limit_samples(4);
    }
    let mut steer = Steering {
        interrupted,
        checkpoint,
        budget: settings.time_budget.map(|b| (b, settings.window().pixels())),
        last_checkpoint: Instant::now(),
        chunk_started: Instant::now(),
    };
    prep.render((settings, accel), &mut sizer, &mut *progress, &mut steer)
}

/// What the path integrator says between waves: stop when interrupted, a checkpoint
/// every so often, and the next chunk once this one's share of the time budget is
/// spent.
struct Steering<'a> {
    interrupted: Box<dyn Fn() -> bool + 'a>,
    checkpoint: Option<(f64, CheckpointWriter<'a>)>,
    /// The time budget (seconds) and the pixels it is shared among.
    budget: Option<(f64, u64)>,
    last_checkpoint: Instant,
    chunk_started: Instant,
}

impl Steering<'_> {
    /// The next chunk once this one (of `len` pixels) has spent its share of the budget.
    fn within_budget(&self, len: u64) -> Next {
        match self.budget {
            Some((budget, total))
                if self.chunk_started.elapsed().as_secs_f64() >= budget * len as f64 / total as f64 =>
            {
                Next::NextChunk
            }
            _ => Next::Continue,
        }
    }
}

impl Steer for Steering<'_> {
    fn started(&mut self) {
        self.last_checkpoint = Instant::now();
        self.chunk_started = Instant::now();
    }

    fn wave(&mut self, wave: Wave) -> Next {
        if (self.interrupted)() {
            return Next::Stop;
        }
        if let Some((every, _)) = &self.checkpoint {
            if self.last_checkpoint.elapsed().as_secs_f64() >= *every {
                return Next::ReadBack;
            }
        }
        self.within_budget(wave.len)
    }

    fn stored(&mut self, frame: &Frame, wave: Wave) -> Result<Next> {
        if wave.complete {
            self.chunk_started = Instant::now();
            return Ok(if (self.interrupted)() { Next::Stop } else { Next::Continue });
        }
        if let Some((_, write)) = self.checkpoint.as_mut() {
            write(frame)?;
            self.last_checkpoint = Instant::now();
        }
        Ok(self.within_budget(wave.len))
    }
}
