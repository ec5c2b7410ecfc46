//! Cut-outs and blended panes (glTF's alphaMode; docs/materials.md, "Alpha"): a quad
//! textured with a checkerboard of alpha 0 and 1 lets camera rays and shadow rays
//! through its transparent squares in every structure, as the CPU reference does; a
//! blended pane converges to the blend; the scene keys are checked.

use crate::common;

use arbor::accel::{Accel, AccelKind, Traverse};
use arbor::math::{Hit, Ray};
use arbor::render::{gpu, Frame, Integrator, RenderSettings};
use arbor::scene::{AlphaMode, Scene};
use arbor::{RayTracer, TraceOptions};
use glam::Vec3;

/// An 8x8 checkerboard: alpha 255 where (x + y) is even, 0 elsewhere; white.
fn checker(dir: &std::path::Path) {
    let img =
        image::RgbaImage::from_fn(8, 8, |x, y| image::Rgba([255, 255, 255, if (x + y) % 2 == 0 { 255 } else { 0 }]));
    img.save(dir.join("checker.png")).expect("png");
}

/// A square from (-1, -1) to (1, 1) in the plane `axis` = `at` (uv 0..1 across it).
fn square_obj(dir: &std::path::Path, name: &str, vertical: bool, at: f32) {
    let v = |x: f32, y: f32| if vertical { format!("v {x} {y} {at}\n") } else { format!("v {x} {at} {y}\n") };
    let text = format!(
        "{}{}{}{}vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n",
        v(-1.0, -1.0),
        v(1.0, -1.0),
        v(1.0, 1.0),
        v(-1.0, 1.0)
    );
    std::fs::write(dir.join(name), text).expect("obj");
}

fn load(dir: &std::path::Path, name: &str, toml: &str) -> Scene {
    let path = dir.join(name);
    std::fs::write(&path, toml).expect("toml");
    Scene::load(&path.display().to_string()).expect("scene")
}

/// The masked quad facing the camera in front of a blue background, lit from the
/// camera.
fn facing_quad(dir: &std::path::Path) -> Scene {
    checker(dir);
    square_obj(dir, "quad.obj", true, 0.0);
    load(
        dir,
        "facing.toml",
        "[camera]\neye = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 45.0\n\
         [render]\nbackground = [0.2, 0.4, 0.9]\nambient = 0.0\n\
         [[mesh]]\nfile = \"quad.obj\"\nmaterial = \"leaf\"\n\
         [[material]]\nname = \"leaf\"\ntype = \"lambert\"\ncolor = [0.8, 0.8, 0.8]\ntexture = \"checker.png\"\n\
         alpha_mode = \"mask\"\nalpha_cutoff = 0.5\n\
         [[light]]\ntype = \"point\"\nposition = [0.0, 0.0, 3.0]\nintensity = [9.0, 9.0, 9.0]\n",
    )
}

fn whitted(ctx: &arbor::gpu::Context, scene: &Scene, kind: AccelKind, w: u32, h: u32) -> Frame {
    let mut s = RenderSettings::for_size(w, h);
    s.integrator = Integrator::Whitted;
    s.accel = kind;
    let (f, _) = gpu::render(ctx, scene, &s, |_, _| {}).expect("render");
    ctx.check_validation().expect("no validation errors");
    f
}

