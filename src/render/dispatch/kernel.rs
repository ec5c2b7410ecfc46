//! Kernel choice and specialization: which trace kernel variant runs (structure
//! family x geometry), which buffers it binds, and the loop bounds that keep every
//! invocation inside the driver's limits.

use crate::accel::{Geometry, GpuImage, KernelFamily, TraceLoop};
use crate::error::{Error, Result};
use crate::gpu::bindings::*;
use crate::gpu::{BindingDesc, BindingKind, Context};
use crate::render::KernelChoice;
use crate::scene::{MaterialKind, Scene};

/// Which geometry a kernel variant handles: the scene's, or every kind with
/// [`KernelChoice::General`].
pub fn kernel_geometry(scene: &Scene, choice: KernelChoice) -> Geometry {
    match choice {
        KernelChoice::General => Geometry::All,
        KernelChoice::Specialized => Geometry::of(scene.stored_triangles() > 0, !scene.spheres.is_empty()),
    }
}

/// The descriptor bindings of a trace variant: structure kernel family and geometry.
/// A family whose structure has no buffers (`GpuImage::buffers` is `None`) binds no
/// node or index buffer.
pub fn trace_bindings(family: KernelFamily, geometry: Geometry) -> Vec<BindingDesc> {
    let mut b = vec![BindingDesc { binding: BINDING_PARAMS, kind: BindingKind::Uniform, name: "params" }];
    if geometry.has_triangles() {
        b.push(BindingDesc { binding: BINDING_VERTICES, kind: BindingKind::Texel, name: "vertices" });
        b.push(BindingDesc { binding: BINDING_TRIANGLES, kind: BindingKind::Texel, name: "triangles" });
    }
    if geometry.has_spheres() {
        b.push(BindingDesc { binding: BINDING_SPHERES, kind: BindingKind::Texel, name: "spheres" });
    }
    b.push(BindingDesc { binding: BINDING_SHADING, kind: BindingKind::Texel, name: "shading" });
    b.push(BindingDesc { binding: BINDING_PIXELS, kind: BindingKind::Storage, name: "pixels" });
    if family.has_buffers() {
        b.push(BindingDesc { binding: BINDING_ACCEL_NODES, kind: BindingKind::Texel, name: "accel_nodes" });
        b.push(BindingDesc { binding: BINDING_ACCEL_INDICES, kind: BindingKind::Texel, name: "accel_indices" });
    }
    if family.uses_ray_queries() {
        b.push(BindingDesc { binding: BINDING_TLAS, kind: BindingKind::RayStructure, name: "tlas" });
    }
    b
}

/// The material kinds `scene` uses, a bit per kind (`SPEC_MATERIAL_KINDS`); Lambert at
/// least, the kind of the default material. The general kernel has code for every kind.
pub fn material_kinds(scene: &Scene, choice: KernelChoice) -> u32 {
    if choice == KernelChoice::General {
        return (1 << (MaterialKind::LAST as u32 + 1)) - 1;
    }
    scene.materials.iter().fold(1 << MaterialKind::Lambert as u32, |m, x| m | 1 << x.kind as u32)
}

/// The trace kernels declare subgroup vote and arithmetic operations (packet
/// traversal); a device without them in compute shaders cannot run them.
pub fn check_subgroups(ctx: &Context) -> Result<()> {
    if ctx.info().subgroup_vote {
        return Ok(());
    }
    Err(Error::Failed(format!(
        "{} lacks subgroup vote and arithmetic operations in compute shaders, which the trace kernels use",
        ctx.info().name
    )))
}

/// `SPEC_PACKET`: packet traversal where asked for and the kernel has it (BVHs).
pub fn packet_spec(traversal: crate::render::Traversal, image: &GpuImage) -> u32 {
    u32::from(traversal == crate::render::Traversal::Packet && image.family.has_packet_traversal())
}

/// Smallest per-trace step budget a tree traversal is given (nodes + primitive tests).
const MIN_TREE_STEPS: u64 = 256;
/// Per-trace step budget of tree traversal where the driver sets no loop limit.
const TREE_STEPS_UNLIMITED: u64 = 1 << 22;

