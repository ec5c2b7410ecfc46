//! Seeded mutation fuzzing of every loader: OBJ, MTL (through an OBJ that names it), PLY
//! (ascii, binary little- and big-endian), OFF and the TOML scene format.
//!
//! Each case starts from a small valid seed file written here, applies one to three seeded
//! mutations (byte flips, truncation, duplicated / deleted / swapped lines, huge numbers,
//! negated numbers, NaN and infinities, deleted tokens, control bytes, very long tokens,
//! random bytes) and loads it with `Scene::load`. A case passes when the load returns a
//! scene that holds together (indices in range, at least one primitive) or an error whose
//! message is one line, free of control characters, at most a few hundred characters and
//! starting with the file's name; never a panic. Deterministic: the RNG is SplitMix64 with
//! fixed seeds, so a failure names the case that reproduces it.

use std::path::{Path, PathBuf};
use std::time::Instant;

use arbor::scene::Scene;

/// Cases per seed file.
const CASES_PER_SEED: u64 = 300;
/// Longest error message accepted (the library caps messages at 400 characters plus the
/// file name and line).
const MAX_MESSAGE: usize = 700;

/// SplitMix64 (Steele, Lea & Flood 2014): tiny, fast and good enough to pick mutations.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (n > 0).
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const MTL: &str =
    "newmtl red\nKd 0.8 0.1 0.1\nKs 0.2 0.2 0.2\nNs 20\n\nnewmtl glass\nillum 7\nNi 1.5\nTf 0.9 0.9 0.9\n\
newmtl light\nKe 4 4 4\n";

const OBJ: &str = "# seed\nmtllib a.mtl\no cube\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1 1\nv 1 0 1 0.5 0.5 0.5\n\
vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\nvn 0 1 0\nusemtl red\nf 1/1/1 2/2/1 3/3/1 4/1/1\ng side\nusemtl glass\n\
f 1//2 2//2 6//2 5//2\nf -1 -2 -3\nusemtl light\nf 3 4 5\nl 1 2\n";

const OFF: &str =
    "OFF\n# seed\n5 3 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 1 255 0 0\n4 0 1 2 3\n3 0 1 4 1 1 1\n3 1 2 4\n";

const NOFF: &str = "NOFF 3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n";

const PLY_ASCII: &str = "ply\nformat ascii 1.0\ncomment seed\nelement vertex 4\nproperty float x\nproperty float y\n\
property float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nelement face 2\n\
property list uchar int vertex_indices\nproperty float quality\nelement edge 1\nproperty int a\nproperty int b\n\
end_header\n0 0 0 0 0 1 255\n1 0 0 0 0 1 0\n1 1 0 0 0 1 7\n0 1 0 0 0 1 9\n3 0 1 2 0.5\n4 0 2 3 1 1.5\n0 1\n";

const TOML: &str = "# seed\n[camera]\neye = [0, 1, 5]\nlook_at = [0, 0, 0]\nvfov = 40\n\n[film]\nwidth = 64\nheight = 48\n\n\
[render]\nbackground = [0.1, 0.1, 0.2]\nambient = 0.1\nmax_depth = 4\n\n[[material]]\nname = \"red\"\ntype = \"phong\"\n\
color = [0.8, 0.1, 0.1]\nshininess = 16\n\n[[material]]\nname = \"lamp\"\ntype = \"emissive\"\nemission = [4, 4, 4]\n\n\
[[mesh]]\nfile = \"cube.obj\"\nscale = 2\ntranslate = [0, -1, 0]\n\n[[mesh]]\nfile = \"tri.off\"\nmaterial = \"red\"\n\n\
[[mesh]]\nfile = \"quad.ply\"\n\n[[sphere]]\ncenter = [0, 1, 0]\nradius = 0.5\nmaterial = \"lamp\"\n\n\
[[light]]\ntype = \"point\"\nposition = [0, 4, 0]\nintensity = [10, 10, 10]\n\n[[light]]\ntype = \"directional\"\n\
direction = [0, -1, 0]\n";

