//! `arbor bench`: builds and traces every requested structure on every scene, ray kind
//! and intersection mode, and reports build and GPU trace times, Mrays/s, speedup over
//! brute force, per-ray cost (mean and p99), cracks, disagreement with the watertight
//! reference, time to image; as a terminal table, `bench.csv`, `bench.json` and plots.
//! Column meanings: README "Benchmark".

#![forbid(unsafe_code)]

use std::path::{Path, PathBuf};

use crate::accel::{AccelKind, AccelParams};
use crate::error::{Error, Result};
use crate::gpu::Context;
use crate::math::intersect::IntersectMode;
use crate::render::RenderSettings;
use crate::scene::Scene;

/// Where the benchmark reports as it goes (the CLI's progress bar).
pub trait Progress {
    fn set_length(&self, n: u64);
    fn message(&self, m: String);
    fn inc(&self, n: u64);
    /// A line of the results table (stdout).
    fn line(&self, l: &str);
    /// A note about files written (stderr).
    fn note(&self, l: &str);
}

/// What to run.
#[derive(Debug, Clone)]
pub struct Options {
    /// Scene arguments, in order.
    pub scenes: Vec<String>,
    /// (structure, parameters, row label) to run on every scene.
    pub variants: Vec<(AccelKind, AccelParams, String)>,
    pub rays: Vec<RayKind>,
    pub intersect: Vec<IntersectMode>,
    /// Camera image size.
    pub size: (u32, u32),
    /// Timed repeats after one warm-up.
    pub repeat: usize,
    /// Directory for bench.csv, bench.json and plots/.
    pub out: Option<PathBuf>,
    /// Extra copy of bench.json.
    pub json: Option<PathBuf>,
}

/// A kind of ray the benchmark traces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RayKind {
    Primary,
    Shadow,
    Diffuse,
}

impl RayKind {
    pub fn name(self) -> &'static str {
        match self {
            RayKind::Primary => "primary",
            RayKind::Shadow => "shadow",
            RayKind::Diffuse => "diffuse",
        }
    }
}

/// Median (sorts `v`).
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Max - min.
pub fn spread(v: &[f64]) -> f64 {
    v.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - v.iter().cloned().fold(f64::INFINITY, f64::min)
}