/// Upper bound on the loop iterations one invocation runs for one sample of `traces`
/// traces of at most `per_trace` iterations each, plus the path and light loops.
pub fn loop_iterations_per_sample(traces: u64, per_trace: u64) -> u64 {
    traces * (per_trace + 1) + 1
}

/// The loop bounds of one kernel: what each trace may iterate and how.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoopBounds {
    /// Unroll factor of unrolled primitive loops (the kernel compiled with this
    /// `BRUTE_UNROLL`, see [`Variant::new`]; 1 otherwise).
    pub unroll: u32,
    /// Iterations of one trace.
    pub per_trace: u64,
    /// The step budget the kernel enforces per trace (`TREE_STEPS`, from the dispatch
    /// header's `limits`; 0 for unrolled loops, which need none).
    pub steps: u64,
    /// Iterations kept out of the driver's budget for what the resume kernel does once
    /// per invocation (restore and save a traversal's stacks, copy the log).
    pub reserve: u64,
}

impl LoopBounds {
    /// Bounds for `traces` traces per sample of a structure traversed as `image` says,
    /// within `ctx`'s loop limit, with the step budget lowered to `forced` (at least
    /// `MIN_FORCED_TRACE_STEPS`) where given.
    pub fn new(ctx: &Context, scene: &Scene, image: &GpuImage, traces: u64, forced: Option<u32>) -> Result<LoopBounds> {
        match image.trace_loop {
            TraceLoop::Unrolled { .. } => {
                // The smallest unroll factor whose loops fit the driver's limit for one sample.
                let fits = |u: u32| match ctx.loop_budget() {
                    None => true,
                    Some(budget) => loop_iterations_per_sample(traces, image.trace_loop.iterations(u, 0)) <= budget,
                };
                let unroll = BRUTE_UNROLL_FACTORS
                    .into_iter()
                    .find(|&u| fits(u))
                    .unwrap_or(BRUTE_UNROLL_FACTORS[BRUTE_UNROLL_FACTORS.len() - 1]);
                Ok(LoopBounds { unroll, per_trace: image.trace_loop.iterations(unroll, 0), steps: 0, reserve: 0 })
            }
            TraceLoop::StepBudget => {
                let (steps, extra, reserve) = Self::step_budget(ctx, image, traces);
                if steps < MIN_TREE_STEPS {
                    return Err(Error::Failed(format!(
                        "{}: {traces} traces per sample leave only {steps} traversal steps each within {}'s loop limit; lower [render] max_depth",
                        scene.name,
                        ctx.info().name
                    )));
                }
                let steps = forced.map_or(steps, |f| steps.min(u64::from(f.max(MIN_FORCED_TRACE_STEPS))));
                Ok(LoopBounds { unroll: 1, per_trace: steps + extra, steps, reserve })
            }
        }
    }

    /// The steps each of `traces` traces a sample may take within `ctx`'s loop limit
    /// (a tree's step budget), the loop iterations the resume kernel adds to each, and
    /// those it keeps for itself once per invocation.
    fn step_budget(ctx: &Context, image: &GpuImage, traces: u64) -> (u64, u64, u64) {
        // The resume kernel's own loops: a few per trace (each runs at least once on
        // llvmpipe, even for no lane) and, once, the stacks and the log.
        let (extra, reserve) = match image.resume_words {
            0 => (0, 0),
            words => (RESUME_LOOPS_PER_TRACE, u64::from(words) + 10 * traces + 16),
        };
        let steps = match ctx.loop_budget() {
            Some(budget) => {
                (budget.saturating_sub(reserve) / traces.max(1)).saturating_sub(2 + extra).min(TREE_STEPS_UNLIMITED)
            }
            None => TREE_STEPS_UNLIMITED,
        };
        (steps, extra, reserve)
    }

