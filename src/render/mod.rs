//! From a scene and a structure to pixels, in folders that show the stages:
//!
//! - [`dispatch`]: the render loop. One preparation step (kernel choice and
//!   specialization, uploads, loop bounds, the resumer) and one dispatch loop (chunks,
//!   sample waves, dispatches sized by the device and kept in flight), shared by every
//!   integrator and by ray batches;
//! - [`integrators`]: what a sample does: Whitted (and the benchmark's probes), path
//!   tracing, ray batches;
//! - [`output`]: what a render leaves: images, AOVs, heatmaps, parts and their merge,
//!   comparisons, timeline pictures;
//!
//! with [`gpu`] (the entry points), [`cpu`] (the CPU reference) and [`cracks`].

#![forbid(unsafe_code)]

pub mod cpu;
pub mod cracks;
pub mod dispatch;
pub mod gpu;
pub mod integrators;
pub mod output;

use serde::Serialize;

use crate::accel::AccelKind;
use crate::error::{Error, Result};
use crate::math::intersect::IntersectMode;

/// Which kernel variant to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum KernelChoice {
    /// Only what the scene needs: no sphere code or buffer without spheres, no mesh
    /// code or buffers without triangles, no light loop without lights.
    #[default]
    Specialized,
    /// The general kernel with every buffer bound (empty ones where the scene has
    /// nothing); used by tests to show the specialised kernels agree with it.
    General,
}

/// Which light transport algorithm renders the image; each has its own kernel and
/// module, and shares the render loop's parts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Integrator {
    /// Direct light from point and directional lights, hard shadows, mirror and glass
    /// ([`integrators::whitted`]); the library's default, which the structure tests pin.
    #[default]
    Whitted,
    /// Unidirectional path tracing with next-event estimation and multiple importance
    /// sampling ([`integrators::path`]); the default of `arbor render`.
    Path,
    /// Stochastic progressive photon mapping ([`integrators::sppm`]): caustics from
    /// small lights through glass and off mirrors, which `path` cannot find.
    Sppm,
}

impl Integrator {
    pub fn name(self) -> &'static str {
        match self {
            Integrator::Whitted => "whitted",
            Integrator::Path => "path",
            Integrator::Sppm => "sppm",
        }
    }

    /// By name (`whitted`, `path`, `sppm`).
    pub fn parse(s: &str) -> Option<Integrator> {
        match s {
            "whitted" => Some(Integrator::Whitted),
            "path" => Some(Integrator::Path),
            "sppm" => Some(Integrator::Sppm),
            _ => None,
        }
    }
}

/// Which estimators of direct light the path integrator combines.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mis {
    /// Light sampling and BSDF sampling, weighed by the power heuristic.
    #[default]
    Both,
    /// Light sampling only (area lights and the environment map are reached only
    /// by next-event estimation).
    Light,
    /// BSDF sampling only (no shadow rays toward area lights or the map).
    Bsdf,
}

impl Mis {
    /// The SPEC_MIS value.
    pub fn spec(self) -> u32 {
        match self {
            Mis::Both => crate::gpu::bindings::MIS_BOTH,
            Mis::Light => crate::gpu::bindings::MIS_LIGHT,
            Mis::Bsdf => crate::gpu::bindings::MIS_BSDF,
        }
    }
}

