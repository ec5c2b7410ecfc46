//! Bad-input tests of the `arbor` binary: every missing or malformed scene, mesh or
//! command-line value must end the process with a non-zero exit code (never a panic, a
//! signal or a hang), print exactly one stderr line `arbor: error: ...` that names the
//! offending file (with `:LINE` where the format has lines) and what was wrong, and leave
//! every output file (`-o`, `--aov`, `--stats`) byte-identical, with no stray temporary
//! files beside them.
//!
//! Failures that need no GPU (parse and validation errors) run with the Vulkan loader
//! pointed at a driver manifest that does not exist, which proves they never touch a
//! device. The cases that need one (a render that must succeed, the storage-buffer limit)
//! are skipped when `arbor devices` fails, unless `ARBOR_REQUIRE_GPU=1`.
//!
//! Fixture files are written at test time into a temporary directory.

use std::collections::BTreeSet;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use tempfile::TempDir;

/// Longest time one `arbor` run may take before it counts as a hang.
const DEADLINE: Duration = Duration::from_secs(60);
/// Debian's assimp-testmodels malformed files.
const ASSIMP_INVALID: &str = "/usr/share/assimp/models/invalid";
/// Exit code of a Rust panic.
const PANIC_EXIT: i32 = 101;

/// Which Vulkan drivers the child process may see.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Device {
    /// None at all: the loader is pointed at a manifest that does not exist.
    Absent,
    /// Whatever the test environment provides (e.g. lavapipe via VK_DRIVER_FILES).
    Inherit,
}

/// What a finished `arbor` run produced.
#[derive(Debug)]
struct Outcome {
    /// Exit code; None when a signal ended the process.
    code: Option<i32>,
    stdout: String,
    stderr: String,
    /// The command line, for messages.
    cmd: String,
}

fn drain(mut r: impl Read + Send + 'static) -> std::thread::JoinHandle<Vec<u8>> {
    std::thread::spawn(move || {
        let mut buf = Vec::new();
        let _ = r.read_to_end(&mut buf);
        buf
    })
}

/// Runs the real binary with a deadline; kills it and fails the test on a hang.
fn arbor(args: &[String], device: Device, env: &[(&str, &str)]) -> Outcome {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_arbor"));
    cmd.args(args).stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
    // Settings of the outer environment must not change what is tested (ARBOR_VALIDATION
    // is kept: CI sets it so that the runs that reach a device are validated).
    for var in ["ARBOR_MAX_STORAGE_RANGE", "RUST_BACKTRACE", "RUST_LIB_BACKTRACE"] {
        cmd.env_remove(var);
    }
    if device == Device::Absent {
        let nowhere = "/nonexistent/arbor-bad-input-test/no_driver.json";
        cmd.env("VK_DRIVER_FILES", nowhere).env("VK_ICD_FILENAMES", nowhere).env_remove("VK_ADD_DRIVER_FILES");
    }
    for (k, v) in env {
        cmd.env(k, v);
    }
    let shown = format!("arbor {}", args.join(" "));
    let mut child = cmd.spawn().unwrap_or_else(|e| panic!("cannot start {shown}: {e}"));
    let out = drain(child.stdout.take().expect("stdout pipe"));
    let err = drain(child.stderr.take().expect("stderr pipe"));
    let start = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) if start.elapsed() > DEADLINE => {
                let _ = child.kill();
                let _ = child.wait();
                let stderr = String::from_utf8_lossy(&err.join().unwrap_or_default()).into_owned();
                panic!("`{shown}` hung: still running after {DEADLINE:?}; killed it. stderr so far:\n{stderr}");
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(20)),
            Err(e) => panic!("waiting for `{shown}`: {e}"),
        }
    };
    let stdout = String::from_utf8_lossy(&out.join().unwrap_or_default()).into_owned();
    let stderr = String::from_utf8_lossy(&err.join().unwrap_or_default()).into_owned();
    Outcome { code: status.code(), stdout, stderr, cmd: shown }
}