/// One measured case of the benchmark.
struct Case {
    phases: Vec<Vec<crate::accel::Phase>>,
    build_ms: Vec<f64>,
    rebuild_ms: Vec<f64>,
    trace_ms: Vec<f64>,
    rates: Vec<f64>,
    stats: crate::render::RenderStats,
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

/// The median of each phase over repeats (phases matched by name, in first-seen order).
fn median_phases(runs: &[Vec<crate::accel::Phase>]) -> Vec<crate::accel::Phase> {
    let Some(first) = runs.first() else { return Vec::new() };
    first
        .iter()
        .map(|p| {
            let mut v: Vec<f64> =
                runs.iter().filter_map(|r| r.iter().find(|q| q.name == p.name)).map(|q| q.ms).collect();
            crate::accel::Phase { name: p.name.clone(), ms: median(&mut v), detail: p.detail.clone() }
        })
        .collect()
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

/// A case with nothing measured yet, at camera size `size`.
fn new_case(size: (u32, u32)) -> Case {
    Case {
        phases: Vec::new(),
        build_ms: Vec::new(),
        rebuild_ms: Vec::new(),
        trace_ms: Vec::new(),
        rates: Vec::new(),
        stats: Default::default(),
        size,
        misses: 0,
        nodes_p99: 0,
        prims_p99: 0,
        nodes: Vec::new(),
        prims: Vec::new(),
    }
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
    (kind, params): (AccelKind, &crate::accel::AccelParams),
    (rays, mode): (RayKind, IntersectMode),
    timed: bool,
    case: &mut Case,
    pipelines: &mut Option<crate::accel::bvh::gpu_build::GpuBuilder>,
) -> Result<()> {
    let mut settings = RenderSettings::for_size(case.size.0, case.size.1);
    settings.primary_only = rays == RayKind::Primary;
    settings.diffuse_probe = rays == RayKind::Diffuse;
    settings.accel = kind;
    settings.intersect = mode;
    let first = if timed {
        let accel = crate::accel::Accel::build_on_reusing(ctx, kind, scene, params, pipelines)?;
        Some(accel.timing())
    } else {
        None
    };
    let accel = crate::accel::Accel::build_on_reusing(ctx, kind, scene, params, pipelines)?;
    let (frame, st) = crate::render::gpu::render_with(ctx, scene, &settings, &accel, |_, _| {})?;
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

/// A case of one scene and ray kind on its way through the rounds.
struct Run<'v> {
    kind: AccelKind,
    params: &'v AccelParams,
    label: String,
    /// Index of the intersection mode in `Options::intersect`.
    mi: usize,
    mode: IntersectMode,
    case: Case,
    pipelines: Option<crate::accel::bvh::gpu_build::GpuBuilder>,
    /// Why it failed (it runs no further rounds).
    error: Option<String>,
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
    rebuild_ms: f64,
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
    /// Median ms of each build phase (JSON only).
    build_phases: Vec<crate::accel::Phase>,
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
    "rebuild_ms",
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
        let v = serde_json::to_value(r).map_err(|e| Error::Usage(format!("bench CSV: {e}")))?;
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
    use crate::render::plots;
    std::fs::create_dir_all(dir).map_err(|cause| Error::Io { path: dir.to_path_buf(), cause })?;
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

/// The terminal table's header line.
pub const HEADER: &str = "           scene triangles            accel    pixels   build_ms rebuild_ms   trace_ms    spread     Mrays/s   speedup nodes/ray   p99 prims/ray   p99 bytes/tri     SAH depth    miss/M  aimed/M  differ/M";

/// Runs the benchmark described by `opts` on `ctx`, reporting through `progress`;
/// writes the files of `opts.out` / `opts.json`.
pub fn run(ctx: &Context, opts: &Options, progress: &dyn Progress) -> Result<()> {
    let (w, h) = opts.size;
    let repeat = opts.repeat.max(1);
    let kinds = &opts.rays;
    let variants = &opts.variants;
    let scenes = &opts.scenes;
    progress.set_length((scenes.len() * kinds.len() * opts.intersect.len() * variants.len() * (repeat + 1)) as u64);
    let mut rows: Vec<Row> = Vec::new();
    let mut tti = Vec::new();
    // Per-phase build figures when a GPU build is compared with the CPU's.
    let show_phases = variants.iter().any(|v| v.1.build == crate::accel::BuildOn::Gpu);
    // (file stem, title, width, height, nodes per pixel) of the cost heatmaps to draw.
    let mut heatmaps: Vec<(String, String, u32, u32, Vec<u32>)> = Vec::new();
    for name in scenes {
        let base = Scene::load(name)?;
        let nt = base.triangles.len();
        let short = name.strip_prefix("builtin:").unwrap_or(name).to_string();
        // Brute force over all pixels would take too long: trace a square subset whose
        // side keeps it under about 4e8 primitive tests.
        let side = ((4e8 / base.prim_count().max(1) as f64).sqrt() as u32).clamp(8, w.min(h));
        // The watertight reference for the camera rays (CPU, a sample of the pixels).
        let stride = ((u64::from(w) * u64::from(h)) / REFERENCE_PIXELS).max(1) as usize;
        let reference = {
            let accel = crate::accel::Accel::build(AccelKind::BvhSah, &base);
            crate::render::cpu::reference_prims(&base, &accel, w, h, stride)
        };
        for &kind_of_rays in kinds {
            let mut scene = base.clone();
            if kind_of_rays == RayKind::Shadow {
                scene.max_depth = 1;
            }
            let first_row = rows.len();
            // The cases (structure by intersection mode) take turns: a warm-up round,
            // then `repeat` timed rounds, each running every case once. Drift in the
            // machine's load then falls on every case alike, and the ratios between
            // structures compare like with like.
            let mut runs: Vec<Run> = variants
                .iter()
                .flat_map(|v| opts.intersect.iter().enumerate().map(move |m| (v, m)))
                .map(|((kind, p, label), (mi, &mode))| {
                    let mut label = label.clone();
                    if opts.intersect.len() > 1 {
                        label = format!("{label}/{mode}");
                    }
                    if kinds.len() > 1 {
                        label = format!("{label}/{}", kind_of_rays.name());
                    }
                    let size = if *kind == AccelKind::None { (side, side) } else { (w, h) };
                    Run { kind: *kind, params: p, label, mi, mode, case: new_case(size), pipelines: None, error: None }
                })
                .collect();
            for round in 0..=repeat {
                let what = if round == 0 { "warm-up".to_string() } else { format!("round {round} of {repeat}") };
                for run in runs.iter_mut().filter(|r| r.error.is_none()) {
                    progress.message(format!("{short}, {}, {what}", run.label));
                    let timed = round > 0;
                    let done = bench_round(
                        ctx,
                        &scene,
                        (run.kind, run.params),
                        (kind_of_rays, run.mode),
                        timed,
                        &mut run.case,
                        &mut run.pipelines,
                    );
                    // A structure can fail on a scene where it degenerates (the grid in
                    // the stadium needs more steps per ray than llvmpipe's loop limit;
                    // brute force too with shadow rays on big scenes): report it, go on.
                    if let Err(e) = done {
                        let msg = format!("{e:#}");
                        progress.line(&format!("{short:>16} {nt:>9} {:>16} failed: {msg}", run.label));
                        run.error = Some(msg);
                        progress.inc((repeat - round) as u64);
                    }
                    progress.inc(1);
                }
            }
            // Brute-force rate per intersection mode, for the speedup column.
            let mut brute_rates: Vec<Option<f64>> = vec![None; opts.intersect.len()];
            for run in runs.iter().filter(|r| r.kind == AccelKind::None && r.error.is_none()) {
                brute_rates[run.mi] = Some(median(&mut run.case.rates.clone()));
            }
            for run in runs {
                let Run { kind, params: p, label, mi, mode, case: c, error, .. } = run;
                let size = c.size;
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
                    rebuild_ms: 0.0,
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
                    build_phases: Vec::new(),
                };
                if let Some(msg) = error {
                    row.error = Some(msg);
                    rows.push(row);
                    continue;
                }
                let brute_rate = brute_rates[mi];
                let rate = median(&mut c.rates.clone());
                let st = &c.stats;
                let pixels = u64::from(c.size.0) * u64::from(c.size.1);
                // Inside a closed mesh: also rays aimed at its vertices and edges (CPU
                // traversal of the same structure), where cracks show. (Not brute
                // force: on the CPU that would take minutes.)
                let aimed = if name.starts_with("builtin:inside:") && kind != AccelKind::None {
                    let accel = crate::accel::Accel::build_with(kind, &scene, p);
                    let rays = crate::render::cracks::aimed_rays(&scene, glam::Vec3::ZERO, 0.3, AIMED_RAYS, 11);
                    Some(crate::render::cracks::escapes(&scene, mode, &accel, &rays) as f64 * 1e6 / AIMED_RAYS as f64)
                } else {
                    None
                };
                row.build_ms = median(&mut c.build_ms.clone());
                row.build_ms_spread = spread(&c.build_ms);
                row.rebuild_ms = median(&mut c.rebuild_ms.clone());
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
                    "{:>16} {:>9} {:>16} {:>9} {:>10.2} {:>10.2} {:>10.2} {:>9.2} {:>11.4} {:>9} {:>8.1} {:>7} {:>8.1} {:>7} {:>8.1} {:>7.1} {:>5} {:>9.1} {:>9} {:>9}",
                    short,
                    nt,
                    label,
                    format!("{}x{}", c.size.0, c.size.1),
                    row.build_ms,
                    row.rebuild_ms,
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
                progress.line(&line);
                row.build_phases = median_phases(&c.phases);
                if show_phases && matches!(kind, AccelKind::Lbvh | AccelKind::Trbvh) {
                    let list: Vec<String> = row
                        .build_phases
                        .iter()
                        .map(|p| format!("{} {:.2} ({:.0})", p.name, p.ms, nt as f64 / (p.ms * 1e3).max(1e-9)))
                        .collect();
                    let gpu: f64 = row.build_phases.iter().filter(|p| p.name.starts_with("gpu ")).map(|p| p.ms).sum();
                    let gpu = if gpu > 0.0 {
                        format!("; GPU total {gpu:.2} ms ({:.1} Mtris/s)", nt as f64 / (gpu * 1e3))
                    } else {
                        String::new()
                    };
                    progress.line(&format!("    build phases, ms (Mtris/s): {}{gpu}", list.join(", ")));
                }
                if opts.out.is_some() && kind != AccelKind::None && kind_of_rays == RayKind::Primary && mi == 0 {
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
            progress.line(&format!("  time to image, {short}, {} rays:\n{}", kind_of_rays.name(), lines.join("\n")));
            tti.push(serde_json::json!({ "scene": name, "rays": kind_of_rays.name(), "structures": t }));
        }
    }
    let json = serde_json::to_vec_pretty(&serde_json::json!({ "rows": rows, "time_to_image": tti }))
        .map_err(|e| Error::Usage(format!("bench JSON: {e}")))?;
    if let Some(p) = &opts.json {
        crate::render::output::write_atomic(p, &json)?;
    }
    if let Some(d) = &opts.out {
        crate::render::output::write_atomic(&d.join("bench.json"), &json)?;
        crate::render::output::write_atomic(&d.join("bench.csv"), to_csv(&rows)?.as_bytes())?;
        progress.note(&format!("wrote {} and {}", d.join("bench.csv").display(), d.join("bench.json").display()));
        let plots = bench_plots(&d.join("plots"), &rows, &heatmaps, opts.intersect[0].name())?;
        progress.note(&format!("wrote {} plots in {}", plots.len(), d.join("plots").display()));
    }
    Ok(())
}
