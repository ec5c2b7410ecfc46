//! Ray batches on the device (src/render/rays.rs) against the CPU reference
//! (`Accel::trace_cpu`): every structure on the mixed scene (triangles and spheres),
//! with misses, tmin/tmax limits and axis-parallel directions; resumed traces; batches
//! over several dispatches and chunks; the empty batch; bad rays as typed errors;
//! instanced scenes and two-level structures refused.

use crate::common;

use arbor::accel::{Accel, AccelKind};
use arbor::gpu::bindings::MIN_FORCED_TRACE_STEPS;
use arbor::render::dispatch::PacingChoice;
use arbor::{Error, Hit, Ray, RayTracer, Scene, TraceOptions};
use common::scenes::{mixed_scene, Rng};
use glam::Vec3;

/// Seeded rays of every kind the batch must get right.
fn rays(scene: &Scene, n: usize, seed: u64) -> Vec<Ray> {
    let b = scene.bounds();
    let (c, size) = (b.center(), b.extent());
    let radius = size.length();
    let mut rng = Rng(seed | 1);
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let inside = b.min + size * Vec3::new(rng.next(), rng.next(), rng.next());
        let ray = match k % 8 {
            // From outside toward a point in the box (mostly hits).
            0 | 1 => {
                let o = c + rng.dir() * radius;
                Ray { origin: o, dir: (inside - o).normalize(), tmin: 0.0, tmax: f32::INFINITY }
            }
            // From inside, any direction.
            2 | 3 => Ray { origin: inside, dir: rng.dir(), tmin: 0.0, tmax: f32::INFINITY },
            // Away from the box: misses.
            4 => {
                let d = rng.dir();
                Ray { origin: c + d * radius * 2.0, dir: d, tmin: 0.0, tmax: f32::INFINITY }
            }
            // A short segment: tmax cuts hits off.
            5 => {
                let o = c + rng.dir() * radius;
                let d = (inside - o).normalize();
                Ray { origin: o, dir: d, tmin: 0.0, tmax: radius * rng.next() }
            }
            // Starting past the first hit: tmin skips it.
            6 => {
                let o = c + rng.dir() * radius;
                let d = (inside - o).normalize();
                Ray { origin: o, dir: d, tmin: radius * rng.next(), tmax: f32::INFINITY }
            }
            // Axis-parallel directions.
            _ => {
                let axis = [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z][k % 6];
                Ray { origin: inside, dir: axis, tmin: 0.0, tmax: f32::INFINITY }
            }
        };
        out.push(ray);
    }
    out
}

/// Every ray: both miss, or the same primitive with t and barycentrics close.
fn assert_same(what: &str, rays: &[Ray], gpu: &[Option<Hit>], cpu: &[Option<Hit>]) {
    assert_eq!(gpu.len(), rays.len(), "{what}: hit count");
    assert_eq!(cpu.len(), rays.len(), "{what}: reference count");
    for (k, ((g, c), r)) in gpu.iter().zip(cpu).zip(rays).enumerate() {
        match (g, c) {
            (None, None) => {}
            (Some(g), Some(c)) => {
                assert_eq!(g.prim, c.prim, "{what}: ray {k} {r:?}: gpu {g:?} cpu {c:?}");
                assert!((g.t - c.t).abs() <= 1e-5 * c.t.abs().max(1e-3), "{what}: ray {k}: t {} vs {}", g.t, c.t);
                assert!((g.u - c.u).abs() <= 1e-4 && (g.v - c.v).abs() <= 1e-4, "{what}: ray {k}: {g:?} vs {c:?}");
                assert!(g.t > r.tmin && g.t <= r.tmax, "{what}: ray {k}: t {} outside its interval", g.t);
            }
            _ => panic!("{what}: ray {k} {r:?}: gpu {g:?} cpu {c:?}"),
        }
    }
}

