//! Stochastic progressive photon mapping (`--integrator sppm`) against a closed form
//! (a point light, a mirror wall and a Lambert floor), against the path tracer where
//! both see the same light, both photon maps against each other, and the same bytes
//! for the same seed. Seeded and deterministic.

use crate::common;

use arbor::accel::AccelKind;
use arbor::render::integrators::sppm::{PhotonMap, SppmSettings};
use arbor::render::{gpu, Frame, Integrator, RenderSettings};
use arbor::scene::procedural::quad;
use arbor::scene::{Camera, Light, Material, MaterialKind, Scene, SceneBuilder};
use glam::Vec3;

fn settings(w: u32, h: u32, iterations: u32, photons: u32) -> RenderSettings {
    let mut s = RenderSettings::for_size(w, h);
    s.integrator = Integrator::Sppm;
    s.spp = iterations;
    s.seed = 7;
    s.accel = AccelKind::BvhSah;
    s.sppm = SppmSettings { photons: Some(photons), radius: None, map: PhotonMap::Hashgrid };
    s
}

fn render(ctx: &arbor::gpu::Context, scene: &Scene, s: &RenderSettings) -> Frame {
    gpu::render(ctx, scene, s, |_, _| {}).expect("render").0
}

fn lum(c: [f32; 3]) -> f64 {
    f64::from(0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2])
}

const ALBEDO: f32 = 0.5;
const REFLECTANCE: f32 = 0.9;
const LIGHT: Vec3 = Vec3::new(0.0, 1.0, 0.0);
const MIRROR_X: f32 = 1.0;

/// A Lambert floor (y = 0, x < 1) lit by a point light 1 above it and by its image in
/// a vertical mirror wall at x = 1, seen from above. Three segments at most: light,
/// floor, camera, and light, mirror, floor, camera; no interreflection.
fn mirror_wall() -> Scene {
    let mut b = SceneBuilder::new("mirror wall");
    let floor = b.material(Material::lambert("floor", Vec3::splat(ALBEDO)));
    let mirror =
        b.material(Material { kind: MaterialKind::Mirror, ..Material::lambert("mirror", Vec3::splat(REFLECTANCE)) });
    let v = Vec3::new;
    // Counter-clockwise seen from +y: the floor faces up.
    b.mesh(
        &quad([v(-3.0, 0.0, 3.0), v(MIRROR_X, 0.0, 3.0), v(MIRROR_X, 0.0, -3.0), v(-3.0, 0.0, -3.0)]),
        1.0,
        Vec3::ZERO,
        Some(floor),
    );
    // Facing -x.
    b.mesh(
        &quad([v(MIRROR_X, 0.0, 3.0), v(MIRROR_X, 3.0, 3.0), v(MIRROR_X, 3.0, -3.0), v(MIRROR_X, 0.0, -3.0)]),
        1.0,
        Vec3::ZERO,
        Some(mirror),
    );
    b.scene.lights.push(Light::Point { position: LIGHT, intensity: Vec3::ONE });
    b.scene.background = Vec3::ZERO;
    b.scene.max_depth = 3;
    b.scene.camera = Camera { eye: v(-0.25, 4.0, 0.0), look_at: v(-0.25, 0.0, 0.0), up: Vec3::NEG_Z, vfov: 28.0 };
    b.finish().expect("scene")
}

/// The floor's radiance at (x, 0, z): albedo / pi times the irradiance of the light
/// (I cos / d^2) and of its mirror image (R I cos' / d'^2).
fn floor_radiance(p: Vec3) -> f64 {
    let image = Vec3::new(2.0 * MIRROR_X - LIGHT.x, LIGHT.y, LIGHT.z);
    let e = |l: Vec3| {
        let d = l - p;
        f64::from(d.y / d.length()) / f64::from(d.length_squared())
    };
    f64::from(ALBEDO) / std::f64::consts::PI * (e(LIGHT) + f64::from(REFLECTANCE) * e(image))
}

/// Where pixel (i, j)'s centre ray meets the floor, if it does (x < the mirror).
fn floor_point(scene: &Scene, w: u32, h: u32, i: u32, j: u32) -> Option<Vec3> {
    let basis = scene.camera.basis(w, h);
    let d = basis.ray_dir(i, j, 0.5, 0.5, w, h);
    let t = -basis.eye.y / d.y;
    let p = basis.eye + d * t;
    (t > 0.0 && p.x < MIRROR_X - 0.05).then_some(p)
}

