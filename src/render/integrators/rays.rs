//! Ray batches on the device: arbitrary rays in, closest hits out, through any
//! structure arbor builds (and the driver's, `rayquery`, where the device has ray
//! queries). The rays go through the render loop as a render's pixels do: the
//! `rays_<family>_<geometry>` variant of `trace.comp` ([`crate::render::dispatch::kernel`]),
//! [`crate::render::dispatch::upload`] (the scene, the structure, a pixel buffer that holds one
//! hit per ray and a ray buffer), and [`crate::render::dispatch`] (chunks of rays
//! uploaded in turn, dispatches sized to the work budget on one ring, each followed by
//! the resume passes of the traces that ran out of steps, and each chunk read back);
//! a batch's [`WavePolicy`] gives the loop its rays and takes the hits.
//!
//! Results are exact: a trace that runs out of its step budget is resumed
//! ([`crate::render::dispatch::resume`]) and ends where it would have without one; a family that
//! cannot resume (the driver's structure) makes the batch fail rather than report a
//! miss. Rays are checked first ([`check_rays`]); a bad one is an [`Error::BadRay`].

use std::time::Instant;

use crate::accel::gpu_layout::{GpuPixel, GpuRay};
use crate::accel::Accel;
use crate::error::{Error, Result};
use crate::gpu::bindings::*;
use crate::gpu::{BindingDesc, BindingKind, Context};
use crate::math::intersect::IntersectMode;
use crate::math::{Hit, Ray};
use crate::render::dispatch::kernel::{base_params, Entry, Film};
use crate::render::dispatch::pacing::Sizer;
use crate::render::dispatch::prepare::{LoopSettings, Prepared, Request};
use crate::render::dispatch::upload::GpuScene;
use crate::render::dispatch::{ChunkInput, Next, Wave, WavePolicy, Waves};
use crate::render::{KernelChoice, Traversal};
use crate::scene::Scene;

/// Most rays held on the device at once by default (96 bytes each: the ray and its hit).
pub const DEFAULT_CHUNK_RAYS: u64 = 1 << 20;

/// How a [`RayTracer`] traces.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceOptions {
    /// The ray/triangle test: watertight (default) or fast. The CPU reference takes
    /// the same choice ([`Accel::trace_cpu_with`]).
    pub intersect: IntersectMode,
    /// How dispatches are sized and kept in flight: a target GPU length, how many run
    /// ahead, and a bound on work (primitive tests and traversal steps, estimated) per
    /// dispatch; unset values take the device's defaults. The hits are the same.
    pub pacing: crate::render::dispatch::PacingChoice,
    /// Most rays held on the device at once; a larger batch is traced in chunks of
    /// this many (also kept within the device's buffer limits). Default
    /// [`DEFAULT_CHUNK_RAYS`].
    pub chunk_rays: u64,
    /// For tests: lower the per-trace step budget to this (at least
    /// `MIN_FORCED_TRACE_STEPS`), so that traces run out of steps and are resumed.
    /// The hits are the same.
    pub trace_steps: Option<u32>,
}

impl Default for TraceOptions {
    fn default() -> Self {
        TraceOptions {
            intersect: IntersectMode::Watertight,
            pacing: Default::default(),
            chunk_rays: DEFAULT_CHUNK_RAYS,
            trace_steps: None,
        }
    }
}

/// What tracing one batch cost.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BatchStats {
    /// Rays traced.
    pub rays: u64,
    /// Trace dispatches (resume passes not counted).
    pub dispatches: u32,
    /// GPU time of every dispatch, resume passes included; `None` where the device
    /// has no timestamps.
    pub gpu_ms: Option<f64>,
    /// Host wall time: checking the rays, uploads, dispatches and readback.
    pub wall_ms: f64,
    /// Rays whose trace ran out of its step budget and was resumed.
    pub resumed: u64,
    /// Dispatches of the resume kernel.
    pub resume_dispatches: u32,
}

