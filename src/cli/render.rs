//! `arbor render` (included by main.rs only): the settings from the arguments, shards
//! and `--resume`, the trace with progress and interruption, checkpoints, and the
//! outputs written together.

use std::time::Instant;

use anyhow::{bail, Result};
use arbor::gpu::Context;
use arbor::render::output::{self, memory};
use arbor::render::{self, KernelChoice, RenderSettings};
use arbor::scene::Scene;

use crate::args::RenderArgs;
use crate::common::{
    aov_scale, context, flatten_if, ms, parse_size, resolve_accel, start_trace, trace_device, usage, DEFAULT_PATH_SPP,
};
use crate::interrupt;
use crate::progress::Reporter;

/// `arbor render`: every setting is checked and the memory it needs estimated before the
/// device is opened; then the trace, the outputs (all or none) and the summary line.
pub(crate) fn run(a: &RenderArgs) -> Result<()> {
    let start = Instant::now();
    let aovs = output::parse_aovs(&a.aov)?;
    let scale = aov_scale(a.aov_scale.as_deref(), &aovs)?;
    let params = a.structure.single()?;
    let format = output::format_of(&a.output, "image")?;
    let paths = std::iter::once(&a.output).chain(aovs.iter().map(|(_, p)| p)).chain(&a.stats);
    output::check_outputs(paths.chain(&a.trace.trace_events).map(|p| p.as_path()))?;
    let _recording = start_trace(&a.trace, "render")?;
    let integrator = render::Integrator::parse(&a.integrator).unwrap_or_default();
    let spp = a.spp.unwrap_or(if integrator == render::Integrator::Whitted { 1 } else { DEFAULT_PATH_SPP });
    if spp == 0 || spp > 1 << 20 {
        return Err(usage(format!("--spp must be 1..=1048576, got {spp}")));
    }
    if integrator == render::Integrator::Whitted && (a.time.is_some() || a.checkpoint.is_some()) {
        return Err(usage("--time and --checkpoint need --integrator path or sppm"));
    }
    let sppm = sppm_settings(a, integrator)?;
    if let Some(c) = a.checkpoint {
        if !(c.is_finite() && c > 0.0) {
            return Err(usage(format!("--checkpoint must be a positive number of seconds, got {c}")));
        }
    }
    let size = a.size.as_deref().map(parse_size).transpose()?;
    let scene = Scene::load(&a.scene)?;
    crate::common::warn_scene(&scene);
    let load_ms = ms(start);
    let (w, h) = size.unwrap_or((scene.width, scene.height));
    let mut encoded = vec![(format, 3)];
    for (name, path) in &aovs {
        encoded.push((output::format_of(path, "aov")?, output::aov_channel_count(name)));
    }
    let stored = scene.stored_triangles() as usize + scene.spheres.len();
    memory::check_render(&format!("--size {w}x{h}"), w, h, stored, &encoded)?;
    let (accel, why) = resolve_accel(&a.accel, &scene, u64::from(w) * u64::from(h), spp, params.build)?;
    if let Some((n, _)) = aovs.iter().find(|(n, _)| output::HEATMAP_AOVS.contains(&n.as_str())) {
        if accel.driver_built() {
            return Err(usage(format!("--aov {n}: {accel} is the driver's structure, whose traversal does not say how many nodes it visited or primitives it tested")));
        }
    }
    let mut heat = output::HeatmapInfo { subject: format!("{}, {accel}", scene.name), scale };
    let scene = flatten_if(scene, a.flatten, accel, a.quiet)?;
    arbor::accel::check_build(accel, &scene, params.build)?;
    let mut settings = RenderSettings::for_size(w, h);
    settings.spp = spp;
    settings.integrator = integrator;
    settings.time_budget = a.time;
    settings.max_depth = a.max_depth;
    settings.sppm = sppm;
    settings.mis = match a.mis.as_str() {
        "light" => render::Mis::Light,
        "bsdf" => render::Mis::Bsdf,
        _ => render::Mis::Both,
    };
    settings.seed = a.seed;
    settings.intersect = a.intersect;
    settings.traversal = a.traversal.parse().map_err(crate::common::usage)?;
    settings.accel = accel;
    settings.params = params;
    a.pacing.apply(&mut settings);
    settings.trace_steps = a.trace_steps;
    settings.kernel = if a.kernel == "general" { KernelChoice::General } else { KernelChoice::Specialized };
    let (spp_total, shard_name) = shard_settings(a, &mut settings)?;
    let part_args = (spp_total, shard_name.clone());
    if let Some((n, _)) = aovs.iter().find(|(n, _)| output::HEATMAP_AOVS.contains(&n.as_str())) {
        if settings.first_sample > 0 {
            eprintln!(
                "arbor: warning: --aov {n}: the counts belong to each pixel's sample 0, which this render (samples from {}) does not trace: they are all 0",
                settings.first_sample
            );
        }
    }
    settings.check()?;
    let mut part = render::output::part::PartInfo::new(&scene, &settings, spp_total, shard_name);
    if let Some(path) = &a.resume {
        settings.resume = Some(std::sync::Arc::new(resumable(path, &part)?));
    }
    // Every check of the command line and its inputs above; the device only now.
    let opened = Instant::now();
    let ctx = {
        let _span = arbor::timeline::span("device", || "open device");
        context(&a.device)?
    };
    trace_device(&ctx);
    let device_ms = ms(opened);
    // Auto drops what does not fit the device, but for the parts of a farm render,
    // which must pick alike on every node (docs/farm.md).
    let farm_part = a.shard.is_some() || a.resume.is_some();
    let why = match why {
        Some(_) if !farm_part => {
            let fit = arbor::accel::auto::Fit::of(&ctx);
            let costs = crate::common::device_costs(&ctx);
            // Without --build, auto also answers where to build.
            let build = a.structure.build.first().copied();
            let pixels = u64::from(w) * u64::from(h);
            let ((kind, on), why) = arbor::accel::auto::choose_on(&scene, pixels, spp, &fit, &costs, build)?;
            if (kind, on) != (settings.accel, settings.params.build) {
                settings.accel = kind;
                settings.params.build = on;
                heat.subject = format!("{}, {kind}", scene.name);
                part = render::output::part::PartInfo::new(&scene, &settings, part_args.0, part_args.1);
            }
            Some(why)
        }
        why => why,
    };
    if let (Some(why), false) = (&why, a.quiet) {
        eprintln!("accel auto: {why}");
    }
    let spp = settings.spp;
    let mut part_note = String::new();
    if let Some(c) = settings.crop {
        part_note += &format!(", window {},{},{},{}", c.x0, c.x1, c.y0, c.y1);
    }
    if settings.first_sample > 0 {
        part_note += &format!(", samples {}..{}", settings.first_sample, settings.first_sample + spp);
    }
    let (frame, mut st) = trace(&ctx, &scene, &settings, a, (&aovs, &heat), &part)?;
    st.load_ms = load_ms;
    st.device_ms = device_ms;
    write_outputs(a, (&aovs, &heat), &frame, Some(&st), &part)?;
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
        let trace = match (st.trace_ms, st.gpu_busy) {
            (Some(t), Some(busy)) => format!("{t:.1} ms GPU in {:.1} ms, {:.0}% busy", st.loop_ms, 100.0 * busy),
            (Some(t), None) => format!("{t:.1} ms GPU"),
            (None, _) => format!("{:.0} ms wall (no GPU timestamps)", st.wall_ms),
        };
        let mr = st.mrays_per_s.map(|m| format!("{m:.4} Mrays/s, ")).unwrap_or_default();
        eprintln!(
            "wrote {} ({w}x{h}{part_note}, {} {}{} spp, {} triangles{}, {} spheres, accel {}) on {}: load {load_ms:.0} ms, build {:.0} ms, kernel {:.0} ms, trace {trace} ({mr}{} dispatches{}), total {:.0} ms",
            a.output.display(),
            st.integrator,
            st.samples_done,
            if st.samples_done < spp { format!(" of {spp}") } else { String::new() },
            st.triangles,
            if st.instances > 0 { format!(" ({} instances)", st.instances) } else { String::new() },
            st.spheres,
            if settings.params.build == arbor::accel::BuildOn::Gpu {
                format!("{} built on the device", st.accel)
            } else {
                st.accel.clone()
            },
            st.device,
            st.build_ms,
            st.kernel_ms,
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
        if let Some(sp) = &st.sppm {
            eprintln!("{}", sppm_line(sp));
        }
        if let Some(p) = &a.trace.trace_events {
            eprintln!("wrote {} (the timeline of this render)", p.display());
        }
    }
    Ok(())
}

