//! `--accel rayquery`: the driver's acceleration structure traced with
//! VK_KHR_ray_query. On a device with ray queries (Mesa 24.1+ lavapipe: CI runs this
//! file again on Mesa 25 with ARBOR_REQUIRE_RAY_QUERY=1), every check the other
//! structures pass: the same primitive and depth per pixel as the CPU reference, the
//! same images as bvh-sah, instancing, crops, stats that say what is not visible. On a
//! device without them, the one-line error naming the missing extension.

use crate::common;

use arbor::accel::{Accel, AccelKind, AccelParams};
use arbor::gpu::Context;
use arbor::render::{cpu, gpu, Frame, Integrator, RenderSettings, RenderStats};
use arbor::scene::{procedural, Light, Scene, SceneBuilder, Sphere};
use glam::{Affine3A, Quat, Vec3};

use common::scenes::mixed_scene;

/// A validated device with ray queries, or None (skipped) where it has none, unless
/// ARBOR_REQUIRE_RAY_QUERY=1, where that is a failure.
fn rq_gpu() -> Option<common::Gpu> {
    let ctx = common::gpu()?;
    if ctx.has_ray_query() {
        return Some(ctx);
    }
    let why = ctx.info().ray_query_missing.clone().unwrap_or_default();
    if std::env::var("ARBOR_REQUIRE_RAY_QUERY").is_ok_and(|v| v == "1") {
        panic!("ARBOR_REQUIRE_RAY_QUERY=1 but {} lacks {why}", ctx.info().name);
    }
    eprintln!("skipped: {} has no ray queries (lacks {why})", ctx.info().name);
    None
}

fn render_stats(
    ctx: &Context,
    scene: &Scene,
    w: u32,
    h: u32,
    f: impl FnOnce(&mut RenderSettings),
) -> (Frame, RenderStats) {
    let mut s = RenderSettings::for_size(w, h);
    s.accel = AccelKind::RayQuery;
    f(&mut s);
    let out = gpu::render(ctx, scene, &s, |_, _| {}).expect("render");
    ctx.check_validation().expect("no validation errors");
    out
}

fn render(ctx: &Context, scene: &Scene, w: u32, h: u32, f: impl FnOnce(&mut RenderSettings)) -> Frame {
    render_stats(ctx, scene, w, h, f).0
}

/// Mean absolute difference over every channel.
fn mean_abs_diff(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let sum: f64 = a.iter().flatten().zip(b.iter().flatten()).map(|(x, y)| f64::from((x - y).abs())).sum();
    sum / (3 * a.len()).max(1) as f64
}

/// Pixels whose primitive differs, and those whose depth is off by more than `rel`.
fn mismatches(a: &Frame, b: &Frame, rel: f32) -> (Vec<usize>, Vec<usize>) {
    let mut prim = Vec::new();
    let mut depth = Vec::new();
    for k in 0..a.prim.len() {
        if a.prim[k] != b.prim[k] {
            prim.push(k);
        }
        let (g, c) = (a.depth[k], b.depth[k]);
        let ok = if c.is_infinite() { g.is_infinite() && g > 0.0 } else { (g - c).abs() <= rel * c.abs() };
        if !ok {
            depth.push(k);
        }
    }
    (prim, depth)
}

/// The driver's hits against arbor's watertight CPU reference: the same primitive on
/// every pixel but those where the camera ray meets an edge or vertex shared by two
/// triangles (a tie the driver may break the other way: then both triangles are hit at
/// the same depth), and the same depth within 1e-5 relative everywhere.
fn assert_matches_reference(name: &str, g: &Frame, c: &Frame) {
    let (prim, depth) = mismatches(g, c, 1e-5);
    assert!(
        depth.is_empty(),
        "{name}: {} pixels with another depth, first {:?}",
        depth.len(),
        &depth[..depth.len().min(5)]
    );
    // Ties at shared edges: at most 1 pixel in 500.
    assert!(
        prim.len() * 500 <= g.prim.len(),
        "{name}: {} of {} pixels with another primitive",
        prim.len(),
        g.prim.len()
    );
    let hits = c.prim.iter().filter(|&&p| p != u32::MAX).count();
    assert!(hits > 0 && hits < c.prim.len(), "{name}: the image must contain hits and misses ({hits})");
}

