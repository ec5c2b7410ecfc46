//! The path integrator against analytic values (seeded, deterministic): the white
//! furnace, three estimators of one integral (light sampling, BSDF sampling, MIS),
//! an emitter seen directly, in a mirror and through a glass slab (with and without
//! absorption), an emission texture, and the same bytes for any dispatch split.

use crate::common;

use arbor::accel::AccelKind;
use arbor::render::{gpu, Frame, Integrator, Mis, RenderSettings};
use arbor::scene::procedural::quad;
use arbor::scene::{Camera, Material, MaterialKind, Scene, SceneBuilder, Sphere};
use glam::Vec3;

pub(crate) fn settings(w: u32, h: u32, spp: u32) -> RenderSettings {
    let mut s = RenderSettings::for_size(w, h);
    s.integrator = Integrator::Path;
    s.spp = spp;
    s.seed = 11;
    s.accel = AccelKind::BvhSah;
    s
}

pub(crate) fn render(ctx: &arbor::gpu::Context, scene: &Scene, s: &RenderSettings) -> Frame {
    gpu::render(ctx, scene, s, |_, _| {}).expect("render").0
}

fn lum(c: [f32; 3]) -> f64 {
    f64::from(0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2])
}

/// Mean luminance of the pixels `keep` selects, and the standard error of that mean
/// from the per-pixel variance estimates.
pub(crate) fn mean_and_error(f: &Frame, keep: impl Fn(usize) -> bool) -> (f64, f64) {
    let (mut sum, mut var, mut n) = (0.0, 0.0, 0.0);
    for k in 0..f.radiance.len() {
        if keep(k) {
            sum += lum(f.radiance[k]);
            var += f64::from(f.variance[k]);
            n += 1.0;
        }
    }
    assert!(n > 0.0, "no pixel selected");
    (sum / n, (var / (n * n)).sqrt())
}

fn lambert(albedo: f32) -> Material {
    Material::lambert("white", Vec3::splat(albedo))
}

pub(crate) fn emitter(radiance: f32) -> Material {
    Material { kind: MaterialKind::Emissive, emission: Vec3::splat(radiance), ..Material::lambert("light", Vec3::ONE) }
}

/// Pixels whose four neighbours see the same thing (hit or miss) as they do: away
/// from silhouettes, where jittered samples mix both.
fn interior(f: &Frame) -> Vec<bool> {
    let (w, h) = (f.width as usize, f.height as usize);
    let miss = |x: usize, y: usize| f.prim[y * w + x] == u32::MAX;
    (0..w * h)
        .map(|k| {
            let (x, y) = (k % w, k / w);
            x > 0
                && y > 0
                && x + 1 < w
                && y + 1 < h
                && [(x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)].iter().all(|&(a, b)| miss(a, b) == miss(x, y))
        })
        .collect()
}

/// A closed diffuse sphere of albedo `rho` under a uniform environment of radiance
/// `l` (the background): every pixel on the sphere converges to rho x l, every other
/// pixel to l. With a convex object every path escapes after one bounce with the same
/// weight, so the estimate is exact up to rounding.
#[test]
fn white_furnace() {
    let Some(ctx) = common::gpu() else { return };
    for rho in [1.0f32, 0.5] {
        let mut b = SceneBuilder::new("furnace");
        let m = b.material(lambert(rho));
        b.scene.spheres.push(Sphere { center: Vec3::ZERO, radius: 1.0, material: m });
        b.scene.background = Vec3::splat(0.5);
        b.scene.camera = Camera { eye: Vec3::new(0.0, 0.0, 4.0), look_at: Vec3::ZERO, up: Vec3::Y, vfov: 40.0 };
        let scene = b.finish().expect("scene");
        let (w, h) = (24usize, 24usize);
        let f = render(&ctx, &scene, &settings(w as u32, h as u32, 8));
        let (mut on, mut off) = (0, 0);
        let miss = |x: usize, y: usize| f.prim[y * w + x] == u32::MAX;
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let k = y * w + x;
                // Pixels on the silhouette mix both values: only those whose
                // neighbours all see what they see count.
                let m = miss(x, y);
                if [(x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)].iter().any(|&(a, b)| miss(a, b) != m) {
                    continue;
                }
                let want = if m { 0.5 } else { 0.5 * rho };
                if m {
                    off += 1;
                } else {
                    on += 1;
                }
                for c in f.radiance[k] {
                    assert!((c - want).abs() < 1e-4, "rho {rho}: pixel ({x}, {y}) = {c}, want {want}");
                }
            }
        }
        assert!(on > 100 && off > 100, "the view holds sphere and background ({on}, {off})");
    }
}