impl BatchStats {
    /// Million rays per second of GPU time (of wall time without timestamps).
    pub fn mrays_per_s(&self) -> f64 {
        let ms = self.gpu_ms.filter(|&ms| ms > 0.0).unwrap_or(self.wall_ms);
        if ms > 0.0 {
            self.rays as f64 / (ms * 1e3)
        } else {
            0.0
        }
    }
}

/// How far from 1 a direction's length may be.
pub const UNIT_TOLERANCE: f32 = 1e-3;

/// Rejects a ray no structure traces the same on the device and the CPU: a
/// non-finite origin or direction, a zero direction or one whose length is not 1
/// (within [`UNIT_TOLERANCE`]), `tmin` negative or not finite,
/// `tmax` NaN or below `tmin` (`tmax` may be +inf). The error names the first bad ray.
pub fn check_rays(rays: &[Ray]) -> Result<()> {
    for (index, r) in rays.iter().enumerate() {
        let reason = if !r.origin.is_finite() {
            "the origin is not finite"
        } else if !r.dir.is_finite() {
            "the direction is not finite"
        } else if r.dir == glam::Vec3::ZERO {
            "the direction is zero"
        } else if (r.dir.length() - 1.0).abs() > UNIT_TOLERANCE {
            "the direction is not unit length (normalize it; ray/sphere tests assume it)"
        } else if !(r.tmin.is_finite() && r.tmin >= 0.0) {
            "tmin must be finite and at least 0"
        } else if r.tmax.is_nan() || r.tmax < r.tmin {
            "tmax must be at least tmin (and not NaN)"
        } else {
            continue;
        };
        return Err(Error::BadRay { index, reason });
    }
    Ok(())
}

/// A scene and a structure on the device, ready to trace batches of rays: the kernel
/// is compiled and the scene and structure uploaded once, in [`RayTracer::new`].
pub struct RayTracer<'a> {
    prep: Prepared<'a>,
    /// Dispatch sizes carry over from batch to batch.
    sizer: std::cell::RefCell<Sizer>,
}

impl std::fmt::Debug for RayTracer<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RayTracer")
            .field("kernel", &self.prep.variant.name)
            .field("chunk_rays", &self.prep.chunk_pixels)
            .field("pacing", &self.prep.pacing)
            .finish_non_exhaustive()
    }
}

