//! `arbor bench` (included by main.rs only): the structures' figures, or with
//! `--reference` error against time, or with `--shards` the cost of splitting a render.

use anyhow::{Context as _, Result};
use arbor::accel::AccelKind;
use arbor::bench;
use arbor::render::{self, output};
use arbor::scene::Scene;

use crate::args::BenchArgs;
use crate::common::{context, parse_size, print_out, start_trace, trace_device, usage, DEFAULT_PATH_SPP};
use crate::farm_bench;
use crate::progress::{BenchProgress, Reporter};

/// `arbor bench`: every input (sizes, values, scenes, memory, output paths) is checked
/// before a device is opened and anything is printed.
pub(crate) fn run(args: &BenchArgs) -> Result<()> {
    if args.trace.trace_events.is_some() && (args.reference.is_some() || !args.shards.is_empty()) {
        return Err(usage("--trace-events traces the structure table; it is not taken with --reference or --shards"));
    }
    // `--out` draws plots at the end: a bad ARBOR_FONT is refused before any work.
    if args.out.is_some() && args.shards.is_empty() {
        arbor::render::output::heatmap::font()?;
    }
    if let Some(reference) = &args.reference {
        return convergence(args, reference);
    }
    if !args.shards.is_empty() {
        return shards(args);
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
        traversal: args.traversal.parse().map_err(usage)?,
        pacing: args.pacing.choice(),
        size,
        repeat: args.repeat,
        quick: args.quick,
        out: args.out.clone(),
        json: args.json.clone(),
        trace_events: args.trace.trace_events.clone(),
        heatmap_scale: args.heatmap_scale.parse().map_err(usage)?,
    }
    .options()?;
    for p in args.json.iter().chain(&args.trace.trace_events) {
        output::check_writable(p)?;
    }
    let _recording = start_trace(&args.trace, "bench")?;
    if let Some(d) = &args.out {
        if d.exists() && !d.is_dir() {
            anyhow::bail!("{}: --out is not a directory", d.display());
        }
    }
    let scenes = bench::load_scenes(&opts)?;
    scenes.iter().for_each(crate::common::warn_scene);
    if let Some(d) = &args.out {
        std::fs::create_dir_all(d).with_context(|| format!("{}: cannot create the --out directory", d.display()))?;
        let files = [d.join("bench.json"), d.join("bench.csv")];
        let extra = args.json.iter().chain(&args.trace.trace_events);
        output::check_outputs(files.iter().map(|p| p.as_path()).chain(extra.map(|p| p.as_path())))?;
    }
    let ctx = context(&args.device)?;
    trace_device(&ctx);
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

/// `bench --shards`: the one --scene path traced as N shards, each its own process.
fn shards(args: &BenchArgs) -> Result<()> {
    let [scene] = args.scene.as_slice() else {
        return Err(usage("--shards needs exactly one --scene"));
    };
    if let Some(bad) = args.shards.iter().find(|&&n| n == 0 || n > 4096) {
        return Err(usage(format!("--shards {bad}: each shard count must be 1..=4096")));
    }
    // The default list (every structure) means render's default here.
    let accel = if args.accel == AccelKind::ALL.to_vec() { AccelKind::Kdtree } else { args.accel[0] };
    if args.accel.len() > 1 && args.accel != AccelKind::ALL.to_vec() {
        return Err(usage("--shards renders with one structure: give one --accel"));
    }
    let (w, h) = parse_size(&args.size)?;
    let spp = args.spp.unwrap_or(DEFAULT_PATH_SPP);
    let files = args.out.as_ref().map(|d| [d.join("shards.csv"), d.join("shards.json")]);
    if let (Some(d), Some(files)) = (&args.out, &files) {
        std::fs::create_dir_all(d).with_context(|| format!("{}: cannot create the --out directory", d.display()))?;
        output::check_outputs(files.iter().map(|p| p.as_path()))?;
    }
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
    let (text, rows) = farm_bench::run(&base, &args.shards, &args.shard_by, false)?;
    print_out(&text)?;
    if let Some([csv, json]) = &files {
        let mut table = format!("{}\n", farm_bench::CSV_HEADER);
        for r in &rows {
            table += &format!("{}\n", r.csv());
        }
        output::write_atomic(csv, table.as_bytes())?;
        let doc =
            serde_json::json!({ "scene": scene, "size": [w, h], "spp": spp, "accel": accel.name(), "rows": rows });
        output::write_atomic(json, format!("{doc:#}\n").as_bytes())?;
        eprintln!("bench --shards: wrote {} and {}", csv.display(), json.display());
    }
    Ok(())
}

/// `bench --reference`: error against time over a ladder of sample counts.
fn convergence(args: &BenchArgs, reference: &std::path::Path) -> Result<()> {
    let [scene_arg] = args.scene.as_slice() else {
        return Err(usage("--reference needs exactly one --scene (the scene the reference image shows)"));
    };
    if let Some(bad) = args.ladder.iter().find(|&&n| n == 0 || n > 1 << 20) {
        return Err(usage(format!("--ladder {bad}: each sample count must be 1..=1048576")));
    }
    if let Some(d) = &args.out {
        std::fs::create_dir_all(d).with_context(|| format!("{}: cannot create the --out directory", d.display()))?;
        output::check_outputs(std::iter::once(d.join("convergence.csv").as_path()))?;
    }
    let scene = Scene::load(scene_arg)?;
    crate::common::warn_scene(&scene);
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
        print_out(&format!("{l}\n")).map_err(|e| arbor::error::Error::Failed(e.to_string()))
    });
    progress.0.finish();
    let rows = rows?;
    if let Some(d) = &args.out {
        bench::convergence::write(d, &rows)?;
    }
    Ok(())
}
