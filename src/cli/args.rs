//! The `arbor` binary's command line, as clap reads it (included by main.rs only): the
//! subcommands and their arguments, with the help texts.

use anyhow::Result;
use arbor::accel::{AccelKind, AccelParams};
use arbor::bench::RayKind;

use clap::{Parser, Subcommand};

/// The structure `render` and `info` build unless `--accel` says otherwise: the cost
/// model's pick for the scene, image size and samples.
pub(crate) const DEFAULT_ACCEL: &str = "auto";
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "arbor",
    version,
    about = "Headless Vulkan compute ray tracer for triangle meshes and spheres",
    long_about = "Headless Vulkan compute ray tracer for triangle meshes and spheres, built around \
spatial data structures. Scenes: a .toml scene file, a mesh (.obj/.ply/.off, camera framed \
automatically), or builtin:default | builtin:cornell | builtin:spheres | builtin:blob:N | builtin:stadium:N | builtin:inside:N.\n\n\
Environment: ARBOR_VALIDATION=1 enables the Khronos validation layer (any error fails the run); \
ARBOR_MAX_STORAGE_RANGE=BYTES lowers the per-buffer limit to check a scene fits a smaller device; \
ARBOR_MEMORY_LIMIT=BYTES caps the host memory a render or bench may plan for (default: what /proc/meminfo and \
`ulimit -v` allow; a larger --size is refused before any work); \
VK_DRIVER_FILES pins a Vulkan driver (e.g. lavapipe); ARBOR_FONT=FILE.ttf draws the text of plots and heatmaps in that font (default: DejaVu Sans, built in); \
MIMALLOC_PURGE_DELAY=MS lets the allocator give freed memory back to the OS after MS ms (default: arbor keeps it for reuse)."
)]
pub(crate) struct Cli {
    #[command(subcommand)]
    pub(crate) command: Command,
}

#[derive(clap::Args, Clone)]
pub(crate) struct DeviceArgs {
    /// Vulkan device: an index from `arbor devices` or a substring of its name
    /// (default: a discrete GPU if present, else the first device).
    #[arg(long, value_name = "INDEX|NAME")]
    pub(crate) device: Option<String>,
    /// Enable the Khronos validation layer; any validation error fails the run.
    #[arg(long)]
    pub(crate) validation: bool,
}

/// Builder parameters of the structures, shared by render, info and bench.
#[derive(clap::Args, Clone)]
pub(crate) struct StructureArgs {
    /// kd-tree builder parameters: a preset (default, quality, fast) or KEY=VALUE pairs:
    /// kt, ki (SAH traversal / intersection cost), bonus (empty-space factor),
    /// leaf (most primitives a node keeps without trying to split), perfect
    /// (true/false), depth (number or auto).
    #[arg(long, default_value = "default", value_name = "PRESET|KEY=VALUE,...")]
    pub(crate) kd: String,
    /// Grid parameters as KEY=VALUE pairs: lambda (cells per primitive, default 2),
    /// cells (most cells in all, default 16777216).
    #[arg(long, default_value = "default", value_name = "KEY=VALUE,...")]
    pub(crate) grid: String,
    /// Octree parameters as KEY=VALUE pairs: leaf (most primitives a node keeps
    /// without splitting, default 8), depth (deepest level, default 20, at most 24).
    #[arg(long, default_value = "default", value_name = "KEY=VALUE,...")]
    pub(crate) octree: String,
    /// trbvh restructuring: a preset (default: 7-leaf treelets, 3 rounds with minimum
    /// subtree sizes 7, 7, 28; paper: 7, 14, 28 as Karras & Aila; fast: 5-leaf
    /// treelets, faster build, higher SAH; quality: every round at 7, lower SAH, longer
    /// build) and/or leaves=3..7, rounds=0..8, gamma=A/B/... (each round's minimum
    /// subtree size as a multiple of leaves; sets the rounds), e.g. leaves=6,gamma=1/2/4.
    #[arg(long, default_value = "default", value_name = "PRESET|KEY=VALUE,...")]
    pub(crate) trbvh: String,
    /// The driver's build (`--accel rayquery`): a preset (fast-trace, the default:
    /// PREFER_FAST_TRACE; fast-build: PREFER_FAST_BUILD) and/or compact=true|false
    /// (compact the bottom-level structures after building, default true).
    #[arg(long, default_value = "default", value_name = "PRESET|KEY=VALUE,...")]
    pub(crate) rayquery: String,
    /// Where to build: cpu (every structure), or gpu (lbvh, trbvh, bvh4 and bvh8 as
    /// Vulkan compute kernels, traced where they were built; lbvh and trbvh are the CPU
    /// builder's tree word for word, bvh4 and bvh8 collapse trbvh's). `bench` takes a
    /// list (cpu,gpu): one row per structure and build device.
    #[arg(long, value_delimiter = ',', default_value = "cpu", value_name = "cpu|gpu")]
    pub(crate) build: Vec<arbor::accel::BuildOn>,
}

