//! The `arbor` command line: render, info, devices, bench, compare.

use std::io::Write;
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use arbor::accel::{Accel, AccelKind, BuildOn};
use arbor::bench;
use arbor::gpu::{Context, ContextOptions};
use arbor::render::{self, memory, output, KernelChoice, RenderSettings};
use arbor::scene::Scene;
use clap::Parser;

// The kd-tree builder allocates many short-lived vectors; mimalloc builds the 75k
// benchmark tree about 25% faster than glibc malloc here. It is built with `no_thp` (it
// never asks for transparent huge pages; the system's policy decides) and told by
// `keep_freed_memory` not to give freed memory back: docs/build-notes.md, "Host memory".
#[path = "cli/args.rs"]
mod args;
#[path = "cli/farm_bench.rs"]
mod farm_bench;
#[path = "cli/interrupt.rs"]
mod interrupt;
#[path = "cli/progress.rs"]
mod progress;

use args::{BenchArgs, Cli, Command, CompareArgs, DeviceArgs, InfoArgs, MergeArgs, RenderArgs};
use progress::{BenchProgress, Reporter};

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
        // SAFETY: the one `unsafe` outside src/gpu besides this file's test (docs/build-notes.md,
        // "Host memory"). `mi_option_set` stores an integer in mimalloc's option table; it is
        // called before any thread is started, and -1 ("never purge") is a documented
        // value of this option.
        #[allow(unsafe_code)]
        unsafe {
            libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, -1)
        }
    }
}

fn main() {
    keep_freed_memory();
    let cli = Cli::try_parse().unwrap_or_else(|e| clap_error(e));
    match run(cli) {
        Ok(()) => {}
        // A reader that stopped early (`arbor bench | head -1`) is a normal end.
        Err(e) if is_broken_pipe(&e) => {}
        Err(e) => {
            eprintln!("arbor: error: {e:#}");
            std::process::exit(if e.is::<BadInput>() { 2 } else { 1 });
        }
    }
}

/// Prints a command-line error as one line, like every other error (clap's first line
/// without its prefix; a missing argument by name), and exits with 2. `--help` and
/// `--version` print as clap formats them, to stdout; `arbor` alone prints the usage.
fn clap_error(e: clap::Error) -> ! {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    if !e.use_stderr() {
        let _ = e.print();
        std::process::exit(0);
    }
    if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
        let _ = e.print();
        std::process::exit(2);
    }
    let text = e.render().to_string();
    // "Usage: arbor info [OPTIONS] <SCENE>" names the (sub)command.
    let command = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("Usage: "))
        .map(|u| u.split_whitespace().take_while(|w| !w.starts_with(['[', '<', '-'])).collect::<Vec<_>>().join(" "))
        .filter(|c| !c.is_empty())
        .unwrap_or_else(|| "arbor".into());
    let what = match (e.kind(), e.get(ContextKind::InvalidArg)) {
        (ErrorKind::MissingRequiredArgument, Some(ContextValue::Strings(args))) => {
            format!("missing {}", args.join(", "))
        }
        _ => text.lines().next().unwrap_or("invalid arguments").trim_start_matches("error: ").to_string(),
    };
    eprintln!("arbor: error: {what} (see {command} --help)");
    std::process::exit(2);
}

/// An error in the files a command was given (`arbor compare`): exit status 2, like a
/// command-line error.
#[derive(Debug, thiserror::Error)]
#[error(transparent)]
struct BadInput(arbor::Error);

/// Whether `e` comes from writing to a pipe whose reader has gone.
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        let io = match c.downcast_ref::<arbor::Error>() {
            Some(arbor::Error::Io { cause, .. }) => Some(cause),
            _ => c.downcast_ref::<std::io::Error>(),
        };
        io.is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Writes `text` to stdout (an error, not a panic, when the reader has gone).
fn print_out(text: &str) -> std::io::Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())?;
    out.flush()
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

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// Samples per pixel of `arbor render --integrator path` without --spp: enough for a
/// clean image of the built-in scenes (README, "Path tracing").
const DEFAULT_PATH_SPP: u32 = 64;

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(args) => render(&args),
        Command::Info(args) => info(&args),
        Command::Devices => devices(),
        Command::Bench(args) => bench(&args),
        Command::Compare(args) => compare(&args),
        Command::Merge(args) => merge(&args),
    }
}