/// A diffuse floor under a one-sided square light: light sampling alone, BSDF sampling
/// alone and MIS estimate one integral, so their image means agree within their
/// confidence intervals, for a small and a large light.
#[test]
fn light_bsdf_and_mis_sampling_agree() {
    let Some(ctx) = common::gpu() else { return };
    for half in [0.08f32, 0.8] {
        let mut b = SceneBuilder::new("floor and light");
        let white = b.material(lambert(0.8));
        let light = b.material(emitter(1.0 / (half * half)));
        let g = 2.0;
        let v = Vec3::new;
        b.mesh(&quad([v(-g, 0.0, g), v(g, 0.0, g), v(g, 0.0, -g), v(-g, 0.0, -g)]), 1.0, Vec3::ZERO, Some(white));
        // Facing down: cross(b - a, c - a) points to -y.
        let y = 1.0;
        b.mesh(
            &quad([v(-half, y, -half), v(half, y, -half), v(half, y, half), v(-half, y, half)]),
            1.0,
            Vec3::ZERO,
            Some(light),
        );
        b.scene.background = Vec3::ZERO;
        b.scene.camera = Camera { eye: v(0.0, 0.6, 3.0), look_at: v(0.0, 0.0, 0.0), up: Vec3::Y, vfov: 50.0 };
        let scene = b.finish().expect("scene");
        let mut results = Vec::new();
        for mis in [Mis::Both, Mis::Light, Mis::Bsdf] {
            let mut s = settings(24, 24, 64);
            s.mis = mis;
            s.max_depth = Some(2);
            let f = render(&ctx, &scene, &s);
            // The floor only (the light's own pixels are exact in every mode).
            let floor = |k: usize| f.prim[k] < 2;
            results.push((mis, mean_and_error(&f, floor)));
        }
        let (_, (m0, e0)) = results[0];
        for &(mis, (m, e)) in &results[1..] {
            let bound = 4.0 * (e0 * e0 + e * e).sqrt();
            assert!((m - m0).abs() <= bound, "light {half}: {mis:?} mean {m} vs MIS {m0} (bound {bound})");
        }
        // MIS is never much noisier than the better single strategy.
        let best = results[1].1 .1.min(results[2].1 .1);
        assert!(e0 <= 1.5 * best, "light {half}: MIS error {e0} vs best single {best}");
    }
}

/// How the light of [`emission_scene`] emits.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Emits {
    /// Through a texture of two texels, white then black along u (which runs along
    /// +x): bright over the light's half at -x.
    Textured,
    /// Uniformly, at the texture's mean (the texels are decoded to linear 1 and 0 and
    /// filtered after, so its mean is exactly 1/2).
    Mean,
    /// Uniformly, at the full factor.
    Full,
}

/// A floor that lies under the -x half of a square light facing down only.
fn emission_scene(emits: Emits) -> Scene {
    use arbor::scene::{Maps, Texture};
    let v = Vec3::new;
    let mut b = SceneBuilder::new("floor under half a light");
    let white = b.material(lambert(0.8));
    b.mesh(
        &quad([v(-2.0, 0.0, 2.0), v(0.0, 0.0, 2.0), v(0.0, 0.0, -2.0), v(-2.0, 0.0, -2.0)]),
        1.0,
        Vec3::ZERO,
        Some(white),
    );
    let (h, y, e) = (0.8, 1.0, 1.5);
    let mut light = quad([v(-h, y, -h), v(h, y, -h), v(h, y, h), v(-h, y, h)]);
    let uv = glam::Vec2::new;
    light.uvs = Some(vec![uv(0.0, 0.0), uv(1.0, 0.0), uv(1.0, 1.0), uv(0.0, 1.0)]);
    let m = match emits {
        Emits::Textured => {
            let texels = vec![[255, 255, 255, 255], [0, 0, 0, 255]];
            light.textures =
                vec![Texture { name: "white, black".into(), width: 2, height: 1, texels, ..Default::default() }];
            Material { maps: Maps { emission: Some(0), ..Maps::default() }, ..emitter(e) }
        }
        Emits::Mean => emitter(0.5 * e),
        Emits::Full => emitter(e),
    };
    light.materials = vec![m];
    light.tri_material = vec![0, 0];
    b.mesh(&light, 1.0, Vec3::ZERO, None);
    b.scene.background = Vec3::ZERO;
    b.scene.camera = Camera { eye: v(-1.0, 0.6, 3.0), look_at: v(-1.0, 0.0, 0.0), up: Vec3::Y, vfov: 50.0 };
    b.finish().expect("scene")
}