impl StructureArgs {
    /// The parameters of a command that builds once (render, info).
    pub(crate) fn single(&self) -> Result<AccelParams> {
        if self.build.len() > 1 {
            return Err(crate::common::usage("--build takes one of cpu, gpu here (a list only in bench)"));
        }
        self.params()
    }

    /// Every structure's parameters: each flag's spec applied over the defaults.
    pub(crate) fn params(&self) -> Result<AccelParams> {
        let mut p = AccelParams { build: self.build.first().copied().unwrap_or_default(), ..Default::default() };
        use arbor::accel::params::Params;
        use arbor::accel::{bvh::treelet::TreeletParams, grid::GridParams, kdtree::KdParams};
        use arbor::accel::{octree::OctreeParams, rayquery::RayQueryParams};
        for (flag, spec) in [
            (KdParams::FLAG, &self.kd),
            (GridParams::FLAG, &self.grid),
            (OctreeParams::FLAG, &self.octree),
            (TreeletParams::FLAG, &self.trbvh),
            (RayQueryParams::FLAG, &self.rayquery),
        ] {
            p.set_flag(flag, spec).map_err(crate::common::usage)?;
        }
        Ok(p)
    }
}

/// How dispatches are sized and kept in flight, shared by render and bench.
#[derive(clap::Args, Clone, Debug, Default)]
pub(crate) struct PacingArgs {
    /// Target GPU milliseconds of one dispatch: each is sized from the time the ones
    /// before it took. Default: 60 on a GPU, 1000 on lavapipe (where --dispatch-budget
    /// bounds dispatches first). The image is the same for any value.
    #[arg(long, allow_negative_numbers = true, value_name = "MS")]
    pub(crate) dispatch_ms: Option<f64>,
    /// Dispatches submitted ahead of the one the device is running (1: wait for each).
    /// Default: 3 on a GPU, 2 on lavapipe. The image is the same for any value.
    #[arg(long, allow_negative_numbers = true, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=16))]
    pub(crate) in_flight: Option<u32>,
    /// Most primitive tests (estimated from the structure) one dispatch may run: a
    /// bound for devices with a watchdog. Default: 60000000 on lavapipe (dispatches of
    /// about 50 ms in the default render on 2 cores), none on a GPU. The image is the
    /// same.
    #[arg(long, allow_negative_numbers = true, value_name = "TESTS", value_parser = clap::value_parser!(u64).range(1..))]
    pub(crate) dispatch_budget: Option<u64>,
}

impl PacingArgs {
    /// Sets `settings`' pacing from the flags given.
    pub(crate) fn apply(&self, settings: &mut arbor::render::RenderSettings) {
        settings.pacing = self.choice();
    }

    /// The choice the flags make.
    pub(crate) fn choice(&self) -> arbor::render::dispatch::PacingChoice {
        arbor::render::dispatch::PacingChoice {
            target_ms: self.dispatch_ms,
            in_flight: self.in_flight,
            budget: self.dispatch_budget,
        }
    }
}

/// `--trace-events`, shared by render, bench and info.
#[derive(clap::Args, Clone)]
pub(crate) struct TraceArgs {
    /// Write a timeline of the run as Chrome trace-event JSON, for Perfetto
    /// (ui.perfetto.dev) or chrome://tracing: scene loading, each build phase, kernel
    /// creation, uploads, readback and output encoding on the CPU track; every GPU
    /// submission (kernel, pixel range, sample wave; GPU build steps) from its
    /// timestamp queries on the GPU track (docs/profiling.md). FILE.png draws the
    /// timeline as a picture instead. Written with the other outputs, or not at all.
    #[arg(long, value_name = "FILE.json|FILE.png")]
    pub(crate) trace_events: Option<PathBuf>,
    /// For tests: place GPU spans at their submission even where the device has
    /// calibrated timestamps.
    #[arg(long, hide = true)]
    pub(crate) trace_align_submit: bool,
}