fn render(a: &RenderArgs) -> Result<()> {
    let start = Instant::now();
    let aovs = output::parse_aovs(&a.aov)?;
    let params = a.structure.single()?;
    let format = output::format_of(&a.output, "image")?;
    let paths = std::iter::once(&a.output).chain(aovs.iter().map(|(_, p)| p)).chain(&a.stats);
    output::check_outputs(paths.map(|p| p.as_path()))?;
    let integrator = render::Integrator::parse(&a.integrator).unwrap_or_default();
    let spp = a.spp.unwrap_or(if integrator == render::Integrator::Path { DEFAULT_PATH_SPP } else { 1 });
    if spp == 0 || spp > 1 << 20 {
        bail!("--spp must be 1..=1048576, got {spp}");
    }
    if integrator == render::Integrator::Whitted && (a.time.is_some() || a.checkpoint.is_some()) {
        bail!("--time and --checkpoint need --integrator path");
    }
    if let Some(c) = a.checkpoint {
        if !(c.is_finite() && c > 0.0) {
            bail!("--checkpoint must be a positive number of seconds, got {c}");
        }
    }
    let size = a.size.as_deref().map(parse_size).transpose()?;
    let scene = Scene::load(&a.scene)?;
    let load_ms = ms(start);
    warn_if_only_emissive(&scene, integrator);
    let (w, h) = size.unwrap_or((scene.width, scene.height));
    let mut encoded = vec![(format, 3)];
    for (name, path) in &aovs {
        encoded.push((output::format_of(path, "aov")?, output::aov_channel_count(name)));
    }
    let stored = scene.stored_triangles() as usize + scene.spheres.len();
    memory::check_render(&format!("--size {w}x{h}"), w, h, stored, &encoded)?;
    let (accel, why) = resolve_accel(&a.accel, &scene, u64::from(w) * u64::from(h), spp)?;
    if let (Some(why), false) = (&why, a.quiet) {
        eprintln!("accel auto: {why}");
    }
    let scene = flatten_if(scene, a.flatten, accel, a.quiet)?;
    let opened = Instant::now();
    let ctx = context(&a.device)?;
    let device_ms = ms(opened);
    let mut settings = RenderSettings::for_size(w, h);
    settings.spp = spp;
    settings.integrator = integrator;
    settings.time_budget = a.time;
    settings.max_depth = a.max_depth;
    settings.mis = match a.mis.as_str() {
        "light" => render::Mis::Light,
        "bsdf" => render::Mis::Bsdf,
        _ => render::Mis::Both,
    };
    settings.seed = a.seed;
    settings.intersect = a.intersect;
    settings.traversal = a.traversal.parse().map_err(anyhow::Error::msg)?;
    settings.accel = accel;
    settings.params = params;
    settings.dispatch_budget = a.dispatch_budget.max(1);
    settings.trace_steps = a.trace_steps;
    settings.kernel = if a.kernel == "general" { KernelChoice::General } else { KernelChoice::Specialized };
    let (spp_total, shard_name) = shard_settings(a, &mut settings)?;
    settings.check()?;
    let part = render::part::PartInfo::new(&scene, &settings, spp_total, shard_name);
    if let Some(path) = &a.resume {
        settings.resume = Some(std::sync::Arc::new(resumable(path, &part)?));
    }
    let spp = settings.spp;
    let mut part_note = String::new();
    if let Some(c) = settings.crop {
        part_note += &format!(", window {},{},{},{}", c.x0, c.x1, c.y0, c.y1);
    }
    if settings.first_sample > 0 {
        part_note += &format!(", samples {}..{}", settings.first_sample, settings.first_sample + spp);
    }
    let (frame, mut st) = trace(&ctx, &scene, &settings, a, &aovs, &part)?;
    st.load_ms = load_ms;
    st.device_ms = device_ms;
    write_outputs(a, &aovs, &frame, Some(&st), &part)?;
    if st.interrupted && interrupt::requested() {
        let resume = if format == output::Format::Exr {
            format!("; continue it with --resume {}", a.output.display())
        } else {
            String::new()
        };
        eprintln!(
            "arbor: interrupted: wrote {} with {} of {spp} samples per pixel{resume}",
            a.output.display(),
            st.samples_done
        );
        std::process::exit(interrupt::EXIT_CODE);
    }
    if !a.quiet {
        let trace = match st.trace_ms {
            Some(t) => format!("{t:.1} ms GPU"),
            None => format!("{:.0} ms wall (no GPU timestamps)", st.wall_ms),
        };
        let mr = st.mrays_per_s.map(|m| format!("{m:.4} Mrays/s, ")).unwrap_or_default();
        eprintln!(
            "wrote {} ({w}x{h}{part_note}, {} {}{} spp, {} triangles{}, {} spheres, accel {}) on {}: load {load_ms:.0} ms, build {:.0} ms, trace {trace} ({mr}{} dispatches{}), total {:.0} ms",
            a.output.display(),
            st.integrator,
            st.samples_done,
            if st.samples_done < spp { format!(" of {spp}") } else { String::new() },
            st.triangles,
            if st.instances > 0 { format!(" ({} instances)", st.instances) } else { String::new() },
            st.spheres,
            st.accel,
            st.device,
            st.build_ms,
            st.dispatches,
            if st.resumed_samples > 0 {
                format!(
                    "; {} pixel samples ran out of traversal steps and were resumed in {} more",
                    st.resumed_samples, st.resume_dispatches
                )
            } else {
                String::new()
            },
            ms(start)
        );
    }
    Ok(())
}

