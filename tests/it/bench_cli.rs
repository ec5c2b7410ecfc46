//! `arbor bench` as CI runs it (`--quick`): CSV and JSON with the columns of
//! `bench::CSV_COLUMNS` (docs/bench.md documents them), plots of the expected size; GPU timestamps behind the trace times; and
//! `--accel auto` choosing brute force for a handful of triangles and a tree for many;
//! plots in the built-in font, and a bad `ARBOR_FONT` refused before any work.

use crate::common;

use std::path::Path;
use std::process::Command;

use arbor::accel::AccelKind;
use arbor::bench::{plots, CSV_COLUMNS};
use arbor::render::{gpu, RenderSettings};
use arbor::scene::Scene;

/// Runs arbor with `ARBOR_FONT` unset: plots are drawn in the font built into the binary.
/// arbor never looks up a system font (plotters reads fonts with ab_glyph, not
/// fontconfig), so these runs show that plots need none.
fn run(args: &[&str]) -> std::process::Output {
    let out = Command::new(env!("CARGO_BIN_EXE_arbor"))
        .args(args)
        .env_remove("ARBOR_FONT")
        .env("ARBOR_CACHE_DIR", "/nonexistent/arbor-test-cache")
        .output()
        .expect("run arbor");
    assert!(
        out.status.success(),
        "arbor {args:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

#[test]
fn quick_bench_writes_documented_csv_json_and_plots() {
    if !common::has_gpu() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("arbor-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let d = dir.to_string_lossy().to_string();
    run(&["bench", "--quick", "--tris", "1000", "--accel", "none,kdtree,grid", "--out", &d]);

    // CSV: the header is exactly `bench::CSV_COLUMNS`, in its order.
    let csv = std::fs::read_to_string(dir.join("bench.csv")).expect("bench.csv");
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    assert_eq!(header, CSV_COLUMNS, "bench.csv header");
    // 1 scene x 2 ray kinds (primary, diffuse) x 3 structures.
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 6, "{csv}");
    for r in &rows {
        assert!(r.contains("builtin:blob:1000"), "{r}");
    }

    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("bench.json")).expect("bench.json")).expect("valid JSON");
    let jrows = json["rows"].as_array().expect("rows");
    assert_eq!(jrows.len(), 6);
    for r in jrows {
        assert!(r["error"].is_null(), "{r}");
        assert!(r["mrays_per_s"].as_f64().expect("rate") > 0.0, "{r}");
        assert!(r["trace_ms"].as_f64().expect("trace") > 0.0, "{r}");
        // Both build times were measured (brute force's build is a box: it may round to 0).
        if r["accel"] != "none" {
            assert!(r["build_ms"].as_f64().expect("build") > 0.0, "{r}");
            assert!(r["rebuild_ms"].as_f64().expect("rebuild") > 0.0, "{r}");
        }
        assert!(r["nodes_p99"].as_u64().expect("p99") as f64 >= r["nodes_mean"].as_f64().expect("mean").floor());
    }
    assert!(!json["time_to_image"].as_array().expect("time to image").is_empty());

    // Plots: charts in both formats at the chart size, one cost figure for the scene.
    let mut pngs = 0;
    for e in std::fs::read_dir(dir.join("plots")).expect("plots dir") {
        let p = e.expect("entry").path();
        let name = p.file_name().unwrap_or_default().to_string_lossy().to_string();
        match p.extension().and_then(|x| x.to_str()) {
            Some("png") => {
                let img = image::open(&p).unwrap_or_else(|e| panic!("{name}: {e}"));
                if name.starts_with("cost_") {
                    assert_eq!(name, "cost_blob_1000.png");
                    check_cost_figure(&img.to_rgb8());
                } else {
                    assert_eq!((img.width(), img.height()), plots::CHART_SIZE, "{name}");
                }
                // Not blank: more than one colour.
                let rgb = img.to_rgb8();
                let first = *rgb.get_pixel(0, 0);
                assert!(rgb.pixels().any(|px| *px != first), "{name} is blank");
                pngs += 1;
            }
            Some("svg") => {
                let text = std::fs::read_to_string(&p).expect("svg");
                assert!(text.contains("<svg") && text.len() > 1000, "{name}");
            }
            _ => panic!("unexpected file {name}"),
        }
    }
    // Mrays/s and time to image for 2 ray kinds, and one cost figure (kdtree and grid
    // side by side; brute force visits no nodes).
    assert_eq!(pngs, 2 + 2 + 1, "PNG plots");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `ARBOR_FONT` naming a missing file, or a file that is not a font: every command that
/// draws (`bench --out`, `bench --reference --out`, `render --aov cost=X.png`,
/// `--trace-events X.png`) exits with status 1 and the path before any work: no device
/// is opened (no GPU needed) and the output directory stays empty.
#[test]
fn a_bad_arbor_font_is_refused_before_any_work() {
    let dir = tempfile::tempdir().expect("tempdir");
    let not_font = dir.path().join("notes.ttf");
    std::fs::write(&not_font, "not a font").expect("write");
    let missing = dir.path().join("missing.ttf");
    let out = dir.path().join("out");
    std::fs::create_dir(&out).expect("mkdir");
    let (o, p) = (out.display().to_string(), |n: &str| out.join(n).display().to_string());
    let commands: [Vec<String>; 4] = [
        ["bench", "--quick", "--tris", "100", "--out", &o].map(String::from).into(),
        ["bench", "--reference", &p("ref.exr"), "--scene", "builtin:default", "--out", &o].map(String::from).into(),
        ["render", "builtin:default", "--size", "8x8", "-o", &p("a.png"), "--aov", &format!("cost={}", p("c.png"))]
            .map(String::from)
            .into(),
        ["render", "builtin:default", "--size", "8x8", "-o", &p("a.png"), "--trace-events", &p("t.png")]
            .map(String::from)
            .into(),
    ];
    for (font, why) in [(&not_font, "not a TrueType/OpenType font"), (&missing, "cannot read the font")] {
        for args in &commands {
            let r = Command::new(env!("CARGO_BIN_EXE_arbor")).args(args).env("ARBOR_FONT", font).output().expect("run");
            let err = String::from_utf8_lossy(&r.stderr);
            assert_eq!(r.status.code(), Some(1), "arbor {args:?} with ARBOR_FONT={}: {err}", font.display());
            assert!(err.contains(&format!("ARBOR_FONT={}", font.display())) && err.contains(why), "{args:?}: {err}");
            let left: Vec<_> = std::fs::read_dir(&out).expect("list").collect();
            assert!(left.is_empty(), "arbor {args:?} left {left:?}");
        }
    }
}

/// The cost figure of `--size 128x128` (--quick) with two panels: two maps zoomed to
/// 256x256 side by side (each a block of viridis colours, not one colour), then the
/// colour bar from viridis(1) at the top to viridis(0) at the bottom, beside both.
fn check_cost_figure(img: &image::RgbImage) {
    use arbor::render::output::heatmap::viridis;
    let px = |x: u32, y: u32| img.get_pixel(x, y).0;
    // Viridis colours: blue never far below red and green, unlike white, black or grey text.
    let palette: Vec<[u8; 3]> = (0..=1000).map(|k| viridis(f64::from(k) / 1000.0)).collect();
    let is_map = |c: [u8; 3]| palette.iter().any(|p| p.iter().zip(c).all(|(a, b)| a.abs_diff(b) <= 1));
    // Runs of map colour along the middle row of the maps: two of 256 pixels, then the bar.
    let y = (0..img.height()).find(|&y| is_map(px(12, y))).expect("a map at the left margin") + 128;
    let mut runs: Vec<(u32, u32)> = Vec::new();
    let mut x = 0;
    while x < img.width() {
        if is_map(px(x, y)) {
            let start = x;
            while x < img.width() && is_map(px(x, y)) {
                x += 1;
            }
            runs.push((start, x - start));
        }
        x += 1;
    }
    assert_eq!(runs.len(), 3, "two maps and the bar along row {y}: {runs:?}");
    assert_eq!((runs[0].1, runs[1].1), (256, 256), "{runs:?}");
    for &(x0, _) in &runs[..2] {
        let mut colours: Vec<[u8; 3]> = (0..256).map(|dx| px(x0 + dx, y)).collect();
        colours.sort_unstable();
        colours.dedup();
        assert!(colours.len() > 3, "a uniform map at x = {x0}");
    }
    let bar_x = runs[2].0 + runs[2].1 / 2;
    let column: Vec<[u8; 3]> = (0..img.height()).map(|y| px(bar_x, y)).filter(|&c| is_map(c)).collect();
    assert_eq!((column.first(), column.last()), (Some(&viridis(1.0)), Some(&viridis(0.0))), "colour bar");
    assert!(column.len() >= 256, "the bar spans the maps: {}", column.len());
}

/// docs/bench.md lists the columns of `bench::CSV_COLUMNS`, in order, under its
/// `<!-- bench.csv columns -->` marker (when the page exists).
#[test]
fn docs_list_the_csv_columns() {
    let page = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/bench.md");
    let Ok(text) = std::fs::read_to_string(&page) else {
        eprintln!("skipped: no {}", page.display());
        return;
    };
    let section = text.split("<!-- bench.csv columns -->").nth(1).expect("docs/bench.md marks the CSV columns");
    let documented: Vec<&str> = section
        .lines()
        .skip_while(|l| !l.starts_with("| `"))
        .take_while(|l| l.starts_with("| `"))
        .map(|l| l.trim_start_matches("| `").split('`').next().unwrap_or(""))
        .collect();
    assert_eq!(documented, CSV_COLUMNS, "docs/bench.md and bench::CSV_COLUMNS differ");
}

/// `arbor bench | head -1`: once the reader has gone, the benchmark ends quietly (exit
/// 0, no panic) instead of failing on the broken pipe.
#[test]
fn bench_ends_quietly_when_stdout_closes() {
    if !common::has_gpu() {
        return;
    }
    let mut child = Command::new(env!("CARGO_BIN_EXE_arbor"))
        .args(["bench", "--quick", "--tris", "1000", "--size", "16x16", "--accel", "none,kdtree"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run arbor");
    let mut stdout = std::io::BufReader::new(child.stdout.take().expect("stdout"));
    let mut first = String::new();
    std::io::BufRead::read_line(&mut stdout, &mut first).expect("first line");
    assert!(first.contains("scene triangles"), "{first}");
    drop(stdout);
    let out = child.wait_with_output().expect("wait");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(!stderr.contains("panicked") && !stderr.contains("Broken pipe"), "{stderr}");
}

#[test]
fn trace_times_come_from_gpu_timestamps() {
    let Some(ctx) = common::gpu() else { return };
    assert!(ctx.has_timestamps(), "lavapipe and real GPUs time compute dispatches");
    assert!(ctx.info().timestamp_period_ns > 0.0);
    let scene = Scene::load("builtin:blob:20000").expect("blob");
    let mut s = RenderSettings::for_size(96, 96);
    s.accel = AccelKind::None;
    s.primary_only = true;
    // Several dispatches, each timed: a render whose timestamps came back out of order
    // fails (Context::timestamp_ms, unit-tested with the scaling by timestampPeriod).
    s.pacing.budget = Some(20_000_000);
    let (_, st) = gpu::render(&ctx, &scene, &s, |_, _| {}).expect("render");
    assert!(st.dispatches > 1, "{} dispatches", st.dispatches);
    let t = st.trace_ms.expect("GPU timestamps");
    // The GPU intervals lie inside the host's wait for them, so their sum cannot exceed
    // the wall clock; no ratio is asserted, which a loaded machine could break.
    assert!(t > 0.0 && t <= st.wall_ms, "trace {t} ms, wall {} ms", st.wall_ms);
}

#[test]
fn auto_picks_brute_force_for_ten_triangles_and_a_tree_for_100k() {
    let small = String::from_utf8(run(&["info", "builtin:blob:10", "--accel", "auto"]).stdout).expect("utf8");
    assert!(small.lines().any(|l| l.starts_with("accel") && l.trim_end().ends_with("none")), "{small}");
    assert!(small.contains("ranked fastest"), "info says why: {small}");
    let big =
        String::from_utf8(run(&["info", "builtin:blob:100000", "--accel", "auto", "--json"]).stdout).expect("utf8");
    let v: serde_json::Value = serde_json::from_str(&big).expect("json");
    let kind = v["accel"].as_str().expect("accel");
    assert!(kind != "none", "{big}");
    assert!(v["accel_auto_reason"].as_str().is_some_and(|w| w.contains(kind)), "{big}");
}

#[test]
fn bench_compares_cpu_and_gpu_builds() {
    if !common::has_gpu() {
        return;
    }
    let json = std::env::temp_dir().join(format!("arbor-bench-build-{}.json", std::process::id()));
    let j = json.to_string_lossy().to_string();
    let out = run(&[
        "bench",
        "--quick",
        "--tris",
        "2000",
        "--accel",
        "lbvh,trbvh",
        "--build",
        "cpu,gpu",
        "--rays",
        "primary",
        "--json",
        &j,
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("trbvh@gpu") && text.contains("lbvh@gpu"), "{text}");
    assert!(text.contains("gpu restructure round 3"), "per-phase GPU figures missing:\n{text}");
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).expect("json")).expect("valid");
    let rows = v["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 4);
    // Same tree on both devices: same SAH cost and depth per structure.
    for kind in ["lbvh", "trbvh"] {
        let pair: Vec<&serde_json::Value> = rows.iter().filter(|r| r["accel"] == kind).collect();
        assert_eq!(pair.len(), 2);
        assert_eq!(pair[0]["sah_cost"], pair[1]["sah_cost"], "{kind}");
        assert_eq!(pair[0]["depth"], pair[1]["depth"], "{kind}");
        assert!(pair.iter().any(|r| r["build_phases"].as_array().is_some_and(|p| !p.is_empty())));
    }
    let _ = std::fs::remove_file(&json);
    // Render and info refuse a GPU build of a structure the GPU cannot build.
    let bad = Command::new(env!("CARGO_BIN_EXE_arbor"))
        .args(["info", "builtin:blob:500", "--accel", "kdtree", "--build", "gpu"])
        .output()
        .expect("run");
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--build gpu builds lbvh, trbvh, bvh4 and bvh8"));
    let ok = run(&["info", "builtin:blob:500", "--accel", "trbvh", "--build", "gpu"]);
    let text = String::from_utf8_lossy(&ok.stdout);
    assert!(text.contains("built on      GPU") && text.contains("validate      ok"), "{text}");
}

/// `bench --reference`: a ladder of sample counts per structure, its error against a
/// reference falling as samples grow, and convergence.csv with the plot.
#[test]
fn reference_ladder_reports_error_against_time() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        "[film]\nwidth = 16\nheight = 12\n[camera]\neye = [0, 0.5, 3]\nlook_at = [0, 0, 0]\n\
         [[material]]\nname = \"glow\"\ntype = \"emissive\"\nemission = [4, 4, 4]\n\
         [[sphere]]\ncenter = [0, -100.5, 0]\nradius = 100\n\
         [[sphere]]\ncenter = [0, 1.2, 0]\nradius = 0.3\nmaterial = \"glow\"\n",
    )
    .expect("scene");
    let s = scene.display().to_string();
    let reference = dir.path().join("ref.exr").display().to_string();
    run(&["render", &s, "--spp", "512", "-o", &reference, "--quiet"]);
    let out_dir = dir.path().join("out").display().to_string();
    let out = run(&[
        "bench",
        "--reference",
        &reference,
        "--scene",
        &s,
        "--accel",
        "bvh-sah,kdtree",
        "--ladder",
        "1,16",
        "--out",
        &out_dir,
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    let rows: Vec<Vec<&str>> = text.lines().skip(1).map(|l| l.split_whitespace().collect()).collect();
    assert_eq!(rows.len(), 4, "2 structures x 2 sample counts:\n{text}");
    for pair in rows.chunks(2) {
        let rel = |r: &[&str]| r[5].parse::<f64>().expect("relMSE");
        assert!(rel(&pair[1]) < rel(&pair[0]), "more samples, less error:\n{text}");
    }
    let csv = std::fs::read_to_string(dir.path().join("out/convergence.csv")).expect("csv");
    assert_eq!(csv.lines().count(), 5, "{csv}");
    assert!(dir.path().join("out/convergence.png").exists());
}

#[test]
fn shard_bench_prints_a_row_per_shard_count() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path().join("out");
    let d_s = d.display().to_string();
    let out = run(&[
        "bench",
        "--shards",
        "1,3",
        "--scene",
        "builtin:cornell",
        "--size",
        "24x16",
        "--spp",
        "2",
        "--out",
        &d_s,
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    // --out: the same rows as CSV and JSON.
    let csv = std::fs::read_to_string(d.join("shards.csv")).expect("shards.csv");
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 3, "{csv}");
    assert!(lines[0].starts_with("shards,by,wall_sum_s") && lines[2].starts_with("3,tiles,"), "{csv}");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("shards.json")).expect("shards.json")).expect("JSON");
    assert_eq!(json["rows"].as_array().map(Vec::len), Some(2), "{json}");
    assert_eq!(json["rows"][1]["shards"], 3);
    let rows: Vec<Vec<&str>> =
        text.lines().filter(|l| !l.starts_with('#')).map(|l| l.split_whitespace().collect()).collect();
    assert_eq!(rows.len(), 3, "a header and two rows:\n{text}");
    assert_eq!(rows[0][0], "shards");
    for (row, n) in rows[1..].iter().zip(["1", "3"]) {
        assert_eq!((row[0], row[1]), (n, "tiles"));
        let figures: Vec<f64> = row[2..11].iter().map(|v| v.parse().expect("a number")).collect();
        assert!(figures.iter().all(|&v| v.is_finite() && v >= 0.0), "{row:?}");
        assert!(figures[0] >= figures[1], "all shards take at least the longest: {row:?}");
    }
    let bad = Command::new(env!("CARGO_BIN_EXE_arbor"))
        .args(["bench", "--shards", "2", "--scene", "builtin:cornell,builtin:spheres"])
        .output()
        .expect("run");
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("exactly one --scene"));
}