#[derive(clap::Args)]
pub(crate) struct BenchArgs {
    /// Triangle counts of the procedural meshes (builtin:blob:N); default 1000,10000,100000
    /// unless --scene is given.
    #[arg(long, value_delimiter = ',')]
    pub(crate) tris: Vec<usize>,
    /// Structures to compare (default: all; names as `render --accel`, aliases
    /// brute-force, kd, bvh too); `none` (brute force) is traced on a smaller image of
    /// the same view and gives the speedup column.
    #[arg(long, value_delimiter = ',', default_values_t = AccelKind::ALL.to_vec())]
    pub(crate) accel: Vec<AccelKind>,
    /// Image size WIDTHxHEIGHT of the camera rays (128x128 with --quick unless given).
    #[arg(long, default_value = "256x256", value_name = "WxH")]
    pub(crate) size: String,
    /// Timed rounds, 1..=1000 (after one warm-up round); in each, every structure builds
    /// and traces once, in turn; medians are reported.
    #[arg(long, allow_negative_numbers = true, default_value_t = 5)]
    pub(crate) repeat: usize,
    /// Write all figures as JSON here.
    #[arg(long, value_name = "PATH")]
    pub(crate) json: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) structure: StructureArgs,
    /// Grid densities to sweep: one grid row per value (cells = lambda x primitives);
    /// default: the one from --grid. Swept in every structure whose parameters take a
    /// lambda.
    #[arg(long, value_delimiter = ',', value_name = "LAMBDA,...")]
    pub(crate) lambda: Vec<f32>,
    /// Extra scenes: builtin:stadium:N (a dense mesh of N triangles inside a huge
    /// sparse one) or any scene argument; traced beside the blobs of --tris.
    #[arg(long, value_delimiter = ',', value_name = "SCENE,...")]
    pub(crate) scene: Vec<String>,
    /// Ray/triangle tests to compare (watertight, fast): one row per structure and mode.
    /// On builtin:inside:N (a closed mesh around the camera) every miss is a ray that
    /// escaped through the mesh: the miss/M column counts them per million rays.
    #[arg(long, value_delimiter = ',', default_value = "watertight", value_name = "MODE,...")]
    pub(crate) intersect: Vec<arbor::math::intersect::IntersectMode>,
    /// Traversal of the coherent rays (primary and diffuse rows' camera rays, shadow
    /// rays toward point and directional lights) in the BVH kernels: single (one ray
    /// per lane) or packet (a subgroup walks one node sequence together).
    #[arg(long, default_value = "single", value_parser = ["single", "packet"])]
    pub(crate) traversal: String,
    /// Ray kinds, one set of rows each: primary (camera rays), shadow (camera rays plus
    /// a shadow ray toward each light from every hit), diffuse (camera rays plus one
    /// cosine-distributed ray from every hit, seeded: incoherent), path (path tracing at
    /// 4 samples per pixel; its rows add million pixel samples per second). Mrays/s
    /// counts all. Default: primary (primary,diffuse with --quick).
    #[arg(long, value_delimiter = ',', value_name = "KIND,...")]
    pub(crate) rays: Vec<RayKind>,
    /// Same as --rays shadow (kept for older command lines).
    #[arg(long, hide = true)]
    pub(crate) shadow: bool,
    /// Write bench.csv, bench.json (every figure; columns in docs/bench.md) and plots/
    /// (PNG and SVG charts; per scene, cost_SCENE.png: the nodes each structure visits
    /// per pixel of the camera rays, side by side) here; with --reference
    /// convergence.csv and its plot, with --shards shards.csv and shards.json instead.
    /// The directory is created if missing.
    #[arg(long, value_name = "DIR")]
    pub(crate) out: Option<PathBuf>,
    /// Colour scale of the cost figures: linear, or log (colour follows log(1 + nodes):
    /// detail among cheap pixels next to a few expensive ones). Every panel of a figure
    /// shares one scale, from the fewest to the most nodes of any structure.
    #[arg(long, default_value = "linear", value_parser = ["linear", "log"], value_name = "SCALE")]
    pub(crate) heatmap_scale: String,
    /// A small run for CI and a first look: blobs of 1000 and 10000 triangles (unless
    /// --tris or --scene), 128x128, one repeat, primary and diffuse rays (unless --rays
    /// is given explicitly).
    #[arg(long)]
    pub(crate) quick: bool,
    /// Error against time instead of the structure table: render the one --scene at
    /// each --ladder sample count with each structure and --integrator, and print the
    /// seconds to image, relative MSE, PSNR against this reference image (EXR, PFM,
    /// HDR or PNG of the scene's film size) and the efficiency 1 / (relMSE x seconds).
    /// With --out: convergence.csv and a log-log plot.
    #[arg(long, value_name = "REF")]
    pub(crate) reference: Option<PathBuf>,
    /// Sample counts of the --reference ladder.
    #[arg(long, allow_negative_numbers = true, value_delimiter = ',', default_values_t = arbor::bench::convergence::DEFAULT_LADDER.to_vec(), value_name = "SPP,...")]
    pub(crate) ladder: Vec<u32>,
    /// Integrators of the --reference ladder (path, whitted).
    #[arg(long, value_delimiter = ',', default_value = "path", value_parser = ["path", "whitted"], value_name = "NAME,...")]
    pub(crate) integrator: Vec<String>,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
    /// Render-farm overhead instead of the structure table: path trace the one --scene
    /// (at --size, --spp, one --accel) split into each of these shard counts, every
    /// shard its own `arbor render` process, one after the other, then `arbor merge`;
    /// print the machine time of all shards, the longest shard, the fixed cost per
    /// shard (process start, load, build, set-up) and the merge (docs/farm.md).
    #[arg(long, allow_negative_numbers = true, value_delimiter = ',', value_name = "N,...")]
    pub(crate) shards: Vec<u32>,
    /// How --shards splits: tiles or samples.
    #[arg(long, default_value = "tiles", value_parser = ["tiles", "samples"])]
    pub(crate) shard_by: String,
    /// Samples per pixel of the --shards renders (default 64).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) spp: Option<u32>,
    #[command(flatten)]
    pub(crate) trace: TraceArgs,
    #[command(flatten)]
    pub(crate) pacing: PacingArgs,
}