/// Writes the image, the AOVs and the statistics of a render: all of them or none.
/// A checkpoint (`st` None) writes the image and the AOVs.
fn write_outputs(
    a: &RenderArgs,
    aovs: &[(String, std::path::PathBuf)],
    frame: &render::Frame,
    st: Option<&render::RenderStats>,
    part: &render::part::PartInfo,
) -> Result<()> {
    let (w, h) = (frame.width, frame.height);
    let mut set = output::OutputSet::new();
    output::write_frame(&mut set, &a.output, part, frame)?;
    output::write_aovs(&mut set, aovs, frame, w, h)?;
    if let (Some(p), Some(st)) = (&a.stats, st) {
        let provenance = output::Provenance {
            version: env!("CARGO_PKG_VERSION").into(),
            seed: a.seed,
            spp: st.spp,
            width: w,
            height: h,
            integrator: st.integrator.clone(),
            command_line: std::env::args_os().map(|s| s.to_string_lossy().into_owned()).collect(),
        };
        output::write_stats(&mut set, p, st, provenance)?;
    }
    Ok(set.commit()?)
}

/// Applies `--crop`, `--shard`, `--shard-by` and `--sample-offset` to `settings`
/// (whose `spp` is the whole render's); returns what a part records: the total
/// samples per pixel (the `--spp` split by a sample shard, else 0) and the shard
/// (`I/N tiles`, empty when not a shard).
fn shard_settings(a: &RenderArgs, settings: &mut RenderSettings) -> Result<(u32, String)> {
    let mut window = render::Crop::full(settings.width, settings.height);
    if let Some(c) = &a.crop {
        window = render::Crop::parse(c).map_err(anyhow::Error::msg)?;
        window.check(settings.width, settings.height)?;
    }
    let first = a.sample_offset.unwrap_or(0);
    let by: render::shard::ShardBy = a.shard_by.parse().map_err(anyhow::Error::msg)?;
    let shard = a.shard.as_deref().map(|s| render::shard::Shard::parse(s, |v| std::env::var(v).ok())).transpose()?;
    let (window, first, count) = match &shard {
        Some(s) => s.plan(by, window, first, settings.spp)?,
        None => (window, first, settings.spp),
    };
    // Only a sample shard is a part of a known total; other parts may be extended.
    let total = if a.shard.is_some() && by == render::shard::ShardBy::Samples { settings.spp } else { 0 };
    settings.crop = (window != render::Crop::full(settings.width, settings.height)).then_some(window);
    settings.first_sample = first;
    settings.spp = count;
    Ok((total, shard.map(|s| s.describe(by)).unwrap_or_default()))
}

/// Reads the part `--resume` names and checks that this command renders the same
/// window and samples of the same image.
fn resumable(path: &std::path::Path, part: &render::part::PartInfo) -> Result<render::Frame> {
    let (info, frame) = render::part::read(path)?;
    let why = if info.hash != part.hash || info.version != part.version {
        Some("it was rendered from another scene or other settings than this command's".to_string())
    } else if (info.width, info.height) != (part.width, part.height) || info.crop != part.crop {
        Some(format!(
            "it holds the window {},{},{},{} of a {}x{} image, this command renders {},{},{},{} of {}x{}",
            info.crop.x0,
            info.crop.x1,
            info.crop.y0,
            info.crop.y1,
            info.width,
            info.height,
            part.crop.x0,
            part.crop.x1,
            part.crop.y0,
            part.crop.y1,
            part.width,
            part.height
        ))
    } else if info.first_sample != part.first_sample || info.samples > part.samples {
        // The same first sample and no more samples than this command's range: a
        // larger --spp continues a finished render too.
        Some(format!(
            "it holds samples from the range {:?}, which does not start this command's {:?}",
            info.sample_range(),
            part.sample_range()
        ))
    } else {
        None
    };
    match why {
        Some(why) => bail!("--resume {}: {why}", path.display()),
        None => Ok(frame),
    }
}

