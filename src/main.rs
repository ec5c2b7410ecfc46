//! The `arbor` command line: render, info, devices, bench.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use arbor::accel::AccelKind;
use arbor::gpu::{Context, ContextOptions};
use arbor::render::{self, output, KernelChoice, RenderSettings};
use arbor::scene::Scene;
use clap::{Parser, Subcommand};

// The kd-tree builder allocates many short-lived vectors; mimalloc builds the 75k
// benchmark tree about 25% faster than glibc malloc here.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

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
VK_DRIVER_FILES pins a Vulkan driver (e.g. lavapipe); ARBOR_FONT=FILE.ttf sets the font of `bench --out` plots."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Args, Clone)]
struct DeviceArgs {
    /// Vulkan device: an index from `arbor devices` or a substring of its name
    /// (default: a discrete GPU if present, else the first device).
    #[arg(long, value_name = "INDEX|NAME")]
    device: Option<String>,
    /// Enable the Khronos validation layer; any validation error fails the run.
    #[arg(long)]
    validation: bool,
}

#[derive(clap::Args)]
struct BenchArgs {
    /// Triangle counts of the procedural meshes (builtin:blob:N); default 1000,10000,100000
    /// unless --scene is given.
    #[arg(long, value_delimiter = ',')]
    tris: Vec<usize>,
    /// Structures to compare; `none` (brute force) is traced on a smaller image of
    /// the same view and gives the speedup column.
    #[arg(long, value_delimiter = ',', default_values_t = [AccelKind::None, AccelKind::Kdtree, AccelKind::BspCourse, AccelKind::BvhSah, AccelKind::Lbvh, AccelKind::Trbvh, AccelKind::Grid, AccelKind::Octree])]
    accel: Vec<AccelKind>,
    /// Image size WIDTHxHEIGHT of the camera rays (128x128 with --quick unless given).
    #[arg(long, default_value = "256x256", value_name = "WxH")]
    size: String,
    /// Timed repeats per case (after one warm-up run); medians are reported.
    #[arg(long, default_value_t = 5)]
    repeat: usize,
    /// Write all figures as JSON here.
    #[arg(long, value_name = "PATH")]
    json: Option<PathBuf>,
    /// kd-tree builder parameters (see `render --kd`).
    #[arg(long, default_value = "default", value_name = "PRESET|KEY=VALUE,...")]
    kd: String,
    /// Grid parameters (see `render --grid`).
    #[arg(long, default_value = "default", value_name = "KEY=VALUE,...")]
    grid: String,
    /// Octree parameters (see `render --octree`).
    #[arg(long, default_value = "default", value_name = "KEY=VALUE,...")]
    octree: String,
    /// trbvh restructuring parameters (see `render --trbvh`).
    #[arg(long, default_value = "default", value_name = "PRESET|KEY=VALUE,...")]
    trbvh: String,
    /// Grid densities to sweep: one grid row per value (cells = lambda x primitives);
    /// default: the one from --grid.
    #[arg(long, value_delimiter = ',', value_name = "LAMBDA,...")]
    lambda: Vec<f32>,
    /// Extra scenes: builtin:stadium:N (a dense mesh of N triangles inside a huge
    /// sparse one) or any scene argument; traced beside the blobs of --tris.
    #[arg(long, value_delimiter = ',', value_name = "SCENE,...")]
    scene: Vec<String>,
    /// Ray/triangle tests to compare (watertight, fast): one row per structure and mode.
    /// On builtin:inside:N (a closed mesh around the camera) every miss is a ray that
    /// escaped through the mesh: the miss/M column counts them per million rays.
    #[arg(long, value_delimiter = ',', default_value = "watertight", value_name = "MODE,...")]
    intersect: Vec<arbor::math::intersect::IntersectMode>,
    /// Ray kinds, one set of rows each: primary (camera rays), shadow (camera rays plus
    /// a shadow ray toward each light from every hit), diffuse (camera rays plus one
    /// cosine-distributed ray from every hit, seeded: incoherent). Mrays/s counts all.
    /// Default: primary (primary,diffuse with --quick).
    #[arg(long, value_delimiter = ',', value_name = "KIND,...")]
    rays: Vec<RayKind>,
    /// Same as --rays shadow (kept for older command lines).
    #[arg(long, hide = true)]
    shadow: bool,
    /// Write bench.csv, bench.json (every figure; columns in the README) and plots/
    /// (PNG and SVG charts, cost heatmaps) here; the directory is created if missing.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// A small run for CI and a first look: blobs of 1000 and 10000 triangles (unless
    /// --tris or --scene), 128x128, one repeat, primary and diffuse rays (unless --rays
    /// is given explicitly).
    #[arg(long)]
    quick: bool,
    #[command(flatten)]
    device: DeviceArgs,
}

/// A kind of ray the benchmark traces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
enum RayKind {
    Primary,
    Shadow,
    Diffuse,
}

