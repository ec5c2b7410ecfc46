//! `scripts/gpu-bench.sh`: `--quick` with this build's binary writes every step's files
//! and the summary's tables; bad options fail with one line and exit status 2.

use crate::common;

use std::path::Path;
use std::process::{Command, Output};

fn script(args: &[&str], out: &Path) -> Output {
    Command::new("bash")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/gpu-bench.sh"))
        .args(args)
        .arg("--out")
        .arg(out)
        .env_remove("ARBOR_CACHE_DIR")
        .output()
        .expect("run bash")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

#[test]
fn quick_run_writes_every_step_and_the_summary() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("bench");
    let run = script(&["--quick", "--bin", env!("CARGO_BIN_EXE_arbor")], &out);
    assert!(run.status.success(), "gpu-bench.sh --quick failed ({}):\n{}", run.status, text(&run));

    assert!(std::fs::read_to_string(out.join("devices.txt")).expect("devices.txt").starts_with("0: "));
    // `arbor calibrate` is left out of a quick run (cli::calibrate_... tests it), and
    // calibration.txt says so.
    let cal = std::fs::read_to_string(out.join("calibration.txt")).expect("calibration.txt");
    assert!(cal.contains("left out with --quick"), "{cal}");
    assert!(!out.join("cache").exists(), "a quick run calibrated");
    for step in ["01-structures", "02-build"] {
        let d = out.join(step);
        for f in ["bench.csv", "bench.json", "table.txt"] {
            let len = std::fs::metadata(d.join(f)).map(|m| m.len()).unwrap_or(0);
            assert!(len > 0, "{step}/{f} missing or empty");
        }
        let plots = std::fs::read_dir(d.join("plots")).expect("plots/").count();
        assert!(plots > 0, "{step}/plots is empty");
    }

    let summary = std::fs::read_to_string(out.join("summary.md")).expect("summary.md");
    for want in [
        "## Mrays/s per structure and ray kind",
        "| structure | primary | diffuse | path |",
        "## GPU build against CPU build",
        "## rayquery against the best software structure",
    ] {
        assert!(summary.contains(want), "summary.md lacks {want:?}:\n{summary}");
    }
    // A figure per structure and ray kind, and the GPU builds against the CPU's.
    for s in ["kdtree", "bvh-sah", "cwbvh"] {
        let row = summary.lines().find(|l| l.starts_with(&format!("| {s} |"))).unwrap_or_default();
        assert_eq!(row.matches(" | ").count(), 3, "no row of 3 figures for {s}:\n{summary}");
        assert!(!row.contains("failed"), "{row}");
    }
    for s in ["lbvh", "trbvh"] {
        assert!(summary.contains(&format!("| {s}@gpu |")), "no {s}@gpu row:\n{summary}");
        assert!(summary.lines().any(|l| l.contains(&format!(" | {s} | "))), "no build row for {s}:\n{summary}");
    }
    // rayquery is compared or said to be left out.
    assert!(summary.contains("| rayquery / best |") || summary.contains("rayquery: left out: "), "{summary}");
    assert!(!summary.contains("## Rows that failed"), "{summary}");
}

#[test]
fn bad_options_fail_with_one_line_and_status_2() {
    let dir = tempfile::tempdir().expect("temp dir");
    let full = dir.path().join("full");
    std::fs::create_dir(&full).expect("mkdir");
    std::fs::write(full.join("notes.txt"), "mine").expect("write");
    let bin = env!("CARGO_BIN_EXE_arbor");
    for (args, out, want) in [
        (&["--bogus"][..], dir.path().join("a"), "unknown option '--bogus'"),
        (
            &["--bin", "/nonexistent/arbor"][..],
            dir.path().join("b"),
            "--bin /nonexistent/arbor: not an executable file",
        ),
        (
            &["--bin", bin, "--mesh", "/nonexistent.ply"][..],
            dir.path().join("c"),
            "--mesh /nonexistent.ply: no such file",
        ),
        (&["--bin", bin][..], full.clone(), "is not empty; pass --force"),
    ] {
        let run = script(args, &out);
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {}", text(&run));
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(err.starts_with("gpu-bench: error: ") && err.contains(want), "{args:?}: {err}");
        assert!(!out.exists() || out == full, "{args:?} created {}", out.display());
    }
    assert_eq!(std::fs::read_to_string(full.join("notes.txt")).expect("kept"), "mine");
}
