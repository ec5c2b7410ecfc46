//! Bad outputs and unbounded requests of the `arbor` binary: an output path that cannot
//! be written, a frame larger than the memory available, a `--repeat` without bound, a
//! bench whose input is wrong. Each must end with a non-zero exit code and exactly one
//! stderr line `arbor: error: ...` (never a panic, a signal or a hang), before any
//! device is opened, and leave no output of any kind and no temporary file behind. The
//! runs that need a device (a bench of a tiny image, progress of a long render) are
//! skipped without one, unless `ARBOR_REQUIRE_GPU=1`.

use std::collections::BTreeSet;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Longest time one `arbor` run may take before it counts as a hang.
const DEADLINE: Duration = Duration::from_secs(120);

/// What a finished run produced.
struct Outcome {
    code: Option<i32>,
    stdout: String,
    stderr: String,
    cmd: String,
}

/// The binary with `args` and `env`; with `device` false the Vulkan loader sees no
/// driver, which proves a failure happens before any device is opened.
fn command(args: &[&str], env: &[(&str, &str)], device: bool) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_arbor"));
    cmd.args(args).stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
    for var in ["ARBOR_MAX_STORAGE_RANGE", "ARBOR_MEMORY_LIMIT", "RUST_BACKTRACE"] {
        cmd.env_remove(var);
    }
    if !device {
        let nowhere = "/nonexistent/arbor-bad-outputs-test/no_driver.json";
        cmd.env("VK_DRIVER_FILES", nowhere).env("VK_ICD_FILENAMES", nowhere).env_remove("VK_ADD_DRIVER_FILES");
    }
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd
}

fn drain(mut r: impl Read + Send + 'static) -> std::thread::JoinHandle<String> {
    std::thread::spawn(move || {
        let mut buf = Vec::new();
        let _ = r.read_to_end(&mut buf);
        String::from_utf8_lossy(&buf).into_owned()
    })
}

/// Runs the binary to its end (killed, and the test failed, after `DEADLINE`).
fn arbor(args: &[&str], env: &[(&str, &str)], device: bool) -> Outcome {
    let cmd_text = format!("arbor {}", args.join(" "));
    let mut child = command(args, env, device).spawn().expect("start arbor");
    let out = drain(child.stdout.take().expect("stdout"));
    let err = drain(child.stderr.take().expect("stderr"));
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait") {
            break s;
        }
        if start.elapsed() > DEADLINE {
            let _ = child.kill();
            let _ = child.wait();
            panic!("`{cmd_text}` hung: still running after {DEADLINE:?}; stderr:\n{}", err.join().unwrap_or_default());
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Outcome {
        code: status.code(),
        stdout: out.join().unwrap_or_default(),
        stderr: err.join().unwrap_or_default(),
        cmd: cmd_text,
    }
}

/// Asserts a failed run: exit code 1, one stderr line `arbor: error: ...` containing
/// every part of `expect`, nothing on stdout.
fn assert_one_line_error(o: &Outcome, expect: &[&str]) {
    assert_failed_with(1, o, expect);
}

/// [`assert_one_line_error`] with exit code `code` (2: a mistake on the command line).
fn assert_failed_with(code: i32, o: &Outcome, expect: &[&str]) {
    assert_eq!(o.code, Some(code), "`{}`: exit code {:?}; stderr:\n{}", o.cmd, o.code, o.stderr);
    let lines: Vec<&str> = o.stderr.lines().collect();
    assert_eq!(lines.len(), 1, "`{}`: expected one stderr line, got:\n{}", o.cmd, o.stderr);
    assert!(lines[0].starts_with("arbor: error: "), "`{}`: {}", o.cmd, lines[0]);
    for part in expect {
        assert!(lines[0].contains(part), "`{}`: error lacks {part:?}: {}", o.cmd, lines[0]);
    }
    assert!(!lines[0].contains("panicked"), "{}", lines[0]);
    assert_eq!(o.stdout, "", "`{}` printed to stdout", o.cmd);
}

/// The names in `dir`.
fn entries(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir)
        .expect("list")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect()
}