impl RayKind {
    fn name(self) -> &'static str {
        match self {
            RayKind::Primary => "primary",
            RayKind::Shadow => "shadow",
            RayKind::Diffuse => "diffuse",
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to PNG (8-bit sRGB) or EXR (linear float).
    Render {
        /// Scene: file.toml, mesh.obj|ply|off, or builtin:NAME.
        #[arg(default_value = "builtin:default")]
        scene: String,
        /// Output image; the extension picks the format (.png or .exr).
        #[arg(short, long, default_value = "render.png")]
        output: PathBuf,
        /// Image size WIDTHxHEIGHT (default: the scene's film size).
        #[arg(long, value_name = "WxH")]
        size: Option<String>,
        /// Samples per pixel (jittered; sample 0 goes through the pixel centre).
        #[arg(long, default_value_t = 1)]
        spp: u32,
        /// Acceleration structure: kdtree (SAH, default), bsp-course (the lecture's
        /// tree), bvh-sah (binned SAH BVH), lbvh (linear BVH, fastest build), trbvh
        /// (LBVH + treelet restructuring), grid (uniform grid), octree, none (brute
        /// force), or auto: the one a cost model expects to build and trace this scene,
        /// image size and sample count fastest (`arbor info --accel auto` says why).
        #[arg(long, default_value = "kdtree", value_name = "KIND|auto")]
        accel: String,
        /// kd-tree builder parameters: a preset (default, quality, fast) or KEY=VALUE pairs:
        /// kt, ki (SAH traversal / intersection cost), bonus (empty-space factor),
        /// leaf (most primitives a node keeps without trying to split), perfect
        /// (true/false), depth (number or auto).
        #[arg(long, default_value = "default", value_name = "PRESET|KEY=VALUE,...")]
        kd: String,
        /// Grid parameters as KEY=VALUE pairs: lambda (cells per primitive, default 2),
        /// cells (most cells in all, default 16777216).
        #[arg(long, default_value = "default", value_name = "KEY=VALUE,...")]
        grid: String,
        /// Octree parameters as KEY=VALUE pairs: leaf (most primitives a node keeps
        /// without splitting, default 8), depth (deepest level, default 20, at most 24).
        #[arg(long, default_value = "default", value_name = "KEY=VALUE,...")]
        octree: String,
        /// trbvh restructuring: a preset (default: 7-leaf treelets, 3 rounds; fast:
        /// 5-leaf treelets, faster build, slightly higher SAH) or leaves=3..7,rounds=N.
        #[arg(long, default_value = "default", value_name = "PRESET|KEY=VALUE,...")]
        trbvh: String,
        /// Ray/triangle test: watertight (Woop, Benthin & Wald 2013: no ray slips
        /// between triangles sharing an edge) or fast (Moller-Trumbore: fewer operations,
        /// rays can escape through shared edges and vertices).
        #[arg(long, default_value = "watertight", value_name = "MODE")]
        intersect: arbor::math::intersect::IntersectMode,
        /// AOVs as NAME=PATH pairs, comma-separated or repeated: depth, normal, prim,
        /// cost (RGB: nodes visited, primitives tested, 0). PFM or EXR by extension.
        #[arg(long, value_name = "NAME=PATH,...")]
        aov: Vec<String>,
        /// Write statistics JSON here.
        #[arg(long, value_name = "PATH")]
        stats: Option<PathBuf>,
        #[command(flatten)]
        device: DeviceArgs,
        /// Random seed for sample jitter and glass.
        #[arg(long, default_value_t = 0)]
        seed: u32,
        /// Kernel variant: `specialized` (only what the scene needs) or `general`.
        #[arg(long, default_value = "specialized", value_parser = ["specialized", "general"])]
        kernel: String,
        /// Primitive tests per dispatch (smaller = shorter dispatches, for devices
        /// with a watchdog); the output is identical for any value.
        #[arg(long, default_value_t = render::DEFAULT_DISPATCH_BUDGET, value_name = "TESTS")]
        dispatch_budget: u64,
        /// No progress bar, no summary line.
        #[arg(short, long)]
        quiet: bool,
    },
    /// Print scene and structure statistics (no rendering).
    Info {
        /// Scene: file.toml, mesh.obj|ply|off, or builtin:NAME.
        scene: String,
        /// Acceleration structure to build and describe, or auto (see `render --accel`;
        /// chosen for the scene's own film size and 1 sample per pixel).
        #[arg(long, default_value = "kdtree", value_name = "KIND|auto")]
        accel: String,
        /// kd-tree builder parameters (see `render --kd`).
        #[arg(long, default_value = "default", value_name = "PRESET|KEY=VALUE,...")]
        kd: String,
        /// Grid parameters (see `render --grid`).
        #[arg(long, default_value = "default", value_name = "KEY=VALUE,...")]
        grid: String,
        /// Octree parameters (see `render --octree`).
        #[arg(long, default_value = "default", value_name = "KEY=VALUE,...")]
        octree: String,
        /// trbvh restructuring parameters (see `render --trbvh`).
        #[arg(long, default_value = "default", value_name = "PRESET|KEY=VALUE,...")]
        trbvh: String,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// List the Vulkan devices arbor can use.
    Devices,
    /// Benchmark every structure's build and trace on procedural meshes and scenes:
    /// build ms, GPU trace ms (timestamps), Mrays/s, speedup over brute force, mean and
    /// p99 nodes and primitives per ray, bytes, SAH cost, cracks and disagreement with
    /// the watertight reference, time to image; CSV, JSON and plots with --out.
    Bench(BenchArgs),
}

fn main() {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) if !e.use_stderr() => {
            // --help and --version print as clap formats them, to stdout.
            let _ = e.print();
            return;
        }
        Err(e) => {
            // One line, like every other error: clap's first line without its prefix.
            let text = e.render().to_string();
            let first = text.lines().next().unwrap_or("invalid arguments");
            eprintln!("arbor: error: {} (see arbor --help)", first.trim_start_matches("error: "));
            std::process::exit(2);
        }
    };
    if let Err(e) = run(cli) {
        eprintln!("arbor: error: {e:#}");
        std::process::exit(1);
    }
}

fn context(d: &DeviceArgs) -> Result<Context> {
    let validation = d.validation || std::env::var("ARBOR_VALIDATION").is_ok_and(|v| v == "1");
    let max_storage_range = match std::env::var("ARBOR_MAX_STORAGE_RANGE") {
        Ok(v) => Some(v.parse::<u64>().with_context(|| format!("ARBOR_MAX_STORAGE_RANGE={v:?} is not a byte count"))?),
        Err(_) => None,
    };
    Ok(Context::new(&ContextOptions { device: d.device.clone(), validation, max_storage_range })?)
}