#[test]
fn every_structure_matches_the_cpu_reference_on_the_mixed_scene() {
    let Some(ctx) = common::gpu() else { return };
    let scene = mixed_scene(Vec3::new(0.0, 0.5, 4.0));
    let rays = rays(&scene, 6000, 0x5eed);
    let mut kinds = AccelKind::ALL.to_vec();
    if ctx.info().ray_query() {
        kinds.push(AccelKind::RayQuery);
    }
    for kind in kinds {
        let accel = Accel::build_on(&ctx, kind, &scene, &Default::default()).expect("build");
        let tracer = RayTracer::new(&ctx, &scene, &accel, &TraceOptions::default()).expect("tracer");
        assert!(tracer.kernel_name().starts_with("rays_") && tracer.kernel_name().ends_with("_all"));
        let gpu = tracer.trace(&rays).expect("trace");
        let cpu = accel.trace_cpu(&scene, &rays);
        let hits = cpu.iter().filter(|h| h.is_some()).count();
        assert!(hits > rays.len() / 4 && hits < rays.len() * 9 / 10, "{kind}: {hits} hits: the rays test too little");
        assert!(cpu.iter().flatten().any(|h| h.prim >= scene.triangles.len() as u32), "{kind}: no sphere hit");
        assert_same(kind.name(), &rays, &gpu, &cpu);
    }
    ctx.check_validation().expect("no validation errors");
}

#[test]
fn resumed_traces_give_the_same_hits() {
    let Some(ctx) = common::gpu() else { return };
    let scene = mixed_scene(Vec3::new(0.0, 0.5, 4.0));
    let rays = rays(&scene, 3000, 7);
    // The 8-wide BVHs are too shallow on this scene to run out: their hits must still
    // not move.
    let kinds = [
        (AccelKind::Kdtree, true),
        (AccelKind::BvhSah, true),
        (AccelKind::Grid, true),
        (AccelKind::Octree, true),
        (AccelKind::Bvh8, false),
        (AccelKind::Cwbvh, false),
    ];
    for (kind, must_resume) in kinds {
        let accel = Accel::build(kind, &scene);
        let whole = RayTracer::new(&ctx, &scene, &accel, &TraceOptions::default()).expect("tracer");
        let (full, _) = whole.trace_stats(&rays).expect("trace");
        let forced = TraceOptions { trace_steps: Some(MIN_FORCED_TRACE_STEPS), ..Default::default() };
        let small = RayTracer::new(&ctx, &scene, &accel, &forced).expect("tracer");
        let (resumed, stats) = small.trace_stats(&rays).expect("trace");
        assert!(!must_resume || stats.resumed > 0, "{kind}: no trace ran out of {MIN_FORCED_TRACE_STEPS} steps");
        assert_eq!(full, resumed, "{kind}: resumed traces changed a hit");
        assert_same(kind.name(), &rays, &resumed, &accel.trace_cpu(&scene, &rays));
    }
    ctx.check_validation().expect("no validation errors");
}

#[test]
fn a_batch_over_many_dispatches_and_chunks_is_one_batch() {
    let Some(ctx) = common::gpu() else { return };
    let scene = mixed_scene(Vec3::new(0.0, 0.5, 4.0));
    let rays = rays(&scene, 5000, 11);
    let accel = Accel::build(AccelKind::BvhSah, &scene);
    let opts = TraceOptions {
        chunk_rays: 1500,
        pacing: PacingChoice { budget: Some(20_000), ..Default::default() },
        ..Default::default()
    };
    let tracer = RayTracer::new(&ctx, &scene, &accel, &opts).expect("tracer");
    assert_eq!(tracer.chunk_rays(), 1500);
    let (hits, stats) = tracer.trace_stats(&rays).expect("trace");
    assert!(stats.dispatches > 4, "{} dispatches: the batch was not split", stats.dispatches);
    assert_eq!(stats.rays, 5000);
    let one = RayTracer::new(&ctx, &scene, &accel, &TraceOptions::default()).expect("tracer");
    let (whole, one_stats) = one.trace_stats(&rays).expect("trace");
    assert_eq!(one_stats.dispatches, 1);
    // A batch holds up to 1M rays on the device by default, not an image's worth.
    assert_eq!(one.chunk_rays(), arbor::render::integrators::rays::DEFAULT_CHUNK_RAYS);
    assert_eq!(hits, whole, "splitting changed a hit");
    assert_same("split", &rays, &hits, &accel.trace_cpu(&scene, &rays));
    // The same tracer traces a second batch.
    let again = tracer.trace(&rays[..777]).expect("trace");
    assert_eq!(again, whole[..777]);
    ctx.check_validation().expect("no validation errors");
}