/// SPPM's summary line: photons, the map and its cost, and what was lost.
fn sppm_line(sp: &render::integrators::sppm::SppmStats) -> String {
    let mut lost = Vec::new();
    if sp.cut_paths > 0 {
        lost.push(format!(
            "{} paths cut short by the traversal's step budget (their light is lost; sppm does not resume a trace as path does: another --accel may need fewer steps)",
            sp.cut_paths
        ));
    }
    if sp.truncated_lookups > 0 {
        lost.push(format!(
            "{} photon lookups met more than {} candidates in one grid cell and tested only those (try --photon-map kdtree or a smaller --photon-radius)",
            sp.truncated_lookups,
            arbor::gpu::bindings::SPPM_BUCKET_MOST
        ));
    }
    format!(
        "sppm: {} iterations x {} photons ({} photon rays, {} deposits), photon map {} built in {:.0} ms in all; {}",
        sp.iterations,
        sp.photons_per_iteration,
        sp.photon_rays,
        sp.deposits,
        sp.photon_map,
        sp.map_ms,
        if lost.is_empty() { "no path cut short, no lookup truncated".to_string() } else { lost.join("; ") }
    )
}

/// The AOVs of a render and what their heatmaps say.
type Aovs<'a> = (&'a [(String, std::path::PathBuf)], &'a output::HeatmapInfo);