/// An emission texture scales the emission both where a path hits the light (BSDF
/// sampling) and where next-event estimation samples a point on it (light sampling,
/// at that point's texture coordinates), and the light's power is its factor times
/// the texture's mean luminance: light sampling, BSDF sampling and MIS agree on the
/// floor; the floor under the bright half is brighter than under a uniform light of
/// the texture's mean and darker than under the untextured light.
#[test]
fn emission_textures_light_where_they_are_bright() {
    let Some(ctx) = common::gpu() else { return };
    let floor_mean = |scene: &Scene, mis: Mis| {
        let mut s = settings(24, 24, 64);
        s.mis = mis;
        s.max_depth = Some(2);
        let f = render(&ctx, scene, &s);
        // The floor only (its two triangles come first).
        mean_and_error(&f, |k| f.prim[k] < 2)
    };
    let textured = emission_scene(Emits::Textured);
    let results: Vec<(Mis, (f64, f64))> =
        [Mis::Both, Mis::Light, Mis::Bsdf].into_iter().map(|mis| (mis, floor_mean(&textured, mis))).collect();
    let (_, (m0, e0)) = results[0];
    eprintln!("emission texture, floor mean and error by strategy: {results:?}");
    for &(mis, (m, e)) in &results[1..] {
        let bound = 4.0 * (e0 * e0 + e * e).sqrt();
        assert!((m - m0).abs() <= bound, "{mis:?} mean {m} vs MIS {m0} (bound {bound})");
    }
    let (mean, _) = floor_mean(&emission_scene(Emits::Mean), Mis::Both);
    let (full, _) = floor_mean(&emission_scene(Emits::Full), Mis::Both);
    eprintln!("floor: textured {m0} (MIS), uniform at the mean {mean}, untextured {full}");
    assert!(m0 > 1.1 * mean && m0 < 0.9 * full, "textured {m0}, mean {mean}, full {full}");
}

/// The test scene of the emitter tests: a one-sided emitter of radiance 2 facing +z,
/// seen along -z, behind `between`.
fn emitter_scene(between: impl FnOnce(&mut SceneBuilder)) -> Scene {
    let mut b = SceneBuilder::new("emitter");
    let light = b.material(emitter(2.0));
    let v = Vec3::new;
    // Counter-clockwise seen from +z: faces the camera.
    b.mesh(
        &quad([v(-1.0, -1.0, -3.0), v(1.0, -1.0, -3.0), v(1.0, 1.0, -3.0), v(-1.0, 1.0, -3.0)]),
        1.0,
        Vec3::ZERO,
        Some(light),
    );
    between(&mut b);
    b.scene.background = Vec3::ZERO;
    b.scene.max_depth = 16;
    b.scene.camera = Camera { eye: v(0.0, 0.0, 2.0), look_at: v(0.0, 0.0, -3.0), up: Vec3::Y, vfov: 5.0 };
    b.finish().expect("scene")
}

/// A box slab of glass between z = -1 and z = -1 - d, faces pointing out.
fn slab(b: &mut SceneBuilder, d: f32, absorption: f32) {
    let glass = b.material(Material {
        kind: MaterialKind::Glass,
        ior: 1.5,
        absorption: Vec3::splat(absorption),
        ..Material::lambert("glass", Vec3::ONE)
    });
    let v = Vec3::new;
    let (z0, z1, s) = (-1.0, -1.0 - d, 2.0);
    let faces = [
        [v(-s, -s, z0), v(s, -s, z0), v(s, s, z0), v(-s, s, z0)], // front (+z)
        [v(-s, -s, z1), v(-s, s, z1), v(s, s, z1), v(s, -s, z1)], // back (-z)
        [v(-s, -s, z0), v(-s, s, z0), v(-s, s, z1), v(-s, -s, z1)], // -x
        [v(s, -s, z0), v(s, -s, z1), v(s, s, z1), v(s, s, z0)],   // +x
        [v(-s, s, z0), v(s, s, z0), v(s, s, z1), v(-s, s, z1)],   // +y
        [v(-s, -s, z0), v(-s, -s, z1), v(s, -s, z1), v(s, -s, z0)], // -y
    ];
    for f in faces {
        b.mesh(&quad(f), 1.0, Vec3::ZERO, Some(glass));
    }
}