/// `--accel`: a structure name, or `auto` resolved by the cost model (with its reason).
fn resolve_accel(s: &str, scene: &Scene, pixels: u64, spp: u32) -> Result<(AccelKind, Option<String>)> {
    if s == "auto" {
        let (k, why) = arbor::accel::auto::choose(scene, pixels, spp);
        return Ok((k, Some(why)));
    }
    let k: AccelKind = s.parse().map_err(|e: String| anyhow::anyhow!("--accel {s}: {e}, or auto"))?;
    Ok((k, None))
}

fn accel_params(kd: &str, grid: &str, octree: &str, trbvh: &str) -> Result<arbor::accel::AccelParams> {
    Ok(arbor::accel::AccelParams {
        treelet: arbor::accel::bvh::treelet::TreeletParams::parse(trbvh).map_err(anyhow::Error::msg)?,
        kd: arbor::accel::kdtree::KdParams::parse(kd).map_err(anyhow::Error::msg)?,
        grid: arbor::accel::grid::GridParams::parse(grid).map_err(anyhow::Error::msg)?,
        octree: arbor::accel::octree::OctreeParams::parse(octree).map_err(anyhow::Error::msg)?,
    })
}

fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) =
        s.split_once(['x', 'X']).with_context(|| format!("--size {s:?}: expected WIDTHxHEIGHT, e.g. 640x480"))?;
    let w: u32 = w.trim().parse().with_context(|| format!("--size {s:?}: bad width"))?;
    let h: u32 = h.trim().parse().with_context(|| format!("--size {s:?}: bad height"))?;
    if w == 0 || h == 0 || w > arbor::scene::MAX_FILM_SIDE || h > arbor::scene::MAX_FILM_SIDE {
        bail!("--size {s}: each side must be 1..={}", arbor::scene::MAX_FILM_SIDE);
    }
    Ok((w, h))
}

const AOV_NAMES: [&str; 4] = ["depth", "normal", "prim", "cost"];

fn parse_aovs(args: &[String]) -> Result<Vec<(String, PathBuf)>> {
    let mut out: Vec<(String, PathBuf)> = Vec::new();
    for item in args.iter().flat_map(|a| a.split(',')).filter(|s| !s.is_empty()) {
        let (name, path) = item.split_once('=').with_context(|| format!("--aov {item:?}: expected NAME=PATH"))?;
        if !AOV_NAMES.contains(&name) {
            bail!("--aov {item:?}: unknown AOV '{name}' (known: {})", AOV_NAMES.join(", "));
        }
        if out.iter().any(|(n, _)| n == name) {
            bail!("--aov: '{name}' given twice");
        }
        let path = PathBuf::from(path);
        output::format_of(&path, "aov")?;
        out.push((name.to_string(), path));
    }
    Ok(out)
}

/// Fails early (before any work) if `path` cannot be written later.
fn check_writable(path: &Path) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        bail!("{}: the directory {} does not exist", path.display(), dir.display());
    }
    if path.is_dir() {
        bail!("{}: is a directory", path.display());
    }
    Ok(())
}