#[derive(clap::Args)]
pub(crate) struct RenderArgs {
    /// Scene: file.toml, mesh.obj|ply|off, or builtin:NAME.
    #[arg(default_value = "builtin:default")]
    pub(crate) scene: String,
    /// Output image; the extension picks the format (.png or .exr). The image, the AOVs
    /// and the statistics are written together, or none of them when one fails.
    #[arg(short, long, default_value = "render.png")]
    pub(crate) output: PathBuf,
    /// Image size WIDTHxHEIGHT (default: the scene's film size).
    #[arg(long, value_name = "WxH")]
    pub(crate) size: Option<String>,
    /// Light transport: path (path tracing with area lights, environment light,
    /// soft shadows and indirect light; converges with more samples), sppm
    /// (stochastic progressive photon mapping: also the caustics path cannot find,
    /// light from small lamps focused by glass or mirrors onto diffuse surfaces;
    /// docs/caustics.md) or whitted (the fast preview: direct light from point,
    /// directional and area lights, textures, mirrors, glass followed both ways to 3
    /// splits; no indirect diffuse light and no environment map: the background
    /// instead; area lights converge with --spp).
    #[arg(long, default_value = "path", value_parser = ["path", "sppm", "whitted"])]
    pub(crate) integrator: String,
    /// Samples per pixel, 1..=1048576 (default: 64 for path and sppm, 1 for whitted).
    /// Path: every sample jittered in the pixel; sppm: the iterations, each a camera
    /// path a pixel and --photons photons; whitted: sample 0 through the pixel centre.
    /// Time grows with pixels x samples: long renders show progress on stderr.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) spp: Option<u32>,
    /// Path and sppm: stop after the first sample wave (sppm: iteration) past this many
    /// seconds (the image holds the samples done so far, at most --spp; the stats say
    /// how many).
    #[arg(long, allow_negative_numbers = true, value_name = "SECONDS")]
    pub(crate) time: Option<f64>,
    /// Path and sppm: write the image (and AOVs and stats) so far every SECONDS,
    /// atomically, to the output paths; the final image replaces it.
    #[arg(long, allow_negative_numbers = true, value_name = "SECONDS")]
    pub(crate) checkpoint: Option<f64>,
    /// Longest path in segments (1: only what emits; 2: direct light; default: the
    /// scene's [render] max_depth, else 8), at most 16.
    #[arg(long, allow_negative_numbers = true, value_name = "N")]
    pub(crate) max_depth: Option<u32>,
    /// Sppm: photons per iteration, 1..=67108864 (default: one a pixel of the image).
    #[arg(long, allow_negative_numbers = true, value_name = "N")]
    pub(crate) photons: Option<i64>,
    /// Sppm: every pixel's initial photon radius, in scene units (default: three pixel
    /// footprints at each pixel's visible point); it shrinks as photons arrive.
    #[arg(long, allow_negative_numbers = true, value_name = "R")]
    pub(crate) photon_radius: Option<f64>,
    /// Sppm: how photons find the pixels they light: hashgrid (a hash grid built on
    /// the device each iteration; the default) or kdtree (the lecture's kd-tree,
    /// balanced on the pixels' points and built on the host). Both give the same image.
    #[arg(long, value_parser = ["hashgrid", "kdtree"], value_name = "MAP")]
    pub(crate) photon_map: Option<String>,
    /// Path: direct-light estimators: both (multiple importance sampling), light
    /// (light sampling only) or bsdf (BSDF sampling only). The three converge to the
    /// same image; both has the least noise.
    #[arg(long, default_value = "both", value_parser = ["both", "light", "bsdf"])]
    pub(crate) mis: String,
    /// Acceleration structure: kdtree (SAH kd-tree), bsp-course (the lecture's
    /// tree), bvh-sah (binned SAH BVH), lbvh (linear BVH, fastest build), trbvh
    /// (LBVH + treelet restructuring), bvh4 (bvh-sah collapsed into 4-wide nodes),
    /// bvh8 (the same, 8-wide), cwbvh (8-wide with 8-bit quantised boxes),
    /// grid (uniform grid), octree, none (brute force), rayquery (the device driver's
    /// own structure, traced with VK_KHR_ray_query, where `arbor devices` says ray
    /// query yes), or auto: the one a cost model expects to build and trace this scene,
    /// image size and sample count fastest (the default; the summary line and `arbor
    /// info --accel auto` say which and why). Aliases: brute-force (= none), kd (=
    /// kdtree), bvh (= bvh-sah).
    #[arg(long, default_value = DEFAULT_ACCEL, value_name = "KIND|auto")]
    pub(crate) accel: String,
    /// Draw instances as transformed copies of their meshes, under one structure,
    /// instead of one structure per instanced mesh and a BVH over the instances
    /// (brute force, --accel none, always does).
    #[arg(long)]
    pub(crate) flatten: bool,
    #[command(flatten)]
    pub(crate) structure: StructureArgs,
    /// Ray/triangle test: watertight (Woop, Benthin & Wald 2013: no ray slips
    /// between triangles sharing an edge) or fast (Moller-Trumbore: fewer operations,
    /// rays can escape through shared edges and vertices).
    #[arg(long, default_value = "watertight", value_name = "MODE")]
    pub(crate) intersect: arbor::math::intersect::IntersectMode,
    /// Traversal of coherent rays (shadow rays toward point and directional lights) in
    /// the BVH kernels: single (one ray per lane) or packet (the rays of a subgroup
    /// walk one node sequence together). The image is the same.
    #[arg(long, default_value = "single", value_parser = ["single", "packet"])]
    pub(crate) traversal: String,
    /// AOVs as NAME=PATH pairs, comma-separated or repeated: depth, normal, prim,
    /// cost (RGB: nodes visited, primitives tested, 0), nodes, tests (one channel each)
    /// of sample 0's camera ray; albedo (first hit, for denoisers); variance (of the
    /// pixel's mean luminance); samples (per pixel). PFM or EXR by extension; cost,
    /// nodes and tests also as .png: a false-colour heatmap (viridis) with a colour
    /// bar, its minimum and maximum and what is counted written in the image (for
    /// cost, nodes visited + primitives tested per pixel). Not with --accel rayquery.
    #[arg(long, value_name = "NAME=PATH,...")]
    pub(crate) aov: Vec<String>,
    /// Colour scale of the heatmap AOVs written as .png: linear, or log (colour
    /// follows log(1 + count): detail among the cheap pixels next to a few expensive
    /// ones). The picture spans the least to the greatest count of the image.
    #[arg(long, value_parser = ["linear", "log"], value_name = "SCALE")]
    pub(crate) aov_scale: Option<String>,
    /// Write statistics JSON here.
    #[arg(long, value_name = "PATH")]
    pub(crate) stats: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) trace: TraceArgs,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
    /// Random seed for sample jitter and glass.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0)]
    pub(crate) seed: u32,
    /// Kernel variant: `specialized` (only what the scene needs) or `general`.
    #[arg(long, default_value = "specialized", value_parser = ["specialized", "general"])]
    pub(crate) kernel: String,
    #[command(flatten)]
    pub(crate) pacing: PacingArgs,
    /// For tests: lower the traversal step budget of a trace to N (at least 48), so
    /// that traces run out of steps and are resumed; the output is identical.
    #[arg(long, allow_negative_numbers = true, hide = true, value_name = "N")]
    pub(crate) trace_steps: Option<u32>,
    /// No progress (bar or lines), no summary line.
    #[arg(short, long)]
    pub(crate) quiet: bool,
    /// Render only this window of the image: pixel bounds X0,X1,Y0,Y1 (half-open, from
    /// the top-left corner). Its pixels are exactly those of the whole render; an EXR
    /// output holds the window inside the full display window.
    #[arg(long, value_name = "X0,X1,Y0,Y1")]
    pub(crate) crop: Option<String>,
    /// Render part I of N (0 <= I < N) of the image (inside --crop if given), split by
    /// --shard-by. I may be `auto`: read from SLURM_ARRAY_TASK_ID, else
    /// JOB_COMPLETION_INDEX (Slurm job arrays, Kubernetes Indexed Jobs). Write the part
    /// as EXR and assemble the parts with `arbor merge`.
    #[arg(long, value_name = "I/N|auto/N")]
    pub(crate) shard: Option<String>,
    /// How --shard splits the work: tiles (N bands of rows) or samples (N contiguous
    /// ranges of the --spp samples of every pixel).
    #[arg(long, default_value = "tiles", value_name = "tiles|samples")]
    pub(crate) shard_by: String,
    /// Trace samples K..K+spp of every pixel instead of 0..spp (an explicit sample
    /// range; `arbor merge` adds ranges that meet). Sample K is the same whoever
    /// traces it.
    #[arg(long, allow_negative_numbers = true, value_name = "K")]
    pub(crate) sample_offset: Option<u32>,
    /// Continue the render held by this EXR part (an interrupted or checkpointed
    /// render, or a shard) up to this command's sample range; the command must
    /// otherwise be the one that wrote it (a larger --spp adds samples to a finished
    /// render). The image is the one an uninterrupted render gives, bit for bit. The
    /// part may be the output file itself.
    #[arg(long, value_name = "PART.exr")]
    pub(crate) resume: Option<PathBuf>,
}

