//! The Whitted preview (docs/kernels.md): at Lambert surfaces it converges to the path
//! tracer's direct light, area lights included; it reads albedo textures; glass is
//! split, not sampled, so one sample per pixel does not depend on the seed.

use crate::common;

use arbor::accel::AccelKind;
use arbor::render::{gpu, Frame, Integrator, RenderSettings};
use arbor::scene::procedural::quad;
use arbor::scene::{Camera, Light, Material, MaterialKind, Scene, SceneBuilder, Sphere};
use glam::Vec3;

/// The texture of the Khronos sample BoxTextured (Debian's assimp-testmodels).
const TEXTURE: &str = "/usr/share/assimp/models/glTF2/BoxTextured-glTF/CesiumLogoFlat.png";

fn settings(integrator: Integrator, w: u32, h: u32, spp: u32) -> RenderSettings {
    let mut s = RenderSettings::for_size(w, h);
    s.integrator = integrator;
    s.spp = spp;
    s.seed = 3;
    s.accel = AccelKind::BvhSah;
    s
}

fn render(ctx: &arbor::gpu::Context, scene: &Scene, s: &RenderSettings) -> Frame {
    let (f, _) = gpu::render(ctx, scene, s, |_, _| {}).expect("render");
    ctx.check_validation().expect("no validation errors");
    f
}

fn lum(c: [f32; 3]) -> f64 {
    f64::from(0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2])
}

/// The image's mean luminance and the standard error of that mean.
fn mean_and_error(f: &Frame) -> (f64, f64) {
    let n = f.radiance.len() as f64;
    let sum: f64 = f.radiance.iter().map(|&c| lum(c)).sum();
    let var: f64 = f.variance.iter().map(|&v| f64::from(v)).sum();
    (sum / n, (var / (n * n)).sqrt())
}

/// Whitted at many samples against the path tracer's direct light (`--max-depth 2`:
/// emission seen, then one bounce), on a scene with a black background, no ambient
/// term and Lambert surfaces only: the image means within 1%.
fn converges_to_direct_light(ctx: &arbor::gpu::Context, scene: &Scene, what: &str) -> Frame {
    let (w, h, spp) = (32, 32, 256);
    let whitted = render(ctx, scene, &settings(Integrator::Whitted, w, h, spp));
    let mut s = settings(Integrator::Path, w, h, spp);
    s.max_depth = Some(2);
    let path = render(ctx, scene, &s);
    let ((mw, ew), (mp, ep)) = (mean_and_error(&whitted), mean_and_error(&path));
    eprintln!("{what}: whitted {mw:.5} +- {ew:.5}, path depth 2 {mp:.5} +- {ep:.5}");
    assert!(mp > 0.01, "{what}: the path tracer's image is black ({mp})");
    assert!((mw - mp).abs() <= 0.01 * mp, "{what}: whitted mean {mw} against the path tracer's direct light {mp}");
    whitted
}

#[test]
fn the_cornell_box_is_lit_by_its_area_light() {
    let Some(ctx) = common::gpu() else { return };
    let mut scene = Scene::load("builtin:cornell").expect("cornell");
    assert!(scene.lights.is_empty(), "builtin:cornell is lit by its emissive ceiling only");
    scene.background = Vec3::ZERO;
    scene.ambient = 0.0;
    let f = converges_to_direct_light(&ctx, &scene, "builtin:cornell");
    // The floor and walls are lit, not only the light itself.
    let lit = f.radiance.iter().filter(|&&c| lum(c) > 0.02).count();
    assert!(lit * 2 > f.radiance.len(), "{lit} of {} pixels lit", f.radiance.len());
}

/// A textured Lambert quad (the BoxTextured logo) under a square area light, as a scene
/// file; with `texture` or without.
fn textured_quad(dir: &std::path::Path, textured: bool) -> Scene {
    std::fs::write(
        dir.join("quad.obj"),
        "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 1\nvt 1 1\nvt 1 0\nvt 0 0\nf 4/4 3/3 2/2 1/1\n",
    )
    .expect("write quad");
    std::fs::write(dir.join("light.obj"), "v -0.3 1 -0.3\nv 0.3 1 -0.3\nv 0.3 1 0.3\nv -0.3 1 0.3\nf 1 2 3 4\n")
        .expect("write light");
    let texture = if textured { format!("texture = \"{TEXTURE}\"\n") } else { String::new() };
    let toml = format!(
        "[camera]\neye = [0.0, 2.2, 1.2]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 55.0\n\
         [render]\nbackground = [0.0, 0.0, 0.0]\nambient = 0.0\n\
         [[mesh]]\nfile = \"quad.obj\"\nmaterial = \"logo\"\n\
         [[mesh]]\nfile = \"light.obj\"\nmaterial = \"light\"\n\
         [[material]]\nname = \"logo\"\ntype = \"lambert\"\ncolor = [0.8, 0.8, 0.8]\n{texture}\
         [[material]]\nname = \"light\"\ntype = \"emissive\"\nemission = [6.0, 6.0, 6.0]\n"
    );
    let path = dir.join(if textured { "textured.toml" } else { "plain.toml" });
    std::fs::write(&path, toml).expect("write scene");
    Scene::load(&path.display().to_string()).expect("textured scene")
}

