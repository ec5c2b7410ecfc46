//! `--trace-events`: the Chrome trace-event JSON of render, bench and info, parsed
//! back. Spans nest on each track, GPU spans do not overlap, the GPU dispatch spans
//! sum to the render's reported trace time within the timestamps' resolution, a
//! calibrated GPU span lies inside the CPU span of its submission, and the file is
//! written with the other outputs or not at all.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use arbor::timeline::chrome::{check_nesting, read};
use arbor::timeline::{GpuClock, Trace, Track};
use serde_json::Value;

fn arbor(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_arbor")).args(args).output().expect("run arbor")
}

fn run_ok(args: &[&str]) {
    let out = arbor(args);
    assert!(out.status.success(), "arbor {args:?} failed:\n{}", String::from_utf8_lossy(&out.stderr));
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("arbor-timeline-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

fn load(path: &Path) -> (Trace, Value) {
    let bytes = std::fs::read(path).expect("trace file");
    let doc: Value = serde_json::from_slice(&bytes).expect("the trace is JSON");
    (read(&bytes, path).expect("a Chrome trace"), doc)
}

fn names<'a>(t: &'a Trace, track: Track, cat: &str) -> Vec<&'a str> {
    t.on(track).filter(|e| e.cat == cat).map(|e| e.name.as_str()).collect()
}

