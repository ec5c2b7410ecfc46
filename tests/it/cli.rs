//! The `arbor` binary's own output: the render summary line, the statistics JSON's
//! provenance, the warning for a scene lit only by emissive materials, and a quiet end
//! when the reader of stdout goes away.

use crate::common;

use std::process::{Command, Output, Stdio};

fn arbor(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_arbor")).args(args).output().expect("run arbor")
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

/// An emissive material as the only light renders black with Whitted: a warning says so
/// (even with --quiet); a scene with a point or directional light, or the path
/// integrator, gets none.
#[test]
fn emissive_only_scene_warns() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("glow.toml");
    let body = "[[material]]\nname = \"glow\"\ntype = \"emissive\"\n\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"glow\"\n";
    std::fs::write(&scene, body).expect("write scene");
    let png = dir.path().join("g.png").display().to_string();
    let s = scene.display().to_string();
    let out = ok(&["render", &s, "--size", "8x8", "-o", &png, "--quiet", "--integrator", "whitted"]);
    let err = String::from_utf8_lossy(&out.stderr);
    let want = format!("arbor: warning: {s}: emissive materials do not light other surfaces");
    assert!(err.contains(&want), "{err}");
    let lit = format!("{body}\n[[light]]\ntype = \"point\"\nposition = [0, 3, 0]\nintensity = [1, 1, 1]\n");
    let out = ok(&["render", &s, "--size", "8x8", "-o", &png, "--quiet", "--integrator", "path"]);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("warning"));
    std::fs::write(&scene, lit).expect("write scene");
    let out = ok(&["render", &s, "--size", "8x8", "-o", &png, "--quiet", "--integrator", "whitted"]);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("warning"));
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
