//! Regression tests for inputs that once hung, read without bound or printed messages
//! that were not one clean line (docs/limits.md). Each load runs on a thread with a
//! deadline, so a hang fails the test instead of blocking it.

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use arbor::scene::limits::{MAX_MESH_FILE_BYTES, MAX_TEXT_FILE_BYTES};
use arbor::scene::Scene;

/// Longest a load may take before it counts as a hang.
const DEADLINE: Duration = Duration::from_secs(30);

/// `Scene::load(path)` with a deadline; the error message, or None when it loaded.
fn load(path: &Path) -> Option<String> {
    let (tx, rx) = mpsc::channel();
    let source = path.display().to_string();
    std::thread::spawn(move || {
        let _ = tx.send(Scene::load(&source).err().map(|e| e.to_string()));
    });
    rx.recv_timeout(DEADLINE).unwrap_or_else(|_| panic!("loading {} did not finish in {DEADLINE:?}", path.display()))
}

/// Loads `path`, expects an error starting with `prefix` and containing `want`, and
/// checks that it is one clean line. Returns the message.
fn rejects(path: &Path, prefix: &str, want: &str) -> String {
    let msg = load(path).unwrap_or_else(|| panic!("{} loaded", path.display()));
    assert!(msg.starts_with(prefix), "{msg:?} should start with {prefix:?}");
    assert!(msg.contains(want), "{msg:?} should contain {want:?}");
    assert!(!msg.chars().any(char::is_control), "{msg:?} has a control character");
    assert!(msg.len() < 600, "message of {} bytes", msg.len());
    msg
}

fn mkfifo(path: &Path) {
    let ok = std::process::Command::new("mkfifo").arg(path).status().expect("run mkfifo").success();
    assert!(ok, "mkfifo {}", path.display());
}

const TRI_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

fn d(dir: &Path, name: &str) -> PathBuf {
    dir.join(name)
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

#[test]
fn fifos_are_refused_not_waited_on() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    for name in ["fifo.obj", "fifo.toml", "fifo.mtl", "fifo.ply"] {
        mkfifo(&d(dir, name));
    }
    rejects(&d(dir, "fifo.obj"), &s(&d(dir, "fifo.obj")), "is a named pipe (FIFO)");
    rejects(&d(dir, "fifo.toml"), &s(&d(dir, "fifo.toml")), "is a named pipe (FIFO)");
    std::fs::write(d(dir, "lib.obj"), format!("mtllib fifo.mtl\n{TRI_OBJ}")).unwrap();
    let m = rejects(&d(dir, "lib.obj"), &format!("{}:1:", s(&d(dir, "lib.obj"))), "mtllib 'fifo.mtl' is a named pipe");
    eprintln!("{m}");
    std::fs::write(d(dir, "mesh.toml"), "[[mesh]]\nfile = \"fifo.ply\"\n").unwrap();
    rejects(
        &d(dir, "mesh.toml"),
        &s(&d(dir, "fifo.ply")),
        "is a named pipe (FIFO); a mesh file must be a regular file",
    );
}

#[cfg(unix)]
#[test]
fn devices_and_oversized_files_are_not_read() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let link = |target: &str, name: &str| std::os::unix::fs::symlink(target, d(dir, name)).unwrap();
    link("/dev/zero", "zero.ply");
    link("/dev/urandom", "rand.obj");
    link("/dev/urandom", "rand.toml");
    link("/dev/zero", "zero.off");
    for name in ["zero.ply", "rand.obj", "rand.toml", "zero.off"] {
        rejects(&d(dir, name), &s(&d(dir, name)), "is a character device");
    }
    std::fs::write(d(dir, "zero_mesh.toml"), "[[mesh]]\nfile = \"zero.ply\"\n").unwrap();
    rejects(&d(dir, "zero_mesh.toml"), &s(&d(dir, "zero.ply")), "is a character device");
    std::fs::write(d(dir, "zero_mtl.obj"), format!("mtllib /dev/zero\n{TRI_OBJ}")).unwrap();
    rejects(
        &d(dir, "zero_mtl.obj"),
        &format!("{}:1:", s(&d(dir, "zero_mtl.obj"))),
        "mtllib '/dev/zero' is a character device",
    );
    std::fs::write(d(dir, "dir.obj"), format!("mtllib .\n{TRI_OBJ}")).unwrap();
    rejects(&d(dir, "dir.obj"), &s(&d(dir, "dir.obj")), "is a directory");

    // Sparse files one byte over each limit cost no disk and are refused from their length.
    let sparse = |name: &str, len: u64| {
        std::fs::File::create(d(dir, name)).unwrap().set_len(len).unwrap();
        d(dir, name)
    };
    let m = rejects(
        &sparse("huge.ply", MAX_MESH_FILE_BYTES + 1),
        &s(&d(dir, "huge.ply")),
        "at most 2 GiB (2147483648 bytes) are read",
    );
    eprintln!("{m}");
    rejects(
        &sparse("huge.toml", MAX_TEXT_FILE_BYTES + 1),
        &s(&d(dir, "huge.toml")),
        "at most 16 MiB (16777216 bytes) are read",
    );
    sparse("huge.mtl", MAX_TEXT_FILE_BYTES + 1);
    std::fs::write(d(dir, "huge_mtl.obj"), format!("mtllib huge.mtl\n{TRI_OBJ}")).unwrap();
    rejects(&d(dir, "huge_mtl.obj"), &s(&d(dir, "huge_mtl.obj")), "at most 16 MiB (16777216 bytes) are read");
}