/// `arbor merge`: parts into one image (and AOVs), written together or not at all.
fn merge(a: &MergeArgs) -> Result<()> {
    let start = Instant::now();
    let aovs = output::parse_aovs(&a.aov)?;
    output::format_of(&a.output, "image")?;
    let paths = std::iter::once(&a.output).chain(aovs.iter().map(|(_, p)| p));
    output::check_outputs(paths.map(|p| p.as_path()))?;
    let mut parts = Vec::new();
    // Parts decode in parallel (each decoder on one thread); the first failure in the
    // order given is reported.
    use rayon::prelude::*;
    let read: Vec<_> = a.parts.par_iter().map(|path| render::part::read(path).map(|(i, f)| (path, i, f))).collect();
    for r in read {
        let (path, info, frame) = r.map_err(BadInput)?;
        parts.push(render::merge::Part { path: path.clone(), info, frame });
    }
    let n = parts.len();
    let (info, frame) = render::merge::merge(parts, a.allow_partial).map_err(BadInput)?;
    let mut set = output::OutputSet::new();
    output::write_frame(&mut set, &a.output, &info, &frame)?;
    output::write_aovs(&mut set, &aovs, &frame, frame.width, frame.height)?;
    set.commit()?;
    if !a.quiet {
        let fewest = frame.samples.iter().copied().min().unwrap_or(0);
        eprintln!(
            "wrote {} ({}x{}, samples {}..{}, fewest per pixel {fewest}) from {n} parts in {:.0} ms",
            a.output.display(),
            info.width,
            info.height,
            info.first_sample,
            info.first_sample + info.samples,
            ms(start)
        );
    }
    Ok(())
}

/// With the Whitted integrator an emissive material lights nothing else: say so when
/// it is the scene's only light.
fn warn_if_only_emissive(scene: &Scene, integrator: render::Integrator) {
    if integrator == render::Integrator::Whitted
        && scene.lights.is_empty()
        && scene.materials.iter().any(|m| m.emission != glam::Vec3::ZERO)
    {
        eprintln!(
            "arbor: warning: {}: emissive materials do not light other surfaces with the whitted integrator (no point or directional light)",
            scene.name
        );
    }
}

/// Renders with progress: a bar on an interactive stderr after the first second, else
/// a plain line every few seconds; none with `quiet`.
/// SIGINT and SIGTERM stop a path-traced render after its current sample wave; the
/// image so far is written and the exit code is [`interrupt::EXIT_CODE`].
fn trace(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    a: &RenderArgs,
    aovs: &[(String, std::path::PathBuf)],
    part: &render::part::PartInfo,
) -> Result<(render::Frame, render::RenderStats)> {
    interrupt::install();
    let progress = Reporter::new("render", a.quiet, false);
    progress.bar().set_message(format!("tracing {} (pixel samples)", scene.name));
    let checkpoint = a.checkpoint.map(|every| {
        let write = move |frame: &render::Frame| -> arbor::error::Result<()> {
            write_outputs(a, aovs, frame, None, part)
                .map_err(|e| arbor::error::Error::Usage(format!("checkpoint: {e:#}")))
        };
        (every, Box::new(write) as Box<dyn FnMut(&render::Frame) -> arbor::error::Result<()>>)
    });
    let control = render::path::Control {
        progress: Box::new(|done, total| progress.update(done, total)),
        interrupted: Box::new(interrupt::requested),
        checkpoint,
    };
    let done = render::gpu::render_controlled(ctx, scene, settings, control);
    progress.finish();
    Ok(done?)
}