#[test]
fn the_background_shows_through_a_masked_quad_in_every_structure() {
    let Some(ctx) = common::gpu() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = facing_quad(dir.path());
    assert!(scene.has_alpha());
    let (w, h) = (64, 64);
    let reference = arbor::render::cpu::reference_aovs(&scene, w, h);
    // The quad fills the middle of the view; about half its pixels are holes.
    let basis = scene.camera.basis(w, h);
    let on_quad = |k: usize| {
        let d = basis.ray_dir((k % w as usize) as u32, (k / w as usize) as u32, 0.5, 0.5, w, h);
        let p = basis.eye + d * (-basis.eye.z / d.z);
        p.x.abs() < 1.0 && p.y.abs() < 1.0
    };
    let quad: Vec<usize> = (0..reference.prim.len()).filter(|&k| on_quad(k)).collect();
    let holes = quad.iter().filter(|&&k| reference.prim[k] == u32::MAX).count();
    assert!(quad.len() > 1000 && (holes as f64 / quad.len() as f64 - 0.5).abs() < 0.1, "{holes} of {}", quad.len());
    let mut kinds = AccelKind::ALL.to_vec();
    if ctx.info().ray_query() {
        kinds.push(AccelKind::RayQuery);
    }
    for kind in kinds {
        let f = whitted(&ctx, &scene, kind, w, h);
        let wrong = (0..f.prim.len()).filter(|&k| f.prim[k] != reference.prim[k]).count();
        assert_eq!(wrong, 0, "{kind}: {wrong} pixels hit other than the CPU reference");
        for &k in &quad {
            if reference.prim[k] == u32::MAX {
                assert_eq!(f.radiance[k], [0.2, 0.4, 0.9], "{kind}: pixel {k} is a hole: the background");
            } else {
                assert!(f.radiance[k][0] > 0.05, "{kind}: pixel {k} is the lit quad: {:?}", f.radiance[k]);
            }
        }
    }
}

#[test]
fn a_masked_quads_shadow_has_the_same_holes() {
    let Some(ctx) = common::gpu() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    checker(dir.path());
    square_obj(dir.path(), "leaf.obj", false, 1.0);
    std::fs::write(dir.path().join("floor.obj"), "v -6 0 -6\nv 6 0 -6\nv 6 0 6\nv -6 0 6\nf 1 4 3 2\n").expect("floor");
    // A point light at the left casts the leaf's shadow to the right of it, where
    // the camera above sees the floor unhidden.
    let scene = load(
        dir.path(),
        "shadow.toml",
        "[camera]\neye = [2.0, 9.0, 0.0]\nlook_at = [2.0, 0.0, 0.0]\nup = [0.0, 0.0, -1.0]\nvfov = 30.0\n\
         [render]\nbackground = [0.0, 0.0, 0.0]\nambient = 0.0\n\
         [[mesh]]\nfile = \"leaf.obj\"\nmaterial = \"leaf\"\n\
         [[mesh]]\nfile = \"floor.obj\"\nmaterial = \"floor\"\n\
         [[material]]\nname = \"leaf\"\ntype = \"lambert\"\ntexture = \"checker.png\"\nalpha_mode = \"mask\"\n\
         [[material]]\nname = \"floor\"\ntype = \"lambert\"\ncolor = [0.8, 0.8, 0.8]\n\
         [[light]]\ntype = \"point\"\nposition = [-3.0, 3.0, 0.0]\nintensity = [40.0, 40.0, 40.0]\n",
    );
    let (w, h) = (96, 96);
    let f = whitted(&ctx, &scene, AccelKind::BvhSah, w, h);
    let reference = arbor::render::cpu::reference_aovs(&scene, w, h);
    let brute = Accel::build(AccelKind::None, &scene);
    let basis = scene.camera.basis(w, h);
    let light = Vec3::new(-3.0, 3.0, 0.0);
    let floor_first = 2u32; // the leaf's two triangles come first
    let (mut shadow_region, mut lit_in_region, mut disagree, mut floor) = (0, 0, 0, 0);
    for k in 0..f.prim.len() {
        if reference.prim[k] < floor_first || reference.prim[k] == u32::MAX {
            continue;
        }
        floor += 1;
        let (i, j) = ((k % w as usize) as u32, (k / w as usize) as u32);
        let p = basis.eye + basis.ray_dir(i, j, 0.5, 0.5, w, h) * reference.depth[k];
        let to = light - p;
        let shadow = Ray { origin: p + Vec3::Y * 1e-3, dir: to.normalize(), tmin: 0.0, tmax: to.length() };
        let blocked = brute.occluded(&scene, &shadow);
        // Where an opaque leaf would shade the floor: the line to the light crosses the
        // leaf's square.
        let s = (1.0 - p.y) / to.y;
        let q = p + to * s;
        if q.x.abs() < 1.0 && q.z.abs() < 1.0 {
            shadow_region += 1;
            lit_in_region += usize::from(!blocked);
        }
        let lit = f.radiance[k][0] > 1e-3;
        disagree += usize::from(lit == blocked);
    }
    assert!(floor > 4000 && shadow_region > 500, "{floor} floor pixels, {shadow_region} in the leaf's shadow");
    let share = lit_in_region as f64 / shadow_region as f64;
    assert!((share - 0.5).abs() < 0.1, "light passes the holes: {share:.3} of the shadow is lit");
    // Pixels at the squares' edges may round either way.
    assert!(disagree * 100 <= floor, "{disagree} of {floor} floor pixels lit other than the CPU reference");
}