#[test]
fn a_device_without_ray_queries_names_what_it_lacks() {
    let Some(ctx) = common::gpu() else { return };
    if ctx.has_ray_query() {
        assert!(ctx.info().ray_query(), "the device reports ray queries and the context enabled them");
        return;
    }
    let scene = Scene::load("builtin:blob:500").expect("blob");
    let mut s = RenderSettings::for_size(8, 8);
    s.accel = AccelKind::RayQuery;
    let err = gpu::render(&ctx, &scene, &s, |_, _| {}).expect_err("no ray queries here").to_string();
    let missing = ctx.info().ray_query_missing.clone().expect("a reason");
    assert!(err.contains(&missing) && err.contains(&ctx.info().name), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
}

#[test]
fn rayquery_aovs_equal_the_cpu_reference() {
    let Some(ctx) = rq_gpu() else { return };
    let mut cases: Vec<(String, Scene)> = Vec::new();
    for (k, eye) in
        [Vec3::new(0.0, 0.5, 4.0), Vec3::new(3.0, 2.0, 2.0), Vec3::new(-2.5, 0.1, -3.0), Vec3::new(0.01, 4.5, 0.01)]
            .into_iter()
            .enumerate()
    {
        cases.push((format!("mixed camera {k}"), mixed_scene(eye)));
    }
    for name in ["builtin:cornell", "builtin:spheres", "builtin:default"] {
        cases.push((name.into(), Scene::load(name).expect("builtin")));
    }
    let obj = "/usr/share/assimp/models/OBJ/spider.obj";
    if std::path::Path::new(obj).exists() {
        cases.push(("spider.obj".into(), Scene::load(obj).expect("spider")));
    }
    for (name, scene) in &cases {
        let (w, h) = (64, 48);
        let g = render(&ctx, scene, w, h, |_| {});
        let c = cpu::reference_aovs(scene, w, h);
        assert_matches_reference(name, &g, &c);
    }
}

#[test]
fn rayquery_renders_what_bvh_sah_renders() {
    let Some(ctx) = rq_gpu() else { return };
    let scene = mixed_scene(Vec3::new(3.0, 2.0, 2.0));
    for integrator in [Integrator::Whitted, Integrator::Path, Integrator::Sppm] {
        let setup = |s: &mut RenderSettings| {
            s.integrator = integrator;
            s.spp = 8;
            s.seed = 3;
        };
        let rq = render(&ctx, &scene, 48, 36, setup);
        let bvh = render(&ctx, &scene, 48, 36, |s| {
            setup(s);
            s.accel = AccelKind::BvhSah;
        });
        // Same hits (up to the driver's last bits of t and barycentrics, and edge
        // ties), so the same image: mean absolute difference far below the noise of 8 spp.
        let n = 3.0 * rq.radiance.len() as f64;
        let diff = mean_abs_diff(&rq.radiance, &bvh.radiance);
        let mean: f64 = bvh.radiance.iter().flatten().map(|a| f64::from(a.abs())).sum::<f64>() / n;
        assert!(mean > 0.01, "{integrator:?}: the image must not be black");
        assert!(diff < 0.01 * mean, "{integrator:?}: mean |rayquery - bvh-sah| = {diff}, mean {mean}");
    }
}

/// Instances hit where their flattened copies do: the TLAS carries each instance's
/// transform and its entry number, the kernel maps the hit back to the flattened
/// primitive number.
#[test]
fn rayquery_instances_hit_like_their_flattened_copies() {
    let Some(ctx) = rq_gpu() else { return };
    let mut b = SceneBuilder::new("instances");
    b.mesh(
        &procedural::quad([
            Vec3::new(-20.0, -1.5, -20.0),
            Vec3::new(20.0, -1.5, -20.0),
            Vec3::new(20.0, -1.5, 20.0),
            Vec3::new(-20.0, -1.5, 20.0),
        ]),
        1.0,
        Vec3::ZERO,
        None,
    );
    b.scene.spheres.push(Sphere { center: Vec3::new(0.0, 2.2, 0.0), radius: 0.6, material: 0 });
    let p = b.prototype("blob", &procedural::blob(400, 0.3, 7), &Affine3A::IDENTITY, None);
    for k in 0..9 {
        let (x, z) = ((k % 3) as f32 - 1.0, (k / 3) as f32 - 1.0);
        let s = if k % 2 == 0 { Vec3::splat(0.5) } else { Vec3::new(-0.5, 0.4, 0.6) };
        let r = Quat::from_axis_angle(Vec3::new(0.2, 1.0, 0.4).normalize(), k as f32 * 0.7);
        b.instance(p, Affine3A::from_scale_rotation_translation(s, r, Vec3::new(x * 1.4, 0.1, z * 1.4)));
    }
    b.scene.lights.push(Light::Directional { direction: Vec3::new(-0.3, -1.0, -0.5), radiance: Vec3::ONE });
    b.scene.camera.eye = Vec3::new(0.5, 4.0, 6.5);
    b.scene.camera.look_at = Vec3::ZERO;
    let scene = b.finish().expect("valid scene");
    let flat = scene.flattened().expect("flattened");
    let (g, st) = render_stats(&ctx, &scene, 64, 48, |_| {});
    assert_eq!(st.kernel, "trace_inst_rayquery_all");
    let c = cpu::reference_aovs(&flat, 64, 48);
    assert_matches_reference("instances", &g, &c);
    // Shading through the instance transforms: the same image as the two-level bvh-sah.
    let a = render(&ctx, &scene, 32, 24, |s| s.integrator = Integrator::Whitted);
    let bv = render(&ctx, &scene, 32, 24, |s| {
        s.integrator = Integrator::Whitted;
        s.accel = AccelKind::BvhSah;
    });
    let diff = mean_abs_diff(&a.radiance, &bv.radiance);
    assert!(diff < 1e-3, "instanced whitted image differs from bvh-sah's by {diff} on average");
}

#[test]
fn rayquery_stats_report_the_driver_build_and_not_its_counters() {
    let Some(ctx) = rq_gpu() else { return };
    let scene = Scene::load("builtin:blob:5000").expect("blob");
    let (frame, st) = render_stats(&ctx, &scene, 32, 32, |_| {});
    assert_eq!(st.accel, "rayquery");
    assert_eq!(st.kernel, "trace_rayquery_tris");
    assert_eq!(st.bindings, ["params", "vertices", "triangles", "shading", "pixels", "tlas"]);
    assert!(st.mean_nodes_visited.is_none() && st.mean_prims_tested.is_none(), "the driver's counters are not visible");
    assert!(st.build.opaque.is_some());
    let names: Vec<&str> = st.build.phases.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["blas", "compact", "tlas"]);
    assert!(st.build_ms > 0.0 && st.accel_bytes > 0, "{} ms, {} bytes", st.build_ms, st.accel_bytes);
    let json = serde_json::to_value(&st).expect("json");
    assert!(json["mean_nodes_visited"].is_null(), "{}", json["mean_nodes_visited"]);
    // Without compaction the structure is at least as large; PREFER_FAST_BUILD traces
    // the same hits.
    let mut params = AccelParams::default();
    params.set_flag("rayquery", "fast-build,compact=false").expect("params");
    let (fast, st2) = render_stats(&ctx, &scene, 32, 32, |s| s.params = params);
    assert!(st2.accel_bytes >= st.accel_bytes, "{} < {}", st2.accel_bytes, st.accel_bytes);
    assert_eq!(st2.build.phases[1].ms, 0.0, "no compaction asked for");
    let (prim, _) = mismatches(&fast, &frame, 1e-5);
    assert!(prim.len() <= 2, "{} pixels differ between fast-build and fast-trace", prim.len());
    // --build gpu is refused for it, and a structure made without a device cannot be traced.
    let cpu_only = Accel::build(AccelKind::RayQuery, &scene);
    assert!(cpu_only.gpu_image(&scene).is_err());
    params.build = arbor::accel::BuildOn::Gpu;
    let err = Accel::build_on(&ctx, AccelKind::RayQuery, &scene, &params).expect_err("gpu build");
    assert!(err.to_string().contains("driver"), "{err}");
}

#[test]
fn rayquery_crops_equal_the_whole_image() {
    let Some(ctx) = rq_gpu() else { return };
    let scene = Scene::load("builtin:cornell").expect("cornell");
    let path = |s: &mut RenderSettings| {
        s.integrator = Integrator::Path;
        s.spp = 4;
    };
    let whole = render(&ctx, &scene, 32, 32, path);
    let c = arbor::render::Crop { x0: 8, x1: 24, y0: 4, y1: 24 };
    let part = render(&ctx, &scene, 32, 32, |s| {
        path(s);
        s.crop = Some(c);
    });
    assert_eq!((part.width, part.height), (16, 20));
    for y in 0..20 {
        for x in 0..16 {
            let w = ((y + 4) * 32 + x + 8) as usize;
            let k = (y * 16 + x) as usize;
            assert_eq!(part.radiance[k], whole.radiance[w], "pixel ({x}, {y}) of the crop");
            assert_eq!(part.prim[k], whole.prim[w], "pixel ({x}, {y}) of the crop");
        }
    }
}