#[derive(clap::Args)]
#[command(after_help = "Exit status: 0 when merged; 1 when a part is unreadable, of another scene, settings or \
image size, or the parts overlap or leave tiles or samples missing (one line naming the file; nothing is written); \
2 for a command-line mistake.")]
pub(crate) struct MergeArgs {
    /// The parts: EXR files written by `arbor render` (--shard, --crop, --sample-offset,
    /// or any EXR output).
    #[arg(required = true, value_name = "PART.exr")]
    pub(crate) parts: Vec<PathBuf>,
    /// Output image; the extension picks the format: .png, or .exr (itself a part,
    /// holding every sum and AOV, so it can be merged again or resumed).
    #[arg(short, long, value_name = "OUT")]
    pub(crate) output: PathBuf,
    /// AOVs of the merged image as NAME=PATH pairs, as `render --aov`.
    #[arg(long, value_name = "NAME=PATH,...")]
    pub(crate) aov: Vec<String>,
    /// Colour scale of the heatmap AOVs written as .png, as `render --aov-scale`.
    #[arg(long, value_parser = ["linear", "log"], value_name = "SCALE")]
    pub(crate) aov_scale: Option<String>,
    /// Merge what is there: missing tiles stay black with no samples; gaps in the
    /// samples and unfinished parts are accepted.
    #[arg(long)]
    pub(crate) allow_partial: bool,
    /// No summary line.
    #[arg(short, long)]
    pub(crate) quiet: bool,
}

