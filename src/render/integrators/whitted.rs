//! The Whitted integrator (`trace.comp`): camera rays, shadow rays toward point and
//! directional lights, mirror and glass, plus the benchmark's probe modes (camera
//! rays only; one cosine bounce). Its settings become specialization constants; the
//! render loop ([`crate::render::dispatch`]) does the rest.

use std::time::Instant;

use crate::accel::gpu_layout::GpuParams;
use crate::accel::Accel;
use crate::error::Result;
use crate::gpu::bindings::*;
use crate::gpu::Context;
use crate::render::dispatch::prepare::{Prepared, Request};
use crate::render::dispatch::upload::GpuScene;
use crate::render::dispatch::{Next, Waves};
use crate::render::{Frame, RenderSettings, RenderStats};
use crate::scene::Scene;

/// Most pixels held on the device at once (64 bytes each).
const MAX_CHUNK_PIXELS: u64 = 1 << 20;

/// Traces one sample may run: at most `max_depth` closest-hit rays and one shadow
/// ray per light.
pub fn traces_per_sample(scene: &Scene, settings: &RenderSettings) -> u64 {
    if settings.diffuse_probe {
        2
    } else if settings.primary_only {
        1
    } else {
        u64::from(scene.max_depth) + scene.lights.len() as u64
    }
}

/// Rays one sample costs when sizing dispatches: the camera ray, a shadow ray per
/// light and a bounce.
fn rays_per_sample(scene: &Scene, settings: &RenderSettings) -> u64 {
    if settings.diffuse_probe {
        2
    } else if settings.primary_only {
        1
    } else {
        1 + scene.lights.len() as u64 + 1
    }
}

/// Whether shadow rays are traced (not in the probe modes, and only with lights).
fn lights_used(scene: &Scene, settings: &RenderSettings) -> u32 {
    let probe = settings.primary_only || settings.diffuse_probe;
    if !probe && !scene.lights.is_empty() {
        scene.lights.len() as u32
    } else {
        0
    }
}

/// The integrator's specialization constants (the loop adds the shared ones).
fn specialization(scene: &Scene, settings: &RenderSettings) -> Vec<(u32, u32)> {
    let probe = settings.primary_only || settings.diffuse_probe;
    vec![
        (SPEC_LIGHTS, lights_used(scene, settings)),
        (SPEC_MAX_DEPTH, if probe { 1 } else { scene.max_depth }),
        (SPEC_DIFFUSE_PROBE, u32::from(settings.diffuse_probe)),
        // The probe modes run the lean probe kernel (trace.comp, probe_main).
        (SPEC_INTEGRATOR, if probe { 2 } else { 0 }),
    ]
}

/// The uniform parameters: camera, scene box, counts, background.
fn params(scene: &Scene, settings: &RenderSettings, accel: &Accel) -> GpuParams {
    let mut p =
        crate::render::dispatch::kernel::base_params(scene, (settings.width, settings.height), settings.seed, accel);
    p.counts[0] = lights_used(scene, settings);
    p.background[3] = scene.ambient;
    p
}

/// Renders `scene` with an already built structure.
pub fn render_with(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    accel: &Accel,
    mut progress: impl FnMut(u64, u64),
) -> Result<(Frame, RenderStats)> {
    settings.check()?;
    let request = Request {
        prefix: "trace",
        traces: traces_per_sample(scene, settings),
        rays_per_sample: rays_per_sample(scene, settings),
        spec: specialization(scene, settings),
        params: params(scene, settings, accel),
        scene: GpuScene::new(scene),
        extra_bindings: Vec::new(),
        chunk_most: MAX_CHUNK_PIXELS,
    };
    let prep = Prepared::new(ctx, scene, &settings.loop_settings(), accel, request)?;
    let start = Instant::now();
    let win = settings.window();
    let mut frame = Frame::new(win.width(), win.height())?;
    let mut overflow = 0u64;
    let mut resumer = prep.resumer()?;
    let mut sizer = prep.sizer(settings.spp);
    let waves = Waves::new(settings, prep.chunk_pixels);
    let pixels = prep.bound.pixels();
    let (totals, _) =
        prep.run((&mut resumer, &mut sizer), waves, settings.resume.as_deref(), &mut progress, |_, wave| {
            if wave.complete {
                overflow +=
                    crate::render::dispatch::readback::read_chunk(ctx, pixels, &mut frame, wave.first, wave.len)?;
            }
            Ok(Next::Continue)
        })?;
    drop(resumer);
    let stats = prep.finish((settings, accel), &frame, &totals, (overflow, start))?;
    Ok((frame, stats))
}