/// 8x8-block medians of measured / expected over the floor: the worst block's ratio.
fn block_ratios(scene: &Scene, f: &Frame) -> Vec<f64> {
    let (w, h) = (f.width, f.height);
    let mut out = Vec::new();
    for by in (0..h).step_by(8) {
        for bx in (0..w).step_by(8) {
            let mut got = Vec::new();
            let mut want = Vec::new();
            for j in by..by + 8 {
                for i in bx..bx + 8 {
                    if let Some(p) = floor_point(scene, w, h, i, j) {
                        got.push(lum(f.radiance[(j * w + i) as usize]));
                        want.push(floor_radiance(p));
                    }
                }
            }
            if got.len() == 64 {
                let median = |v: &mut Vec<f64>| {
                    v.sort_by(f64::total_cmp);
                    0.5 * (v[31] + v[32])
                };
                out.push(median(&mut got) / median(&mut want));
            }
        }
    }
    assert!(out.len() >= 16, "only {} blocks on the floor", out.len());
    out
}

#[test]
fn mirror_wall_matches_the_closed_form() {
    let Some(ctx) = common::gpu() else { return };
    let scene = mirror_wall();
    let f = render(&ctx, &scene, &settings(64, 64, 128, 1 << 15));
    let ratios = block_ratios(&scene, &f);
    let worst = ratios.iter().map(|r| (r - 1.0).abs()).fold(0.0, f64::max);
    eprintln!("mirror wall: worst block off by {worst:.4}");
    assert!(worst < 0.03, "sppm against the closed form: block ratios {ratios:.3?}");
    // The path tracer finds the light only directly: the mirror's share is missing.
    let mut s = settings(64, 64, 64, 1);
    s.integrator = Integrator::Path;
    let p = render(&ctx, &scene, &s);
    let ratios = block_ratios(&scene, &p);
    let least = ratios.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(least < 0.85, "path should miss the mirrored light: block ratios {ratios:.3?}");
}

#[test]
fn same_seed_same_bytes_and_both_maps_agree() {
    let Some(ctx) = common::gpu() else { return };
    let scene = mirror_wall();
    let s = settings(32, 32, 8, 4096);
    let a = render(&ctx, &scene, &s);
    let b = render(&ctx, &scene, &s);
    assert_eq!(a.sum, b.sum, "the same seed must give the same image");
    let mut t = s.clone();
    t.sppm.map = PhotonMap::Kdtree;
    let k = render(&ctx, &scene, &t);
    // The two maps find the same visible points for every photon: equal sums but for
    // the order of float operations within a pixel (none: deposits are integers).
    assert_eq!(a.sum, k.sum, "hashgrid and kdtree must deposit the same photons");
}

/// Mean luminance over the image.
fn mean(f: &Frame) -> f64 {
    f.radiance.iter().map(|&c| lum(c)).sum::<f64>() / f.radiance.len() as f64
}

#[test]
fn cornell_box_converges_to_the_path_tracer() {
    let Some(ctx) = common::gpu() else { return };
    let scene = Scene::load("builtin:cornell").expect("cornell");
    let s = settings(32, 32, 128, 1 << 13);
    let f = render(&ctx, &scene, &s);
    let mut p = s.clone();
    p.integrator = Integrator::Path;
    p.spp = 512;
    let g = render(&ctx, &scene, &p);
    let (a, b) = (mean(&f), mean(&g));
    eprintln!("cornell: sppm mean {a:.5}, path mean {b:.5}, ratio {:.4}", a / b);
    assert!((a / b - 1.0).abs() < 0.02, "sppm mean {a} against path's {b}");
}

/// A tile renders exactly the pixels the whole image has there: photons are keyed by
/// their index, pixels by themselves, and deposits sum as integers.
#[test]
fn a_tile_is_the_whole_image_there() {
    let Some(ctx) = common::gpu() else { return };
    let scene = mirror_wall();
    let s = settings(32, 24, 4, 2048);
    let whole = render(&ctx, &scene, &s);
    let mut t = s.clone();
    t.crop = Some(arbor::render::Crop { x0: 8, x1: 27, y0: 5, y1: 17 });
    let tile = render(&ctx, &scene, &t);
    for y in 5..17u32 {
        for x in 8..27u32 {
            let a = whole.sum[(y * 32 + x) as usize];
            let b = tile.sum[((y - 5) * 19 + x - 8) as usize];
            assert_eq!(a, b, "pixel ({x}, {y})");
        }
    }
}

fn arbor_cmd() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_arbor"))
}