/// How to render.
#[derive(Debug, Clone)]
pub struct RenderSettings {
    /// The light transport algorithm.
    pub integrator: Integrator,
    /// Ray/triangle test: watertight (default) or fast.
    pub intersect: IntersectMode,
    pub width: u32,
    pub height: u32,
    /// Samples per pixel; the Whitted integrator's sample 0 goes through the pixel
    /// centre, the path tracer jitters every sample.
    pub spp: u32,
    pub seed: u32,
    pub accel: AccelKind,
    /// Builder parameters (kd-tree, grid, octree).
    pub params: crate::accel::AccelParams,
    pub kernel: KernelChoice,
    /// Trace camera rays only (no shadows, no bounces): the benchmark's primary-ray mode.
    pub primary_only: bool,
    /// Camera rays plus one cosine-distributed ray from each hit, no shading: the
    /// benchmark's incoherent-ray mode (the image is ambient occlusion). Takes
    /// precedence over `primary_only`.
    pub diffuse_probe: bool,
    /// How dispatches are sized and kept in flight (`--dispatch-ms`, `--in-flight`,
    /// `--dispatch-budget`); unset values take the device's defaults. The image is
    /// the same for any choice.
    pub pacing: dispatch::PacingChoice,
    /// Path integrator: which direct-light estimators it combines.
    pub mis: Mis,
    /// Path integrator: stop after the first sample wave past this many seconds (the
    /// image then holds fewer than `spp` samples).
    pub time_budget: Option<f64>,
    /// Overrides the scene's maximum path depth.
    pub max_depth: Option<u32>,
    /// How coherent rays traverse BVHs: one ray per lane, or packets of a subgroup.
    pub traversal: Traversal,
    /// The window of the image to render (`--crop`, a tile shard); `None`: all of it.
    /// The frame has the window's size; every pixel is the one the whole render gives.
    pub crop: Option<Crop>,
    /// The first sample index (`--sample-offset`, a sample shard): the render traces
    /// samples `first_sample..first_sample + spp` of every pixel.
    pub first_sample: u32,
    /// Continue from this frame's sums (`--resume`): a frame of the window's size
    /// whose pixels hold samples `first_sample..first_sample + n` (n may differ per
    /// pixel); each pixel traces only the samples of the range it lacks.
    pub resume: Option<std::sync::Arc<Frame>>,
    /// For tests and experiments: lower the per-trace step budget to this (at least
    /// `MIN_FORCED_TRACE_STEPS`), so that traces on small scenes run out of steps and
    /// are resumed (docs/kernels.md, "Resumed traces"). The image is the same.
    pub trace_steps: Option<u32>,
    /// For tests: hold at most this many trace records per pass (at least 1), so that
    /// stopped samples without one run again from their start.
    pub resume_records: Option<u32>,
    /// SPPM's photons, initial radius and photon map (`spp` is its iterations).
    pub sppm: integrators::sppm::SppmSettings,
}

/// Called with the image so far at each checkpoint.
pub type CheckpointWriter<'a> = Box<dyn FnMut(&Frame) -> Result<()> + 'a>;

/// What a render is told from outside: progress, and for the path integrator
/// interruption and checkpoints (the Whitted integrator reports progress only).
pub struct Control<'a> {
    /// `(done, total)` pixel-samples after every dispatch (SPPM: iterations, after
    /// each).
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

/// A pixel window of the image: columns `x0..x1`, rows `y0..y1` (half-open, from the
/// top-left corner).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Crop {
    pub x0: u32,
    pub x1: u32,
    pub y0: u32,
    pub y1: u32,
}

impl Crop {
    /// The whole of a `width` x `height` image.
    pub fn full(width: u32, height: u32) -> Crop {
        Crop { x0: 0, x1: width, y0: 0, y1: height }
    }

    pub fn width(&self) -> u32 {
        self.x1.saturating_sub(self.x0)
    }

    pub fn height(&self) -> u32 {
        self.y1.saturating_sub(self.y0)
    }

    pub fn pixels(&self) -> u64 {
        u64::from(self.width()) * u64::from(self.height())
    }

    /// Parses `X0,X1,Y0,Y1`.
    pub fn parse(s: &str) -> std::result::Result<Crop, String> {
        let v: Vec<&str> = s.split(',').map(str::trim).collect();
        let nums: Option<Vec<u32>> = v.iter().map(|x| x.parse().ok()).collect();
        match nums.as_deref() {
            Some(&[x0, x1, y0, y1]) => Ok(Crop { x0, x1, y0, y1 }),
            _ => Err(format!("--crop '{s}': expected X0,X1,Y0,Y1 (four pixel bounds, e.g. 0,512,0,256)")),
        }
    }

