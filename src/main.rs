//! The `arbor` command line: render, info, devices, bench.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use arbor::accel::AccelKind;
use arbor::bench::{self, RayKind};
use arbor::gpu::{Context, ContextOptions};
use arbor::render::{self, output, KernelChoice, RenderSettings};
use arbor::scene::Scene;
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

// The kd-tree builder allocates many short-lived vectors; mimalloc builds the 75k
// benchmark tree about 25% faster than glibc malloc here. It is built with `no_thp` (it
// never asks for transparent huge pages; the system's policy decides) and told by
// `keep_freed_memory` not to give freed memory back: README, "Host memory".
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// mimalloc v3's `mi_option_purge_delay` (its place in `mi_option_e`, mimalloc.h; the
/// `libmimalloc-sys` crate names no constant for it). Its default is 1000 (ms), which
/// `purge_delay_option_is_the_one_meant` checks.
const MI_OPTION_PURGE_DELAY: libmimalloc_sys::mi_option_t = 15;

/// Keep the memory arbor frees for its own reuse instead of returning it to the OS a
/// second later (mimalloc's default). Builds then reuse pages the scene loading or an
/// earlier structure freed instead of faulting in fresh ones: on the development VM a
/// 1M-triangle LBVH built after other structures took 71-85 ms with purging and 60-66
/// without, as long as a repeated build. `MIMALLOC_PURGE_DELAY`, when set, still wins.
fn keep_freed_memory() {
    if std::env::var_os("MIMALLOC_PURGE_DELAY").is_none() {
        // SAFETY: the one `unsafe` outside src/gpu besides this file's test (README, "Host
        // memory"). `mi_option_set` stores an integer in mimalloc's option table; it is
        // called before any thread is started, and -1 ("never purge") is a documented
        // value of this option.
        #[allow(unsafe_code)]
        unsafe {
            libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, -1)
        }
    }
}

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
VK_DRIVER_FILES pins a Vulkan driver (e.g. lavapipe); ARBOR_FONT=FILE.ttf sets the font of `bench --out` plots; \
MIMALLOC_PURGE_DELAY=MS lets the allocator give freed memory back to the OS after MS ms (default: arbor keeps it for reuse)."
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

/// Builder parameters of the structures, shared by render, info and bench.
#[derive(clap::Args, Clone)]
struct StructureArgs {
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
    /// trbvh restructuring: a preset (default: 7-leaf treelets, 3 rounds with minimum
    /// subtree sizes 7, 7, 28; paper: 7, 14, 28 as Karras & Aila; fast: 5-leaf
    /// treelets, faster build, higher SAH; quality: every round at 7, lower SAH, longer
    /// build) and/or leaves=3..7, rounds=0..8, gamma=A/B/... (each round's minimum
    /// subtree size as a multiple of leaves; sets the rounds), e.g. leaves=6,gamma=1/2/4.
    #[arg(long, default_value = "default", value_name = "PRESET|KEY=VALUE,...")]
    trbvh: String,
    /// Where to build: cpu (every structure), or gpu (lbvh and trbvh as Vulkan compute
    /// kernels; the same tree as the CPU builder's, word for word). `bench` takes a
    /// list (cpu,gpu): one row per structure and build device.
    #[arg(long, value_delimiter = ',', default_value = "cpu", value_name = "cpu|gpu")]
    build: Vec<arbor::accel::BuildOn>,
}

impl StructureArgs {
    /// The parameters of a command that builds once (render, info).
    fn single(&self) -> Result<arbor::accel::AccelParams> {
        if self.build.len() > 1 {
            bail!("--build takes one of cpu, gpu here (a list only in bench)");
        }
        self.params()
    }