/// Rays through a masked quad and a blended pane behind it, and past a blended and a
/// masked-out sphere: the device's hits equal the CPU reference's in every structure.
#[test]
fn device_equals_cpu_through_masked_and_blended_surfaces() {
    let Some(ctx) = common::gpu() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    checker(dir.path());
    square_obj(dir.path(), "leaf.obj", true, 0.0);
    square_obj(dir.path(), "pane.obj", true, -1.0);
    square_obj(dir.path(), "wall.obj", true, -2.0);
    let scene = load(
        dir.path(),
        "layers.toml",
        "[[mesh]]\nfile = \"leaf.obj\"\nmaterial = \"leaf\"\n\
         [[mesh]]\nfile = \"pane.obj\"\nmaterial = \"pane\"\n\
         [[mesh]]\nfile = \"wall.obj\"\nmaterial = \"wall\"\n\
         [[material]]\nname = \"leaf\"\ntype = \"lambert\"\ntexture = \"checker.png\"\nalpha_mode = \"mask\"\n\
         [[material]]\nname = \"pane\"\ntype = \"lambert\"\nalpha_mode = \"blend\"\nopacity = 0.5\n\
         [[material]]\nname = \"wall\"\ntype = \"lambert\"\n\
         [[sphere]]\ncenter = [0.6, 0.6, 0.5]\nradius = 0.35\nmaterial = \"bubble\"\n\
         [[sphere]]\ncenter = [-0.6, -0.6, 0.5]\nradius = 0.35\nmaterial = \"ghost\"\n\
         [[material]]\nname = \"bubble\"\ntype = \"lambert\"\nalpha_mode = \"blend\"\nopacity = 0.5\n\
         [[material]]\nname = \"ghost\"\ntype = \"lambert\"\nalpha_mode = \"mask\"\nopacity = 0.2\n",
    );
    assert_eq!(scene.materials.iter().map(|m| m.alpha_mode).filter(|m| *m == AlphaMode::Blend).count(), 2);
    let mut rng = common::scenes::Rng(0x9e37_79b9_7f4a_7c15);
    let rays: Vec<Ray> = (0..4000)
        .map(|_| {
            let o = Vec3::new(rng.range(-1.5, 1.5), rng.range(-1.5, 1.5), 3.0);
            let t = Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), -1.0);
            Ray { origin: o, dir: (t - o).normalize(), tmin: 0.0, tmax: f32::INFINITY }
        })
        .collect();
    let cpu = Accel::build(AccelKind::BvhSah, &scene).trace_cpu(&scene, &rays);
    every_kind_hits_as_the_cpu(&ctx, &scene, &rays, &cpu);
    // Hits on the leaf, the pane, the wall, the bubble, the ghost; misses.
    let mut layers = [0usize; 6];
    for c in &cpu {
        layers[c.map_or(5, |h| if h.prim < 6 { h.prim as usize / 2 } else { h.prim as usize - 3 })] += 1;
    }
    // Rays reach every layer: the leaf's squares, the pane half the time, the wall,
    // the bubble half the time; the masked-out ghost never.
    assert!(layers.iter().take(3).all(|&n| n > 400) && layers[3] > 100, "{layers:?}");
    assert_eq!(layers[4], 0, "{layers:?}");
}