/// The default render (path tracing), with the kd-tree, on a small image: every part of
/// the run is on the timeline, nested, and the GPU spans add up to `trace_ms`.
#[test]
fn a_render_timeline_nests_and_its_gpu_spans_sum_to_the_trace_time() {
    let Some(ctx) = common::gpu() else { return };
    let period_ns = f64::from(ctx.info().timestamp_period_ns);
    drop(ctx);
    let dir = temp_dir("render");
    let (img, stats, trace) = (dir.join("img.png"), dir.join("stats.json"), dir.join("trace.json"));
    let s = |p: &Path| p.to_string_lossy().into_owned();
    run_ok(&[
        "render",
        "builtin:default",
        "--accel",
        "kdtree",
        // Sized by the work budget alone, so that the waves below do not depend on
        // how loaded the machine is.
        "--dispatch-ms",
        "60000",
        "--size",
        "96x72",
        "--spp",
        "3",
        "--validation",
        "-q",
        "-o",
        &s(&img),
        "--stats",
        &s(&stats),
        "--trace-events",
        &s(&trace),
    ]);
    let (t, doc) = load(&trace);
    assert_eq!(t.process, "arbor render");
    assert_eq!(doc["displayTimeUnit"], "ms");
    for (tid, name) in [(1, "CPU"), (2, "GPU queue")] {
        let named = doc["traceEvents"]
            .as_array()
            .expect("events")
            .iter()
            .any(|e| e["ph"] == "M" && e["name"] == "thread_name" && e["tid"] == tid && e["args"]["name"] == name);
        assert!(named, "thread {tid} is named {name}");
    }
    check_nesting(&t, 0).expect("spans nest on each track");

    // The CPU track: loading, the build with its phases inside, kernel, uploads, the
    // trace loop with its dispatches and readbacks, and every output encoded.
    assert_eq!(names(&t, Track::Cpu, "load"), ["load scene builtin:default"]);
    let build = t.on(Track::Cpu).find(|e| e.name == "build kdtree").expect("the build span");
    let phases: Vec<&str> = t
        .on(Track::Cpu)
        .filter(|e| e.cat == "build" && e.start_ns >= build.start_ns && e.end_ns() <= build.end_ns())
        .map(|e| e.name.as_str())
        .collect();
    assert_eq!(phases, ["build kdtree", "events", "event sort", "SAH splits", "flatten"]);
    assert_eq!(names(&t, Track::Cpu, "kernel"), ["create kernel trace_kdtree_all"]);
    assert_eq!(names(&t, Track::Cpu, "trace"), ["trace"]);
    assert!(!names(&t, Track::Cpu, "upload").is_empty() && !names(&t, Track::Cpu, "readback").is_empty());
    let encoded = names(&t, Track::Cpu, "output");
    for f in [&img, &stats] {
        assert!(encoded.contains(&format!("encode {}", f.display()).as_str()), "{f:?} in {encoded:?}");
    }

    // The GPU track: 3 sample waves of one dispatch each, named by pixel range and
    // samples, with the kernel's name; their durations sum to the stats' trace_ms.
    let dispatches: Vec<_> = t.on(Track::Gpu).filter(|e| e.cat == "dispatch").collect();
    let labels: Vec<&str> = dispatches.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(
        labels,
        ["trace pixels 0+6912 samples 0..1", "trace pixels 0+6912 samples 1..2", "trace pixels 0+6912 samples 2..3"]
    );
    assert!(dispatches.iter().all(|e| e.args["kernel"] == "trace_kdtree_all"));
    let st: Value = serde_json::from_slice(&std::fs::read(&stats).expect("stats")).expect("stats JSON");
    let trace_ms = st["trace_ms"].as_f64().expect("timestamps on this device");
    // Each span is its timestamps' difference times the period, rounded to a nanosecond.
    let resolution_ms = dispatches.len() as f64 * period_ns.max(1.0) * 1e-6;
    let sum = t.gpu_ms("dispatch");
    assert!((sum - trace_ms).abs() <= resolution_ms, "GPU spans sum to {sum} ms, stats say {trace_ms} ms");
    assert!(!names(&t, Track::Gpu, "transfer").is_empty(), "uploads and readbacks are GPU spans too");

    // Calibrated placement: every GPU span starts after its submission did and, but
    // for trace dispatches (kept in flight: the host does not wait in their
    // submission), lies inside that CPU span, to within the calibration's error; the
    // dispatches end inside the trace loop.
    assert_eq!(t.gpu_clock, Some(GpuClock::Calibrated), "lavapipe has VK_EXT_calibrated_timestamps");
    assert_eq!(doc["otherData"]["gpu_clock"], "calibrated");
    let slack = t.calibration_error_ns;
    assert!(slack < 50_000_000, "calibration error {slack} ns");
    let trace = t.on(Track::Cpu).find(|e| e.name == "trace").expect("the trace loop");
    for g in t.on(Track::Gpu) {
        let cpu = t
            .on(Track::Cpu)
            .filter(|c| c.cat == "submit" && c.name == g.name && c.start_ns <= g.start_ns + slack)
            .last();
        let cpu = cpu.unwrap_or_else(|| panic!("no submission span for {:?}", g.name));
        let end = if g.cat == "dispatch" { trace.end_ns() } else { cpu.end_ns() };
        let inside = g.start_ns + slack >= cpu.start_ns && g.end_ns() <= end + slack;
        assert!(inside, "GPU span {g:?} outside its submission {cpu:?} (error {slack} ns)");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Without calibration (forced here) the file says the spans were aligned at submit,
/// and each starts where its submission did (a dispatch in flight: or where the one
/// before it ended).
#[test]
fn spans_aligned_at_submit_say_so() {
    if !common::has_gpu() {
        return;
    }
    let dir = temp_dir("submit");
    let trace = dir.join("t.json");
    let s = |p: &Path| p.to_string_lossy().into_owned();
    let img = s(&dir.join("i.png"));
    let args = ["render", "builtin:cornell", "--size", "48x48", "--spp", "2", "--validation", "-q", "-o", &img];
    run_ok(&[&args[..], &["--trace-events", &s(&trace), "--trace-align-submit"]].concat());
    let (t, doc) = load(&trace);
    assert_eq!(t.gpu_clock, Some(GpuClock::Submit));
    assert_eq!(doc["otherData"]["gpu_clock"], "submit");
    assert!(doc["otherData"]["gpu_clock_note"].as_str().expect("note").contains("aligned at submit"));
    check_nesting(&t, 0).expect("spans nest");
    for g in t.on(Track::Gpu) {
        let cpu = t.on(Track::Cpu).filter(|c| c.cat == "submit" && c.name == g.name && c.start_ns <= g.start_ns).last();
        let cpu = cpu.unwrap_or_else(|| panic!("no submission span for {:?}", g.name));
        // A dispatch in flight starts where its submission did or where the one
        // before it ended; other submissions are waited for inside their span.
        assert!(g.start_ns >= cpu.start_ns, "{g:?} starts before {cpu:?}");
        assert!(g.cat == "dispatch" || g.start_ns <= cpu.end_ns(), "{g:?} starts inside {cpu:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--trace-events FILE.png` draws the timeline: both tracks in their colours.
#[test]
fn a_png_timeline_is_a_picture_of_both_tracks() {
    if !common::has_gpu() {
        return;
    }
    let dir = temp_dir("png");
    let (img, pic) = (dir.join("i.png"), dir.join("timeline.png"));
    let s = |p: &Path| p.to_string_lossy().into_owned();
    run_ok(&[
        "render",
        "builtin:cornell",
        "--size",
        "48x48",
        "--spp",
        "2",
        "--validation",
        "-q",
        "-o",
        &s(&img),
        "--trace-events",
        &s(&pic),
    ]);
    let png = image::open(&pic).expect("a PNG").to_rgb8();
    assert_eq!(png.width(), 1600);
    // The build (orange) on the CPU track and the dispatches (red) on the GPU track.
    for rgb in [[242, 142, 43], [225, 87, 89]] {
        assert!(png.pixels().any(|p| p.0 == rgb), "colour {rgb:?} drawn");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// bench writes the timeline with bench.json and bench.csv: both structures' builds,
/// and their trace dispatches on the GPU track.
#[test]
fn bench_and_info_write_timelines() {
    if !common::has_gpu() {
        return;
    }
    let dir = temp_dir("bench");
    let trace = dir.join("bench-trace.json");
    let s = |p: &Path| p.to_string_lossy().into_owned();
    run_ok(&[
        "bench",
        "--quick",
        "--tris",
        "1000",
        "--rays",
        "primary",
        "--accel",
        "kdtree,bvh-sah",
        "--validation",
        "--out",
        &s(&dir.join("out")),
        "--trace-events",
        &s(&trace),
    ]);
    assert!(dir.join("out/bench.csv").is_file());
    let (t, _) = load(&trace);
    assert_eq!(t.process, "arbor bench");
    check_nesting(&t, 0).expect("spans nest");
    let builds = names(&t, Track::Cpu, "build");
    for b in ["build kdtree", "build bvh-sah", "binned SAH", "event sort"] {
        assert!(builds.contains(&b), "{b} in {builds:?}");
    }
    assert!(t.on(Track::Gpu).filter(|e| e.cat == "dispatch").count() >= 4, "warm-up and timed traces of each");

    // info --build gpu: the GPU builder's steps nest inside its submission.
    let info = dir.join("info.json");
    run_ok(&[
        "info",
        "builtin:blob:2000",
        "--accel",
        "lbvh",
        "--build",
        "gpu",
        "--validation",
        "--trace-events",
        &s(&info),
    ]);
    let (t, _) = load(&info);
    check_nesting(&t, 0).expect("spans nest");
    let gpu_build: Vec<_> = t.on(Track::Gpu).filter(|e| e.cat == "build").collect();
    let whole = gpu_build.iter().find(|e| e.name == "build lbvh").expect("the GPU build's submission");
    let steps: Vec<&str> = gpu_build.iter().filter(|e| e.name.starts_with("gpu ")).map(|e| e.name.as_str()).collect();
    assert!(steps.len() >= 3, "GPU build steps: {steps:?}");
    for e in &gpu_build {
        assert!(e.start_ns >= whole.start_ns && e.end_ns() <= whole.end_ns(), "{e:?} inside {whole:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A trace file that cannot be written fails the render before any work, and leaves
/// no other output; a name that is not .json is refused.
#[test]
fn the_trace_file_is_all_or_nothing_with_the_other_outputs() {
    let dir = temp_dir("fail");
    let img = dir.join("img.png");
    let stats = dir.join("s.json");
    let s = |p: &Path| p.to_string_lossy().into_owned();
    let missing = dir.join("no/such/dir/t.json");
    let out = arbor(&[
        "render",
        "builtin:cornell",
        "--size",
        "16x16",
        "-o",
        &s(&img),
        "--stats",
        &s(&stats),
        "--trace-events",
        &s(&missing),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("t.json"), "the error names the trace file: {err}");
    assert!(!img.exists() && !stats.exists(), "nothing written");
    let out = arbor(&["render", "builtin:cornell", "-o", &s(&img), "--trace-events", &s(&dir.join("t.txt"))]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("FILE.json"));
    assert!(String::from_utf8_lossy(&out.stderr).contains("t.txt"));
    assert!(!img.exists());
    let out =
        arbor(&["bench", "--shards", "2", "--scene", "builtin:cornell", "--trace-events", &s(&dir.join("b.json"))]);
    assert!(!out.status.success(), "bench --shards does not take --trace-events");
    let _ = std::fs::remove_dir_all(&dir);
}