impl<'a> RayTracer<'a> {
    /// Compiles the ray-batch kernel for `accel`'s family and the scene's geometry and
    /// uploads `scene` and `accel` (built for this scene; `rayquery` built on `ctx`
    /// with [`Accel::build_on`]). Instanced scenes are refused
    /// ([`Error::Unsupported`]): trace [`Scene::flattened`] instead.
    pub fn new(ctx: &'a Context, scene: &'a Scene, accel: &'a Accel, options: &TraceOptions) -> Result<RayTracer<'a>> {
        // A two-level structure over a flat scene is refused when its kernel is chosen.
        if scene.has_instances() {
            return Err(Error::Unsupported(format!(
                "scene {}: ray batches trace flat scenes; flatten the instances first (Scene::flattened)",
                scene.name
            )));
        }
        let settings = LoopSettings {
            kernel: KernelChoice::Specialized,
            intersect: options.intersect,
            traversal: Traversal::Single,
            trace_steps: options.trace_steps,
            resume_records: None,
            pacing: options.pacing,
            // Two texels a ray, within the device's texel-buffer view.
            pixels: options.chunk_rays.max(1).min((ctx.max_texel_elements() / 2).max(1)),
        };
        settings.check()?;
        let request = Request {
            entry: Entry::Rays,
            traces: 1,
            rays_per_sample: 1,
            spec: vec![(SPEC_LIGHTS, 0), (SPEC_MAX_DEPTH, 1)],
            // No camera: the rays come from the batch.
            params: base_params(scene, Film { width: 1, height: 1, seed: 0 }, accel),
            scene: GpuScene::new(scene),
            extra_bindings: vec![BindingDesc { binding: BINDING_RAYS, kind: BindingKind::Texel, name: "rays" }],
            chunk_most: settings.pixels,
            fit: None,
        };
        let prep = Prepared::new(ctx, scene, &settings, accel, request)?;
        let sizer = std::cell::RefCell::new(prep.sizer(1));
        Ok(RayTracer { prep, sizer })
    }

    /// The name of the compiled kernel (`rays_<family>_<geometry>`).
    pub fn kernel_name(&self) -> &str {
        &self.prep.variant.name
    }

    /// Most rays one chunk holds on the device (see [`TraceOptions::chunk_rays`]).
    pub fn chunk_rays(&self) -> u64 {
        self.prep.chunk_pixels
    }

    /// The closest hit of each ray, in order: `None` where the ray meets nothing in
    /// `(tmin, tmax]`. An empty batch gives an empty vector.
    pub fn trace(&self, rays: &[Ray]) -> Result<Vec<Option<Hit>>> {
        self.trace_stats(rays).map(|(hits, _)| hits)
    }

    /// [`RayTracer::trace`], with what the batch cost.
    pub fn trace_stats(&self, rays: &[Ray]) -> Result<(Vec<Option<Hit>>, BatchStats)> {
        let start = Instant::now();
        check_rays(rays)?;
        let mut stats = BatchStats { rays: rays.len() as u64, gpu_ms: Some(0.0), ..Default::default() };
        if rays.is_empty() {
            return Ok((Vec::new(), stats));
        }
        let prep = &self.prep;
        let chunk = prep.chunk_pixels;
        let waves = Waves {
            total_pixels: rays.len() as u64,
            chunk_pixels: chunk,
            spp: 1,
            first_sample: 0,
            window: [0, 0, chunk as u32],
            resumed: false,
        };
        let mut batch = Batch { rays, hits: Vec::with_capacity(rays.len()), scene: &prep.scene.name };
        let totals = prep.run(&mut self.sizer.borrow_mut(), waves, &mut |_, _| {}, &mut batch)?;
        stats.dispatches = totals.dispatches;
        stats.gpu_ms = totals.gpu_ms;
        stats.resumed = totals.resumes.samples;
        stats.resume_dispatches = totals.resumes.dispatches;
        stats.wall_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok((batch.hits, stats))
    }
}

/// The wave policy of a batch: each chunk's rays in, their hits out.
struct Batch<'b> {
    rays: &'b [Ray],
    hits: Vec<Option<Hit>>,
    scene: &'b str,
}

impl WavePolicy for Batch<'_> {
    fn input(&mut self, first: u64, len: u64) -> Result<ChunkInput> {
        let chunk = &self.rays[first as usize..(first + len) as usize];
        Ok(ChunkInput::Rays(
            chunk
                .iter()
                .map(|r| GpuRay {
                    origin_tmin: [r.origin.x, r.origin.y, r.origin.z, r.tmin],
                    dir_tmax: [r.dir.x, r.dir.y, r.dir.z, r.tmax],
                })
                .collect(),
        ))
    }

    fn pixels(&mut self, wave: Wave, pixels: &[GpuPixel]) -> Result<Next> {
        for (k, p) in pixels.iter().enumerate() {
            // A trace that ran out of steps is the loop's to refuse; any other must
            // have reached its end (resumed where it stopped).
            if p.prim_cost[3] & OVERFLOW_FLAG == 0 && p.radiance[3] != 1.0 {
                return Err(Error::scene(
                    self.scene.to_string(),
                    format!("ray {} of the batch was not traced to its end", wave.first + k as u64),
                ));
            }
            self.hits.push(hit_of(p));
        }
        Ok(Next::Continue)
    }
}

/// The hit the ray-batch kernel wrote into a pixel record (layout: [`GpuPixel`]).
fn hit_of(p: &GpuPixel) -> Option<Hit> {
    let prim = p.prim_cost[0];
    (prim != u32::MAX).then_some(Hit { t: p.normal_depth[3], prim, u: p.radiance[0], v: p.radiance[1] })
}

/// Traces `rays` through `accel` over `scene` on `ctx` with default options: a
/// [`RayTracer`] for one batch.
pub fn trace_rays(ctx: &Context, scene: &Scene, accel: &Accel, rays: &[Ray]) -> Result<Vec<Option<Hit>>> {
    RayTracer::new(ctx, scene, accel, &TraceOptions::default())?.trace(rays)
}
