//! The one preparation step of every kernel run (the Whitted and path integrators, the
//! benchmark's probes, ray batches): the kernel variant for the structure's family and
//! the scene's geometry, the loop bounds that keep each invocation within the driver's
//! limits, the specialization constants every integrator shares plus its own, the
//! kernel itself (timed apart: on lavapipe this is the shader compile), the uploads,
//! and the sizes of chunks and dispatches.

use std::time::Instant;

use super::kernel::{self, Entry, LoopBounds, Variant};
use super::pacing::{Pacing, Sizer};
use super::readback::FrameWaves;
use super::resume::Resumer;
use super::upload::{self, Bound, GpuScene};
use super::{DispatchTotals, LoopInput, PacingChoice, WavePolicy, Waves};
use crate::accel::gpu_layout::GpuParams;
use crate::accel::{Accel, GpuImage};
use crate::error::{Error, Result};
use crate::gpu::bindings::*;
use crate::gpu::{BindingDesc, Context, Kernel};
use crate::math::intersect::IntersectMode;
use crate::render::{Control, Frame, KernelChoice, RenderSettings, RenderStats, Traversal};
use crate::scene::Scene;

/// What the loop takes of a render's settings; ray batches give their own
/// ([`RenderSettings::loop_settings`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopSettings {
    /// The specialised kernel, or the general one.
    pub kernel: KernelChoice,
    /// Ray/triangle test: watertight or fast.
    pub intersect: IntersectMode,
    /// Traversal of coherent rays in the BVH kernels.
    pub traversal: Traversal,
    /// For tests: a lower per-trace step budget.
    pub trace_steps: Option<u32>,
    /// For tests: at most this many resume records a pass.
    pub resume_records: Option<u32>,
    /// How dispatches are sized and kept in flight.
    pub pacing: PacingChoice,
    /// Pixels (or rays) of the work: a chunk holds no more.
    pub pixels: u64,
}

impl LoopSettings {
    /// Rejects values no loop takes.
    pub fn check(&self) -> Result<()> {
        Pacing::check(&self.pacing)?;
        if let Some(n) = self.trace_steps {
            let least = MIN_FORCED_TRACE_STEPS;
            if n < least {
                return Err(Error::Usage(format!("--trace-steps must be at least {least}, got {n}")));
            }
        }
        Ok(())
    }
}

impl RenderSettings {
    /// What the render loop takes of these settings.
    pub fn loop_settings(&self) -> LoopSettings {
        LoopSettings {
            kernel: self.kernel,
            intersect: self.intersect,
            traversal: self.traversal,
            trace_steps: self.trace_steps,
            resume_records: self.resume_records,
            pacing: self.pacing,
            pixels: self.window().pixels(),
        }
    }
}

/// What an integrator asks of the loop.
pub struct Request {
    /// What the kernel runs: an integrator, the probe or ray batches.
    pub entry: Entry,
    /// Traces one sample may run (each gets its share of the loop limit).
    pub traces: u64,
    /// Rays one sample typically costs, to size dispatches from the structure's cost.
    pub rays_per_sample: u64,
    /// The integrator's own specialization constants (lights, depth, tables; the loop
    /// adds the entry's).
    pub spec: Vec<(u32, u32)>,
    /// The uniform parameters.
    pub params: GpuParams,
    /// The scene as the kernel reads it, with the integrator's extra shading rows.
    pub scene: GpuScene,
    /// Bindings beyond the variant's (the ray buffer of batches).
    pub extra_bindings: Vec<BindingDesc>,
    /// Most pixels (or rays) a chunk holds; also kept within the device's buffers.
    pub chunk_most: u64,
    /// For an integrator whose work per sample can shrink to fit the driver's loop
    /// limit: given whether a number of traces a sample fits, the traces it will run
    /// (replacing `traces`) and the specialization constants that say so.
    pub fit: Option<Fit>,
}

/// See [`Request::fit`].
pub type Fit = Box<dyn Fn(&dyn Fn(u64) -> bool) -> (u64, Vec<(u32, u32)>)>;

impl std::fmt::Debug for Request {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Request")
            .field("entry", &self.entry)
            .field("traces", &self.traces)
            .field("spec", &self.spec)
            .field("fit", &self.fit.is_some())
            .finish_non_exhaustive()
    }
}