#[test]
fn emitter_seen_directly_in_a_mirror_and_through_glass() {
    let Some(ctx) = common::gpu() else { return };
    // Directly: exactly its radiance, and nothing from behind (one-sided).
    let f = render(&ctx, &emitter_scene(|_| {}), &settings(8, 8, 4));
    for c in f.radiance.iter().flatten() {
        assert!((c - 2.0).abs() < 1e-5, "direct {c}");
    }
    let mut back = emitter_scene(|_| {});
    back.camera = Camera { eye: Vec3::new(0.0, 0.0, -8.0), look_at: Vec3::new(0.0, 0.0, -3.0), up: Vec3::Y, vfov: 5.0 };
    let f = render(&ctx, &back, &settings(8, 8, 4));
    assert!(f.radiance.iter().flatten().all(|&c| c == 0.0), "a one-sided emitter is dark from behind");

    // In a mirror of reflectance 0.9: the camera looks down -x at a 45-degree mirror.
    let mut m = emitter_scene(|b| {
        let mirror =
            b.material(Material { kind: MaterialKind::Mirror, ..Material::lambert("mirror", Vec3::splat(0.9)) });
        let v = Vec3::new;
        // The plane x + z = 0, normal (-1, 0, -1) / sqrt 2: it turns +x into -z.
        b.mesh(
            &quad([v(-1.0, -2.0, 1.0), v(-1.0, 2.0, 1.0), v(1.0, 2.0, -1.0), v(1.0, -2.0, -1.0)]),
            1.0,
            Vec3::ZERO,
            Some(mirror),
        );
    });
    m.camera = Camera { eye: Vec3::new(-6.0, 0.0, 0.0), look_at: Vec3::ZERO, up: Vec3::Y, vfov: 3.0 };
    let f = render(&ctx, &m, &settings(8, 8, 4));
    for c in f.radiance.iter().flatten() {
        assert!((c - 1.8).abs() < 1e-4, "mirror {c}");
    }

    // Through a lossless slab at normal incidence: transmittance (1 - F) / (1 + F) with
    // F = 0.04, summed over internal reflections; with absorption sigma over thickness
    // d: (1 - F)^2 a / (1 - F^2 a^2), a = exp(-sigma d).
    for (sigma, d) in [(0.0f32, 0.5f32), (0.8, 0.5)] {
        let scene = emitter_scene(|b| slab(b, d, sigma));
        let f = render(&ctx, &scene, &settings(8, 8, 2048));
        let fr = 0.04f64;
        let a = (-f64::from(sigma) * f64::from(d)).exp();
        let want = 2.0 * (1.0 - fr).powi(2) * a / (1.0 - fr * fr * a * a);
        let (mean, err) = mean_and_error(&f, |_| true);
        // Each sample is 0 or a fixed value, so the mean's error is known; allow 4 sigma.
        assert!((mean - want).abs() <= 4.0 * err + 1e-4, "slab sigma {sigma}: {mean} vs {want} (error {err})");
    }
}

/// The same bytes whatever the dispatch split.
#[test]
fn dispatch_split_does_not_change_the_image() {
    let Some(ctx) = common::gpu() else { return };
    let scene = Scene::load("builtin:cornell").expect("cornell");
    let mut a = settings(20, 16, 6);
    a.max_depth = Some(4);
    let mut b = a.clone();
    b.pacing.budget = Some(1);
    let fa = render(&ctx, &scene, &a);
    let fb = render(&ctx, &scene, &b);
    assert_eq!(fa.radiance, fb.radiance);
    assert_eq!(fa.variance, fb.variance);
    assert!(fa.radiance.iter().flatten().any(|&c| c > 0.0), "the box is lit");
}

fn arbor_cmd() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_arbor"))
}

/// Values of a one-channel PFM AOV.
fn read_pfm(path: &std::path::Path) -> Vec<f32> {
    arbor::render::output::read_pfm(path).expect("pfm").3
}