    fn params(&self) -> Result<arbor::accel::AccelParams> {
        let mut p =
            arbor::accel::AccelParams { build: self.build.first().copied().unwrap_or_default(), ..Default::default() };
        for (flag, spec) in [("kd", &self.kd), ("grid", &self.grid), ("octree", &self.octree), ("trbvh", &self.trbvh)] {
            p.set_flag(flag, spec)?;
        }
        Ok(p)
    }
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
    /// Timed rounds (after one warm-up round); in each, every structure builds and
    /// traces once, in turn; medians are reported.
    #[arg(long, default_value_t = 5)]
    repeat: usize,
    /// Write all figures as JSON here.
    #[arg(long, value_name = "PATH")]
    json: Option<PathBuf>,
    #[command(flatten)]
    structure: StructureArgs,
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
        #[command(flatten)]
        structure: StructureArgs,
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
        #[command(flatten)]
        structure: StructureArgs,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
        /// Device for --build gpu (unused otherwise).
        #[command(flatten)]
        device: DeviceArgs,
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
    keep_freed_memory();
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
            structure,
            intersect,
        } => {
            let aovs = parse_aovs(&aov)?;
            let params = structure.single()?;
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
            let scene = Scene::load(&scene)?;
            let (w, h) = size.unwrap_or((scene.width, scene.height));
            let (accel, why) = resolve_accel(&accel, &scene, u64::from(w) * u64::from(h), spp)?;
            if let (Some(why), false) = (&why, quiet) {
                eprintln!("accel auto: {why}");
            }
            let ctx = context(&device)?;
            let mut settings = RenderSettings::for_size(w, h);
            settings.spp = spp;
            settings.seed = seed;
            settings.intersect = intersect;
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
        Command::Info { scene, accel, json, structure, device } => {
            let params = structure.single()?;
            let scene = Scene::load(&scene)?;
            let (accel, why) = resolve_accel(&accel, &scene, u64::from(scene.width) * u64::from(scene.height), 1)?;
            let built = match params.build {
                arbor::accel::BuildOn::Cpu => arbor::accel::Accel::build_with(accel, &scene, &params),
                arbor::accel::BuildOn::Gpu => {
                    arbor::accel::Accel::build_on(&context(&device)?, accel, &scene, &params)?
                }
            };
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
                "built_on": params.build.name(),
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
                println!("  built on      {}", params.build.name().to_uppercase());
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
                    match &ph.detail {
                        Some(d) => println!("  phase         {:<22} {:.2} ms  ({d})", ph.name, ph.ms),
                        None => println!("  phase         {:<22} {:.2} ms", ph.name, ph.ms),
                    }
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
                    "{}: {} ({}, Vulkan {}, {}), maxStorageBufferRange {} bytes, timestampPeriod {} ns, subgroup {}",
                    d.index,
                    d.name,
                    d.kind,
                    d.api_version,
                    d.driver,
                    d.max_storage_buffer_range,
                    d.timestamp_period_ns,
                    d.subgroup_size
                );
            }
            Ok(())
        }
        Command::Bench(args) => {
            println!("{}", bench::HEADER);
            bench(&args)
        }
    }
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
        } else if matches!(kind, AccelKind::Lbvh | AccelKind::Trbvh) {
            for &on in &args.structure.build {
                let p = arbor::accel::AccelParams { build: on, ..*base };
                let label = match on {
                    arbor::accel::BuildOn::Cpu => kind.name().to_string(),
                    arbor::accel::BuildOn::Gpu => format!("{}@gpu", kind.name()),
                };
                out.push((kind, p, label));
            }
        } else {
            out.push((
                kind,
                arbor::accel::AccelParams { build: arbor::accel::BuildOn::Cpu, ..*base },
                kind.name().to_string(),
            ));
        }
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
    let params = args.structure.params()?;
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
        "device: {} ({}); {w}x{h} camera rays, kinds {}; brute force on a smaller image of the same view; median of {repeat} rounds (structures in turn) after 1 warm-up",
        ctx.info().name,
        ctx.info().kind,
        kinds.iter().map(|k| k.name()).collect::<Vec<_>>().join(", ")
    );
    let pb = progress_bar(false);
    if std::io::stderr().is_terminal() {
        pb.set_draw_target(ProgressDrawTarget::stderr());
    }
    let opts = bench::Options {
        scenes,
        variants,
        rays: kinds,
        intersect: args.intersect.clone(),
        size: (w, h),
        repeat,
        out: args.out.clone(),
        json: args.json.clone(),
    };
    bench::run(&ctx, &opts, &BarProgress(pb.clone()))?;
    pb.finish_and_clear();
    Ok(())
}

/// The progress bar as the benchmark's reporter.
struct BarProgress(ProgressBar);

impl bench::Progress for BarProgress {
    fn set_length(&self, n: u64) {
        self.0.set_length(n);
    }
    fn message(&self, m: String) {
        self.0.set_message(m);
    }
    fn inc(&self, n: u64) {
        self.0.inc(n);
    }
    fn line(&self, l: &str) {
        self.0.suspend(|| println!("{l}"));
    }
    fn note(&self, l: &str) {
        self.0.suspend(|| eprintln!("{l}"));
    }
}

#[cfg(test)]
mod tests {
    /// Option 15 is the purge delay (its default, 1000 ms, is no other option's), and
    /// `keep_freed_memory` turns purging off.
    #[test]
    fn purge_delay_option_is_the_one_meant() {
        // SAFETY: reads an integer from mimalloc's option table.
        #[allow(unsafe_code)]
        let get = || unsafe { libmimalloc_sys::mi_option_get(super::MI_OPTION_PURGE_DELAY) };
        if std::env::var_os("MIMALLOC_PURGE_DELAY").is_some() {
            return;
        }
        assert_eq!(get(), 1000, "option {} is not mimalloc's purge delay", super::MI_OPTION_PURGE_DELAY);
        super::keep_freed_memory();
        assert_eq!(get(), -1);
    }
}