#[derive(clap::Args)]
pub(crate) struct InfoArgs {
    /// Scene: file.toml, mesh.obj|ply|off, or builtin:NAME.
    pub(crate) scene: String,
    /// Acceleration structure to build and describe, or auto (the default, as for
    /// `render --accel`: chosen for the scene's own film size and the default render's
    /// 64 samples per pixel, so that `info` describes what `render` builds).
    #[arg(long, default_value = DEFAULT_ACCEL, value_name = "KIND|auto")]
    pub(crate) accel: String,
    /// Describe the scene with its instances flattened into copies (see `render --flatten`).
    #[arg(long)]
    pub(crate) flatten: bool,
    #[command(flatten)]
    pub(crate) structure: StructureArgs,
    /// Print JSON instead of text.
    #[arg(long)]
    pub(crate) json: bool,
    #[command(flatten)]
    pub(crate) trace: TraceArgs,
    /// Device for --build gpu (unused otherwise).
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
}

#[derive(clap::Args)]
#[command(after_help = "Exit status: 0 when compared; 1 when an image is missing, unreadable, of an unknown \
format or of another size, or --diff cannot be written (one line naming the file; nothing is written); 2 for a \
command-line mistake (--diff not a .png).")]
pub(crate) struct CompareArgs {
    /// The image to measure: .exr, .pfm, .hdr (linear) or .png, .jpg (sRGB, decoded to linear).
    pub(crate) test: PathBuf,
    /// The reference image, of the same size and any of the same formats.
    pub(crate) reference: PathBuf,
    /// Write the per-pixel relative error (mean over R, G, B of (a-b)^2 / (b^2 + 0.01)) as a
    /// false-colour PNG, on a log scale: black <= 1e-4, blue 1e-3, green 1e-2, yellow 0.1,
    /// red >= 1.
    #[arg(long, value_name = "OUT.png")]
    pub(crate) diff: Option<PathBuf>,
    /// Print JSON (width, height, mse, rel_mse, psnr, max_abs; psnr is "inf" for equal
    /// images) instead of text.
    #[arg(long)]
    pub(crate) json: bool,
}