/// `bench --shards`: the one --scene path traced as N shards, each its own process.
fn bench_shards(args: &BenchArgs) -> Result<()> {
    let [scene] = args.scene.as_slice() else {
        bail!("--shards needs exactly one --scene");
    };
    if let Some(bad) = args.shards.iter().find(|&&n| n == 0 || n > 4096) {
        bail!("--shards {bad}: each shard count must be 1..=4096");
    }
    // The default list (every structure) means render's default here.
    let accel = if args.accel == AccelKind::ALL.to_vec() { AccelKind::Kdtree } else { args.accel[0] };
    if args.accel.len() > 1 && args.accel != AccelKind::ALL.to_vec() {
        bail!("--shards renders with one structure: give one --accel");
    }
    let (w, h) = parse_size(&args.size)?;
    let spp = args.spp.unwrap_or(DEFAULT_PATH_SPP);
    let base: Vec<String> = vec![
        scene.clone(),
        "--size".into(),
        format!("{w}x{h}"),
        "--spp".into(),
        spp.to_string(),
        "--accel".into(),
        accel.name().into(),
    ];
    eprintln!("bench --shards: {scene} at {w}x{h}, path tracing, {spp} spp, accel {}", accel.name());
    let text = farm_bench::run(&base, &args.shards, &args.shard_by, false)?;
    Ok(print_out(&text)?)
}

/// `bench --reference`: error against time over a ladder of sample counts.
fn bench_convergence(args: &BenchArgs, reference: &std::path::Path) -> Result<()> {
    let [scene_arg] = args.scene.as_slice() else {
        bail!("--reference needs exactly one --scene (the scene the reference image shows)");
    };
    if let Some(bad) = args.ladder.iter().find(|&&n| n == 0 || n > 1 << 20) {
        bail!("--ladder {bad}: each sample count must be 1..=1048576");
    }
    if let Some(d) = &args.out {
        std::fs::create_dir_all(d).with_context(|| format!("{}: cannot create the --out directory", d.display()))?;
        output::check_outputs(std::iter::once(d.join("convergence.csv").as_path()))?;
    }
    let scene = Scene::load(scene_arg)?;
    let ladder = bench::convergence::Ladder {
        reference: reference.to_path_buf(),
        accel: args.accel.iter().copied().filter(|k| !k.is_brute_force() || scene.prim_count() <= 4096).collect(),
        params: args.structure.params()?,
        integrators: args.integrator.iter().filter_map(|n| render::Integrator::parse(n)).collect(),
        spp: args.ladder.clone(),
        seed: 0,
    };
    let ctx = context(&args.device)?;
    eprintln!(
        "device: {} ({}); {} at {}x{} against {}; brute force only on scenes of at most 4096 primitives",
        ctx.info().name,
        ctx.info().driver,
        scene.name,
        scene.width,
        scene.height,
        reference.display()
    );
    print_out(&format!("{}\n", bench::convergence::HEADER))?;
    let progress = BenchProgress(Reporter::new("bench", false, true));
    let rows = bench::convergence::run(&ctx, &scene, &ladder, &progress, |l| {
        print_out(&format!("{l}\n")).map_err(|e| arbor::error::Error::Usage(e.to_string()))
    });
    progress.0.finish();
    let rows = rows?;
    if let Some(d) = &args.out {
        bench::convergence::write(d, &rows)?;
    }
    Ok(())
}

/// The scene with its instances flattened into copies where asked, or where brute
/// force (which has no instance level) will trace it.
fn flatten_if(scene: Scene, asked: bool, accel: AccelKind, quiet: bool) -> Result<Scene> {
    if !scene.has_instances() || !(asked || accel.is_brute_force()) {
        return Ok(scene);
    }
    if !asked && !quiet {
        eprintln!("accel none: brute force has no instance level; drawing the instances as copies");
    }
    Ok(scene.flattened()?)
}

fn info(a: &InfoArgs) -> Result<()> {
    let params = a.structure.single()?;
    let scene = Scene::load(&a.scene)?;
    let (accel, why) = resolve_accel(&a.accel, &scene, u64::from(scene.width) * u64::from(scene.height), 1)?;
    let scene = flatten_if(scene, a.flatten, accel, true)?;
    let built = match params.build {
        BuildOn::Cpu => Accel::build_with(accel, &scene, &params),
        BuildOn::Gpu => Accel::build_on(&context(&a.device)?, accel, &scene, &params)?,
    };
    let report = arbor::info::Report::new(&scene, accel, params.build, why, &built);
    print_out(&if a.json { format!("{}\n", report.to_json()) } else { report.to_string() })?;
    report.validation.map_err(|e| anyhow::anyhow!("{}: structure failed validation: {e}", scene.name))
}