#[test]
fn a_material_library_named_many_times_is_read_once() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let mtl: String = (0..20_000).map(|i| format!("newmtl m{i}\nKd 0.5 0.5 0.5\nKs 0.1 0.1 0.1\n")).collect();
    std::fs::write(d(dir, "big.mtl"), mtl).unwrap();
    std::fs::write(d(dir, "many.obj"), format!("{}{TRI_OBJ}usemtl m7\nf 1 2 3\n", "mtllib big.mtl\n".repeat(150)))
        .unwrap();
    assert_eq!(load(&d(dir, "many.obj")), None);
    let scene = Scene::load(&s(&d(dir, "many.obj"))).unwrap();
    assert!(scene.materials.len() <= 20_002, "{} materials", scene.materials.len());

    let distinct: String = (0..100).map(|i| format!("mtllib m{i}.mtl\n")).collect();
    std::fs::write(d(dir, "distinct.obj"), format!("{distinct}{TRI_OBJ}")).unwrap();
    rejects(&d(dir, "distinct.obj"), &format!("{}:65:", s(&d(dir, "distinct.obj"))), "distinct material libraries");
}

/// A binary PLY grid of `2 * (n-1)^2` triangles.
fn grid_ply(n: u32) -> Vec<u8> {
    let nt = 2 * (n - 1) * (n - 1);
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {nt}\nproperty list uchar int vertex_indices\nend_header\n",
        n * n
    )
    .into_bytes();
    for i in 0..n {
        for j in 0..n {
            for v in [i as f32, j as f32, 0.0] {
                out.extend(v.to_le_bytes());
            }
        }
    }
    for i in 0..n - 1 {
        for j in 0..n - 1 {
            let a = (i * n + j) as i32;
            for t in [[a, a + 1, a + n as i32 + 1], [a, a + n as i32 + 1, a + n as i32]] {
                out.push(3);
                t.iter().for_each(|v| out.extend(v.to_le_bytes()));
            }
        }
    }
    out
}

#[test]
fn a_scene_too_large_in_total_is_refused_before_it_is_built() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    std::fs::write(d(dir, "m.ply"), grid_ply(160)).unwrap(); // 50562 triangles
    let tables: String = (0..2000).map(|i| format!("[[mesh]]\nfile = \"m.ply\"\ntranslate = [{i}, 0, 0]\n")).collect();
    std::fs::write(d(dir, "many.toml"), tables).unwrap();
    let start = std::time::Instant::now();
    let m = rejects(&d(dir, "many.toml"), &format!("{}:", s(&d(dir, "many.toml"))), "use fewer or smaller meshes");
    eprintln!("{m}");
    assert!(m.contains("[[mesh]] table 664") && m.contains("at most 33554432"), "{m}");
    assert!(start.elapsed() < Duration::from_secs(10), "took {:?}", start.elapsed());
}

#[test]
fn messages_are_one_clean_short_line() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    std::fs::write(d(dir, "nl.toml"), "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"x\\ny\"\n").unwrap();
    let m = rejects(&d(dir, "nl.toml"), &format!("{}:4:", s(&d(dir, "nl.toml"))), "unknown material 'x\\ny'");
    eprintln!("{m}");
    std::fs::write(d(dir, "nlfile.toml"), "[[mesh]]\nfile = \"a\\nb.obj\"\n").unwrap();
    rejects(&d(dir, "nlfile.toml"), &s(&d(dir, "nlfile.toml")), "mesh file 'a\\nb.obj' not found");

    std::fs::write(d(dir, "esc.off"), b"\x1b[2J\x1b]0;pwned\x07OFF\n").unwrap();
    let m = rejects(&d(dir, "esc.off"), &s(&d(dir, "esc.off")), "found '\\x1b[2J\\x1b]0;pwned\\x07OFF'");
    eprintln!("{m}");

    std::fs::write(d(dir, "long.obj"), format!("v 0 0 {}\n", "x".repeat(10_000_000))).unwrap();
    let m = rejects(&d(dir, "long.obj"), &format!("{}:1:", s(&d(dir, "long.obj"))), "...");
    assert!(m.len() < 300, "{} bytes", m.len());
    eprintln!("{m}");

    // A face pointing at a vertex defined only after its group ended: tobj reports no line.
    std::fs::write(d(dir, "late.obj"), "v 0 0 0\nv 1 0 0\ng a\nf 1 2 3\ng b\nv 0 1 0\nf 1 2 3\n").unwrap();
    let m = rejects(&d(dir, "late.obj"), &format!("{}:4:", s(&d(dir, "late.obj"))), "face references vertex 3");
    eprintln!("{m}");
}