/// SIGINT writes the image so far, every pixel with the same sample count, and the
/// exit code says the render was interrupted.
#[test]
fn interrupt_writes_the_image_so_far() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let png = dir.path().join("i.png");
    let samples = dir.path().join("n.pfm");
    let aov = format!("samples={}", samples.display());
    let child = arbor_cmd()
        .args(["render", "builtin:cornell", "--size", "16x16", "--spp", "1000000", "-o"])
        .arg(&png)
        .args(["--aov", &aov])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn");
    // Wait for the first dispatches (the render prints progress lines after 5 s).
    std::thread::sleep(std::time::Duration::from_secs(6));
    let pid = child.id().to_string();
    let kill = std::process::Command::new("kill").args(["-INT", &pid]).status().expect("kill");
    assert!(kill.success());
    let out = child.wait_with_output().expect("wait");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted: wrote"), "{err}");
    let img = image::open(&png).expect("a whole PNG");
    assert_eq!((img.width(), img.height()), (16, 16));
    let n = read_pfm(&samples);
    assert!(n[0] >= 1.0 && n[0] < 1e6, "samples {}", n[0]);
    assert!(n.iter().all(|&v| v == n[0]), "every pixel holds the same samples");
    assert!(err.contains(&format!("with {} of 1000000 samples", n[0] as u32)), "{err}");
}

/// With --time the render ends on its own with fewer samples than asked; checkpoint
/// files are complete images whenever they are read.
#[test]
fn time_budget_and_checkpoints() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let png = dir.path().join("t.png");
    let stats = dir.path().join("t.json");
    let mut child = arbor_cmd()
        .args(["render", "builtin:cornell", "--size", "16x16", "--spp", "1000000", "--time", "6", "--checkpoint", "1"])
        .arg("-o")
        .arg(&png)
        .arg("--stats")
        .arg(&stats)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn");
    let mut seen = 0;
    let start = std::time::Instant::now();
    while start.elapsed().as_secs() < 60 {
        if let Some(status) = child.try_wait().expect("poll") {
            assert!(status.success(), "render failed");
            break;
        }
        if png.exists() {
            let img = image::open(&png).expect("a checkpoint is always a whole PNG");
            assert_eq!((img.width(), img.height()), (16, 16));
            seen += 1;
        }
        std::thread::sleep(std::time::Duration::from_millis(150));
    }
    let out = child.wait_with_output().expect("wait");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(seen > 0, "no checkpoint was seen");
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&stats).expect("stats")).expect("json");
    let done = v["samples_done"].as_u64().expect("samples_done");
    assert!((1..1_000_000).contains(&done), "samples_done {done}");
    assert_eq!(v["interrupted"], false);
    assert_eq!(v["integrator"], "path");
}

/// The white furnace under an environment map of constant radiance: light sampling of
/// the map, BSDF sampling and MIS together still converge to rho x L on the sphere.
#[test]
fn white_furnace_under_an_environment_map() {
    let Some(ctx) = common::gpu() else { return };
    let mut b = SceneBuilder::new("furnace map");
    let m = b.material(lambert(0.5));
    b.scene.spheres.push(Sphere { center: Vec3::ZERO, radius: 1.0, material: m });
    b.scene.environment = Some(arbor::scene::Environment {
        name: "constant".into(),
        width: 16,
        height: 8,
        texels: vec![[0.25, 0.25, 0.25]; 128],
        rotation: 40.0,
        intensity: 2.0,
    });
    b.scene.camera = Camera { eye: Vec3::new(0.0, 0.0, 4.0), look_at: Vec3::ZERO, up: Vec3::Y, vfov: 40.0 };
    let scene = b.finish().expect("scene");
    let f = render(&ctx, &scene, &settings(24, 24, 64));
    let inner = interior(&f);
    let (on, on_err) = mean_and_error(&f, |k| inner[k] && f.prim[k] != u32::MAX);
    let (off, _) = mean_and_error(&f, |k| inner[k] && f.prim[k] == u32::MAX);
    assert!((off - 0.5).abs() < 2e-3, "the map seen directly: {off}");
    assert!((on - 0.25).abs() <= 4.0 * on_err + 2e-3, "sphere under the map: {on} (error {on_err})");
}

/// A quad from (-1, -1) to (1, 1) in z = 0 whose texture coordinates run from 0 to
/// `uv_max` along x and y, textured (albedo) with `texture`, seen head-on from far away
/// through a narrow view that the quad fills exactly.
fn textured_quad(texture: arbor::scene::Texture, uv_max: f32) -> Scene {
    let v = Vec3::new;
    let mut mesh = quad([v(-1.0, -1.0, 0.0), v(1.0, -1.0, 0.0), v(1.0, 1.0, 0.0), v(-1.0, 1.0, 0.0)]);
    let uv = glam::Vec2::new;
    mesh.uvs = Some(vec![uv(0.0, 0.0), uv(uv_max, 0.0), uv(uv_max, uv_max), uv(0.0, uv_max)]);
    mesh.textures = vec![texture];
    mesh.materials = vec![Material { texture: Some(0), ..lambert(1.0) }];
    mesh.tri_material = vec![0, 0];
    let mut b = SceneBuilder::new("textured quad");
    b.mesh(&mesh, 1.0, Vec3::ZERO, None);
    b.scene.camera = Camera {
        eye: v(0.0, 0.0, 100.0),
        look_at: Vec3::ZERO,
        up: Vec3::Y,
        vfov: 2.0 * (1.0f32 / 100.0).atan().to_degrees(),
    };
    b.finish().expect("scene")
}