    /// Whether `traces` traces a sample fit `ctx`'s loop limit: each trace of a tree
    /// keeps at least its smallest step budget; brute force's loops, at their largest
    /// unroll factor, fit one sample. (Always, on a driver without a limit.)
    pub fn fits(ctx: &Context, image: &GpuImage, traces: u64) -> bool {
        let Some(budget) = ctx.loop_budget() else { return true };
        match image.trace_loop {
            TraceLoop::Unrolled { .. } => {
                let most = BRUTE_UNROLL_FACTORS[BRUTE_UNROLL_FACTORS.len() - 1];
                loop_iterations_per_sample(traces, image.trace_loop.iterations(most, 0)) <= budget
            }
            TraceLoop::StepBudget => Self::step_budget(ctx, image, traces).0 >= MIN_TREE_STEPS,
        }
    }

    /// The most samples one dispatch may run per pixel within `ctx`'s loop limit, or an
    /// error when even one sample crosses it.
    pub fn samples_within_limit(&self, ctx: &Context, scene: &Scene, traces: u64) -> Result<Option<u32>> {
        let Some(budget) = ctx.loop_budget() else { return Ok(None) };
        let budget = budget.saturating_sub(self.reserve);
        let per_sample = loop_iterations_per_sample(traces, self.per_trace);
        if per_sample > budget {
            return Err(Error::Failed(format!(
                "{}: one sample needs up to {per_sample} loop iterations per pixel, more than the {budget} that {} runs per invocation; use fewer primitives, a lower [render] max_depth, or an acceleration structure",
                scene.name,
                ctx.info().name
            )));
        }
        Ok(Some((budget / per_sample) as u32))
    }
}

/// What a kernel runs: an integrator's entry point of `trace.comp` (its
/// `SPEC_INTEGRATOR` value and module suffix, [`TRACE_ENTRIES`]), or the ray-batch
/// kernel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Entry {
    /// The Whitted integrator (`trace_*.whitted`).
    Whitted,
    /// The path tracer (`trace_*.path`).
    Path,
    /// The benchmark's probe: camera rays, and one bounce with `SPEC_DIFFUSE_PROBE`
    /// (`trace_*.probe`).
    Probe,
    /// Ray batches (`rays_*`): one trace a job, resumed as the probe's.
    Rays,
    /// SPPM's camera, photon and update passes (`trace_*.sppm`), never resumed: a
    /// path whose trace runs out of steps is counted and dropped.
    Sppm,
}

impl Entry {
    /// The value of `SPEC_INTEGRATOR` the kernel is specialised with.
    pub fn spec(self) -> u32 {
        match self {
            Entry::Whitted => INTEGRATOR_WHITTED,
            Entry::Path => INTEGRATOR_PATH,
            Entry::Sppm => INTEGRATOR_SPPM,
            // The resume sweep finds a stopped ray by its zero count, as a probe's
            // (shaders/common/resume_trace.glsl).
            Entry::Probe | Entry::Rays => INTEGRATOR_PROBE,
        }
    }

    /// The kernel family's name prefix: `trace` or `rays`.
    pub fn prefix(self) -> &'static str {
        match self {
            Entry::Rays => "rays",
            _ => "trace",
        }
    }

    /// The SPIR-V module of the variant named `name`: the variant itself for ray
    /// batches, `name.<entry>` for the trace kernel's integrators.
    fn module(self, name: &str) -> Result<String> {
        if self == Entry::Rays {
            return Ok(name.to_string());
        }
        let integrator = self.spec();
        let entry = TRACE_ENTRIES.iter().find(|e| e.1 == integrator).map(|e| e.0);
        let entry = entry.ok_or_else(|| Error::Failed(format!("no trace entry point {integrator}")))?;
        Ok(format!("{name}.{entry}"))
    }

    /// What one unit of the loop's work is, in messages: a pixel or a ray.
    pub fn unit(self) -> &'static str {
        match self {
            Entry::Rays => "rays",
            _ => "pixels",
        }
    }
}

/// A trace kernel variant with its SPIR-V and bindings, before specialization.
#[derive(Debug)]
pub struct Variant {
    pub name: String,
    pub spirv: &'static [u8],
    pub bindings: Vec<BindingDesc>,
}