    /// Rejects an empty window or one outside a `width` x `height` image.
    pub fn check(&self, width: u32, height: u32) -> Result<()> {
        if self.x0 >= self.x1 || self.y0 >= self.y1 || self.x1 > width || self.y1 > height {
            return Err(Error::Usage(format!(
                "--crop {},{},{},{} is not a non-empty window of the {width}x{height} image (X0 < X1 <= {width}, Y0 < Y1 <= {height})",
                self.x0, self.x1, self.y0, self.y1
            )));
        }
        Ok(())
    }
}

/// Traversal of coherent rays (camera rays of `bench --rays primary,diffuse`, shadow
/// rays toward point and directional lights) in the BVH kernels; other rays and other
/// structures always trace one ray per lane. Either gives the same image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Traversal {
    /// One ray per lane, each on its own path through the tree.
    #[default]
    Single,
    /// The subgroup's rays walk one node sequence together (subgroupAny decides).
    Packet,
}

impl std::str::FromStr for Traversal {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "single" => Ok(Traversal::Single),
            "packet" => Ok(Traversal::Packet),
            _ => Err(format!("unknown traversal '{s}'; expected single or packet")),
        }
    }
}

impl Traversal {
    pub fn name(self) -> &'static str {
        match self {
            Traversal::Single => "single",
            Traversal::Packet => "packet",
        }
    }
}

impl RenderSettings {
    /// Default settings for an image of the scene's own size.
    pub fn for_size(width: u32, height: u32) -> Self {
        RenderSettings {
            integrator: Integrator::Whitted,
            intersect: IntersectMode::Watertight,
            width,
            height,
            spp: 1,
            seed: 0,
            accel: AccelKind::None,
            params: Default::default(),
            kernel: KernelChoice::Specialized,
            primary_only: false,
            diffuse_probe: false,
            pacing: dispatch::PacingChoice::default(),
            mis: Mis::Both,
            time_budget: None,
            max_depth: None,
            traversal: Traversal::Single,
            crop: None,
            first_sample: 0,
            resume: None,
            trace_steps: None,
            resume_records: None,
            sppm: Default::default(),
        }
    }

    /// The window rendered: the crop, or the whole image.
    pub fn window(&self) -> Crop {
        self.crop.unwrap_or(Crop::full(self.width, self.height))
    }
}

impl RenderSettings {
    /// Rejects an image size or sample count no render accepts.
    pub fn check(&self) -> Result<()> {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 || w > crate::scene::MAX_FILM_SIDE || h > crate::scene::MAX_FILM_SIDE {
            return Err(Error::Usage(format!("image size {w}x{h} is invalid")));
        }
        if self.spp == 0 || self.spp > 1 << 20 {
            return Err(Error::Usage(format!("--spp must be 1..=1048576, got {}", self.spp)));
        }
        if self.first_sample > 1 << 20 {
            return Err(Error::Usage(format!("--sample-offset must be 0..=1048576, got {}", self.first_sample)));
        }
        if let Some(c) = &self.crop {
            c.check(w, h)?;
        }
        if let Some(f) = &self.resume {
            let win = self.window();
            if (f.width, f.height) != (win.width(), win.height()) {
                return Err(Error::Failed(format!(
                    "the resumed part is {}x{}, the window {}x{}",
                    f.width,
                    f.height,
                    win.width(),
                    win.height()
                )));
            }
        }
        self.loop_settings().check()?;
        if let Some(t) = self.time_budget {
            if !(t.is_finite() && t > 0.0) {
                return Err(Error::Usage(format!("--time must be a positive number of seconds, got {t}")));
            }
        }
        if let Some(d) = self.max_depth {
            let most = crate::gpu::bindings::MAX_PATH_DEPTH;
            if d == 0 || d > most {
                return Err(Error::Usage(format!("--max-depth must be 1..={most}, got {d}")));
            }
        }
        Ok(())
    }
}

/// Primitive tests per dispatch on llvmpipe, where it keeps dispatches short (a median
/// of 43 ms in the default render on 2 cores, kd-tree; docs/kernels.md, "Dispatches
/// sized by the device"); on other
/// devices only `--dispatch-budget` bounds a dispatch, and time sizes it.
pub const DEFAULT_DISPATCH_BUDGET: u64 = 60_000_000;