/// A binary PLY of a quad with an ignored list, in either byte order.
fn ply_binary(big_endian: bool) -> Vec<u8> {
    let fmt = if big_endian { "binary_big_endian" } else { "binary_little_endian" };
    let mut out = format!(
        "ply\nformat {fmt} 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
         property list uchar short junk\nelement face 2\nproperty list uchar uint vertex_indices\nend_header\n"
    )
    .into_bytes();
    let f32b = |v: f32| if big_endian { v.to_be_bytes() } else { v.to_le_bytes() };
    let u32b = |v: u32| if big_endian { v.to_be_bytes() } else { v.to_le_bytes() };
    for (i, [x, y, z]) in [[0f32, 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]].into_iter().enumerate() {
        out.extend(f32b(x));
        out.extend(f32b(y));
        out.extend(f32b(z));
        out.push(i as u8 % 2);
        for _ in 0..i % 2 {
            out.extend(if big_endian { 7i16.to_be_bytes() } else { 7i16.to_le_bytes() });
        }
    }
    for face in [[0u32, 1, 2], [0, 2, 3]] {
        out.push(3);
        for i in face {
            out.extend(u32b(i));
        }
    }
    out
}

/// Tokens that replace a number: huge, tiny, negative, not finite, not a number.
const NASTY_NUMBERS: [&str; 16] = [
    "1e39",
    "-1e39",
    "3.4028236e38",
    "99999999999999999999",
    "4294967296",
    "4294967295",
    "2147483648",
    "-2147483649",
    "-1",
    "0",
    "nan",
    "inf",
    "-inf",
    "NaN",
    "1e-45",
    "18446744073709551615",
];

const CONTROL_BYTES: [u8; 8] = [0, 0x1b, 0x07, b'\r', 0x0b, 0x0c, 0x7f, 0xff];

/// Byte ranges of whitespace-separated tokens.
fn tokens(data: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, &b) in data.iter().enumerate() {
        match (b.is_ascii_whitespace(), start) {
            (true, Some(s)) => {
                out.push((s, i));
                start = None;
            }
            (false, None) => start = Some(i),
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push((s, data.len()));
    }
    out
}

/// Byte ranges of lines, each with its '\n'.
fn lines(data: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for (i, &b) in data.iter().enumerate() {
        if b == b'\n' {
            out.push((start, i + 1));
            start = i + 1;
        }
    }
    if start < data.len() {
        out.push((start, data.len()));
    }
    out
}