fn progress_bar(quiet: bool) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::hidden());
    if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} [{bar:40}] {percent}% eta {eta}") {
        pb.set_style(style.progress_chars("=> "));
    }
    if quiet || !std::io::stderr().is_terminal() {
        return pb;
    }
    pb
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render {
            scene,
            output,
            size,
            spp,
            accel,
            aov,
            stats,
            device,
            seed,
            kernel,
            dispatch_budget,
            quiet,
            kd,
            grid,
            octree,
            trbvh,
            intersect,
        } => {
            let aovs = parse_aovs(&aov)?;
            let params = accel_params(&kd, &grid, &octree, &trbvh)?;
            output::format_of(&output, "image")?;
            check_writable(&output)?;
            for (_, p) in &aovs {
                check_writable(p)?;
            }
            if let Some(p) = &stats {
                check_writable(p)?;
            }
            if spp == 0 || spp > 1 << 20 {
                bail!("--spp must be 1..=1048576, got {spp}");
            }
            let size = size.as_deref().map(parse_size).transpose()?;
            let mut scene = Scene::load(&scene)?;
            scene.intersect = intersect;
            let (w, h) = size.unwrap_or((scene.width, scene.height));
            let (accel, why) = resolve_accel(&accel, &scene, u64::from(w) * u64::from(h), spp)?;
            if let (Some(why), false) = (&why, quiet) {
                eprintln!("accel auto: {why}");
            }
            let ctx = context(&device)?;
            let mut settings = RenderSettings::for_size(w, h);
            settings.spp = spp;
            settings.seed = seed;
            settings.accel = accel;
            settings.params = params;
            settings.dispatch_budget = dispatch_budget.max(1);
            settings.kernel = if kernel == "general" { KernelChoice::General } else { KernelChoice::Specialized };
            let pb = progress_bar(quiet);
            let interactive = !quiet && std::io::stderr().is_terminal();
            pb.set_message(format!("tracing {}", scene.name));
            let start = Instant::now();
            let mut shown = false;
            let (frame, st) = render::gpu::render(&ctx, &scene, &settings, |done, total| {
                pb.set_length(total);
                pb.set_position(done);
                if interactive && !shown && start.elapsed().as_secs_f64() > 1.0 {
                    pb.set_draw_target(ProgressDrawTarget::stderr());
                    shown = true;
                }
            })?;
            pb.finish_and_clear();
            output::write_image(&output, w, h, &frame.radiance)?;
            for (name, path) in &aovs {
                match name.as_str() {
                    "depth" => output::write_aov(path, w, h, 1, &frame.depth)?,
                    "normal" => {
                        let n: Vec<f32> = frame.normal.iter().flatten().copied().collect();
                        output::write_aov(path, w, h, 3, &n)?
                    }
                    "prim" => {
                        let p: Vec<f32> =
                            frame.prim.iter().map(|&p| if p == u32::MAX { -1.0 } else { p as f32 }).collect();
                        output::write_aov(path, w, h, 1, &p)?
                    }
                    _ => {
                        // RGB: nodes visited, primitives tested, 0.
                        let c: Vec<f32> = frame
                            .nodes
                            .iter()
                            .zip(&frame.tests)
                            .flat_map(|(&n, &t)| [n as f32, t as f32, 0.0])
                            .collect();
                        output::write_aov(path, w, h, 3, &c)?
                    }
                }
            }
            if let Some(p) = &stats {
                let json = serde_json::to_vec_pretty(&st)?;
                output::write_atomic(p, &json)?;
            }
            if !quiet {
                let trace = st.trace_ms.map(|t| format!("{t:.1} ms GPU")).unwrap_or_else(|| "no GPU timestamps".into());
                let mr = st.mrays_per_s.map(|m| format!(", {m:.4} Mrays/s")).unwrap_or_default();
                eprintln!(
                    "wrote {} ({w}x{h}, {spp} spp, {} triangles, {} spheres, accel {}) on {}: trace {trace}{mr}, {} dispatches, {:.0} ms wall",
                    output.display(),
                    st.triangles,
                    st.spheres,
                    st.accel,
                    st.device,
                    st.dispatches,
                    st.wall_ms
                );
            }
            Ok(())
        }
        Command::Info { scene, accel, json, kd, grid, octree, trbvh } => {
            let params = accel_params(&kd, &grid, &octree, &trbvh)?;
            let scene = Scene::load(&scene)?;
            let (accel, why) = resolve_accel(&accel, &scene, u64::from(scene.width) * u64::from(scene.height), 1)?;
            let built = arbor::accel::Accel::build_with(accel, &scene, &params);
            let valid = built.validate(&scene);
            let st = built.stats(&scene);
            let bounds = scene.bounds();
            let geometry = render::gpu::geometry_suffix(&scene, KernelChoice::Specialized);
            let kernel = format!("trace_{}_{geometry}", accel.kernel());
            let buffers: Vec<&str> =
                render::gpu::trace_bindings(accel.kernel(), geometry).iter().map(|b| b.name).collect();
            let info = serde_json::json!({
                "scene": scene.name,
                "triangles": scene.triangles.len(),
                "degenerate_triangles": scene.degenerate_triangles,
                "vertices": scene.positions.len(),
                "spheres": scene.spheres.len(),
                "materials": scene.materials.len(),
                "lights": scene.lights.len(),
                "film": [scene.width, scene.height],
                "bounds_min": bounds.min.to_array(),
                "bounds_max": bounds.max.to_array(),
                "accel": accel.name(),
                "accel_auto_reason": why,
                "build": st,
                "valid": valid.is_ok(),
                "kernel": kernel,
                "buffers": buffers,
            });
            if json {
                println!("{}", serde_json::to_string_pretty(&info)?);
            } else {
                let n = scene.prim_count().max(1) as f64;
                println!("scene           {}", scene.name);
                println!(
                    "triangles       {} ({} degenerate, kept and never hit)",
                    scene.triangles.len(),
                    scene.degenerate_triangles
                );
                println!("vertices        {}", scene.positions.len());
                println!("spheres         {}", scene.spheres.len());
                println!("materials       {}", scene.materials.len());
                println!("lights          {}", scene.lights.len());
                println!("film            {}x{}", scene.width, scene.height);
                println!("bounds          {:?} .. {:?}", bounds.min.to_array(), bounds.max.to_array());
                println!("accel           {}", accel.name());
                if let Some(why) = &why {
                    println!("  auto          {why}");
                }
                println!("  build         {:.2} ms", st.build_ms);
                println!(
                    "  nodes         {} ({} leaves, {} empty: {:.1}%)",
                    st.nodes,
                    st.leaves,
                    st.empty_leaves,
                    100.0 * st.empty_leaves as f64 / st.leaves.max(1) as f64
                );
                if let Some(r) = st.resolution {
                    println!("  resolution    {} x {} x {} cells", r[0], r[1], r[2]);
                }
                println!("  depth         max {}, mean leaf {:.2}", st.max_depth, st.mean_leaf_depth);
                println!("  refs/prim     {:.3} ({:.2} per leaf)", st.refs_per_prim, st.prims_per_leaf);
                println!("  bytes         {} ({:.2} per primitive)", st.bytes, st.bytes as f64 / n);
                println!("  SAH cost      {:.3}", st.sah_cost);
                for ph in &st.phases {
                    println!("  phase         {:<22} {:.2} ms", ph.name, ph.ms);
                }
                println!(
                    "  validate      {}",
                    match &valid {
                        Ok(()) => "ok".to_string(),
                        Err(e) => format!("FAILED: {e}"),
                    }
                );
                println!("kernel          {kernel}");
                println!("buffers         {}", buffers.join(", "));
            }
            valid.map_err(|e| anyhow::anyhow!("{}: structure failed validation: {e}", scene.name))
        }
        Command::Devices => {
            let list = Context::list_devices()?;
            if list.is_empty() {
                bail!("no Vulkan 1.2 device with a compute queue");
            }
            for d in list {
                println!(
                    "{}: {} ({}, Vulkan {}, {}), maxStorageBufferRange {} bytes, timestampPeriod {} ns",
                    d.index, d.name, d.kind, d.api_version, d.driver, d.max_storage_buffer_range, d.timestamp_period_ns
                );
            }
            Ok(())
        }
        Command::Bench(args) => {
            println!("{BENCH_HEADER}");
            bench(&args)
        }
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn spread(v: &[f64]) -> f64 {
    v.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - v.iter().cloned().fold(f64::INFINITY, f64::min)
}