/// A kernel ready to run, with its buffers bound.
pub struct Prepared<'a> {
    pub ctx: &'a Context,
    pub scene: &'a Scene,
    pub image: GpuImage<'a>,
    pub entry: Entry,
    pub variant: Variant,
    pub spec: Vec<(u32, u32)>,
    pub bounds: LoopBounds,
    pub kernel: Kernel,
    pub bound: Bound,
    /// Host milliseconds to create the kernel.
    pub kernel_ms: f64,
    /// Traces one sample may run.
    pub traces: u64,
    /// Pixels the pixel buffer holds.
    pub chunk_pixels: u64,
    /// The work budget's units one sample of a pixel costs.
    pub cost_per_sample: u64,
    /// Most samples one dispatch may run within the driver's loop limit.
    pub most_samples: Option<u32>,
    pub pacing: Pacing,
    /// For tests: at most this many resume records a pass.
    pub resume_records: Option<u32>,
}

impl std::fmt::Debug for Prepared<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Prepared").field("kernel", &self.variant.name).field("pacing", &self.pacing).finish()
    }
}

/// The specialization constants every kernel shares: the structure's stack,
/// the intersection test, the primitive counts, the material kinds, packets.
fn shared_spec(scene: &Scene, settings: &LoopSettings, image: &GpuImage) -> Vec<(u32, u32)> {
    vec![
        (SPEC_STACK_SIZE, image.stack_size),
        (SPEC_INTERSECT, settings.intersect.spec()),
        (SPEC_TRIANGLE_COUNT, scene.triangles.len() as u32),
        (SPEC_SPHERE_COUNT, scene.spheres.len() as u32),
        (SPEC_MATERIAL_KINDS, kernel::material_kinds(scene, settings.kernel)),
        (SPEC_PACKET, kernel::packet_spec(settings.traversal, image)),
        (SPEC_ALPHA, upload::alpha_spec(scene)),
        (SPEC_VERTEX_COLORS, u32::from(scene.has_vertex_colors())),
    ]
}