/// Every `--accel` kind (and `rayquery` where the device has it) traces `rays` on the
/// device to the primitives of `cpu`, the CPU reference's hits.
pub(crate) fn every_kind_hits_as_the_cpu(ctx: &arbor::gpu::Context, scene: &Scene, rays: &[Ray], cpu: &[Option<Hit>]) {
    let mut kinds = AccelKind::ALL.to_vec();
    if ctx.info().ray_query() {
        kinds.push(AccelKind::RayQuery);
    }
    for kind in kinds {
        let accel = Accel::build_on(ctx, kind, scene, &Default::default()).expect("build");
        let gpu =
            RayTracer::new(ctx, scene, &accel, &TraceOptions::default()).expect("tracer").trace(rays).expect("trace");
        for (k, (g, c)) in gpu.iter().zip(cpu).enumerate() {
            assert_eq!(g.map(|h| h.prim), c.map(|h| h.prim), "{kind}: ray {k}");
        }
        ctx.check_validation().expect("no validation errors");
    }
}

/// A blended pane of opacity 0.25 in front of the background converges to 0.25 x its
/// colour + 0.75 x the background; Whitted's preview splits the ray there and gives
/// the blend at one sample.
#[test]
fn a_blended_pane_converges_to_the_blend() {
    let Some(ctx) = common::gpu() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    square_obj(dir.path(), "pane.obj", true, 0.0);
    let scene = load(
        dir.path(),
        "pane.toml",
        "[camera]\neye = [0.0, 0.0, 1.5]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 40.0\n\
         [render]\nbackground = [0.2, 0.4, 0.8]\n\
         [[mesh]]\nfile = \"pane.obj\"\nmaterial = \"pane\"\n\
         [[material]]\nname = \"pane\"\ntype = \"emissive\"\nemission = [1.0, 1.0, 1.0]\n\
         alpha_mode = \"blend\"\nopacity = 0.25\n",
    );
    let mut s = RenderSettings::for_size(16, 16);
    s.integrator = Integrator::Path;
    s.spp = 512;
    s.seed = 5;
    s.accel = AccelKind::BvhSah;
    let (f, _) = gpu::render(&ctx, &scene, &s, |_, _| {}).expect("render");
    ctx.check_validation().expect("no validation errors");
    let want = [0.25 + 0.75 * 0.2, 0.25 + 0.75 * 0.4, 0.25 + 0.75 * 0.8];
    for c in 0..3 {
        let mean = f.radiance.iter().map(|p| f64::from(p[c])).sum::<f64>() / f.radiance.len() as f64;
        assert!((mean / want[c] - 1.0).abs() < 0.01, "channel {c}: {mean:.4} against {:.4}", want[c]);
    }
    s.integrator = Integrator::Whitted;
    s.spp = 1;
    let (f, _) = gpu::render(&ctx, &scene, &s, |_, _| {}).expect("whitted");
    ctx.check_validation().expect("no validation errors");
    for (k, p) in f.radiance.iter().enumerate() {
        for c in 0..3 {
            assert!((f64::from(p[c]) - want[c]).abs() < 1e-5, "whitted pixel {k}: {p:?} against {want:?}");
        }
    }
}

#[test]
fn alpha_keys_are_checked_at_their_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    square_obj(dir.path(), "q.obj", true, 0.0);
    for (keys, want, line) in [
        ("alpha_mode = \"blend\"\nalpha_cutoff = 0.3\n", "alpha_cutoff needs alpha_mode = \"mask\"", 6),
        ("alpha_mode = \"mask\"\nalpha_cutoff = 1.5\n", "alpha_cutoff must be in [0, 1], got 1.5", 6),
        ("alpha_mode = \"blend\"\nopacity = -0.5\n", "opacity must be in [0, 1]", 6),
        ("opacity = 0.5\n", "opacity needs alpha_mode", 5),
        ("alpha_mode = \"cutout\"\n", "unknown variant `cutout`", 5),
    ] {
        let path = dir.path().join("bad.toml");
        std::fs::write(
            &path,
            format!(
                "[[mesh]]\nfile = \"q.obj\"\nmaterial = \"m\"\n[[material]]\nname = \"m\"\ntype = \"lambert\"\n{keys}"
            ),
        )
        .expect("toml");
        let e = Scene::load(&path.display().to_string()).expect_err(keys).to_string();
        assert!(e.contains(want) && e.contains(&format!("bad.toml:{}:", line + 2)), "{keys}: {e}");
    }
}
