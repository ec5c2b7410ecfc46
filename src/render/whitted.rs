//! The Whitted integrator (`trace.comp`): camera rays, shadow rays toward point and
//! directional lights, mirror and glass, plus the benchmark's probe modes (camera
//! rays only; one cosine bounce). Its settings become specialization constants; the
//! shared parts do the rest: [`super::kernel`] (variant and loop bounds),
//! [`super::upload`], [`super::dispatch`] and [`super::readback`].

use std::time::Instant;

use super::dispatch::{self, Waves};
use super::kernel::{LoopBounds, Variant};
use super::resume::Resumer;
use super::upload::{self, GpuScene};
use super::{Frame, RenderSettings, RenderStats};
use crate::accel::gpu_layout::GpuParams;
use crate::accel::{Accel, GpuImage};
use crate::error::{Error, Result};
use crate::gpu::bindings::*;
use crate::gpu::Context;
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

/// The kernel's specialization constants.
fn specialization(scene: &Scene, settings: &RenderSettings, image: &GpuImage, bounds: &LoopBounds) -> Vec<(u32, u32)> {
    let probe = settings.primary_only || settings.diffuse_probe;
    vec![
        (SPEC_LIGHTS, lights_used(scene, settings)),
        (SPEC_MAX_DEPTH, if probe { 1 } else { scene.max_depth }),
        (SPEC_STACK_SIZE, image.stack_size),
        (SPEC_TREE_STEPS, bounds.steps as u32),
        (SPEC_BRUTE_UNROLL, bounds.unroll),
        (SPEC_INTERSECT, settings.intersect.spec()),
        (SPEC_DIFFUSE_PROBE, u32::from(settings.diffuse_probe)),
        (SPEC_TRIANGLE_COUNT, scene.triangles.len() as u32),
        (SPEC_SPHERE_COUNT, scene.spheres.len() as u32),
        // The probe modes run the lean probe kernel (trace.comp, probe_main).
        (SPEC_INTEGRATOR, if probe { 2 } else { 0 }),
        (SPEC_MATERIAL_KINDS, super::kernel::material_kinds(scene, settings)),
        (SPEC_PACKET, super::kernel::packet_spec(settings, image)),
    ]
}

/// The uniform parameters: camera, scene box, counts, background.
fn params(scene: &Scene, settings: &RenderSettings, accel: &Accel) -> GpuParams {
    let mut p = super::kernel::base_params(scene, settings, accel);
    p.counts[0] = lights_used(scene, settings);
    p.background[3] = scene.ambient;
    p
}

/// How the image is cut into dispatches on `ctx`.
fn waves(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    image: &GpuImage,
    bounds: &LoopBounds,
) -> Result<Waves> {
    let total_pixels = settings.window().pixels();
    let chunk_pixels = super::kernel::chunk_pixels(ctx, total_pixels, MAX_CHUNK_PIXELS);
    let cost = image.cost_per_ray * rays_per_sample(scene, settings);
    let (px_per, mut spp_per) = dispatch::dispatch_shape(chunk_pixels, settings.spp, cost, settings.dispatch_budget);
    if let Some(most) = bounds.samples_within_limit(ctx, scene, traces_per_sample(scene, settings))? {
        spp_per = spp_per.min(most).max(1);
    }
    Ok(Waves::new(settings, chunk_pixels, px_per, spp_per))
}

/// Renders `scene` with an already built structure.
pub fn render_with(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    accel: &Accel,
    progress: impl FnMut(u64, u64),
) -> Result<(Frame, RenderStats)> {
    settings.check()?;
    super::kernel::check_subgroups(ctx)?;
    let image = accel.gpu_image(scene).map_err(|e| Error::scene(scene.name.clone(), e.to_string()))?;
    let variant = Variant::new("trace", scene, settings, &image)?;
    let traces = traces_per_sample(scene, settings);
    let bounds = LoopBounds::new(ctx, scene, &image, traces, settings.trace_steps)?;
    let spec = specialization(scene, settings, &image, &bounds);
    let compile = Instant::now();
    let mut kernel = ctx.create_kernel(&variant.name, variant.spirv, &variant.bindings, &spec, 0)?;
    let kernel_ms = compile.elapsed().as_secs_f64() * 1e3;

    let start = Instant::now();
    let waves = waves(ctx, scene, settings, &image, &bounds)?;
    let gs = GpuScene::new(scene);
    let p = params(scene, settings, accel);
    let bound = upload::bind_all(ctx, &mut kernel, &variant.bindings, &p, &gs, &image, waves.chunk_pixels)?;
    let win = settings.window();
    let mut frame = Frame::new(win.width(), win.height())?;
    let mut overflow = 0u64;
    let resume = settings.resume.as_deref();
    let mut resumer = Resumer::new(
        ctx,
        settings,
        &scene.name,
        (&variant, &spec),
        &bound,
        &image,
        (traces, bounds.steps),
        waves.pixels_per_dispatch,
    )?;
    let totals =
        dispatch::run(ctx, (&kernel, &mut resumer), bound.pixels(), &waves, resume, progress, |first, len| {
            overflow += super::readback::read_chunk(ctx, bound.pixels(), &mut frame, first, len)?;
            Ok(())
        })?;
    drop(resumer);
    ctx.check_validation()?;
    super::kernel::check_overflow(ctx, scene, &bounds, overflow)?;
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    let build = accel.stats(scene);
    let mut stats = RenderStats::new(ctx, scene, settings, &frame, build, variant.name, bound.names, totals, wall_ms);
    stats.kernel_ms = kernel_ms + totals.resumes.kernel_ms;
    Ok((frame, stats))
}