#[test]
fn an_empty_batch_is_empty() {
    let Some(ctx) = common::gpu() else { return };
    let scene = mixed_scene(Vec3::new(0.0, 0.5, 4.0));
    let accel = Accel::build(AccelKind::Kdtree, &scene);
    let tracer = RayTracer::new(&ctx, &scene, &accel, &TraceOptions::default()).expect("tracer");
    let (hits, stats) = tracer.trace_stats(&[]).expect("trace");
    assert!(hits.is_empty());
    assert_eq!((stats.rays, stats.dispatches), (0, 0));
    assert!(accel.trace_cpu(&scene, &[]).is_empty());
    assert_eq!(arbor::trace_rays(&ctx, &scene, &accel, &[]).expect("trace"), vec![]);
}

#[test]
fn bad_rays_are_typed_errors_naming_the_ray() {
    let good = Ray { origin: Vec3::ZERO, dir: Vec3::X, tmin: 0.0, tmax: f32::INFINITY };
    let cases = [
        (Ray { dir: Vec3::ZERO, ..good }, "direction is zero"),
        (Ray { dir: Vec3::new(f32::NAN, 0.0, 1.0), ..good }, "direction is not finite"),
        (Ray { dir: Vec3::X * 2.0, ..good }, "not unit length"),
        (Ray { origin: Vec3::new(0.0, f32::INFINITY, 0.0), ..good }, "origin is not finite"),
        (Ray { tmin: -1.0, ..good }, "tmin"),
        (Ray { tmin: f32::NAN, ..good }, "tmin"),
        (Ray { tmin: 2.0, tmax: 1.0, ..good }, "tmax"),
        (Ray { tmax: f32::NAN, ..good }, "tmax"),
    ];
    for (bad, what) in cases {
        let batch = [good, good, bad, good];
        match arbor::render::integrators::rays::check_rays(&batch) {
            Err(Error::BadRay { index: 2, reason }) => assert!(reason.contains(what), "{reason}"),
            other => panic!("{bad:?}: {other:?}"),
        }
    }
    arbor::render::integrators::rays::check_rays(&[good, Ray { tmin: 1.0, tmax: 1.0, ..good }]).expect("good rays");
    // The device path refuses them the same way, before tracing anything.
    let Some(ctx) = common::gpu() else { return };
    let scene = mixed_scene(Vec3::new(0.0, 0.5, 4.0));
    let accel = Accel::build(AccelKind::Grid, &scene);
    let err = arbor::trace_rays(&ctx, &scene, &accel, &[good, Ray { dir: Vec3::ZERO, ..good }]).unwrap_err();
    assert!(matches!(err, Error::BadRay { index: 1, .. }), "{err}");
    assert_eq!(err.to_string(), "ray 1: the direction is zero");
}

#[test]
fn a_structure_built_for_the_cpu_only_is_refused_on_the_device() {
    let Some(ctx) = common::gpu() else { return };
    let scene = mixed_scene(Vec3::new(0.0, 0.5, 4.0));
    // `rayquery` built without a device has no driver structure to bind.
    let accel = Accel::build(AccelKind::RayQuery, &scene);
    let err = RayTracer::new(&ctx, &scene, &accel, &TraceOptions::default()).unwrap_err();
    assert!(err.to_string().contains("rayquery") || err.to_string().contains("driver"), "{err}");
}

#[test]
fn instanced_scenes_and_two_level_structures_are_refused() {
    let Some(ctx) = common::gpu() else { return };
    let instanced = crate::instances::scene(50, 0);
    let two_level = Accel::build(AccelKind::BvhSah, &instanced);
    let err = RayTracer::new(&ctx, &instanced, &two_level, &TraceOptions::default()).unwrap_err();
    assert!(matches!(err, Error::Unsupported(_)), "{err}");
    assert!(err.to_string().contains("flatten the instances first"), "{err}");
    // The flattened scene traces; the two-level structure still does not.
    let flat = instanced.flattened().expect("flattened");
    let err = RayTracer::new(&ctx, &flat, &two_level, &TraceOptions::default()).unwrap_err();
    assert!(err.to_string().contains("flat"), "{err}");
    let accel = Accel::build(AccelKind::BvhSah, &flat);
    let rays = rays(&flat, 500, 3);
    let gpu =
        RayTracer::new(&ctx, &flat, &accel, &TraceOptions::default()).expect("tracer").trace(&rays).expect("trace");
    assert_same("flattened", &rays, &gpu, &accel.trace_cpu(&flat, &rays));
}
