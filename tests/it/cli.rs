//! The `arbor` binary's own output: the render summary line, the statistics JSON's
//! provenance, the warning for a scene lit only by emissive materials, and a quiet end
//! when the reader of stdout goes away.

use crate::common;

use std::process::{Command, Output, Stdio};

/// No calibration file is read: auto's picks are the built-in model's on every machine.
const NO_CACHE: &str = "/nonexistent/arbor-test-cache";

fn arbor(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_arbor")).args(args).env("ARBOR_CACHE_DIR", NO_CACHE).output().expect("run arbor")
}

fn ok(args: &[&str]) -> Output {
    let out = arbor(args);
    assert!(out.status.success(), "arbor {args:?} failed:\n{}", String::from_utf8_lossy(&out.stderr));
    out
}

/// The summary names load, build, trace and total times; the stats JSON carries what
/// reruns it.
#[test]
fn render_reports_every_time_and_stats_carry_provenance() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let png = dir.path().join("a.png").display().to_string();
    let stats = dir.path().join("s.json").display().to_string();
    let args =
        ["render", "builtin:cornell", "--size", "16x12", "--spp", "2", "--seed", "7", "-o", &png, "--stats", &stats];
    let out = ok(&args);
    let line = String::from_utf8_lossy(&out.stderr).to_string();
    for part in ["wrote ", "(16x12, path 2 spp", ": load ", " ms, build ", " ms, trace ", "dispatches), total "] {
        assert!(line.contains(part), "summary lacks {part:?}: {line}");
    }
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&stats).expect("stats")).expect("JSON");
    assert!(v["wall_ms"].as_f64().is_some() && v["build_ms"].as_f64().is_some(), "{v}");
    let p = &v["provenance"];
    assert_eq!(p["version"], env!("CARGO_PKG_VERSION"));
    assert_eq!((p["seed"].as_u64(), p["spp"].as_u64()), (Some(7), Some(2)), "{p}");
    assert_eq!((p["width"].as_u64(), p["height"].as_u64()), (Some(16), Some(12)), "{p}");
    assert_eq!(p["integrator"], "path");
    let cmd: Vec<&str> =
        p["command_line"].as_array().expect("command line").iter().filter_map(|a| a.as_str()).collect();
    assert_eq!(&cmd[1..], &args[..], "{p}");
}

/// An emissive material as the only light lights the Whitted preview (its surfaces
/// sample it as the path tracer does): no warning, and the lit sphere is not black.
#[test]
fn emissive_only_scene_lights_the_preview() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("glow.toml");
    let body = "[camera]\neye = [0, 0, 6]\nlook_at = [0, 0, 0]\n\n[[material]]\nname = \"glow\"\ntype = \"emissive\"\nemission = [4, 4, 4]\n\n[[material]]\nname = \"white\"\ntype = \"lambert\"\ncolor = [0.8, 0.8, 0.8]\n\n[[sphere]]\ncenter = [-1.2, 0, 0]\nradius = 0.5\nmaterial = \"glow\"\n\n[[sphere]]\ncenter = [1.2, 0, 0]\nradius = 1\nmaterial = \"white\"\n";
    std::fs::write(&scene, body).expect("write scene");
    let exr = dir.path().join("g.exr");
    let s = scene.display().to_string();
    let out = ok(&[
        "render",
        &s,
        "--size",
        "32x16",
        "-o",
        &exr.display().to_string(),
        "--integrator",
        "whitted",
        "--spp",
        "16",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("warning"), "{err}");
    let (_, frame) = arbor::render::output::part::read(&exr).expect("read the EXR");
    // The white sphere fills the right half: its side facing the glow is lit.
    let lit = (0..frame.radiance.len()).filter(|&k| k % 32 >= 16 && frame.radiance[k][0] > 0.01).count();
    assert!(lit > 20, "{lit} pixels of the white sphere are lit");
}