/// Applies one seeded mutation; returns its name.
fn mutate(rng: &mut Rng, data: &mut Vec<u8>) -> &'static str {
    let splice = |data: &mut Vec<u8>, (a, b): (usize, usize), with: &[u8]| {
        data.splice(a..b, with.iter().copied());
    };
    let pick = |rng: &mut Rng, ranges: &[(usize, usize)]| ranges.get(rng.below(ranges.len())).copied();
    match rng.below(12) {
        0 => {
            let n = 1 + rng.below(4);
            for _ in 0..n {
                if !data.is_empty() {
                    let i = rng.below(data.len());
                    data[i] ^= 1 << rng.below(8);
                }
            }
            "flip bits"
        }
        1 => {
            let n = rng.below(data.len() + 1);
            data.truncate(n);
            "truncate"
        }
        2 => {
            if let Some((a, b)) = pick(rng, &lines(data)) {
                let line = data[a..b].to_vec();
                let copies = if rng.below(4) == 0 { 1 + rng.below(200) } else { 1 };
                for _ in 0..copies {
                    splice(data, (b, b), &line);
                }
            }
            "duplicate line"
        }
        3 => {
            if let Some(r) = pick(rng, &lines(data)) {
                splice(data, r, b"");
            }
            "delete line"
        }
        4 | 5 => {
            let numeric: Vec<_> = tokens(data)
                .into_iter()
                .filter(|&(a, b)| std::str::from_utf8(&data[a..b]).is_ok_and(|t| t.parse::<f64>().is_ok()))
                .collect();
            if let Some(r) = pick(rng, &numeric) {
                let with = NASTY_NUMBERS[rng.below(NASTY_NUMBERS.len())];
                splice(data, r, with.as_bytes());
            }
            "nasty number"
        }
        6 => {
            let ints: Vec<_> = tokens(data)
                .into_iter()
                .filter(|&(a, b)| std::str::from_utf8(&data[a..b]).is_ok_and(|t| t.parse::<u64>().is_ok()))
                .collect();
            if let Some((a, _)) = pick(rng, &ints) {
                splice(data, (a, a), b"-");
            }
            "negate count"
        }
        7 => {
            if let Some(r) = pick(rng, &tokens(data)) {
                splice(data, r, b"");
            }
            "delete token"
        }
        8 => {
            let at = rng.below(data.len() + 1);
            let n = 1 + rng.below(3);
            let bytes: Vec<u8> = (0..n).map(|_| CONTROL_BYTES[rng.below(CONTROL_BYTES.len())]).collect();
            splice(data, (at, at), &bytes);
            "control bytes"
        }
        9 => {
            let len = [100, 5_000, 200_000][rng.below(3)];
            let fill = [b'x', b'9', b'/', b'a'][rng.below(4)];
            let long = vec![fill; len];
            match pick(rng, &tokens(data)) {
                Some(r) if rng.below(2) == 0 => splice(data, r, &long),
                _ => {
                    let at = rng.below(data.len() + 1);
                    splice(data, (at, at), &long)
                }
            }
            "long token"
        }
        10 => {
            let ls = lines(data);
            if ls.len() >= 2 {
                let (i, j) = (rng.below(ls.len()), rng.below(ls.len()));
                let (x, y) = (ls[i.min(j)], ls[i.max(j)]);
                if x != y {
                    let mut out = data[..x.0].to_vec();
                    out.extend_from_slice(&data[y.0..y.1]);
                    out.extend_from_slice(&data[x.1..y.0]);
                    out.extend_from_slice(&data[x.0..x.1]);
                    out.extend_from_slice(&data[y.1..]);
                    *data = out;
                }
            }
            "swap lines"
        }
        _ => {
            let at = rng.below(data.len() + 1);
            let n = 1 + rng.below(16);
            let bytes: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
            splice(data, (at, at), &bytes);
            "random bytes"
        }
    }
}

/// One fuzzed format: the seed, the file it is written to, the file `Scene::load` opens.
struct Target {
    name: &'static str,
    seed: Vec<u8>,
    /// File (in the case directory) the mutated seed is written to.
    mutated: &'static str,
    /// File passed to `Scene::load`.
    load: &'static str,
}

#[derive(Default)]
struct Counts {
    cases: u64,
    rejected: u64,
    accepted: u64,
    failures: Vec<String>,
}

/// Why `msg` is not one clean line starting with one of `prefixes`, or None when it is.
fn message_problem(msg: &str, prefixes: &[String]) -> Option<String> {
    if msg.contains('\n') || msg.contains('\r') {
        return Some("message spans more than one line".into());
    }
    if let Some(c) = msg.chars().find(|c| c.is_control()) {
        return Some(format!("message has control character {c:?}"));
    }
    if msg.chars().count() > MAX_MESSAGE {
        return Some(format!("message has {} characters (at most {MAX_MESSAGE})", msg.chars().count()));
    }
    if !prefixes.iter().any(|p| msg.starts_with(p.as_str())) {
        return Some(format!("message does not start with any of {prefixes:?}"));
    }
    None
}

/// Why an accepted scene does not hold together, or None.
fn scene_problem(s: &Scene) -> Option<String> {
    let nv = s.positions.len();
    let nm = s.materials.len();
    if s.prim_count() == 0 {
        return Some("accepted an empty scene".into());
    }
    if s.normals.len() != nv || s.tri_material.len() != s.triangles.len() {
        return Some("per-vertex or per-triangle arrays differ in length".into());
    }
    if s.triangles.iter().flatten().any(|&i| i as usize >= nv) {
        return Some("a triangle index is out of range".into());
    }
    if s.tri_material.iter().chain(s.spheres.iter().map(|sp| &sp.material)).any(|&m| m as usize >= nm) {
        return Some("a material index is out of range".into());
    }
    if s.positions.iter().any(|p| !p.is_finite()) {
        return Some("a vertex is not finite".into());
    }
    None
}