fn devices() -> Result<()> {
    let list = Context::list_devices()?;
    if list.is_empty() {
        bail!("no Vulkan 1.2 device with a compute queue");
    }
    let mut text = String::new();
    for d in list {
        text += &format!(
            "{}: {} ({}, Vulkan {}, {}), maxStorageBufferRange {} bytes, timestampPeriod {} ns, subgroup {}, ray query {}\n",
            d.index,
            d.name,
            d.kind,
            d.api_version,
            d.driver,
            d.max_storage_buffer_range,
            d.timestamp_period_ns,
            d.subgroup_size,
            match &d.ray_query_missing {
                None => "yes".to_string(),
                Some(m) => format!("no (lacks {m})"),
            }
        );
    }
    Ok(print_out(&text)?)
}

/// `arbor bench`: every input (sizes, values, scenes, memory, output paths) is checked
/// before a device is opened and anything is printed.
fn bench(args: &BenchArgs) -> Result<()> {
    if let Some(reference) = &args.reference {
        return bench_convergence(args, reference);
    }
    if !args.shards.is_empty() {
        return bench_shards(args);
    }
    let size = if args.quick && args.size == "256x256" { (128, 128) } else { parse_size(&args.size)? };
    let opts = bench::Request {
        tris: args.tris.clone(),
        scenes: args.scene.clone(),
        accel: args.accel.clone(),
        params: args.structure.params()?,
        builds: args.structure.build.clone(),
        lambda: args.lambda.clone(),
        rays: args.rays.clone(),
        shadow: args.shadow,
        intersect: args.intersect.clone(),
        traversal: args.traversal.parse().map_err(anyhow::Error::msg)?,
        size,
        repeat: args.repeat,
        quick: args.quick,
        out: args.out.clone(),
        json: args.json.clone(),
    }
    .options()?;
    if let Some(p) = &args.json {
        output::check_writable(p)?;
    }
    if let Some(d) = &args.out {
        if d.exists() && !d.is_dir() {
            bail!("{}: --out is not a directory", d.display());
        }
    }
    let scenes = bench::load_scenes(&opts)?;
    if let Some(d) = &args.out {
        std::fs::create_dir_all(d).with_context(|| format!("{}: cannot create the --out directory", d.display()))?;
        let files = [d.join("bench.json"), d.join("bench.csv")];
        output::check_outputs(files.iter().map(|p| p.as_path()).chain(args.json.as_deref()))?;
    }
    let ctx = context(&args.device)?;
    eprintln!(
        "device: {} ({}, {}); {}x{} camera rays, kinds {}; brute force on a smaller image of the same view; median of {} rounds (structures in turn) after 1 warm-up",
        ctx.info().name,
        ctx.info().kind,
        ctx.info().driver,
        size.0,
        size.1,
        opts.rays.iter().map(|k| k.name()).collect::<Vec<_>>().join(", "),
        opts.repeat
    );
    print_out(&format!("{}\n", bench::HEADER))?;
    let progress = BenchProgress(Reporter::new("bench", false, true));
    let done = bench::run(&ctx, &opts, Some(scenes), &progress);
    progress.0.finish();
    Ok(done?)
}

/// `arbor compare`: both images are read and checked before --diff is written.
fn compare(a: &CompareArgs) -> Result<()> {
    use arbor::render::compare as cmp;
    let checked = || -> arbor::Result<(u32, u32, cmp::ErrorStats, Option<Vec<u8>>)> {
        if let Some(d) = &a.diff {
            if !d.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
                return Err(arbor::Error::invalid(d, "--diff must end in .png"));
            }
            output::check_writable(d)?;
        }
        let (w, h, test, reference) = cmp::read_pair(&a.test, &a.reference)?;
        let png = a.diff.as_ref().map(|_| cmp::error_png(w, h, &test, &reference)).transpose()?;
        Ok((w, h, cmp::compare(&test, &reference), png))
    };
    let (w, h, st, png) = checked().map_err(BadInput)?;
    if let (Some(d), Some(png)) = (&a.diff, png) {
        output::write_atomic(d, &png).map_err(BadInput)?;
    }
    let text = if a.json {
        format!("{}\n", st.to_json(w, h))
    } else {
        format!("mse      {}\nrel_mse  {}\npsnr     {} dB\nmax_abs  {}\n", st.mse, st.rel_mse, st.psnr, st.max_abs)
    };
    Ok(print_out(&text)?)
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