/// A rendered frame: linear radiance (averaged over samples) and the AOVs of each
/// pixel's first camera ray (its centre with the Whitted integrator, jittered with the
/// path tracer). Row-major, row 0 at the top.
#[derive(Debug, Clone, Default)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub radiance: Vec<[f32; 3]>,
    /// t of the nearest hit, +inf on a miss.
    pub depth: Vec<f32>,
    /// Shading normal at the hit, zero on a miss.
    pub normal: Vec<[f32; 3]>,
    /// Primitive index, `u32::MAX` on a miss.
    pub prim: Vec<u32>,
    /// Boxes / nodes visited by the camera ray.
    pub nodes: Vec<u32>,
    /// Primitives tested by the camera ray.
    pub tests: Vec<u32>,
    /// Rays traced per pixel over all samples (camera, shadow, bounce).
    pub rays: Vec<u32>,
    /// Albedo at sample 0's first hit (textured; the tint of mirror and glass), for
    /// denoisers; zero on a miss.
    pub albedo: Vec<[f32; 3]>,
    /// Variance of the pixel's mean luminance (sample variance / samples), for judging
    /// convergence; 0 with fewer than two samples.
    pub variance: Vec<f32>,
    /// Samples the pixel holds (fewer than asked for after an interruption or with
    /// `--time`).
    pub samples: Vec<u32>,
    /// The kernel's radiance sums, of which `radiance` is the mean: kept so that a
    /// part can be resumed and merged exactly.
    pub sum: Vec<[f32; 3]>,
    /// The kernel's sum of squared luminance (for `variance`).
    pub sum_y2: Vec<f32>,
}

/// The figures `--stats` writes.
#[derive(Debug, Clone, Default, Serialize)]
pub struct RenderStats {
    pub device: String,
    pub scene: String,
    /// Triangles drawn: the scene's own plus every instance's copy.
    pub triangles: usize,
    pub spheres: usize,
    /// Instances drawn (0 without instancing).
    pub instances: usize,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    /// The light transport algorithm.
    pub integrator: String,
    /// Fewest samples any pixel holds (less than `spp` after an interruption or with
    /// a time budget).
    pub samples_done: u32,
    /// The window rendered (`--crop`, a tile shard); null: the whole image.
    pub crop: Option<Crop>,
    /// The first sample index (`--sample-offset`, a sample shard): the render traced
    /// samples `first_sample..first_sample + spp`.
    pub first_sample: u32,
    /// The render stopped early (interrupted, or the time budget ran out).
    pub interrupted: bool,
    pub accel: String,
    /// Structure statistics (nodes, leaves, depth, references, SAH cost, bytes).
    pub build: crate::accel::BuildStats,
    pub kernel: String,
    /// Storage and uniform buffers the kernel bound, by name.
    pub bindings: Vec<String>,
    pub build_ms: f64,
    /// Sum of GPU time of the trace dispatches (timestamps); null without timestamps.
    pub trace_ms: Option<f64>,
    /// Host wall time of the whole trace, uploads and readback included.
    pub wall_ms: f64,
    /// Host wall time of the dispatch loop alone, first submission to last landing:
    /// with `trace_ms` beside it, how busy the device was kept.
    pub loop_ms: f64,
    /// `trace_ms / loop_ms`: the share of the loop the device spent tracing (1: never
    /// idle); null without timestamps.
    pub gpu_busy: Option<f64>,
    /// The target GPU length dispatches were sized toward (ms).
    pub dispatch_target_ms: f64,
    /// Mean, median and longest GPU time of one trace dispatch (ms; 0 without
    /// timestamps).
    pub dispatch_mean_ms: f64,
    pub dispatch_median_ms: f64,
    pub dispatch_max_ms: f64,
    /// Most dispatches in flight at once.
    pub in_flight: u32,
    /// Host time to create the kernel (on lavapipe: compiling it).
    pub kernel_ms: f64,
    /// Host time to load the scene (set by the command line; 0 otherwise).
    pub load_ms: f64,
    /// Host time to open the Vulkan device (set by the command line; 0 otherwise).
    pub device_ms: f64,
    pub dispatches: u32,
    /// Pixel samples whose trace ran out of its step budget in a trace dispatch and
    /// were resumed (docs/kernels.md, "Resumed traces"); 0 on most scenes.
    pub resumed_samples: u64,
    /// Dispatches of the resume kernel (not counted in `dispatches`; their GPU time is
    /// in `trace_ms`, and alone in `resume_ms`).
    pub resume_dispatches: u32,
    /// Jobs those dispatches ran: a sample continued (or, without a free record, run
    /// again from its start) once per job.
    pub resume_jobs: u64,
    /// GPU time of the resume dispatches; null without timestamps.
    pub resume_ms: Option<f64>,
    /// Every ray traced: camera, shadow and bounce rays.
    pub rays: u64,
    pub mrays_per_s: Option<f64>,
    pub accel_bytes: u64,
    /// Mean primitives tested by each pixel's first camera ray; null where the kernel
    /// cannot count them (the driver's structure, `rayquery`).
    pub mean_prims_tested: Option<f64>,
    /// Mean nodes (or boxes) visited by each pixel's first camera ray; null as above.
    pub mean_nodes_visited: Option<f64>,
    /// SPPM's figures (null for the other integrators).
    pub sppm: Option<integrators::sppm::SppmStats>,
}