fn write_fixtures(dir: &Path) {
    std::fs::write(dir.join("a.mtl"), MTL).unwrap();
    std::fs::write(dir.join("cube.obj"), OBJ).unwrap();
    std::fs::write(dir.join("tri.off"), OFF).unwrap();
    std::fs::write(dir.join("quad.ply"), ply_binary(false)).unwrap();
}

fn run_target(target: &Target, seed: u64, counts: &mut Counts) {
    let dir = tempfile::tempdir().unwrap();
    write_fixtures(dir.path());
    let load_path: PathBuf = dir.path().join(target.load);
    let prefixes = [load_path.display().to_string(), dir.path().display().to_string()];
    // The seed must load: otherwise the fuzzing says nothing.
    std::fs::write(dir.path().join(target.mutated), &target.seed).unwrap();
    if let Err(e) = Scene::load(&load_path.display().to_string()) {
        counts.failures.push(format!("{}: the unmutated seed does not load: {e}", target.name));
        return;
    }
    let mut rng = Rng(seed);
    for case in 0..CASES_PER_SEED {
        let mut data = target.seed.clone();
        let mut applied = Vec::new();
        for _ in 0..1 + rng.below(3) {
            applied.push(mutate(&mut rng, &mut data));
        }
        std::fs::write(dir.path().join(target.mutated), &data).unwrap();
        counts.cases += 1;
        let source = load_path.display().to_string();
        let result = std::panic::catch_unwind(|| Scene::load(&source));
        let problem = match result {
            Err(_) => Some("panicked".to_string()),
            Ok(Ok(scene)) => {
                counts.accepted += 1;
                scene_problem(&scene)
            }
            Ok(Err(e)) => {
                counts.rejected += 1;
                message_problem(&e.to_string(), &prefixes).map(|p| format!("{p}: {:.300}", e.to_string()))
            }
        };
        if let Some(p) = problem {
            counts.failures.push(format!("{} seed {seed:#x} case {case} ({}): {p}", target.name, applied.join(", ")));
        }
    }
}

#[test]
fn every_loader_survives_seeded_mutations() {
    let start = Instant::now();
    let text = |s: &str| s.as_bytes().to_vec();
    let targets = [
        Target { name: "OBJ", seed: text(OBJ), mutated: "case.obj", load: "case.obj" },
        Target { name: "MTL", seed: text(MTL), mutated: "a.mtl", load: "cube.obj" },
        Target { name: "PLY ascii", seed: text(PLY_ASCII), mutated: "case.ply", load: "case.ply" },
        Target { name: "PLY binary LE", seed: ply_binary(false), mutated: "case.ply", load: "case.ply" },
        Target { name: "PLY binary BE", seed: ply_binary(true), mutated: "case.ply", load: "case.ply" },
        Target { name: "OFF", seed: text(OFF), mutated: "case.off", load: "case.off" },
        Target { name: "NOFF", seed: text(NOFF), mutated: "case.off", load: "case.off" },
        Target { name: "TOML", seed: text(TOML), mutated: "case.toml", load: "case.toml" },
    ];
    // Silence the default panic message: panics are counted and reported below.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut counts = Counts::default();
    for (k, target) in targets.iter().enumerate() {
        let before = (counts.cases, counts.rejected, counts.accepted);
        run_target(target, 0xA4B0_0000 + k as u64, &mut counts);
        eprintln!(
            "fuzz {:<14} cases {:>5}  clean rejections {:>5}  accepted {:>5}",
            target.name,
            counts.cases - before.0,
            counts.rejected - before.1,
            counts.accepted - before.2
        );
    }
    std::panic::set_hook(hook);
    eprintln!(
        "fuzz total: {} cases, {} clean rejections, {} accepted, {} failures in {:.1} s",
        counts.cases,
        counts.rejected,
        counts.accepted,
        counts.failures.len(),
        start.elapsed().as_secs_f64()
    );
    for f in counts.failures.iter().take(40) {
        eprintln!("  {f}");
    }
    assert!(counts.failures.is_empty(), "{} fuzz cases failed (listed above)", counts.failures.len());
}