/// Whether a Vulkan device is usable; fails the test when one is required and missing.
/// Callers return early (the test is skipped) on false.
fn gpu_available() -> bool {
    static AVAILABLE: OnceLock<bool> = OnceLock::new();
    let ok = *AVAILABLE.get_or_init(|| {
        let o = arbor(&["devices".into()], Device::Inherit, &[]);
        let ok = o.code == Some(0) && !o.stdout.trim().is_empty();
        if !ok {
            eprintln!("`arbor devices` failed (code {:?}): {}", o.code, o.stderr.trim());
        }
        ok
    });
    if !ok {
        let required = std::env::var("ARBOR_REQUIRE_GPU").is_ok_and(|v| v == "1");
        assert!(!required, "ARBOR_REQUIRE_GPU=1 but `arbor devices` finds no usable Vulkan device");
        eprintln!("skipped: no Vulkan device");
    }
    ok
}

/// A temporary directory with scene fixtures and an `out/` folder of protected outputs.
struct Fixture {
    dir: TempDir,
}

impl Fixture {
    fn new() -> Self {
        let dir = tempfile::tempdir().expect("create a temporary directory");
        std::fs::create_dir(dir.path().join("out")).expect("create out/");
        Fixture { dir }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// `path(name)` as a string (temporary directories have plain ASCII names).
    fn p(&self, name: &str) -> String {
        self.path(name).display().to_string()
    }

    /// Writes a fixture file and returns its path as a string.
    fn write(&self, name: &str, contents: impl AsRef<[u8]>) -> String {
        let path = self.path(name);
        std::fs::write(&path, contents).unwrap_or_else(|e| panic!("write {}: {e}", path.display()));
        path.display().to_string()
    }

    /// A valid one-triangle OBJ.
    fn triangle_obj(&self) -> String {
        self.write("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    }

    /// The default output arguments: image, a depth AOV and statistics, all in `out/`.
    fn output_args(&self) -> Vec<String> {
        vec![
            "-o".into(),
            self.p("out/out.png"),
            "--aov".into(),
            format!("depth={}", self.p("out/depth.pfm")),
            "--stats".into(),
            self.p("out/stats.json"),
            "--quiet".into(),
        ]
    }

    /// `render SCENE` with the default outputs, `--size 8x8` unless `extra` has a
    /// `--size`, then `extra`.
    fn render_args(&self, scene: &str, extra: &[&str]) -> Vec<String> {
        let mut a = vec!["render".to_string(), scene.to_string()];
        a.extend(self.output_args());
        if !extra.iter().any(|a| a.starts_with("--size")) {
            a.extend(["--size".into(), "8x8".into()]);
        }
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    }

    /// Writes sentinel content to every default output (and to `more`, relative to the
    /// fixture), and records what `out/` holds.
    fn guard(&self, more: &[&str]) -> Guard {
        let mut files = Vec::new();
        for name in ["out/out.png", "out/depth.pfm", "out/stats.json"].iter().chain(more) {
            let path = self.path(name);
            let content = format!("sentinel for {name}: must survive a failed run\n").into_bytes();
            std::fs::write(&path, &content).unwrap_or_else(|e| panic!("write {}: {e}", path.display()));
            files.push((path, content));
        }
        let out_dir = self.path("out");
        let entries = list_dir(&out_dir);
        Guard { files, out_dir, entries }
    }
}

fn list_dir(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("list {}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").file_name().to_string_lossy().into_owned())
        .collect()
}

/// Output files with sentinel content, checked after a failed run.
struct Guard {
    files: Vec<(PathBuf, Vec<u8>)>,
    out_dir: PathBuf,
    entries: BTreeSet<String>,
}

impl Guard {
    /// Every sentinel is byte-identical and the output folder gained nothing (no
    /// temporary `.NAME.PID.tmp` files, no partial outputs, no new folders).
    fn check_untouched(&self, o: &Outcome) {
        for (path, content) in &self.files {
            let now = std::fs::read(path)
                .unwrap_or_else(|e| panic!("`{}`: output {} was removed: {e}", o.cmd, path.display()));
            assert!(&now == content, "`{}`: failed run clobbered {}", o.cmd, path.display());
        }
        let now = list_dir(&self.out_dir);
        let stray: Vec<&String> = now.difference(&self.entries).collect();
        let hidden: Vec<&String> = now.iter().filter(|n| n.starts_with('.')).collect();
        assert!(hidden.is_empty(), "`{}`: temporary files left in {}: {hidden:?}", o.cmd, self.out_dir.display());
        assert!(stray.is_empty(), "`{}`: failed run created {stray:?} in {}", o.cmd, self.out_dir.display());
    }
}

/// Asserts `o` is a clean failure and returns its one error line. Each entry of `wants`
/// must occur in that line (case-insensitively); `a|b` accepts either alternative.
fn expect_failure(o: &Outcome, wants: &[&str]) -> String {
    let ctx = || format!("`{}`\n--- stderr ---\n{}--- stdout ---\n{}", o.cmd, o.stderr, o.stdout);
    let code = o.code.unwrap_or_else(|| panic!("killed by a signal (crash), not an error exit: {}", ctx()));
    assert_ne!(code, 0, "bad input was accepted: {}", ctx());
    assert_ne!(code, PANIC_EXIT, "exit code 101 is a Rust panic: {}", ctx());
    assert!(!o.stderr.contains("panicked"), "panicked: {}", ctx());
    assert!(!o.stderr.contains("RUST_BACKTRACE"), "panic/backtrace text on stderr: {}", ctx());
    assert!(o.stdout.trim().is_empty(), "a failed run printed to stdout: {}", ctx());
    let text = o.stderr.trim_end_matches(['\n', '\r']);
    assert!(!text.contains('\n'), "stderr must be exactly one line: {}", ctx());
    assert!(text.starts_with("arbor: error: "), "stderr must start with 'arbor: error: ': {}", ctx());
    let line = text.to_string();
    // "a: X: X" (the same clause twice in a row) is not a clear message.
    let parts: Vec<&str> = line.split(": ").map(str::trim).collect();
    if let Some(w) = parts.windows(2).find(|w| w[0] == w[1] && !w[0].is_empty()) {
        panic!("the error line repeats '{}': {}", w[0], ctx());
    }
    let lower = line.to_lowercase();
    for want in wants {
        let ok = want.split('|').any(|alt| lower.contains(&alt.to_lowercase()));
        assert!(ok, "the error line should mention {want:?}: {}", ctx());
    }
    line
}

/// Runs `arbor render` on `scene` with guarded outputs and checks a clean failure.
fn render_fails(fx: &Fixture, scene: &str, extra: &[&str], device: Device, wants: &[&str]) -> String {
    let guard = fx.guard(&[]);
    let o = arbor(&fx.render_args(scene, extra), device, &[]);
    guard.check_untouched(&o);
    expect_failure(&o, wants)
}

/// Runs `arbor info` on `scene` and checks a clean failure.
fn info_fails(scene: &str, wants: &[&str]) -> String {
    let o = arbor(&["info".into(), scene.into()], Device::Absent, &[]);
    expect_failure(&o, wants)
}

/// Both `render` and `info` must fail the same way on a bad scene, without a device.
fn scene_fails(fx: &Fixture, scene: &str, wants: &[&str]) {
    render_fails(fx, scene, &[], Device::Absent, wants);
    info_fails(scene, wants);
}

/// `path:line:` as the error line must show it.
fn at(path: &str, line: usize) -> String {
    format!("{path}:{line}:")
}

const SPHERE: &str = "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\n";

// --- missing files --------------------------------------------------------------------

#[test]
fn missing_scene_files() {
    let fx = Fixture::new();
    for name in ["nope.toml", "nope.obj", "nope.ply", "nope.off"] {
        let path = fx.p(name);
        scene_fails(&fx, &path, &[&path, "not found|no such file"]);
    }
}

#[test]
fn toml_mesh_file_missing() {
    let fx = Fixture::new();
    let toml = fx.write("s.toml", "# a scene\n\n[[mesh]]\nfile = \"missing.obj\"\n");
    scene_fails(&fx, &toml, &[&at(&toml, 3), "missing.obj", "not found"]);
}

#[test]
fn scene_path_is_a_directory() {
    let fx = Fixture::new();
    std::fs::create_dir(fx.path("dir.obj")).expect("mkdir");
    let dir = fx.p("dir.obj");
    scene_fails(&fx, &dir, &[&dir, "directory"]);
    let toml = fx.write("s.toml", "[[mesh]]\nfile = \"dir.obj\"\n");
    scene_fails(&fx, &toml, &["dir.obj", "directory"]);
}

#[test]
fn unknown_scene_source() {
    let fx = Fixture::new();
    let xyz = fx.write("scene.xyz", "whatever");
    scene_fails(&fx, &xyz, &[&xyz, "unknown scene type"]);
    scene_fails(&fx, "builtin:nope", &["builtin:nope", "unknown built-in"]);
    scene_fails(&fx, "builtin:blob:3", &["builtin:blob:3", "between"]);
}

// --- TOML scene files -----------------------------------------------------------------

#[test]
fn toml_syntax_error_names_the_line() {
    let fx = Fixture::new();
    let toml = fx.write("s.toml", "[[sphere]]\ncenter = [0, 0, 0]\nradius = = 1\n");
    scene_fails(&fx, &toml, &[&at(&toml, 3), "expected"]);
    let toml = fx.write("u.toml", "[[sphere]]\ncenter = [0, 0,\n");
    scene_fails(&fx, &toml, &[&format!("{toml}:"), "unclosed|expected"]);
}

#[test]
fn toml_not_utf8() {
    let fx = Fixture::new();
    // No line to blame, but the file and the reason.
    let toml = fx.write("bin.toml", b"\xff\xfe[[sphere]]\n");
    scene_fails(&fx, &toml, &[&toml, "utf-8"]);
}

#[test]
fn toml_unknown_key() {
    let fx = Fixture::new();
    let toml = fx.write("s.toml", format!("{SPHERE}\n[camera]\neyes = [0, 0, 3]\nlook_at = [0, 0, 0]\n"));
    scene_fails(&fx, &toml, &[&at(&toml, 6), "unknown field|unknown key", "eyes"]);
    let toml = fx.write("t.toml", format!("{SPHERE}colour = [1, 0, 0]\n"));
    scene_fails(&fx, &toml, &[&format!("{toml}:"), "unknown field|unknown key", "colour"]);
    let toml = fx.write("v.toml", format!("{SPHERE}\n[lights]\nx = 1\n"));
    scene_fails(&fx, &toml, &[&at(&toml, 5), "unknown field|unknown key", "lights"]);
    let toml = fx.write("w.toml", format!("[[material]]\nname = \"a\"\ntype = \"plastic\"\n\n{SPHERE}"));
    scene_fails(&fx, &toml, &[&at(&toml, 3), "plastic"]);
}

#[test]
fn toml_unknown_material() {
    let fx = Fixture::new();
    fx.triangle_obj();
    let header = "# scene\n[[material]]\nname = \"red\"\ntype = \"lambert\"\n\n";
    let toml =
        fx.write("sphere.toml", format!("{header}[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"gold\"\n"));
    // At the line of the name, not of its table.
    scene_fails(&fx, &toml, &[&at(&toml, 9), "unknown material", "gold"]);
    let toml = fx.write("mesh.toml", format!("{header}[[mesh]]\nfile = \"tri.obj\"\nmaterial = \"gold\"\n"));
    scene_fails(&fx, &toml, &[&at(&toml, 8), "unknown material", "gold"]);
}

#[test]
fn toml_bad_sphere() {
    let fx = Fixture::new();
    for (i, body) in [
        "center = [0, 0, 0]\nradius = -1\n",
        "center = [0, 0, 0]\nradius = 0\n",
        "center = [nan, 0, 0]\nradius = 1\n",
        "center = [0, inf, 0]\nradius = 1\n",
        "center = [0, 0, 0]\nradius = inf\n",
    ]
    .iter()
    .enumerate()
    {
        let toml = fx.write(&format!("s{i}.toml"), format!("{SPHERE}\n[[sphere]]\n{body}"));
        scene_fails(&fx, &toml, &[&at(&toml, 5), "finite|radius"]);
    }
}

#[test]
fn toml_empty_scene() {
    let fx = Fixture::new();
    for (name, text) in [
        ("empty.toml", ""),
        ("comments.toml", "# nothing here\n"),
        ("settings.toml", "[camera]\neye = [0, 0, 3]\nlook_at = [0, 0, 0]\n\n[film]\nwidth = 8\nheight = 8\n"),
    ] {
        let toml = fx.write(name, text);
        scene_fails(&fx, &toml, &[&toml, "empty"]);
    }
}

#[test]
fn toml_zero_size_film() {
    let fx = Fixture::new();
    for (name, film) in [("w0.toml", "width = 0\nheight = 10\n"), ("h0.toml", "width = 10\nheight = 0\n")] {
        let toml = fx.write(name, format!("{SPHERE}\n[film]\n{film}"));
        // No --size: the film size itself is what is wrong.
        let guard = fx.guard(&[]);
        let mut args = vec!["render".to_string(), toml.clone()];
        args.extend(fx.output_args());
        let o = arbor(&args, Device::Absent, &[]);
        guard.check_untouched(&o);
        expect_failure(&o, &[&format!("{toml}:"), "image size|width|height", "1..="]);
        info_fails(&toml, &[&format!("{toml}:"), "image size|width|height"]);
        // The line of the [film] table or of the zero key.
        let line = expect_failure(&o, &[]);
        assert!(
            line.contains(&at(&toml, 5)) || line.contains(&at(&toml, 6)) || line.contains(&at(&toml, 7)),
            "the error should give the line of [film] in {toml}: {line}"
        );
    }
}

// --- OBJ --------------------------------------------------------------------------------

#[test]
fn obj_face_index_out_of_range() {
    let fx = Fixture::new();
    let obj = fx.write("oor.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n# a face\nf 1 2 9\n");
    scene_fails(&fx, &obj, &[&at(&obj, 5), "references vertex", "9"]);
    let obj = fx.write("neg.obj", "v 0 0 0\nv 1 0 0\nf 1 2 -5\nv 0 1 0\n");
    scene_fails(&fx, &obj, &[&at(&obj, 3), "vertex -5"]);
    let obj = fx.write("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
    scene_fails(&fx, &obj, &[&at(&obj, 4), "vertex 0"]);
    // Reached through a TOML scene: the OBJ is the file to blame.
    let toml = fx.write("s.toml", "[[mesh]]\nfile = \"oor.obj\"\n");
    scene_fails(&fx, &toml, &[&at(&fx.p("oor.obj"), 5), "references vertex"]);
}

#[test]
fn obj_non_finite_coordinates() {
    let fx = Fixture::new();
    for (name, v) in
        [("nan.obj", "v nan 0 0"), ("inf.obj", "v inf 0 0"), ("ninf.obj", "v 0 -inf 0"), ("big.obj", "v 1e39 0 0")]
    {
        let obj = fx.write(name, format!("# c\n{v}\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"));
        scene_fails(&fx, &obj, &[&at(&obj, 2), "non-finite"]);
    }
    let obj = fx.write("w.obj", "v 1 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    scene_fails(&fx, &obj, &[&at(&obj, 1), "w = 0"]);
}

#[test]
fn obj_without_faces_is_an_empty_scene() {
    let fx = Fixture::new();
    let obj = fx.write("nofaces.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    scene_fails(&fx, &obj, &[&obj, "empty"]);
    let obj = fx.write("blank.obj", "");
    scene_fails(&fx, &obj, &[&obj, "empty"]);
}

/// A missing or malformed MTL is not an error: the faces get the default material.
#[test]
fn obj_with_broken_mtl_renders_with_the_default_material() {
    let fx = Fixture::new();
    let geometry = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let missing = fx.write("missing_mtl.obj", format!("mtllib nowhere.mtl\nusemtl red\n{geometry}"));
    fx.write("bad.mtl", "newmtl red\nKd 1 2\nNs abc\n");
    let broken = fx.write("broken_mtl.obj", format!("mtllib bad.mtl\nusemtl red\n{geometry}"));
    // Loading needs no device.
    for obj in [&missing, &broken] {
        let o = arbor(&["info".into(), "--json".into(), obj.clone()], Device::Absent, &[]);
        assert_eq!(o.code, Some(0), "`{}` failed:\n{}", o.cmd, o.stderr);
        let info: serde_json::Value = serde_json::from_str(&o.stdout).expect("info --json output");
        assert_eq!(info["triangles"], 1, "{}", o.stdout);
    }
    if !gpu_available() {
        return;
    }
    for obj in [&missing, &broken] {
        let guard = fx.guard(&[]);
        let o = arbor(&fx.render_args(obj, &[]), Device::Inherit, &[]);
        assert_eq!(o.code, Some(0), "`{}` should succeed with the default material:\n{}", o.cmd, o.stderr);
        assert!(!o.stderr.contains("panicked"), "{}", o.stderr);
        for (path, sentinel) in &guard.files {
            let now = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(&now != sentinel, "`{}` did not write {}", o.cmd, path.display());
        }
        let img = image::open(fx.path("out/out.png")).expect("the output is a readable PNG");
        assert_eq!((img.width(), img.height()), (8, 8));
        let hidden: Vec<String> = list_dir(&fx.path("out")).into_iter().filter(|n| n.starts_with('.')).collect();
        assert!(hidden.is_empty(), "temporary files left behind: {hidden:?}");
    }
}

// --- PLY and OFF ------------------------------------------------------------------------

const PLY_HEADER: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";

#[test]
fn ply_ascii_index_out_of_range() {
    let fx = Fixture::new();
    let ply = fx.write("oor.ply", format!("{PLY_HEADER}0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"));
    scene_fails(&fx, &ply, &[&at(&ply, 13), "references vertex 7"]);
    let ply = fx.write("neg.ply", format!("{PLY_HEADER}0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n"));
    scene_fails(&fx, &ply, &[&at(&ply, 13), "references vertex -1"]);
}

#[test]
fn ply_ascii_non_finite_coordinates() {
    let fx = Fixture::new();
    let ply = fx.write("nan.ply", format!("{PLY_HEADER}0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n"));
    scene_fails(&fx, &ply, &[&at(&ply, 11), "non-finite"]);
    let ply = fx.write("inf.ply", format!("{PLY_HEADER}0 0 0\n1 0 0\n0 inf 0\n3 0 1 2\n"));
    scene_fails(&fx, &ply, &[&at(&ply, 12), "non-finite"]);
}

fn binary_ply() -> Vec<u8> {
    let mut b = PLY_HEADER.replace("format ascii", "format binary_little_endian").into_bytes();
    for v in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.push(3);
    for i in [0i32, 1, 2] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b
}

#[test]
fn ply_binary_truncated() {
    let fx = Fixture::new();
    let full = binary_ply();
    let header = full.windows(11).position(|w| w == b"end_header\n").expect("end_header") + 11;
    for (name, len) in [("vertices.ply", header + 20), ("face.ply", full.len() - 3), ("body.ply", header)] {
        let ply = fx.write(name, &full[..len]);
        scene_fails(&fx, &ply, &[&ply, "truncated"]);
    }
    // The untruncated file is fine (the cut is what fails).
    let ply = fx.write("full.ply", &full);
    let o = arbor(&["info".into(), ply], Device::Absent, &[]);
    assert_eq!(o.code, Some(0), "{}", o.stderr);
}

#[test]
fn off_bad_counts() {
    let fx = Fixture::new();
    for (name, text, line, want) in [
        ("x.off", "OFF\n3 x\n", 2, "face count 'x'"),
        ("neg.off", "OFF\n-3 1\n", 2, "vertex count"),
        ("missing.off", "OFF\n", 2, "counts"),
        ("short.off", "OFF\n5 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", 7, "file ends after 4 of 5 vertices"),
        ("faces.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", 7, "file ends after 1 of 2 faces"),
        ("poly.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", 6, "declares 4 vertices but lists only 3"),
        ("oor.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", 6, "references vertex 3"),
        ("inf.off", "OFF\n3 1 0\n0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n", 4, "non-finite"),
    ] {
        let off = fx.write(name, text);
        scene_fails(&fx, &off, &[&at(&off, line), want]);
    }
}

#[test]
fn assimp_invalid_models_fail_cleanly() {
    let dir = Path::new(ASSIMP_INVALID);
    assert!(
        dir.is_dir(),
        "{ASSIMP_INVALID} is missing: install Debian's assimp-testmodels package (these tests need its files)"
    );
    let fx = Fixture::new();
    for (name, line, want) in [
        ("malformed.obj", Some(23), "references vertex 12"),
        ("empty.obj", None, "empty"),
        ("empty.ply", Some(1), "empty"),
        ("empty.off", Some(1), "empty"),
        ("OutOfMemory.off", Some(2), "353535235358"),
    ] {
        let path = dir.join(name).display().to_string();
        let named = match line {
            Some(l) => at(&path, l),
            None => path.clone(),
        };
        scene_fails(&fx, &path, &[&named, want]);
    }
    // malformed2.obj references a material that does not exist: the default is used.
    let o = arbor(&["info".into(), dir.join("malformed2.obj").display().to_string()], Device::Absent, &[]);
    assert_eq!(o.code, Some(0), "malformed2.obj (unknown usemtl) should load: {}", o.stderr);
}

// --- command-line values ------------------------------------------------------------------

#[test]
fn zero_size_image_on_the_command_line() {
    let fx = Fixture::new();
    let obj = fx.triangle_obj();
    for size in ["0x10", "10x0", "0x0", "16385x8"] {
        render_fails(&fx, &obj, &[&format!("--size={size}")], Device::Absent, &["--size", size, "1..="]);
    }
}

#[test]
fn bad_size_syntax() {
    let fx = Fixture::new();
    let obj = fx.triangle_obj();
    for size in ["8by8", "8x", "x8", "-1x8", "8x8x8", "", "axb"] {
        render_fails(&fx, &obj, &[&format!("--size={size}")], Device::Absent, &["--size"]);
    }
}

#[test]
fn zero_spp() {
    if !gpu_available() {
        return;
    }
    let fx = Fixture::new();
    let obj = fx.triangle_obj();
    render_fails(&fx, &obj, &["--spp", "0"], Device::Inherit, &["--spp", "0"]);
}

/// `--spp` is a command-line value: it must be rejected before any GPU work, so the
/// message is the same without a device.
#[test]
fn zero_spp_is_rejected_without_a_device() {
    let fx = Fixture::new();
    let obj = fx.triangle_obj();
    render_fails(&fx, &obj, &["--spp", "0"], Device::Absent, &["--spp"]);
}

#[test]
fn unknown_accel() {
    let fx = Fixture::new();
    let obj = fx.triangle_obj();
    render_fails(&fx, &obj, &["--accel", "octree-x"], Device::Absent, &["--accel", "octree-x"]);
    let o = arbor(&["info".into(), obj, "--accel".into(), "octree-x".into()], Device::Absent, &[]);
    expect_failure(&o, &["--accel", "octree-x"]);
}

#[test]
fn bad_kd_parameters() {
    let fx = Fixture::new();
    let obj = fx.triangle_obj();
    render_fails(&fx, &obj, &["--kd", "leafs=3"], Device::Absent, &["--kd", "unknown key"]);
    render_fails(&fx, &obj, &["--kd", "ki=-1"], Device::Absent, &["--kd", "non-negative"]);
    render_fails(&fx, &obj, &["--kd", "perfect=maybe"], Device::Absent, &["--kd", "true or false"]);
}

#[test]
fn unknown_aov() {
    let fx = Fixture::new();
    let obj = fx.triangle_obj();
    let bogus = format!("bogus={}", fx.p("out/bogus.pfm"));
    render_fails(&fx, &obj, &["--aov", &bogus], Device::Absent, &["unknown aov", "bogus"]);
    let noeq = fx.p("out/depth2.pfm");
    render_fails(&fx, &obj, &["--aov", &noeq], Device::Absent, &["--aov", "name=path"]);
    let twice = format!("depth={}", fx.p("out/d2.pfm"));
    render_fails(&fx, &obj, &["--aov", &twice], Device::Absent, &["depth", "twice"]);
    let png = format!("normal={}", fx.p("out/normal.png"));
    render_fails(&fx, &obj, &["--aov", &png], Device::Absent, &[&fx.p("out/normal.png"), ".pfm"]);
}

#[test]
fn unsupported_image_extension() {
    let fx = Fixture::new();
    let obj = fx.triangle_obj();
    for name in ["out/out.jpg", "out/out", "out/out.pfm"] {
        let guard = fx.guard(&[name]);
        let mut args = fx.render_args(&obj, &[]);
        args[3] = fx.p(name); // -o VALUE
        let o = arbor(&args, Device::Absent, &[]);
        guard.check_untouched(&o);
        expect_failure(&o, &[&fx.p(name), ".png"]);
    }
}

#[test]
fn output_into_a_missing_directory() {
    let fx = Fixture::new();
    let obj = fx.triangle_obj();
    let nodir = fx.p("out/nodir/out.png");
    for (flag, value, named) in [
        ("-o", nodir.clone(), nodir.clone()),
        ("--aov", format!("depth={}", fx.p("out/nodir/d.pfm")), fx.p("out/nodir/d.pfm")),
        ("--stats", fx.p("out/nodir/s.json"), fx.p("out/nodir/s.json")),
    ] {
        let guard = fx.guard(&[]);
        let mut args = fx.render_args(&obj, &[]);
        let i = args.iter().position(|a| a == flag).expect("flag present");
        args[i + 1] = value;
        let o = arbor(&args, Device::Absent, &[]);
        guard.check_untouched(&o);
        expect_failure(&o, &[&named, "does not exist"]);
    }
}

#[test]
fn output_path_is_a_directory() {
    let fx = Fixture::new();
    let obj = fx.triangle_obj();
    std::fs::create_dir(fx.path("out/img.png")).expect("mkdir");
    let guard = fx.guard(&[]);
    let mut args = fx.render_args(&obj, &[]);
    args[3] = fx.p("out/img.png");
    let o = arbor(&args, Device::Absent, &[]);
    guard.check_untouched(&o);
    expect_failure(&o, &[&fx.p("out/img.png"), "is a directory"]);
}

#[test]
fn bad_storage_range_variable() {
    let fx = Fixture::new();
    let obj = fx.triangle_obj();
    let guard = fx.guard(&[]);
    let o = arbor(&fx.render_args(&obj, &[]), Device::Absent, &[("ARBOR_MAX_STORAGE_RANGE", "lots")]);
    guard.check_untouched(&o);
    expect_failure(&o, &["ARBOR_MAX_STORAGE_RANGE", "lots"]);
}

// --- device limits ------------------------------------------------------------------------

/// A scene whose vertex buffer exceeds maxStorageBufferRange (lowered to 64 KiB).
#[test]
fn scene_larger_than_the_device_allows() {
    if !gpu_available() {
        return;
    }
    let fx = Fixture::new();
    let limit = 65536u64;
    let guard = fx.guard(&[]);
    let o = arbor(&fx.render_args("builtin:blob:20000", &[]), Device::Inherit, &[("ARBOR_MAX_STORAGE_RANGE", "65536")]);
    guard.check_untouched(&o);
    let line = expect_failure(&o, &["'vertices'", "maxStorageBufferRange", &limit.to_string(), "too large"]);
    let size: u64 = line
        .split("needs ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("the error should state the buffer size ('needs N bytes'): {line}"));
    assert!(size > limit, "the stated size {size} should exceed the limit {limit}: {line}");
}

// --- `arbor info` -------------------------------------------------------------------------

#[test]
fn info_fails_the_same_way() {
    let fx = Fixture::new();
    let obj = fx.write("oor.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
    info_fails(&obj, &[&at(&obj, 4), "references vertex 4"]);
    let toml = fx.write("s.toml", format!("{SPHERE}material = \"gold\"\n"));
    info_fails(&toml, &[&at(&toml, 4), "unknown material"]);
    let toml = fx.write("e.toml", "");
    info_fails(&toml, &[&toml, "empty"]);
    let off = fx.write("bad.off", "OFF\n3 x\n");
    info_fails(&off, &[&at(&off, 2), "face count"]);
}

// --- the command line itself --------------------------------------------------------------

/// `arbor` alone prints the usage (not the description as an error).
#[test]
fn no_arguments_print_the_usage() {
    let o = arbor(&[], Device::Absent, &[]);
    assert_eq!(o.code, Some(2), "{o:?}");
    assert!(o.stderr.contains("Usage: arbor <COMMAND>") && o.stderr.contains("render"), "{o:?}");
    assert!(!o.stderr.contains("error"), "{o:?}");
}

/// Each clap error is one line that says what is wrong and where to read more.
#[test]
fn command_line_errors_name_what_is_wrong() {
    let o = arbor(&["info".into()], Device::Absent, &[]);
    expect_failure(&o, &["missing <SCENE>", "arbor info --help"]);
    let o = arbor(&["render".into(), "--bogus".into()], Device::Absent, &[]);
    expect_failure(&o, &["--bogus", "arbor render --help"]);
    let o = arbor(&["rendr".into()], Device::Absent, &[]);
    expect_failure(&o, &["rendr", "arbor --help"]);
    let o = arbor(&["render".into(), "--spp".into(), "many".into()], Device::Absent, &[]);
    expect_failure(&o, &["--spp", "many"]);
}

/// `bsp` is not an alias of `kdtree` (it reads as `bsp-course`); the kept aliases work.
#[test]
fn accel_bsp_is_rejected() {
    let fx = Fixture::new();
    let obj = fx.triangle_obj();
    let o = arbor(&["info".into(), obj.clone(), "--accel".into(), "bsp".into()], Device::Absent, &[]);
    expect_failure(&o, &["--accel", "bsp"]);
    let o = arbor(&["bench".into(), "--accel".into(), "bsp".into()], Device::Absent, &[]);
    expect_failure(&o, &["--accel", "bsp"]);
    for alias in ["brute-force", "kd", "bvh"] {
        let o = arbor(&["info".into(), obj.clone(), "--accel".into(), alias.into()], Device::Absent, &[]);
        assert_eq!(o.code, Some(0), "--accel {alias}: {o:?}");
    }
}
