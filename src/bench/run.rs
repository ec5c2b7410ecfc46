//! The run loop: per scene and ray kind, every case (structure x intersection mode)
//! takes its turn in a warm-up round and then in each timed round; the cases then
//! become rows.

use crate::accel::bvh::gpu_build::GpuBuilder;
use crate::accel::{Accel, AccelKind, AccelParams, BuildOn};
use crate::error::{Error, Result};
use crate::gpu::Context;
use crate::math::intersect::IntersectMode;
use crate::render::RenderSettings;
use crate::scene::Scene;

use super::files;
use super::rows::{quantile, Case, Heatmap, Row, RowKey};
use super::{Options, Progress, RayKind};

/// Camera rays per scene checked against the watertight CPU reference.
const REFERENCE_PIXELS: u64 = 16_384;

/// Rays aimed at vertices and edges from inside `builtin:inside:N` per bench row.
const AIMED_RAYS: usize = 300_000;

/// Everything measured so far.
#[derive(Default)]
struct Results {
    rows: Vec<Row>,
    /// Time-to-image tables, one per scene and ray kind.
    tti: Vec<serde_json::Value>,
    heatmaps: Vec<Heatmap>,
}

/// A scene as every case on it shares it.
struct SceneRun<'a> {
    name: &'a str,
    /// The name without `builtin:`.
    short: String,
    triangles: usize,
    /// Side of the square image brute force traces.
    side: u32,
    /// (pixel, primitive) of the watertight CPU reference on a sample of the pixels.
    reference: Vec<(usize, u32)>,
}

/// A case of one scene and ray kind on its way through the rounds.
struct Run<'v> {
    kind: AccelKind,
    params: &'v AccelParams,
    label: String,
    /// Index of the intersection mode in `Options::intersect`.
    mi: usize,
    mode: IntersectMode,
    case: Case,
    pipelines: Option<GpuBuilder>,
    /// Why it failed (it runs no further rounds).
    error: Option<String>,
}

/// Prints a line of the results table; a closed stdout ends the run (with an error
/// whose cause is the `BrokenPipe`).
fn print(progress: &dyn Progress, l: &str) -> Result<()> {
    progress.line(l).map_err(|e| Error::io("stdout", e))
}

/// Loads every scene of `opts` (before a device is opened: a bad scene fails first)
/// and checks that the frames of `opts.size` fit in the host memory available.
pub fn load_scenes(opts: &Options) -> Result<Vec<Scene>> {
    let (w, h) = opts.size;
    let what = format!("--size {w}x{h}");
    let mut scenes = Vec::with_capacity(opts.scenes.len());
    for name in &opts.scenes {
        let scene = Scene::load(name)?;
        crate::render::output::memory::check_render(&what, w, h, scene.prim_count(), &[])?;
        scenes.push(scene);
    }
    Ok(scenes)
}

/// Runs the benchmark described by `opts` on `ctx`, reporting through `progress`;
/// writes the files of `opts.out` / `opts.json`. `scenes` are those of `opts.scenes`,
/// loaded by [`load_scenes`] (`None`: loaded here).
pub fn run(ctx: &Context, opts: &Options, scenes: Option<Vec<Scene>>, progress: &dyn Progress) -> Result<()> {
    let scenes = match scenes {
        Some(s) => s,
        None => load_scenes(opts)?,
    };
    let with_driver;
    let opts = if opts.with_driver {
        let mut o = opts.clone();
        if ctx.has_ray_query() {
            let base = o.variants.first().map(|v| v.1).unwrap_or_default();
            let p = AccelParams { build: BuildOn::Cpu, ..base };
            o.variants.push((AccelKind::RayQuery, p, AccelKind::RayQuery.name().to_string()));
        } else {
            progress.note(&format!(
                "rayquery left out: {} lacks {} (`arbor devices`)",
                ctx.info().name,
                ctx.info().ray_query_missing.as_deref().unwrap_or("ray queries")
            ));
        }
        with_driver = o;
        &with_driver
    } else {
        opts
    };
    let cases = opts.scenes.len() * opts.rays.len() * opts.intersect.len() * opts.variants.len();
    progress.set_length((cases * (opts.repeat.max(1) + 1)) as u64);
    let mut out = Results::default();
    for (name, base) in opts.scenes.iter().zip(&scenes) {
        run_scene(ctx, opts, name, base, progress, &mut out)?;
    }
    files::write(opts, &out.rows, &out.tti, &out.heatmaps, progress)
}