impl<'a> Prepared<'a> {
    /// Prepares `request` for `scene` traced through `accel` with `settings`.
    pub fn new(
        ctx: &'a Context,
        scene: &'a Scene,
        settings: &LoopSettings,
        accel: &'a Accel,
        request: Request,
    ) -> Result<Prepared<'a>> {
        kernel::check_subgroups(ctx)?;
        let image = accel.gpu_image(scene).map_err(|e| Error::scene(scene.name.clone(), e.to_string()))?;
        let mut request = request;
        if let Some(fit) = request.fit.take() {
            let (traces, spec) = fit(&|t| LoopBounds::fits(ctx, &image, t));
            request.traces = traces;
            request.spec.extend(spec);
        }
        let traces = request.traces;
        let bounds = LoopBounds::new(ctx, scene, &image, traces, settings.trace_steps)?;
        let entry = request.entry;
        let mut variant = Variant::new(entry, scene, settings.kernel, &image, &bounds)?;
        variant.bindings.extend(request.extra_bindings);
        let most_samples = bounds.samples_within_limit(ctx, scene, traces)?;
        let mut spec = request.spec;
        spec.push((SPEC_INTEGRATOR, entry.spec()));
        spec.extend(shared_spec(scene, settings, &image));
        let compile = Instant::now();
        let mut kernel = ctx.create_kernel(&variant.name, variant.spirv, &variant.bindings, &spec, 0)?;
        let kernel_ms = compile.elapsed().as_secs_f64() * 1e3;
        let chunk_pixels = kernel::chunk_pixels(ctx, settings.pixels.max(1), request.chunk_most);
        let bound = upload::bind_all(
            ctx,
            &mut kernel,
            &variant.bindings,
            &request.params,
            &request.scene,
            &image,
            chunk_pixels,
        )?;
        let pacing = Pacing::for_device(ctx, &settings.pacing);
        Ok(Prepared {
            ctx,
            scene,
            cost_per_sample: image.cost_per_ray.saturating_mul(request.rays_per_sample.max(1)),
            image,
            entry,
            variant,
            spec,
            bounds,
            kernel,
            bound,
            kernel_ms,
            traces,
            chunk_pixels,
            most_samples,
            pacing,
            resume_records: settings.resume_records,
        })
    }

    /// What the resume passes take of this kernel.
    pub fn resume_source(&self) -> super::resume::ResumeSource<'_> {
        super::resume::ResumeSource {
            ctx: self.ctx,
            scene: self.scene,
            image: &self.image,
            variant: &self.variant,
            spec: &self.spec,
            bound: &self.bound,
            bounds: self.bounds,
            traces: self.traces,
            chunk_pixels: self.chunk_pixels,
            resume_records: self.resume_records,
        }
    }

    /// A sizer for `spp` samples a pixel in chunks of this kernel's size.
    pub fn sizer(&self, spp: u32) -> Sizer {
        Sizer::new(&self.pacing, self.chunk_pixels, spp, self.cost_per_sample, self.most_samples)
    }

    /// Runs the loop ([`super::run`]) over `waves` with `policy`, and its resume passes;
    /// then checks the validation layer and refuses work whose traces ran out of steps
    /// in a family that cannot resume them.
    pub fn run(
        &self,
        sizer: &mut Sizer,
        waves: Waves,
        progress: &mut dyn FnMut(u64, u64),
        policy: &mut dyn WavePolicy,
    ) -> Result<DispatchTotals> {
        // The resume passes of this kernel (created only if a trace stops).
        let mut resumer = Resumer::new(self.resume_source())?;
        let input = LoopInput {
            ctx: self.ctx,
            kernel: &self.kernel,
            resumer: &mut resumer,
            pixel_buf: self.bound.pixels(),
            ray_buf: self.bound.rays(),
            waves,
            sizer,
            in_flight: self.pacing.in_flight,
            target_ms: self.pacing.target_ms,
            tree_steps: self.bounds.steps as u32,
        };
        let totals = super::run(input, progress, policy)?;
        drop(resumer);
        self.ctx.check_validation()?;
        self.check_overflow(totals.overflow)?;
        Ok(totals)
    }

    /// Refuses a loop in which `overflow` pixels (or rays: the entry's unit) ran out of
    /// traversal steps, in a family that cannot resume a trace.
    fn check_overflow(&self, overflow: u64) -> Result<()> {
        if overflow == 0 {
            return Ok(());
        }
        let entry = self.entry;
        let result = if entry == Entry::Rays { "no hits are returned" } else { "nothing was written" };
        Err(Error::scene(
            self.scene.name.clone(),
            format!(
                "{overflow} {} needed more than {} traversal steps per ray (the per-trace budget on {}) in a structure that cannot resume a trace; their results would be wrong, so {result}",
                entry.unit(),
                self.bounds.steps,
                self.ctx.info().name
            ),
        ))
    }

    /// Renders `settings`' window and samples into a frame, told from outside by
    /// `control` and, with `budget`, moving on once each chunk's share of that many
    /// seconds is spent ([`FrameWaves`] decides between waves); the render's figures.
    /// The set-up and end every integrator shares.
    pub fn render(
        &self,
        settings: &RenderSettings,
        accel: &Accel,
        sizer: &mut Sizer,
        control: Control<'_>,
        budget: Option<f64>,
    ) -> Result<(Frame, RenderStats)> {
        let start = Instant::now();
        let win = settings.window();
        let frame = Frame::new(win.width(), win.height())?;
        let Control { mut progress, interrupted, checkpoint } = control;
        let mut policy = FrameWaves {
            frame,
            resume: settings.resume.as_deref(),
            interrupted,
            checkpoint,
            budget: budget.map(|b| (b, win.pixels())),
            last_checkpoint: Instant::now(),
            chunk_started: Instant::now(),
        };
        let totals = self.run(sizer, Waves::new(settings, self.chunk_pixels), &mut *progress, &mut policy)?;
        let frame = policy.frame;
        let wall_ms = start.elapsed().as_secs_f64() * 1e3;
        let stats = RenderStats::new(self, settings, accel.stats(self.scene), &frame, &totals, wall_ms);
        Ok((frame, stats))
    }
}
