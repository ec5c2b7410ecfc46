//! The path integrator (`shaders/common/path.glsl`): unidirectional path tracing with
//! next-event estimation toward point and directional lights, area lights (emissive
//! triangles and spheres) and the environment map, multiple importance sampling with
//! the power heuristic, Russian roulette, Beer-Lambert absorption in glass, textures.
//!
//! The shading tables it reads beyond the scene (emitters, textures, the environment
//! map and its distribution) are built by [`crate::render::dispatch::tables`], as the
//! Whitted integrator's are. It runs the dispatches progressively (whole sample
//! waves), so that a time budget, an interruption or a checkpoint always sees every
//! pixel of a chunk with the same number of samples.

use crate::accel::gpu_layout::GpuParams;
use crate::accel::Accel;
use crate::error::Result;
use crate::gpu::bindings::*;
use crate::gpu::Context;
use crate::render::dispatch::kernel::{base_params, Entry, Film};
use crate::render::dispatch::prepare::{Prepared, Request};
use crate::render::dispatch::tables::{extras, Extras};
use crate::render::dispatch::upload::GpuScene;
use crate::render::{Control, Frame, RenderSettings, RenderStats};
use crate::scene::Scene;

/// Most pixels held on the device at once (64 bytes each).
const MAX_CHUNK_PIXELS: u64 = 1 << 21;

/// The depth from which Russian roulette may end a path (Mitsuba's default).
pub const RR_DEPTH: u32 = 5;

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
pub(crate) fn specialization(scene: &Scene, settings: &RenderSettings, ex: &Extras) -> Vec<(u32, u32)> {
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
pub(crate) fn params(scene: &Scene, settings: &RenderSettings, accel: &Accel, ex: &Extras) -> GpuParams {
    let (intensity, rotation) =
        scene.environment.as_ref().map_or((0.0, 0.0), |e| (e.intensity, e.rotation.to_radians()));
    let mut p = base_params(scene, Film::of(settings), accel);
    p.light_count = scene.lights.len() as u32;
    ex.set_tables(&mut p);
    p.env_intensity = intensity;
    p.env_rotation = rotation;
    p
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
    if settings.time_budget.is_some() || control.checkpoint.is_some() {
        sizer.limit_samples(4);
    }
    prep.render(settings, accel, &mut sizer, control, settings.time_budget)
}