/// Writes the image, the AOVs and the statistics of a render: all of them or none.
/// A checkpoint (`st` None) writes the image and the AOVs.
fn write_outputs(
    a: &RenderArgs,
    (aovs, heat): Aovs,
    frame: &render::Frame,
    st: Option<&render::RenderStats>,
    part: &render::output::part::PartInfo,
) -> Result<()> {
    let (w, h) = (frame.width, frame.height);
    let mut set = output::OutputSet::new();
    output::write_frame(&mut set, &a.output, part, frame)?;
    output::write_aovs(&mut set, aovs, frame, w, h, heat)?;
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
    // The timeline ends here, after every output was encoded: only the renames follow.
    if let (Some(p), Some(_)) = (&a.trace.trace_events, st) {
        if let Some(trace) = arbor::timeline::take() {
            set.add(p, &output::encode_trace(p, &trace)?)?;
        }
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
        window = render::Crop::parse(c).map_err(usage)?;
        window.check(settings.width, settings.height)?;
    }
    let first = a.sample_offset.unwrap_or(0);
    let by: render::output::shard::ShardBy = a.shard_by.parse().map_err(usage)?;
    let shard =
        a.shard.as_deref().map(|s| render::output::shard::Shard::parse(s, |v| std::env::var(v).ok())).transpose()?;
    let (window, first, count) = match &shard {
        Some(s) => s.plan(by, window, first, settings.spp)?,
        None => (window, first, settings.spp),
    };
    // Only a sample shard is a part of a known total; other parts may be extended.
    let total = if a.shard.is_some() && by == render::output::shard::ShardBy::Samples { settings.spp } else { 0 };
    settings.crop = (window != render::Crop::full(settings.width, settings.height)).then_some(window);
    settings.first_sample = first;
    settings.spp = count;
    Ok((total, shard.map(|s| s.describe(by)).unwrap_or_default()))
}