#[test]
fn a_textured_quad_under_an_area_light_shows_its_texture() {
    let Some(ctx) = common::gpu() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let textured = textured_quad(dir.path(), true);
    assert_eq!(textured.textures.len(), 1, "the scene has its texture");
    let f = converges_to_direct_light(&ctx, &textured, "textured quad");
    let plain = render(&ctx, &textured_quad(dir.path(), false), &settings(Integrator::Whitted, 32, 32, 256));
    // The logo is blue, green and white on grey: most pixels of the quad differ from
    // the untextured colour, and in hue, not only in brightness.
    let on_quad: Vec<usize> =
        (0..f.prim.len()).filter(|&k| f.prim[k] != u32::MAX && lum(plain.radiance[k]) > 0.0).collect();
    assert!(on_quad.len() > 200, "the quad fills the view ({} pixels)", on_quad.len());
    let tinted = on_quad
        .iter()
        .filter(|&&k| {
            let (a, b) = (f.radiance[k], plain.radiance[k]);
            let chroma = |c: [f32; 3]| (c[2] - c[0]) / (c[0] + c[1] + c[2]).max(1e-6);
            (chroma(a) - chroma(b)).abs() > 0.05
        })
        .count();
    assert!(tinted * 2 > on_quad.len(), "{tinted} of {} quad pixels show the texture's colours", on_quad.len());
    // The albedo AOV is the textured one.
    assert!(on_quad.iter().any(|&k| (f.albedo[k][2] - f.albedo[k][0]).abs() > 0.1), "albedo AOV without texture");
}

/// Glass and point lights only: one sample per pixel through the pixel centre, and
/// glass followed both ways, not chosen at random: the seed changes no bit.
#[test]
fn glass_under_point_lights_does_not_depend_on_the_seed() {
    let Some(ctx) = common::gpu() else { return };
    let mut b = SceneBuilder::new("glass");
    let white = b.material(Material::lambert("white", Vec3::splat(0.8)));
    let glass = b.material(Material { kind: MaterialKind::Glass, ior: 1.5, ..Material::lambert("glass", Vec3::ONE) });
    let v = Vec3::new;
    let g = 3.0;
    b.mesh(&quad([v(-g, -1.0, g), v(g, -1.0, g), v(g, -1.0, -g), v(-g, -1.0, -g)]), 1.0, Vec3::ZERO, Some(white));
    b.scene.spheres.push(Sphere { center: Vec3::ZERO, radius: 0.8, material: glass });
    b.scene.spheres.push(Sphere { center: v(1.2, 0.3, -1.5), radius: 0.5, material: glass });
    b.scene.lights.push(Light::Point { position: v(1.0, 3.0, 2.0), intensity: Vec3::splat(6.0) });
    b.scene.lights.push(Light::Point { position: v(-2.0, 2.0, -1.0), intensity: Vec3::splat(3.0) });
    b.scene.background = v(0.2, 0.3, 0.5);
    b.scene.camera = Camera { eye: v(0.0, 0.8, 4.0), look_at: Vec3::ZERO, up: Vec3::Y, vfov: 45.0 };
    let scene = b.finish().expect("scene");
    let mut s = settings(Integrator::Whitted, 40, 30, 1);
    let a = render(&ctx, &scene, &s);
    s.seed = 12345;
    let c = render(&ctx, &scene, &s);
    let same = a.radiance.iter().zip(&c.radiance).all(|(x, y)| x.map(f32::to_bits) == y.map(f32::to_bits));
    assert!(same, "the seed changed the image");
    // Both rays of the glass: the sphere shows the floor through it and the sky in it,
    // so its pixels are neither black nor the plain background.
    let sphere = scene.triangles.len() as u32;
    let on_glass: Vec<usize> = (0..a.prim.len()).filter(|&k| a.prim[k] == sphere).collect();
    assert!(on_glass.len() > 50, "the glass sphere fills part of the view ({})", on_glass.len());
    assert!(on_glass.iter().all(|&k| lum(a.radiance[k]) > 0.0), "a black pixel on the glass");
}

/// Glass with the deepest paths and many lights: three splits would leave each trace
/// too few steps on lavapipe, so the split is shallower there; the render is never
/// refused, and it still splits (the seed changes nothing).
#[test]
fn deep_glass_with_many_lights_fits_the_loop_limit() {
    let Some(ctx) = common::gpu() else { return };
    let mut b = SceneBuilder::new("deep glass");
    let white = b.material(Material::lambert("white", Vec3::splat(0.8)));
    let glass = b.material(Material { kind: MaterialKind::Glass, ior: 1.5, ..Material::lambert("glass", Vec3::ONE) });
    let v = Vec3::new;
    b.mesh(
        &quad([v(-3.0, -1.0, 3.0), v(3.0, -1.0, 3.0), v(3.0, -1.0, -3.0), v(-3.0, -1.0, -3.0)]),
        1.0,
        Vec3::ZERO,
        Some(white),
    );
    for k in 0..4 {
        b.scene.spheres.push(Sphere {
            center: v(k as f32 * 0.5 - 0.75, 0.0, -0.3 * k as f32),
            radius: 0.4,
            material: glass,
        });
    }
    for k in 0..24 {
        let a = k as f32 * 0.26;
        b.scene
            .lights
            .push(Light::Point { position: v(3.0 * a.cos(), 2.5, 3.0 * a.sin()), intensity: Vec3::splat(0.3) });
    }
    b.scene.camera = Camera { eye: v(0.0, 0.8, 4.0), look_at: Vec3::ZERO, up: Vec3::Y, vfov: 45.0 };
    b.scene.max_depth = arbor::gpu::bindings::MAX_PATH_DEPTH;
    let scene = b.finish().expect("scene");
    let mut s = settings(Integrator::Whitted, 24, 18, 1);
    let a = render(&ctx, &scene, &s);
    s.seed = 99;
    let c = render(&ctx, &scene, &s);
    assert!(a.radiance.iter().zip(&c.radiance).all(|(x, y)| x.map(f32::to_bits) == y.map(f32::to_bits)));
    assert!(a.radiance.iter().any(|c| lum(*c) > 0.0), "a black image");
}