/// One measured case of the benchmark.
struct Case {
    build_ms: Vec<f64>,
    trace_ms: Vec<f64>,
    rates: Vec<f64>,
    stats: render::RenderStats,
    size: (u32, u32),
    /// Camera rays that hit nothing (last repeat; the same in every repeat).
    misses: u64,
    /// 99th percentile of nodes visited and primitives tested per camera ray.
    nodes_p99: u32,
    prims_p99: u32,
    /// Nodes visited per camera ray, per pixel (last repeat), for the cost heatmap.
    nodes: Vec<u32>,
    /// Primitive hit per pixel (last repeat), for the comparison with the reference.
    prims: Vec<u32>,
}

/// The `q` quantile (0..=1) of `v` by the nearest-rank method.
fn quantile(v: &[u32], q: f64) -> u32 {
    if v.is_empty() {
        return 0;
    }
    let mut s = v.to_vec();
    s.sort_unstable();
    let rank = ((q * s.len() as f64).ceil() as usize).clamp(1, s.len());
    s[rank - 1]
}

fn bench_case(
    ctx: &Context,
    scene: &Scene,
    (kind, params): (AccelKind, &arbor::accel::AccelParams),
    size: (u32, u32),
    rays: RayKind,
    repeat: usize,
    pb: &ProgressBar,
) -> Result<Case> {
    let mut settings = RenderSettings::for_size(size.0, size.1);
    settings.primary_only = rays == RayKind::Primary;
    settings.diffuse_probe = rays == RayKind::Diffuse;
    settings.accel = kind;
    let mut case = Case {
        build_ms: Vec::new(),
        trace_ms: Vec::new(),
        rates: Vec::new(),
        stats: Default::default(),
        size,
        misses: 0,
        nodes_p99: 0,
        prims_p99: 0,
        nodes: Vec::new(),
        prims: Vec::new(),
    };
    for r in 0..=repeat {
        let accel = arbor::accel::Accel::build_with(kind, scene, params);
        let (frame, st) = render::gpu::render_with(ctx, scene, &settings, &accel, |_, _| {})?;
        case.misses = frame.prim.iter().filter(|&&p| p == u32::MAX).count() as u64;
        case.nodes_p99 = quantile(&frame.nodes, 0.99);
        case.prims_p99 = quantile(&frame.tests, 0.99);
        case.nodes = frame.nodes;
        case.prims = frame.prim;
        pb.inc(1);
        if r > 0 {
            let ms = st.trace_ms.unwrap_or(st.wall_ms);
            case.build_ms.push(st.build.build_ms);
            case.trace_ms.push(ms);
            case.rates.push(st.rays as f64 / (ms * 1e3));
        }
        case.stats = st;
    }
    Ok(case)
}

/// The structures to run, with the parameters of each row and its label: the grid once
/// per --lambda value.
fn bench_variants(
    args: &BenchArgs,
    base: &arbor::accel::AccelParams,
) -> Vec<(AccelKind, arbor::accel::AccelParams, String)> {
    let mut out = Vec::new();
    for &kind in &args.accel {
        if kind == AccelKind::Grid && !args.lambda.is_empty() {
            for &lambda in &args.lambda {
                let mut p = *base;
                p.grid.lambda = lambda;
                out.push((kind, p, format!("grid:{lambda}")));
            }
        } else {
            out.push((kind, *base, kind.name().to_string()));
        }
    }
    out
}

/// One row of the benchmark's output (bench.json, bench.csv; columns in the README).
#[derive(serde::Serialize)]
struct Row {
    scene: String,
    triangles: usize,
    accel: String,
    label: String,
    intersect: String,
    rays: String,
    width: u32,
    height: u32,
    device: String,
    build_ms: f64,
    build_ms_spread: f64,
    trace_ms: f64,
    trace_ms_spread: f64,
    rays_traced: u64,
    mrays_per_s: f64,
    speedup: Option<f64>,
    bytes: u64,
    sah_cost: f64,
    depth: u32,
    nodes_mean: f64,
    nodes_p99: u32,
    prims_mean: f64,
    prims_p99: u32,
    misses_per_million: f64,
    aimed_escapes_per_million: Option<f64>,
    disagree_per_million: Option<f64>,
    error: Option<String>,
}

/// Columns of bench.csv, in order (the fields of `Row`).
const CSV_COLUMNS: &[&str] = &[
    "scene",
    "triangles",
    "accel",
    "label",
    "intersect",
    "rays",
    "width",
    "height",
    "device",
    "build_ms",
    "build_ms_spread",
    "trace_ms",
    "trace_ms_spread",
    "rays_traced",
    "mrays_per_s",
    "speedup",
    "bytes",
    "sah_cost",
    "depth",
    "nodes_mean",
    "nodes_p99",
    "prims_mean",
    "prims_p99",
    "misses_per_million",
    "aimed_escapes_per_million",
    "disagree_per_million",
    "error",
];