/// A temporary directory with a one-triangle OBJ.
fn fixture() -> (tempfile::TempDir, String) {
    let dir = tempfile::tempdir().expect("tempdir");
    let obj = dir.path().join("tri.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").expect("write tri.obj");
    (dir, obj.display().to_string())
}

fn p(dir: &Path, name: &str) -> String {
    dir.join(name).display().to_string()
}

/// Whether a Vulkan device is usable (fails when one is required and missing).
fn gpu_available() -> bool {
    static AVAILABLE: OnceLock<bool> = OnceLock::new();
    let ok = *AVAILABLE.get_or_init(|| {
        let o = arbor(&["devices"], &[], true);
        o.code == Some(0) && !o.stdout.trim().is_empty()
    });
    if !ok {
        let required = std::env::var("ARBOR_REQUIRE_GPU").is_ok_and(|v| v == "1");
        assert!(!required, "ARBOR_REQUIRE_GPU=1 but `arbor devices` finds no usable Vulkan device");
        eprintln!("skipped: no Vulkan device");
    }
    ok
}

/// Case 1: an AOV or stats path ending in '/', a parent that is a file, a missing
/// parent, a directory, the same path twice: refused before the render, and no image,
/// AOV, stats or temporary file appears.
#[test]
fn unwritable_output_leaves_nothing_behind() {
    let (dir, obj) = fixture();
    let d = dir.path();
    std::fs::write(d.join("file"), "a plain file").expect("write");
    std::fs::create_dir(d.join("sub")).expect("mkdir");
    let before = entries(d);
    let png = p(d, "out.png");
    let aov_slash = format!("depth={}/", p(d, "d.pfm"));
    let aov_in_file = format!("depth={}", p(d, "file/d.pfm"));
    let aov_missing = format!("depth={}", p(d, "missing/d.pfm"));
    let aov_same = format!("depth={}", p(d, "x.exr"));
    let stats_slash = format!("{}/", p(d, "s.json"));
    let stats_in_file = p(d, "file/s.json");
    let stats_dir = p(d, "sub");
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (vec!["--aov", &aov_slash], vec!["d.pfm/", "expected a file name"]),
        (vec!["--aov", &aov_in_file], vec!["file/d.pfm", "is not a directory"]),
        (vec!["--aov", &aov_missing], vec!["missing/d.pfm", "does not exist"]),
        (vec!["--stats", &stats_slash], vec!["s.json/", "expected a file name"]),
        (vec!["--stats", &stats_in_file], vec!["file/s.json", "is not a directory"]),
        (vec!["--stats", &stats_dir], vec!["sub", "is a directory"]),
    ];
    for (extra, expect) in cases {
        let mut args = vec!["render", &obj, "-o", &png, "--size", "8x8", "--quiet"];
        args.extend(extra);
        let o = arbor(&args, &[], false);
        assert_one_line_error(&o, &expect);
        assert_eq!(entries(d), before, "`{}` left files behind", o.cmd);
    }
    let exr = p(d, "x.exr");
    let o = arbor(&["render", &obj, "-o", &exr, "--aov", &aov_same, "--size", "8x8", "--quiet"], &[], false);
    assert_failed_with(2, &o, &["x.exr", "two outputs"]);
    assert_eq!(entries(d), before);
}

/// Case 1, a read-only directory for one AOV: refused before the render (a probe file
/// cannot be created). As root a mode of 555 does not stop writes; then the test says so
/// and checks nothing more.
#[test]
fn read_only_directory_is_refused_before_the_render() {
    use std::os::unix::fs::PermissionsExt;
    let (dir, obj) = fixture();
    let d = dir.path();
    let ro = d.join("ro");
    std::fs::create_dir(&ro).expect("mkdir");
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).expect("chmod");
    let probe = ro.join("probe");
    if std::fs::write(&probe, "x").is_ok() {
        let _ = std::fs::remove_file(&probe);
        let _ = std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755));
        eprintln!("skipped: a read-only directory is writable here (running as root)");
        return;
    }
    let before = entries(d);
    let png = p(d, "out.png");
    let aov = format!("depth={}", p(d, "ro/d.pfm"));
    let o = arbor(&["render", &obj, "-o", &png, "--aov", &aov, "--size", "8x8", "--quiet"], &[], false);
    let _ = std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755));
    assert_one_line_error(&o, &["ro/d.pfm", "cannot create a file in"]);
    assert_eq!(entries(d), before);
    assert!(entries(&ro).is_empty());
}