/// Every ray kind and case on the scene `base`, loaded from `name`.
fn run_scene(
    ctx: &Context,
    opts: &Options,
    name: &str,
    base: &Scene,
    progress: &dyn Progress,
    out: &mut Results,
) -> Result<()> {
    let (w, h) = opts.size;
    // Brute force over all pixels would take too long: trace a square subset whose
    // side keeps it under about 4e8 primitive tests.
    let side = ((4e8 / base.prim_count().max(1) as f64).sqrt() as u32).max(8).min(w.min(h));
    // The watertight reference for the camera rays (CPU, a sample of the pixels).
    let stride = ((u64::from(w) * u64::from(h)) / REFERENCE_PIXELS).max(1) as usize;
    let reference = {
        let _span = crate::timeline::span("run", || format!("{name}: CPU reference"));
        let accel = Accel::build(AccelKind::CPU_REFERENCE, base);
        crate::render::cpu::reference_prims(base, &accel, w, h, stride)
    };
    let short = name.strip_prefix("builtin:").unwrap_or(name).to_string();
    // Triangles drawn: instances count each copy (bytes/tri is then per triangle drawn).
    let sc = SceneRun { name, short, triangles: base.drawn_triangles() as usize, side, reference };
    for &rays in &opts.rays {
        let mut scene = base.clone();
        if rays == RayKind::Shadow {
            scene.max_depth = 1;
        }
        let first_row = out.rows.len();
        let mut runs = cases(opts, &sc, rays);
        rounds(ctx, opts, &sc, &scene, rays, &mut runs, progress)?;
        // Brute-force rate per intersection mode, for the speedup column.
        let mut brute_rates: Vec<Option<f64>> = vec![None; opts.intersect.len()];
        for run in runs.iter().filter(|r| r.kind.is_brute_force() && r.error.is_none()) {
            brute_rates[run.mi] = Some(run.case.rate());
        }
        for run in runs {
            let brute_rate = brute_rates[run.mi];
            let row = finish(ctx, opts, &sc, &scene, rays, run, brute_rate, progress, &mut out.heatmaps)?;
            out.rows.push(row);
        }
        // Time to image for this scene and ray kind.
        let t = files::time_to_image(&out.rows[first_row..]);
        print(progress, &files::time_to_image_text(&sc.short, rays, &t))?;
        out.tti.push(serde_json::json!({ "scene": name, "rays": rays.name(), "structures": t }));
    }
    // SPPM's photon maps over this scene's visible points, beside its ray structures.
    progress.message(format!("{}, photon maps", sc.short));
    let line = super::photon::photon_line(ctx, base, &sc.short, opts.size, opts.repeat)?;
    print(progress, &line)?;
    Ok(())
}

/// The cases of one scene and ray kind: every variant in every intersection mode.
fn cases<'v>(opts: &'v Options, sc: &SceneRun, rays: RayKind) -> Vec<Run<'v>> {
    let (w, h) = opts.size;
    opts.variants
        .iter()
        .flat_map(|v| opts.intersect.iter().enumerate().map(move |m| (v, m)))
        .map(|((kind, p, label), (mi, &mode))| {
            let mut label = label.clone();
            if opts.intersect.len() > 1 {
                label = format!("{label}/{mode}");
            }
            if opts.rays.len() > 1 {
                label = format!("{label}/{}", rays.name());
            }
            let size = if kind.is_brute_force() { (sc.side, sc.side) } else { (w, h) };
            Run { kind: *kind, params: p, label, mi, mode, case: Case::new(size), pipelines: None, error: None }
        })
        .collect()
}

/// The rounds: a warm-up, then `repeat` timed rounds, each running every case once.
/// Drift in the machine's load then falls on every case alike, and the ratios between
/// structures compare like with like.
fn rounds(
    ctx: &Context,
    opts: &Options,
    sc: &SceneRun,
    scene: &Scene,
    rays: RayKind,
    runs: &mut [Run],
    progress: &dyn Progress,
) -> Result<()> {
    let repeat = opts.repeat.max(1);
    for round in 0..=repeat {
        let what = if round == 0 { "warm-up".to_string() } else { format!("round {round} of {repeat}") };
        for run in runs.iter_mut().filter(|r| r.error.is_none()) {
            progress.message(format!("{}, {}, {what}", sc.short, run.label));
            let _span = crate::timeline::span("run", || format!("{} {} {what}", sc.short, run.label));
            let timed = round > 0;
            let done = bench_round(
                ctx,
                scene,
                (run.kind, run.params),
                (rays, run.mode, opts.traversal, opts.pacing),
                timed,
                &mut run.case,
                &mut run.pipelines,
            );
            // A structure can fail on a scene (brute force with shadow rays on big
            // scenes cannot fit llvmpipe's loop limit; a trace that needs more steps than
            // its budget is resumed instead, docs/kernels.md): report it, go on.
            if let Err(e) = done {
                let msg = format!("{e:#}");
                print(progress, &format!("{:>16} {:>9} {:>16} failed: {msg}", sc.short, sc.triangles, run.label))?;
                run.error = Some(msg);
                progress.inc((repeat - round) as u64);
            }
            progress.inc(1);
        }
    }
    Ok(())
}