/// `arbor info | head -1` (needs no device): a closed stdout is a quiet end.
#[test]
fn info_ends_quietly_when_stdout_closes() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_arbor"))
        .args(["info", "builtin:blob:20000"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run arbor");
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("wait");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stderr.is_empty(), "{stderr}");
}

/// `--accel auto` drops the structures whose buffers would not fit the device
/// (`ARBOR_MAX_STORAGE_RANGE` lowers every buffer's limit, texel bindings included) and
/// says which; a farm part keeps the pick made from the scene alone, so that every
/// node picks alike, and fails naming the buffer.
#[test]
fn auto_drops_structures_that_do_not_fit_the_device() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let png = dir.path().join("x.png").display().to_string();
    let args = ["render", "builtin:blob:20000", "--size", "64x64", "--integrator", "whitted", "-o", &png];
    let run = |extra: &[&str], limit: Option<&str>| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_arbor"));
        c.args(args).args(extra).env_remove("ARBOR_MAX_STORAGE_RANGE").env("ARBOR_CACHE_DIR", NO_CACHE);
        if let Some(l) = limit {
            c.env("ARBOR_MAX_STORAGE_RANGE", l);
        }
        let out = c.output().expect("run arbor");
        (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
    };
    let (code, err) = run(&[], None);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("accel auto: ") && err.contains("lbvh ranked fastest"), "{err}");
    // lbvh's nodes (68 bytes a primitive, 1.3 MB) exceed 1 MB; trbvh's (39) do not.
    let (code, err) = run(&[], Some("1000000"));
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("lbvh, bvh8, octree would not fit the device"), "{err}");
    assert!(err.contains("accel trbvh"), "{err}");
    let (code, err) = run(&["--shard", "0/2"], Some("1000000"));
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("'accel_nodes'") && err.contains("1000000"), "{err}");
    // Nothing fits: the smallest structure's need and the limit.
    let (code, err) = run(&[], Some("420000"));
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("no structure fits") && err.contains("cwbvh") && err.contains("420000"), "{err}");
}

/// `arbor calibrate` writes the device's costs to the cache and `render --accel auto`
/// then names them; a corrupt file is ignored with a warning; a cache directory that
/// cannot be created fails before any measuring (under a regular file: tests run as
/// root, so permissions would not stop them).
#[test]
fn calibrate_writes_the_cache_that_auto_reads() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let cache = dir.path().join("cache");
    let run = |args: &[&str], cache: &std::path::Path| {
        let out =
            Command::new(env!("CARGO_BIN_EXE_arbor")).args(args).env("ARBOR_CACHE_DIR", cache).output().expect("run");
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (code, table, err) = run(&["calibrate"], &cache);
    assert_eq!(code, Some(0), "{err}");
    for row in ["kdtree     cpu", "cwbvh      cpu", "lbvh       gpu", "bvh8       gpu", "brute force:"] {
        assert!(table.contains(row), "no {row:?} in:\n{table}");
    }
    assert!(err.contains("calibrate: 9/9: octree") && err.contains("wrote"), "{err}");
    let files: Vec<_> = std::fs::read_dir(&cache).expect("cache").filter_map(|e| e.ok()).map(|e| e.path()).collect();
    assert_eq!(files.len(), 1, "{files:?}");
    let png = dir.path().join("x.png").display().to_string();
    let render = ["render", "builtin:blob:20000", "--size", "32x32", "--integrator", "whitted", "-o", png.as_str()];
    let (code, _, err) = run(&render, &cache);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("measured on this device by `arbor calibrate`"), "{err}");
    std::fs::write(&files[0], "{ torn").expect("corrupt it");
    let (code, _, err) = run(&render, &cache);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("warning: calibration") && err.contains("corrupt"), "{err}");
    assert!(err.contains("built-in costs measured on lavapipe"), "{err}");
    let plain = dir.path().join("plain");
    std::fs::write(&plain, "x").expect("write");
    let (code, _, err) = run(&["calibrate"], &plain.join("cache"));
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("cannot write the cache") && !err.contains("calibrate: 1/9"), "{err}");
}