/// `arbor calibrate`.
#[derive(clap::Args)]
pub(crate) struct CalibrateArgs {
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
    /// Print the constants as JSON on stdout instead of a table.
    #[arg(long)]
    pub(crate) json: bool,
}

#[derive(Subcommand)]
pub(crate) enum Command {
    /// Render a scene to PNG (8-bit sRGB) or EXR (linear float).
    Render(RenderArgs),
    /// Print scene and structure statistics (no rendering).
    Info(InfoArgs),
    /// List the Vulkan devices arbor can use.
    Devices,
    /// Measure the cost model of `--accel auto` on this device: build every structure
    /// on the CPU (and, where the device builds, lbvh, trbvh, bvh4 and bvh8 there) and
    /// trace camera rays with each; about 10-20 s on lavapipe. The constants go to a
    /// cache file keyed by the device and driver (ARBOR_CACHE_DIR, else
    /// $XDG_CACHE_HOME/arbor or ~/.cache/arbor), which `render --accel auto` reads.
    Calibrate(CalibrateArgs),
    /// Benchmark every structure's build and trace on procedural meshes and scenes:
    /// build ms, GPU trace ms (timestamps), Mrays/s, speedup over brute force, mean and
    /// p99 nodes and primitives per ray, bytes, SAH cost, cracks and disagreement with
    /// the watertight reference, time to image; CSV, JSON and plots with --out.
    Bench(BenchArgs),
    /// Compare an image with a reference: MSE, relative MSE, PSNR, largest difference.
    ///
    /// All on linear values: MSE; relative MSE, the mean over pixels and channels of
    /// (a-b)^2 / (b^2 + 0.01) (the pbrt/Mitsuba convention); PSNR, 10 log10(1 / MSE) of
    /// the values clamped to [0, 1], in dB (inf when equal); and the largest absolute
    /// difference.
    Compare(CompareArgs),
    /// Assemble render parts (tiles and sample ranges, EXR) into one image.
    ///
    /// Tiles are placed by their data window; parts of the same window are sample
    /// ranges and are combined as a sample-weighted mean (sums added in sample order);
    /// the AOVs of sample 0's camera ray come from the part that holds sample 0.
    Merge(MergeArgs),
}