fn csv_field(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::Null => String::new(),
        serde_json::Value::String(s) if s.contains([',', '"', '\n']) => format!("\"{}\"", s.replace('"', "\"\"")),
        serde_json::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

fn to_csv(rows: &[Row]) -> Result<String> {
    let mut out = CSV_COLUMNS.join(",");
    out.push('\n');
    for r in rows {
        let v = serde_json::to_value(r)?;
        let line: Vec<String> = CSV_COLUMNS.iter().map(|c| csv_field(&v[*c])).collect();
        out.push_str(&line.join(","));
        out.push('\n');
    }
    Ok(out)
}

/// Time to image: build plus trace for `spp` samples per pixel, per structure, and the
/// samples per pixel from which each structure beats every one that builds faster.
fn time_to_image(rows: &[&Row]) -> Vec<serde_json::Value> {
    let mut list: Vec<&Row> =
        rows.iter().copied().filter(|r| r.error.is_none() && r.accel != "none" && r.trace_ms > 0.0).collect();
    list.sort_by(|a, b| a.build_ms.total_cmp(&b.build_ms));
    let mut out = Vec::new();
    for (k, r) in list.iter().enumerate() {
        // Against each faster-building structure: build_r + s trace_r < build_o + s trace_o.
        let mut wins_from: Option<f64> = Some(0.0);
        for o in &list[..k] {
            if r.trace_ms >= o.trace_ms {
                wins_from = None;
                break;
            }
            let s = (r.build_ms - o.build_ms) / (o.trace_ms - r.trace_ms);
            wins_from = wins_from.map(|w| w.max(s));
        }
        let totals: Vec<(u32, f64)> =
            [1u32, 4, 16, 64, 256].iter().map(|&s| (s, r.build_ms + f64::from(s) * r.trace_ms)).collect();
        out.push(serde_json::json!({
            "label": r.label, "build_ms": r.build_ms, "trace_ms_per_spp": r.trace_ms,
            "beats_faster_builders_from_spp": wins_from, "total_ms": totals,
        }));
    }
    out
}

fn bench(args: &BenchArgs) -> Result<()> {
    if let Some(p) = &args.json {
        check_writable(p)?;
    }
    if let Some(d) = &args.out {
        std::fs::create_dir_all(d).with_context(|| format!("--out {}: cannot create the directory", d.display()))?;
    }
    let (w, h) = if args.quick && args.size == "256x256" { (128, 128) } else { parse_size(&args.size)? };
    let params = accel_params(&args.kd, &args.grid, &args.octree, &args.trbvh)?;
    if let Some(bad) = args.lambda.iter().find(|l| !(l.is_finite() && **l > 0.0 && **l <= 1e4)) {
        bail!("--lambda {bad}: each value must be in (0, 10000]");
    }
    let variants = bench_variants(args, &params);
    let repeat = if args.quick { 1 } else { args.repeat.max(1) };
    let tris = match (args.tris.is_empty() && args.scene.is_empty(), args.quick) {
        (true, true) => vec![1000, 10_000],
        (true, false) => vec![1000, 10_000, 100_000],
        _ => args.tris.clone(),
    };
    let mut kinds = args.rays.clone();
    if kinds.is_empty() {
        kinds = if args.quick { vec![RayKind::Primary, RayKind::Diffuse] } else { vec![RayKind::Primary] };
    }
    if args.shadow && !kinds.contains(&RayKind::Shadow) {
        kinds.push(RayKind::Shadow);
    }
    let scenes: Vec<String> =
        tris.iter().map(|n| format!("builtin:blob:{n}")).chain(args.scene.iter().cloned()).collect();
    let ctx = context(&args.device)?;
    eprintln!(
        "device: {} ({}); {w}x{h} camera rays, kinds {}; brute force on a smaller image of the same view; median of {repeat} after 1 warm-up",
        ctx.info().name,
        ctx.info().kind,
        kinds.iter().map(|k| k.name()).collect::<Vec<_>>().join(", ")
    );
    let pb = progress_bar(false);
    pb.set_length((scenes.len() * kinds.len() * args.intersect.len() * variants.len() * (repeat + 1)) as u64);
    if std::io::stderr().is_terminal() {
        pb.set_draw_target(ProgressDrawTarget::stderr());
    }
    let mut rows: Vec<Row> = Vec::new();
    let mut tti = Vec::new();
    // (file stem, title, width, height, nodes per pixel) of the cost heatmaps to draw.
    let mut heatmaps: Vec<(String, String, u32, u32, Vec<u32>)> = Vec::new();
    for name in &scenes {
        let base = Scene::load(name)?;
        let nt = base.triangles.len();
        let short = name.strip_prefix("builtin:").unwrap_or(name).to_string();
        // Brute force over all pixels would take too long: trace a square subset whose
        // side keeps it under about 4e8 primitive tests.
        let side = ((4e8 / base.prim_count().max(1) as f64).sqrt() as u32).clamp(8, w.min(h));
        // The watertight reference for the camera rays (CPU, a sample of the pixels).
        let stride = ((u64::from(w) * u64::from(h)) / REFERENCE_PIXELS).max(1) as usize;
        let reference = {
            let accel = arbor::accel::Accel::build(AccelKind::BvhSah, &base);
            render::cpu::reference_prims(&base, &accel, w, h, stride)
        };
        for &kind_of_rays in &kinds {
            let mut scene = base.clone();
            if kind_of_rays == RayKind::Shadow {
                scene.max_depth = 1;
            }
            let first_row = rows.len();
            // Brute-force rate per intersection mode, for the speedup column.
            let mut brute_rates: Vec<Option<f64>> = vec![None; args.intersect.len()];
            // Each structure's modes run back to back, so that their Mrays/s compare
            // under the same machine load.
            let cases = variants.iter().flat_map(|v| args.intersect.iter().enumerate().map(move |m| (v, m)));
            for ((kind, p, label), (mi, &mode)) in cases {
                let kind = *kind;
                scene.intersect = mode;
                let brute_rate = &mut brute_rates[mi];
                let mut label = label.clone();
                if args.intersect.len() > 1 {
                    label = format!("{label}/{mode}");
                }
                if kinds.len() > 1 {
                    label = format!("{label}/{}", kind_of_rays.name());
                }
                pb.set_message(format!("{short}, {label}"));
                let size = if kind == AccelKind::None { (side, side) } else { (w, h) };
                let mut row = Row {
                    scene: name.clone(),
                    triangles: nt,
                    accel: kind.name().into(),
                    label: label.clone(),
                    intersect: mode.name().into(),
                    rays: kind_of_rays.name().into(),
                    width: size.0,
                    height: size.1,
                    device: ctx.info().name.clone(),
                    build_ms: 0.0,
                    build_ms_spread: 0.0,
                    trace_ms: 0.0,
                    trace_ms_spread: 0.0,
                    rays_traced: 0,
                    mrays_per_s: 0.0,
                    speedup: None,
                    bytes: 0,
                    sah_cost: 0.0,
                    depth: 0,
                    nodes_mean: 0.0,
                    nodes_p99: 0,
                    prims_mean: 0.0,
                    prims_p99: 0,
                    misses_per_million: 0.0,
                    aimed_escapes_per_million: None,
                    disagree_per_million: None,
                    error: None,
                };
                let c = match bench_case(&ctx, &scene, (kind, p), size, kind_of_rays, repeat, &pb) {
                    Ok(c) => c,
                    // A structure can fail on a scene where it degenerates (the grid in
                    // the stadium needs more steps per ray than llvmpipe's loop limit;
                    // brute force too with shadow rays on big scenes): report it, go on.
                    Err(e) => {
                        let msg = format!("{e:#}");
                        pb.suspend(|| println!("{short:>16} {nt:>9} {label:>16} failed: {msg}"));
                        row.error = Some(msg);
                        rows.push(row);
                        pb.inc(repeat as u64 + 1);
                        continue;
                    }
                };
                let rate = median(&mut c.rates.clone());
                if kind == AccelKind::None {
                    *brute_rate = Some(rate);
                }
                let st = &c.stats;
                let pixels = u64::from(c.size.0) * u64::from(c.size.1);
                // Inside a closed mesh: also rays aimed at its vertices and edges (CPU
                // traversal of the same structure), where cracks show. (Not brute
                // force: on the CPU that would take minutes.)
                let aimed = if name.starts_with("builtin:inside:") && kind != AccelKind::None {
                    let accel = arbor::accel::Accel::build_with(kind, &scene, p);
                    let rays = render::cracks::aimed_rays(&scene, glam::Vec3::ZERO, 0.3, AIMED_RAYS, 11);
                    Some(render::cracks::escapes(&scene, &accel, &rays) as f64 * 1e6 / AIMED_RAYS as f64)
                } else {
                    None
                };
                row.build_ms = median(&mut c.build_ms.clone());
                row.build_ms_spread = spread(&c.build_ms);
                row.trace_ms = median(&mut c.trace_ms.clone());
                row.trace_ms_spread = spread(&c.trace_ms);
                row.rays_traced = st.rays;
                row.mrays_per_s = rate;
                row.speedup = brute_rate.map(|b| rate / b);
                row.bytes = st.build.bytes;
                row.sah_cost = st.build.sah_cost;
                row.depth = st.build.max_depth;
                row.nodes_mean = st.mean_nodes_visited;
                row.nodes_p99 = c.nodes_p99;
                row.prims_mean = st.mean_prims_tested;
                row.prims_p99 = c.prims_p99;
                row.misses_per_million = c.misses as f64 * 1e6 / pixels.max(1) as f64;
                row.aimed_escapes_per_million = aimed;
                if kind != AccelKind::None {
                    let differ = reference.iter().filter(|(k, p)| c.prims.get(*k) != Some(p)).count();
                    row.disagree_per_million = Some(differ as f64 * 1e6 / reference.len().max(1) as f64);
                }
                let line = format!(
                    "{:>16} {:>9} {:>16} {:>9} {:>10.2} {:>10.2} {:>9.2} {:>11.4} {:>9} {:>8.1} {:>7} {:>8.1} {:>7} {:>8.1} {:>7.1} {:>5} {:>9.1} {:>9} {:>9}",
                    short,
                    nt,
                    label,
                    format!("{}x{}", c.size.0, c.size.1),
                    row.build_ms,
                    row.trace_ms,
                    row.trace_ms_spread,
                    rate,
                    row.speedup.map(|s| format!("{s:.0}x")).unwrap_or_else(|| "-".into()),
                    row.nodes_mean,
                    row.nodes_p99,
                    row.prims_mean,
                    row.prims_p99,
                    row.bytes as f64 / nt.max(1) as f64,
                    row.sah_cost,
                    row.depth,
                    row.misses_per_million,
                    aimed.map(|a| format!("{a:.0}")).unwrap_or_else(|| "-".into()),
                    row.disagree_per_million.map(|a| format!("{a:.0}")).unwrap_or_else(|| "-".into())
                );
                pb.suspend(|| println!("{line}"));
                if args.out.is_some() && kind != AccelKind::None && kind_of_rays == RayKind::Primary && mi == 0 {
                    heatmaps.push((
                        format!("cost_{}_{}", file_part(&short), file_part(&row.label)),
                        format!("nodes per camera ray: {short}, {}", row.label),
                        c.size.0,
                        c.size.1,
                        c.nodes,
                    ));
                }
                rows.push(row);
            }
            // Time to image for this scene and ray kind.
            let group: Vec<&Row> = rows[first_row..].iter().collect();
            let t = time_to_image(&group);
            let lines: Vec<String> = t
                .iter()
                .map(|v| {
                    let from = match v["beats_faster_builders_from_spp"].as_f64() {
                        Some(s) if s <= 0.0 => "always".to_string(),
                        Some(s) => format!("from {s:.1} spp"),
                        None => "never".to_string(),
                    };
                    let totals: Vec<String> = v["total_ms"]
                        .as_array()
                        .map(|a| a.iter().map(|p| format!("{:.0}", p[1].as_f64().unwrap_or(0.0))).collect())
                        .unwrap_or_default();
                    format!(
                        "    {:>16}  total ms at 1/4/16/64/256 spp: {:<40} beats faster builders {from}",
                        v["label"].as_str().unwrap_or(""),
                        totals.join(" / ")
                    )
                })
                .collect();
            pb.suspend(|| println!("  time to image, {short}, {} rays:\n{}", kind_of_rays.name(), lines.join("\n")));
            tti.push(serde_json::json!({ "scene": name, "rays": kind_of_rays.name(), "structures": t }));
        }
    }
    pb.finish_and_clear();
    let json = serde_json::to_vec_pretty(&serde_json::json!({ "rows": rows, "time_to_image": tti }))?;
    if let Some(p) = &args.json {
        output::write_atomic(p, &json)?;
    }
    if let Some(d) = &args.out {
        output::write_atomic(&d.join("bench.json"), &json)?;
        output::write_atomic(&d.join("bench.csv"), to_csv(&rows)?.as_bytes())?;
        eprintln!("wrote {} and {}", d.join("bench.csv").display(), d.join("bench.json").display());
        let plots = bench_plots(&d.join("plots"), &rows, &heatmaps, args.intersect[0].name())?;
        eprintln!("wrote {} plots in {}", plots.len(), d.join("plots").display());
    }
    Ok(())
}

/// A file-name-safe version of `s`.
fn file_part(s: &str) -> String {
    s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '.' { c } else { '_' }).collect()
}