/// Case 2: a bench of an image smaller than brute force's smallest square side (8) ran
/// into `clamp(min > max)` and exited 101.
#[test]
fn bench_of_a_tiny_image_does_not_panic() {
    if !gpu_available() {
        return;
    }
    let args = ["bench", "--scene", "builtin:default", "--size", "7x7", "--repeat", "1", "--accel", "kdtree"];
    let o = arbor(&args, &[], true);
    assert_eq!(o.code, Some(0), "`{}`:\n{}", o.cmd, o.stderr);
    assert!(o.stdout.contains("default"), "no row for the scene:\n{}", o.stdout);
}

/// Case 3: a frame larger than the memory available is refused with the size to reduce,
/// before a device is opened (`ARBOR_MEMORY_LIMIT` plays a small machine).
#[test]
fn frame_larger_than_memory_is_refused() {
    let (dir, obj) = fixture();
    let d = dir.path();
    let before = entries(d);
    let png = p(d, "out.png");
    let args = ["render", &obj, "-o", &png, "--size", "64x64", "--quiet"];
    let o = arbor(&args, &[("ARBOR_MEMORY_LIMIT", "100000")], false);
    assert_one_line_error(&o, &["--size 64x64: the frame needs about", "GiB are available; use a smaller --size"]);
    let o = arbor(&args, &[("ARBOR_MEMORY_LIMIT", "lots")], false);
    assert_one_line_error(&o, &["ARBOR_MEMORY_LIMIT", "not a byte count"]);
    let bench = ["bench", "--scene", "builtin:default", "--size", "64x64", "--repeat", "1"];
    let o = arbor(&bench, &[("ARBOR_MEMORY_LIMIT", "100000")], false);
    assert_one_line_error(&o, &["--size 64x64: the frame needs about"]);
    assert_eq!(entries(d), before);
}

/// Case 4: `--repeat` is bounded (it ran until killed with the largest integer).
#[test]
fn repeat_out_of_range_is_refused() {
    for r in ["18446744073709551615", "0", "1001"] {
        let o = arbor(&["bench", "--scene", "builtin:default", "--size", "8x8", "--repeat", r], &[], false);
        assert_failed_with(2, &o, &[&format!("--repeat {r}: must be 1..=1000")]);
    }
}

/// Case 4: a long render with stderr not a terminal prints plain progress lines
/// (`render: P% (T s, about R s left)`); the most samples on one pixel takes minutes,
/// so the child is stopped at its first line, leaving no file behind.
#[test]
fn long_render_shows_progress_without_a_terminal() {
    if !gpu_available() {
        return;
    }
    let (dir, _) = fixture();
    let d = dir.path();
    let before = entries(d);
    let png = p(d, "long.png");
    let args = ["render", "builtin:default", "--size", "1x1", "--spp", "1048576", "-o", &png];
    let mut child = command(&args, &[], true).spawn().expect("start arbor");
    let _out = drain(child.stdout.take().expect("stdout"));
    let (tx, rx) = std::sync::mpsc::channel();
    let stderr = child.stderr.take().expect("stderr");
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let start = Instant::now();
    let mut seen = Vec::new();
    let found = loop {
        match rx.recv_timeout(Duration::from_millis(200)) {
            Ok(l) if l.starts_with("render: ") => break Some(l),
            Ok(l) => seen.push(l),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) if start.elapsed() < DEADLINE => {}
            Err(_) => break None,
        }
    };
    let _ = child.kill();
    let _ = child.wait();
    let line = found.unwrap_or_else(|| panic!("no progress line within {DEADLINE:?}; stderr:\n{}", seen.join("\n")));
    assert!(line.contains("% (") && line.contains(" s"), "{line}");
    assert_eq!(entries(d), before, "a stopped render left files behind");
}