/// One round of `kind` into `case`: recorded when `timed` (else a warm-up).
/// `pipelines` keeps a GPU build's kernels from one round to the next.
///
/// A timed round builds twice. The first build comes after the other structures'
/// rounds (caches and the allocator's free memory are theirs), as a first render's
/// does: its time and phases are `build_ms`. The second follows it at once, as
/// repeated builds do: `rebuild_ms`. The trace uses the second.
fn bench_round(
    ctx: &Context,
    scene: &Scene,
    (kind, params): (AccelKind, &AccelParams),
    (rays, mode, traversal, pacing): (
        RayKind,
        IntersectMode,
        crate::render::Traversal,
        crate::render::dispatch::PacingChoice,
    ),
    timed: bool,
    case: &mut Case,
    pipelines: &mut Option<GpuBuilder>,
) -> Result<()> {
    let mut settings = RenderSettings::for_size(case.size.0, case.size.1);
    settings.primary_only = rays == RayKind::Primary;
    settings.diffuse_probe = rays == RayKind::Diffuse;
    if rays == RayKind::Path {
        settings.integrator = crate::render::Integrator::Path;
        settings.spp = super::PATH_SPP;
    }
    settings.accel = kind;
    settings.intersect = mode;
    settings.traversal = traversal;
    settings.pacing = pacing;
    let first = if timed {
        let accel = Accel::build_on_reusing(ctx, kind, scene, params, pipelines)?;
        Some(accel.timing())
    } else {
        None
    };
    let mut accel = Accel::build_on_reusing(ctx, kind, scene, params, pipelines)?;
    let (frame, mut st) = crate::render::gpu::render_with(ctx, scene, &settings, &accel, |_, _| {})?;
    if accel.on_device_only() {
        // The row's SAH cost and leaf counts need the tree on the host: read back
        // after the trace, outside the timed build.
        accel.read_back(ctx)?;
        st.build = crate::accel::BuildStats {
            build_ms: st.build.build_ms,
            phases: std::mem::take(&mut st.build.phases),
            ..accel.stats(scene)
        };
    }
    case.misses = frame.prim.iter().filter(|&&p| p == u32::MAX).count() as u64;
    case.nodes_p99 = quantile(&frame.nodes, 0.99);
    case.prims_p99 = quantile(&frame.tests, 0.99);
    case.nodes = frame.nodes;
    case.prims = frame.prim;
    if let Some((first_ms, first_phases)) = first {
        let ms = st.trace_ms.unwrap_or(st.wall_ms);
        case.build_ms.push(first_ms);
        case.rebuild_ms.push(st.build.build_ms);
        case.phases.push(first_phases);
        case.trace_ms.push(ms);
        case.rates.push(st.rays as f64 / (ms * 1e3));
    }
    case.stats = st;
    Ok(())
}

/// The row of a case after its rounds: its figures, the checks against the reference,
/// its table line (and build phases), and its cost heatmap.
#[allow(clippy::too_many_arguments)]
fn finish(
    ctx: &Context,
    opts: &Options,
    sc: &SceneRun,
    scene: &Scene,
    rays: RayKind,
    run: Run,
    brute_rate: Option<f64>,
    progress: &dyn Progress,
    heatmaps: &mut Vec<Heatmap>,
) -> Result<Row> {
    let Run { kind, params, label, mi, mode, case: c, error, .. } = run;
    let mut row = Row::new(&RowKey {
        scene: sc.name,
        triangles: sc.triangles,
        accel: kind.name(),
        brute_force: kind.is_brute_force(),
        label: &label,
        intersect: mode.name(),
        rays: rays.name(),
        size: c.size,
        device: &ctx.info().name,
        driver: &ctx.info().driver,
    });
    if let Some(msg) = error {
        row.error = Some(msg);
        return Ok(row);
    }
    row.fill(&c, brute_rate);
    if !kind.is_brute_force() {
        // Inside a closed mesh: also rays aimed at its vertices and edges (CPU traversal
        // of the same structure), where cracks show. (Not brute force: on the CPU that
        // would take minutes.)
        if sc.name.starts_with("builtin:inside:") {
            let accel = Accel::build_with(kind, scene, params);
            let aimed = crate::render::cracks::aimed_rays(scene, glam::Vec3::ZERO, 0.3, AIMED_RAYS, 11);
            let escapes = crate::render::cracks::escapes(scene, mode, &accel, &aimed);
            row.aimed_escapes_per_million = Some(escapes as f64 * 1e6 / AIMED_RAYS as f64);
        }
        // Path-traced camera rays are jittered: they do not go through the pixel
        // centres the reference traced.
        if rays != RayKind::Path {
            let differ = sc.reference.iter().filter(|(k, p)| c.prims.get(*k) != Some(p)).count();
            row.disagree_per_million = Some(differ as f64 * 1e6 / sc.reference.len().max(1) as f64);
        }
    }
    print(progress, &row.table_line(&sc.short))?;
    // Per-phase build figures when a GPU build is compared with the CPU's.
    let gpu_builds = opts.variants.iter().any(|v| v.1.build == BuildOn::Gpu);
    if gpu_builds && kind.builds_on_gpu() {
        print(progress, &row.phases_line())?;
    }
    // No heatmap for the driver's structure: its node counts are not visible (not zero).
    if opts.out.is_some() && kind.texels_per_node().is_some() && rays == RayKind::Primary && mi == 0 {
        heatmaps.push(Heatmap {
            scene: sc.short.clone(),
            label: row.label.clone(),
            width: c.size.0,
            height: c.size.1,
            nodes: c.nodes,
        });
    }
    Ok(row)
}
