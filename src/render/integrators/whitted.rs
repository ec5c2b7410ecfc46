//! The Whitted integrator (`trace.comp`), the fast preview: camera rays; at Lambert and
//! Phong surfaces, point and directional lights with hard shadows, one area light
//! (emissive triangle or sphere) sampled by power as the path tracer does, and the
//! ambient term; mirrors; glass split into its reflected and refracted rays up to
//! [`WHITTED_SPLIT_MAX`] splits. No indirect diffuse light. Also the benchmark's probe
//! modes (camera rays only; one cosine bounce). Its settings become specialization
//! constants; the render loop ([`crate::render::dispatch`]) does the rest.

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
const MAX_CHUNK_PIXELS: u64 = 1 << 20;

fn probe(settings: &RenderSettings) -> bool {
    settings.primary_only || settings.diffuse_probe
}

/// Closest-hit traces of one sample whose glass splits up to `split` times on the
/// way from the camera, with paths of at most `depth` segments: at depth d at most
/// 2^min(d, split) rays.
pub fn closest_traces(depth: u32, split: u32) -> u64 {
    (0..depth).map(|d| 1u64 << d.min(split)).sum()
}

/// Traces one sample may run: the closest-hit rays, and at each of the at most
/// 2^split surfaces where a branch ends a shadow ray per light and one toward an area
/// light (plus one whose share of the loop budget covers the area-light search).
pub fn traces_per_sample(scene: &Scene, settings: &RenderSettings, emitters: u32, split: u32) -> u64 {
    if settings.diffuse_probe {
        2
    } else if settings.primary_only {
        1
    } else {
        shading_traces(scene.max_depth, scene.lights.len() as u64, emitters, split)
    }
}

/// [`traces_per_sample`] of a shading sample: paths of `depth` segments, `lights`
/// point and directional lights, `emitters` area lights.
fn shading_traces(depth: u32, lights: u64, emitters: u32, split: u32) -> u64 {
    let area = u64::from(emitters > 0);
    closest_traces(depth, split) + (1u64 << split) * (lights + area) + area
}

/// Rays one sample costs when sizing dispatches: the camera ray, a shadow ray per
/// light and toward an area light, and a bounce.
fn rays_per_sample(scene: &Scene, settings: &RenderSettings, emitters: u32) -> u64 {
    if settings.diffuse_probe {
        2
    } else if settings.primary_only {
        1
    } else {
        1 + scene.lights.len() as u64 + u64::from(emitters > 0) + 1
    }
}

/// Whether shadow rays are traced (not in the probe modes, and only with lights).
fn lights_used(scene: &Scene, settings: &RenderSettings) -> u32 {
    if !probe(settings) && !scene.lights.is_empty() {
        scene.lights.len() as u32
    } else {
        0
    }
}

/// The integrator's specialization constants (the loop adds the shared ones, and the
/// glass split that fits).
fn specialization(scene: &Scene, settings: &RenderSettings, ex: &Extras) -> Vec<(u32, u32)> {
    let probe = probe(settings);
    vec![
        (SPEC_LIGHTS, lights_used(scene, settings)),
        (SPEC_MAX_DEPTH, if probe { 1 } else { scene.max_depth }),
        (SPEC_DIFFUSE_PROBE, u32::from(settings.diffuse_probe)),
        (SPEC_EMITTERS, ex.emitter_count),
        (SPEC_TEXTURES, u32::from(!probe && !scene.textures.is_empty())),
    ]
}

/// The uniform parameters: camera, scene box, counts, background, the area lights'
/// and textures' tables.
fn params(scene: &Scene, settings: &RenderSettings, accel: &Accel, ex: &Extras) -> GpuParams {
    let mut p = base_params(scene, Film::of(settings), accel);
    p.light_count = lights_used(scene, settings);
    p.ambient = scene.ambient;
    ex.set_tables(&mut p);
    p
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
    let mut gs = GpuScene::new(scene);
    let ex = if probe(settings) { Extras::default() } else { extras(scene, gs.shading.len() as u32, false)? };
    gs.shading.extend_from_slice(&ex.rows);
    // Glass and blended panes split a ray in two.
    let glass = !probe(settings)
        && scene.materials.iter().any(|m| m.is_smooth_glass() || m.alpha_mode == crate::scene::AlphaMode::Blend);
    let (depth, lights, emitters) = (scene.max_depth, scene.lights.len() as u64, ex.emitter_count);
    let request = Request {
        // The probe modes run the lean probe kernel (trace.comp, probe_main).
        entry: if probe(settings) { Entry::Probe } else { Entry::Whitted },
        traces: traces_per_sample(scene, settings, emitters, 0),
        rays_per_sample: rays_per_sample(scene, settings, emitters),
        spec: specialization(scene, settings, &ex),
        params: params(scene, settings, accel, &ex),
        scene: gs,
        extra_bindings: Vec::new(),
        chunk_most: MAX_CHUNK_PIXELS,
        // Glass splits as deep as the driver's loop limit allows, never refused for it.
        fit: glass.then(|| -> crate::render::dispatch::prepare::Fit {
            Box::new(move |fits| {
                let traces = |s| shading_traces(depth, lights, emitters, s);
                let split = (0..=WHITTED_SPLIT_MAX).rev().find(|&s| fits(traces(s))).unwrap_or(0);
                (traces(split), vec![(SPEC_WHITTED_SPLIT, split)])
            })
        }),
    };
    let prep = Prepared::new(ctx, scene, &settings.loop_settings(), accel, request)?;
    let mut sizer = prep.sizer(settings.spp);
    prep.render(settings, accel, &mut sizer, Control::progress_only(progress), None)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rays at depth d: 2^min(d, split); without a split, one a segment.
    #[test]
    fn closest_traces_count_the_branches() {
        assert_eq!(closest_traces(8, 0), 8);
        assert_eq!(closest_traces(1, 3), 1);
        assert_eq!(closest_traces(4, 3), 1 + 2 + 4 + 8);
        assert_eq!(closest_traces(8, 3), 1 + 2 + 4 + 8 * 5);
        assert_eq!(closest_traces(16, 2), 1 + 2 + 4 * 14);
        // Shadow rays where each of the 2^split branches ends, plus the area search.
        assert_eq!(shading_traces(8, 2, 0, 0), 8 + 2);
        assert_eq!(shading_traces(8, 2, 5, 3), 47 + 8 * 3 + 1);
    }
}