/// Case 5: bench checks every input before it opens a device and prints its `device:`
/// line (or the table header): a missing scene, a bad size, lambda, repeat or output path.
#[test]
fn bench_checks_inputs_before_the_device_line() {
    let (dir, _) = fixture();
    let d = dir.path();
    std::fs::write(d.join("file"), "x").expect("write");
    let missing = p(d, "missing.obj");
    let json_slash = format!("{}/", p(d, "b.json"));
    let out_file = p(d, "file");
    let cases: Vec<(Vec<&str>, i32, Vec<&str>)> = vec![
        (vec!["--scene", &missing], 1, vec!["missing.obj"]),
        (vec!["--size", "0x8"], 2, vec!["--size"]),
        (vec!["--lambda=-1"], 2, vec!["--lambda"]),
        (vec!["--repeat", "5000"], 2, vec!["--repeat 5000"]),
        (vec!["--json", &json_slash], 1, vec!["b.json/"]),
        (vec!["--out", &out_file], 1, vec!["file", "not a directory"]),
    ];
    for (extra, code, expect) in cases {
        let mut args = vec!["bench", "--tris", "100", "--accel", "kdtree"];
        for (flag, value) in [("--size", "8x8"), ("--repeat", "1")] {
            if !extra.contains(&flag) {
                args.extend([flag, value]);
            }
        }
        args.extend(extra);
        // With the environment's device: the error must still come before the device line.
        let o = arbor(&args, &[], true);
        assert!(!o.stderr.contains("device:"), "`{}` printed the device line:\n{}", o.cmd, o.stderr);
        assert_failed_with(code, &o, &expect);
    }
    assert_eq!(entries(d), BTreeSet::from(["file".to_string(), "tri.obj".to_string()]));
}

/// Exit codes, one rule for every command: 2 for a mistake on the command line (a flag's
/// value, flags that contradict each other), 1 for a failure reading, building or
/// rendering. Every case fails before a device is opened, with one line and no file.
#[test]
fn exit_codes_follow_one_rule() {
    let (dir, obj) = fixture();
    let d = dir.path();
    let before = entries(d);
    let png = p(d, "out.png");
    let missing = p(d, "missing.obj");
    let missing_exr = p(d, "missing.exr");
    let (jpg, merged) = (p(d, "out.jpg"), p(d, "m.exr"));
    let cases: Vec<(Vec<&str>, i32, Vec<&str>)> = vec![
        (vec!["render", &obj, "-o", &png, "--size", "0x0"], 2, vec!["--size 0x0"]),
        (vec!["render", &obj, "-o", &png, "--size", "64"], 2, vec!["--size", "WIDTHxHEIGHT"]),
        (vec!["render", &obj, "-o", &png, "--spp", "0"], 2, vec!["--spp"]),
        (vec!["render", &obj, "-o", &png, "--spp", "-1"], 2, vec!["'-1'", "--spp"]),
        (vec!["render", &obj, "-o", &png, "--max-depth", "-3"], 2, vec!["--max-depth"]),
        (vec!["render", &obj, "-o", &png, "--accel", "bvh2"], 2, vec!["--accel bvh2"]),
        (vec!["render", &obj, "-o", &png, "--size", "8x8", "--crop", "6,2,0,8"], 2, vec!["--crop"]),
        (vec!["render", &obj, "-o", &jpg], 2, vec!["out.jpg", ".png or .exr"]),
        (vec!["render", &obj, "-o", &png, "--accel", "kdtree", "--build", "gpu"], 2, vec!["--build gpu"]),
        (vec!["render", &obj, "-o", &png, "--shard", "3/2"], 2, vec!["--shard"]),
        (vec!["render", &obj, "-o", &png, "--no-such-flag"], 2, vec!["--no-such-flag"]),
        (vec!["bench", "--accel", "kdtree,foo", "--size", "8x8"], 2, vec!["foo"]),
        (vec!["bench", "--repeat", "0"], 2, vec!["--repeat 0"]),
        (vec!["render", &missing, "-o", &png], 1, vec!["missing.obj"]),
        (vec!["info", &missing], 1, vec!["missing.obj"]),
        (vec!["merge", "-o", &merged, &missing_exr], 1, vec!["missing.exr"]),
        (vec!["compare", &missing_exr, &obj], 1, vec!["missing.exr"]),
    ];
    for (args, code, expect) in cases {
        let o = arbor(&args, &[], false);
        assert_failed_with(code, &o, &expect);
        assert_eq!(entries(d), before, "`{}` left files behind", o.cmd);
    }
}