/// Draws the benchmark plots into `dir`; returns the files written.
fn bench_plots(
    dir: &Path,
    rows: &[Row],
    heatmaps: &[(String, String, u32, u32, Vec<u32>)],
    first_mode: &str,
) -> Result<Vec<PathBuf>> {
    use render::plots;
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create the directory", dir.display()))?;
    let mut files = Vec::new();
    let ok: Vec<&Row> = rows.iter().filter(|r| r.error.is_none() && r.intersect == first_mode).collect();
    // Per scene and ray kind: Mrays/s bars and time-to-image curves.
    let mut groups: Vec<(&str, &str)> = ok.iter().map(|r| (r.scene.as_str(), r.rays.as_str())).collect();
    groups.dedup();
    for (scene, rays) in groups {
        let g: Vec<&&Row> = ok.iter().filter(|r| r.scene == scene && r.rays == rays).collect();
        let short = scene.strip_prefix("builtin:").unwrap_or(scene);
        let bars: Vec<(String, f64)> = g.iter().map(|r| (r.label.clone(), r.mrays_per_s)).collect();
        let stem = dir.join(format!("mrays_{}_{rays}", file_part(short)));
        files.extend(plots::mrays_bars(&stem, &format!("Mrays/s, {short}, {rays} rays"), &bars)?);
        let spp: Vec<f64> = (0..=10).map(|k| f64::from(1u32 << k)).collect();
        let series: Vec<(String, Vec<(f64, f64)>)> = g
            .iter()
            .filter(|r| r.accel != "none")
            .map(|r| (r.label.clone(), spp.iter().map(|&s| (s, r.build_ms + s * r.trace_ms)).collect()))
            .collect();
        let stem = dir.join(format!("time_to_image_{}_{rays}", file_part(short)));
        let title = format!("time to image, {short}, {rays} rays");
        files.extend(plots::loglog(&stem, &title, "samples per pixel", "build + trace ms", &series)?);
    }
    // Build time against triangle count over the blobs, per structure.
    let blobs: Vec<&&Row> = ok.iter().filter(|r| r.scene.starts_with("builtin:blob:") && r.accel != "none").collect();
    let mut labels: Vec<&str> = blobs.iter().map(|r| r.accel.as_str()).collect();
    labels.sort_unstable();
    labels.dedup();
    let series: Vec<(String, Vec<(f64, f64)>)> = labels
        .iter()
        .map(|l| {
            let mut pts: Vec<(f64, f64)> =
                blobs.iter().filter(|r| r.accel == *l).map(|r| (r.triangles as f64, r.build_ms)).collect();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            pts.dedup_by(|a, b| a.0 == b.0);
            (l.to_string(), pts)
        })
        .collect();
    if series.iter().any(|s| s.1.len() > 1) {
        let stem = dir.join("build_vs_triangles");
        files.extend(plots::loglog(&stem, "build time", "triangles", "build ms", &series)?);
    }
    for (stem, title, w, h, nodes) in heatmaps {
        files.push(plots::heatmap(&dir.join(format!("{stem}.png")), title, *w, *h, nodes)?);
    }
    Ok(files)
}

/// Camera rays per scene checked against the watertight CPU reference.
const REFERENCE_PIXELS: u64 = 16_384;

/// Rays aimed at vertices and edges from inside `builtin:inside:N` per bench row.
const AIMED_RAYS: usize = 300_000;

const BENCH_HEADER: &str = "           scene triangles            accel    pixels   build_ms   trace_ms    spread     Mrays/s   speedup nodes/ray   p99 prims/ray   p99 bytes/tri     SAH depth    miss/M  aimed/M  differ/M";