/// SPPM's flags, refused with another integrator and checked as `arbor render --help`
/// states them.
fn sppm_settings(a: &RenderArgs, integrator: render::Integrator) -> Result<render::integrators::sppm::SppmSettings> {
    use render::integrators::sppm::{PhotonMap, SppmSettings, MAX_PHOTONS};
    let given = [
        (a.photons.is_some(), "--photons"),
        (a.photon_radius.is_some(), "--photon-radius"),
        (a.photon_map.is_some(), "--photon-map"),
    ];
    if integrator != render::Integrator::Sppm {
        if let Some((_, flag)) = given.iter().find(|g| g.0) {
            return Err(usage(format!("{flag} is a setting of --integrator sppm, not {}", integrator.name())));
        }
        return Ok(SppmSettings::default());
    }
    let photons = match a.photons {
        Some(n) if n < 1 || n > i64::from(MAX_PHOTONS) => {
            return Err(usage(format!("--photons must be 1..={MAX_PHOTONS}, got {n}")));
        }
        n => n.map(|n| n as u32),
    };
    let radius = match a.photon_radius {
        Some(r) if !(r.is_finite() && r > 0.0 && r < f64::from(f32::MAX)) => {
            return Err(usage(format!("--photon-radius must be a positive distance, got {r}")));
        }
        r => r.map(|r| r as f32),
    };
    if a.resume.is_some() {
        return Err(usage("--resume cannot continue an sppm render: each iteration shrinks every pixel's radius from the last, so a render is one run; render it again with more --spp"));
    }
    if a.shard.is_some() && a.shard_by != "tiles" {
        return Err(usage(
            "sppm renders shard by tiles only (--shard-by tiles): averaging independent sppm runs is not one long run",
        ));
    }
    if a.sample_offset.is_some_and(|o| o > 0) {
        return Err(usage("--sample-offset: sppm renders cannot be split by samples (averaging independent sppm runs is not one long run)"));
    }
    let map = a.photon_map.as_deref().map_or(Some(PhotonMap::default()), PhotonMap::parse);
    let map = map.ok_or_else(|| usage("--photon-map must be hashgrid or kdtree"))?;
    Ok(SppmSettings { photons, radius, map })
}

/// Reads the part `--resume` names and checks that this command renders the same
/// window and samples of the same image.
fn resumable(path: &std::path::Path, part: &render::output::part::PartInfo) -> Result<render::Frame> {
    let (info, frame) = render::output::part::read(path)?;
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

/// With the Whitted integrator an emissive material lights nothing else: say so when
/// it is the scene's only light.
/// Renders with progress: a bar on an interactive stderr after the first second, else
/// a plain line every few seconds; none with `quiet`.
/// SIGINT and SIGTERM stop a path-traced render after its current sample wave; the
/// image so far is written and the exit code is [`interrupt::EXIT_CODE`].
fn trace(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    a: &RenderArgs,
    aovs: Aovs,
    part: &render::output::part::PartInfo,
) -> Result<(render::Frame, render::RenderStats)> {
    interrupt::install();
    let progress = if settings.integrator == render::Integrator::Sppm {
        // SPPM counts iterations, each a camera path a pixel and the photons.
        let photons = settings.sppm.photons_for(settings.width, settings.height);
        let p = Reporter::new("sppm", a.quiet, false);
        p.bar().set_message(format!("tracing {} (iterations of {photons} photons)", scene.name));
        p
    } else {
        let p = Reporter::new("render", a.quiet, false);
        p.bar().set_message(format!("tracing {} (pixel samples)", scene.name));
        p
    };
    let checkpoint = a.checkpoint.map(|every| {
        let write = move |frame: &render::Frame| -> arbor::error::Result<()> {
            write_outputs(a, aovs, frame, None, part)
                .map_err(|e| arbor::error::Error::Failed(format!("checkpoint: {e:#}")))
        };
        (every, Box::new(write) as Box<dyn FnMut(&render::Frame) -> arbor::error::Result<()>>)
    });
    let control = render::Control {
        progress: Box::new(|done, total| progress.update(done, total)),
        interrupted: Box::new(interrupt::requested),
        checkpoint,
    };
    let done = render::gpu::render_controlled(ctx, scene, settings, control);
    progress.finish();
    Ok(done?)
}