impl Variant {
    /// `<prefix>_<family>_<geometry>` for `entry`'s kernel ([`Entry::prefix`]),
    /// `image`'s structure family and the scene's geometry (or every buffer with
    /// [`KernelChoice::General`]), with `_x8` or `_x32` for brute force's unrolled
    /// loops (`bounds.unroll`). A trace kernel's module is that name and the entry
    /// point's suffix (`.whitted`, `.path`, `.probe` or `.sppm`, [`TRACE_ENTRIES`]).
    pub fn new(
        entry: Entry,
        scene: &Scene,
        choice: KernelChoice,
        image: &GpuImage,
        bounds: &LoopBounds,
    ) -> Result<Variant> {
        if entry == Entry::Rays && image.family.is_instanced() {
            return Err(Error::Unsupported(format!(
                "scene {}: ray batches trace flat scenes; flatten the instances first (Scene::flattened)",
                scene.name
            )));
        }
        let geometry = kernel_geometry(scene, choice);
        let unrolled = if bounds.unroll > 1 { format!("_x{}", bounds.unroll) } else { String::new() };
        let name = format!("{}_{}_{geometry}{unrolled}", entry.prefix(), image.family);
        let module = entry.module(&name)?;
        let spirv = crate::gpu::spirv::get(&module)
            .ok_or_else(|| Error::Failed(format!("no kernel '{module}' was compiled")))?;
        let mut bindings = trace_bindings(image.family, geometry);
        if image.resume_words > 0 {
            // A stand-in for the trace kernel, the pool for the resume kernel (resume.rs).
            bindings.push(BindingDesc { binding: BINDING_RESUME, kind: BindingKind::Storage, name: "resume" });
        }
        Ok(Variant { bindings, name, spirv })
    }
}

/// Pixels a chunk holds: the image, at most `most`, and what one pixel buffer (the
/// dispatch header, then 64-byte pixels) may hold within the device's storage range.
pub fn chunk_pixels(ctx: &Context, total_pixels: u64, most: u64) -> u64 {
    use crate::accel::gpu_layout::{GpuPixel, PIXEL_HEADER_BYTES};
    let fits = ctx.max_storage_range().saturating_sub(PIXEL_HEADER_BYTES) / std::mem::size_of::<GpuPixel>() as u64;
    total_pixels.min(most).min(fits.max(1))
}

/// The image a kernel renders into: its size (of the whole image, not the window)
/// and the seed of its samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub seed: u32,
}

impl Film {
    /// The image of `settings`.
    pub fn of(settings: &crate::render::RenderSettings) -> Film {
        Film { width: settings.width, height: settings.height, seed: settings.seed }
    }
}

/// The uniform parameters every integrator shares: camera, scene box, image size and
/// primitive counts, materials, seed and background (ambient 0, no lights counted,
/// no path-integrator tables); each integrator fills in the rest.
pub fn base_params(scene: &Scene, film: Film, accel: &crate::accel::Accel) -> crate::accel::gpu_layout::GpuParams {
    let Film { width: w, height: h, seed } = film;
    let basis = scene.camera.basis(w, h);
    let bounds = accel.bounds();
    crate::accel::gpu_layout::GpuParams {
        cam_eye: basis.eye.to_array(),
        tan_half_fov: basis.tan_half,
        cam_right: basis.right.to_array(),
        aspect: basis.aspect,
        cam_up: basis.up.to_array(),
        cam_forward: basis.forward.to_array(),
        scene_min: bounds.min.to_array(),
        scene_max: bounds.max.to_array(),
        width: w,
        height: h,
        triangle_count: scene.stored_triangles() as u32,
        sphere_count: scene.spheres.len() as u32,
        material_count: scene.materials.len() as u32,
        alpha_table: super::upload::alpha_table_row(scene),
        vertex_color_table: super::upload::vertex_color_table_row(scene),
        seed,
        background: scene.background.to_array(),
        ..Default::default()
    }
}