impl RenderStats {
    /// The figures of a finished render of `prep`'s kernel over a structure whose
    /// figures are `build`.
    pub fn new(
        prep: &dispatch::prepare::Prepared<'_>,
        settings: &RenderSettings,
        build: crate::accel::BuildStats,
        frame: &Frame,
        totals: &dispatch::DispatchTotals,
        wall_ms: f64,
    ) -> RenderStats {
        let (ctx, scene) = (prep.ctx, prep.scene);
        let (mean, median, longest) = dispatch::length_summary(&totals.lengths_ms);
        let total_pixels = frame.depth.len().max(1) as f64;
        let rays: u64 = frame.rays.iter().map(|&r| u64::from(r)).sum();
        let mrays = totals.gpu_ms.filter(|&ms| ms > 0.0).map(|ms| rays as f64 / (ms * 1e3));
        let counted = build.opaque.is_none();
        RenderStats {
            device: ctx.info().name.clone(),
            scene: scene.name.clone(),
            triangles: scene.drawn_triangles() as usize,
            spheres: scene.spheres.len(),
            instances: scene.instancing.as_ref().map_or(0, |i| i.instances.len()),
            width: settings.width,
            height: settings.height,
            spp: settings.spp,
            integrator: settings.integrator.name().to_string(),
            samples_done: frame.samples.iter().copied().min().unwrap_or(0),
            crop: settings.crop,
            first_sample: settings.first_sample,
            interrupted: totals.stopped,
            accel: settings.accel.name().to_string(),
            build_ms: build.build_ms,
            accel_bytes: build.bytes,
            build,
            kernel: prep.variant.name.clone(),
            bindings: prep.bound.names.clone(),
            trace_ms: totals.gpu_ms,
            wall_ms,
            loop_ms: totals.loop_ms,
            gpu_busy: totals.gpu_ms.filter(|_| totals.loop_ms > 0.0).map(|g| g / totals.loop_ms),
            dispatch_target_ms: totals.target_ms,
            dispatch_mean_ms: mean,
            dispatch_median_ms: median,
            dispatch_max_ms: longest,
            in_flight: totals.in_flight,
            kernel_ms: prep.kernel_ms + totals.resumes.kernel_ms,
            load_ms: 0.0,
            device_ms: 0.0,
            dispatches: totals.dispatches,
            resumed_samples: totals.resumes.samples,
            resume_dispatches: totals.resumes.dispatches,
            resume_jobs: totals.resumes.jobs,
            resume_ms: totals.resumes.gpu_ms,
            rays,
            mrays_per_s: mrays,
            mean_prims_tested: counted.then(|| frame.tests.iter().map(|&t| t as f64).sum::<f64>() / total_pixels),
            mean_nodes_visited: counted.then(|| frame.nodes.iter().map(|&t| t as f64).sum::<f64>() / total_pixels),
            sppm: None,
        }
    }
}