/// A texture on a quad: the albedo AOV inside each block of equal texels is the texel,
/// decoded from sRGB; the blocks land where the UVs put them (row 0 at the top).
#[test]
fn textured_albedo_is_the_decoded_texel() {
    let Some(ctx) = common::gpu() else { return };
    // 4x4 texels in four blocks of 2x2, so that bilinear filtering inside a block
    // (where the pixels below look) sees one colour.
    let colours = [[255u8, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255], [128, 128, 128, 255]];
    let texels: Vec<[u8; 4]> = (0..16).map(|k| colours[(k % 4) / 2 + 2 * ((k / 4) / 2)]).collect();
    let texture = arbor::scene::Texture { name: "4x4".into(), width: 4, height: 4, texels, ..Default::default() };
    let scene = textured_quad(texture, 1.0);
    let f = render(&ctx, &scene, &settings(64, 64, 1));
    let decode = |c: u8| {
        let c = f32::from(c) / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    // Block (x, y), row 0 at the top, is centred at pixel (16 + 32 x, 16 + 32 y).
    for (k, t) in [[255u8, 0, 0], [0, 255, 0], [0, 0, 255], [128, 128, 128]].iter().enumerate() {
        let (x, y) = (16 + 32 * (k % 2), 16 + 32 * (k / 2));
        let got = f.albedo[y * 64 + x];
        for c in 0..3 {
            let want = decode(t[c]);
            assert!((got[c] - want).abs() < 1e-3, "block {k} channel {c}: {} vs {want}", got[c]);
        }
    }
}

/// A texture's wrap modes (glTF's samplers): a quad whose texture coordinates run
/// from 0 to 2 in u and v, textured with 2x2 texels of which only the top-left is
/// white, read at the texel centres past 1 (so bilinear filtering sees one texel) by
/// the Whitted integrator's unjittered first sample.
#[test]
fn wrap_modes_repeat_clamp_and_mirror() {
    use arbor::scene::{Texture, Wrap};
    let Some(ctx) = common::gpu() else { return };
    // 68 pixels over two units: texel centres (u = 0.25, 1.25, 1.75) fall on pixel
    // centres (columns 8, 42, 59; rows 42, 25, 8 for v = 0.75, 1.25, 1.75).
    let n = 68u32;
    let render_with = |wrap: Wrap| {
        let (white, black) = ([255u8, 255, 255, 255], [0u8, 0, 0, 255]);
        let texels = vec![white, black, black, black];
        let scene = textured_quad(Texture { name: "corner".into(), width: 2, height: 2, texels, wrap: [wrap; 2] }, 2.0);
        // Whitted's first sample is the pixel's centre (the path tracer jitters it).
        let mut s = settings(n, n, 1);
        s.integrator = Integrator::Whitted;
        render(&ctx, &scene, &s)
    };
    let at = |f: &Frame, col: u32, row: u32| f.albedo[(row * n + col) as usize][0];
    // (u = 1.25, 1.75 along the top row's centre v = 0.75; v = 1.25, 1.75 along the
    // left column's centre u = 0.25): 1 where the white texel is read.
    for (wrap, along_u, along_v) in [
        (Wrap::Repeat, [1.0, 0.0], [0.0, 1.0]),
        (Wrap::Clamp, [0.0, 0.0], [1.0, 1.0]),
        (Wrap::Mirror, [0.0, 1.0], [1.0, 0.0]),
    ] {
        let f = render_with(wrap);
        assert!((at(&f, 8, 42) - 1.0).abs() < 1e-3, "{wrap:?}: the white texel itself");
        let got_u = [at(&f, 42, 42), at(&f, 59, 42)];
        let got_v = [at(&f, 8, 25), at(&f, 8, 8)];
        for (got, want) in got_u.iter().chain(&got_v).zip(along_u.iter().chain(&along_v)) {
            assert!((got - want).abs() < 1e-3, "{wrap:?}: along u {got_u:?}, along v {got_v:?}");
        }
    }
}
