//! `examples/trace_rays.rs`, the library example: run with a small ray count, its
//! output names both structures, full agreement and the rates.

use crate::common;

use std::process::Command;

/// `cargo run --example trace_rays -- ARGS` in this build's profile.
fn run_example(args: &[&str]) -> std::process::Output {
    let mut cmd = Command::new(env!("CARGO"));
    cmd.current_dir(env!("CARGO_MANIFEST_DIR")).args(["run", "--quiet", "--example", "trace_rays"]);
    if !cfg!(debug_assertions) {
        cmd.arg("--release");
    }
    cmd.arg("--").args(args).output().expect("cargo runs")
}

#[test]
fn the_example_traces_two_structures_and_they_agree() {
    // Without a device the example fails (status 3): skip as the GPU tests do.
    if !common::has_gpu() {
        return;
    }
    let out = run_example(&["builtin:blob:20000", "--rays", "20000", "--accel", "kdtree,bvh-sah", "--seed", "3"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "status {:?}\nstdout:\n{stdout}\nstderr:\n{stderr}", out.status.code());
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 4, "{stdout}");
    assert!(lines[0].starts_with("trace_rays: scene builtin:blob:20000 (") && lines[0].contains("20000 rays, seed 3"));
    for (line, kind) in lines[1..3].iter().zip(["kdtree", "bvh-sah"]) {
        assert!(line.starts_with(&format!("{kind}: build ")), "{line}");
        assert!(line.contains(" Mrays/s ("), "{line}");
        assert!(line.ends_with("gpu = cpu on 20000 of 20000 rays"), "{line}");
        let rate: f64 =
            line.split("gpu ").nth(1).and_then(|s| s.split(' ').next()).and_then(|s| s.parse().ok()).expect("rate");
        assert!(rate > 0.0, "{line}");
    }
    assert_eq!(lines[3], "kdtree vs bvh-sah (gpu): same hit on 20000 of 20000 rays");
}

#[test]
fn the_example_rejects_bad_arguments() {
    let out = run_example(&["--rays", "many"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--rays: expected a count"));
}