/// Values no sppm render takes, and settings that are not sppm's, are refused before
/// the device opens, with a message that names the flag.
#[test]
fn bad_sppm_flags_are_refused() {
    let cases: &[(&[&str], &str)] = &[
        (&["--integrator", "sppm", "--photons", "0"], "--photons must be 1..="),
        (&["--integrator", "sppm", "--photons", "-5"], "--photons must be 1..="),
        (&["--integrator", "sppm", "--photon-radius", "0"], "--photon-radius must be a positive distance"),
        (&["--integrator", "sppm", "--photon-radius", "-1"], "--photon-radius must be a positive distance"),
        (&["--integrator", "sppm", "--photon-radius", "nan"], "--photon-radius must be a positive distance"),
        (
            &["--integrator", "path", "--photon-map", "kdtree"],
            "--photon-map is a setting of --integrator sppm, not path",
        ),
        (&["--integrator", "whitted", "--photons", "10"], "--photons is a setting of --integrator sppm, not whitted"),
        (&["--integrator", "sppm", "--shard", "0/2", "--shard-by", "samples"], "sppm renders shard by tiles only"),
        (&["--integrator", "sppm", "--sample-offset", "4"], "sppm renders cannot be split by samples"),
        (&["--integrator", "sppm", "--resume", "part.exr"], "--resume cannot continue an sppm render"),
    ];
    let dir = tempfile::tempdir().expect("tempdir");
    for (args, want) in cases {
        let out = arbor_cmd()
            .args(["render", "builtin:cornell", "--size", "8x8", "-o"])
            .arg(dir.path().join("x.png"))
            .args(*args)
            .output()
            .expect("run");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!dir.path().join("x.png").exists(), "{args:?} wrote an image");
    }
}

/// `--time` ends an sppm render early with the iterations done; the stats say sppm's
/// figures.
#[test]
fn time_budget_ends_an_sppm_render() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let stats = dir.path().join("s.json");
    let out = arbor_cmd()
        .args([
            "render",
            "builtin:cornell",
            "--integrator",
            "sppm",
            "--size",
            "16x16",
            "--spp",
            "1000000",
            "--time",
            "2",
        ])
        .args(["--accel", "bvh", "-o"])
        .arg(dir.path().join("s.png"))
        .arg("--stats")
        .arg(&stats)
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("sppm: ") && err.contains("iterations x 256 photons"), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&stats).expect("stats")).expect("json");
    let done = v["samples_done"].as_u64().expect("samples_done");
    assert!((1..1_000_000).contains(&done), "samples_done {done}");
    assert_eq!(v["integrator"], "sppm");
    assert_eq!(v["sppm"]["iterations"].as_u64(), Some(done));
    assert_eq!(v["sppm"]["photon_map"], "hashgrid");
}

/// Camera paths and photons go through each structure's own traversal: every kind
/// gives the image the BVH gives, byte for byte.
#[test]
fn every_structure_gives_the_same_image() {
    let Some(ctx) = common::gpu() else { return };
    let scene = mirror_wall();
    let s = settings(24, 24, 3, 1024);
    let want = render(&ctx, &scene, &s);
    for kind in [
        AccelKind::None,
        AccelKind::Kdtree,
        AccelKind::Lbvh,
        AccelKind::Bvh4,
        AccelKind::Cwbvh,
        AccelKind::Grid,
        AccelKind::Octree,
    ] {
        let mut t = s.clone();
        t.accel = kind;
        let (f, st) = gpu::render(&ctx, &scene, &t, |_, _| {}).expect("render");
        assert_eq!(st.sppm.as_ref().map(|x| x.cut_paths), Some(0), "{kind:?}");
        assert_eq!(f.sum, want.sum, "{kind:?}");
    }
}

/// SIGINT stops an sppm render between dispatches: the image so far (whole
/// iterations, every pixel alike) is written and the exit status says interrupted;
/// checkpoints before it are whole images.
#[test]
fn interrupt_and_checkpoints_write_the_image_so_far() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let png = dir.path().join("i.png");
    let samples = dir.path().join("n.pfm");
    let aov = format!("samples={}", samples.display());
    let child = arbor_cmd()
        .args(["render", "builtin:caustic", "--integrator", "sppm", "--size", "24x16", "--spp", "1000000"])
        .args(["--accel", "bvh", "--checkpoint", "1", "-o"])
        .arg(&png)
        .args(["--aov", &aov])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn");
    std::thread::sleep(std::time::Duration::from_secs(6));
    assert!(png.exists(), "no checkpoint after 6 s");
    let pid = child.id().to_string();
    let kill = std::process::Command::new("kill").args(["-INT", &pid]).status().expect("kill");
    assert!(kill.success());
    let out = child.wait_with_output().expect("wait");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted: wrote"), "{err}");
    let img = image::open(&png).expect("a whole PNG");
    assert_eq!((img.width(), img.height()), (24, 16));
    let n = arbor::render::output::read_pfm(&samples).expect("pfm").3;
    assert!(n[0] >= 1.0 && n[0] < 1e6, "iterations {}", n[0]);
    assert!(n.iter().all(|&v| v == n[0]), "every pixel holds the same iterations");
}
