//! Open3D's ray-casting surface over arbor (`arbor::raycast`, the core of issue 68's
//! Python module): hits on the device equal the CPU reference for every structure,
//! geometry and primitive ids, `t_hit` in units of the given direction, occlusion
//! tests, and errors that name the first bad row.

use crate::common;

use arbor::accel::{AccelKind, AccelParams};
use arbor::raycast::{RaycastingScene, INVALID_ID};
use common::scenes::Rng;

/// Two meshes (a floor quad and a tilted triangle) and a sphere.
fn scene(kind: AccelKind) -> RaycastingScene {
    let mut s = RaycastingScene::new(kind, AccelParams::default());
    let floor = s
        .add_triangles(
            &[[-2.0, 0.0, -2.0], [2.0, 0.0, -2.0], [2.0, 0.0, 2.0], [-2.0, 0.0, 2.0]],
            &[[0, 2, 1], [0, 3, 2]],
        )
        .expect("floor");
    let tri = s.add_triangles(&[[-1.0, 0.5, 0.0], [1.0, 0.5, 0.2], [0.0, 1.5, -0.2]], &[[0, 1, 2]]).expect("triangle");
    let ball = s.add_sphere([0.8, 0.6, 0.8], 0.3).expect("sphere");
    assert_eq!((floor, tri, ball), (0, 1, 2));
    s
}

/// Random rays from a box above the scene, downward, with directions of random length.
fn rays(n: usize) -> Vec<[f32; 6]> {
    let mut rng = Rng(12345);
    (0..n)
        .map(|_| {
            let o = [rng.range(-1.5, 1.5), rng.range(1.8, 2.5), rng.range(-1.5, 1.5)];
            let mut d = rng.dir() * rng.range(0.2, 3.0);
            // Downward: most rays meet the scene.
            d.y = -d.y.abs();
            [o[0], o[1], o[2], d.x, d.y, d.z]
        })
        .collect()
}

#[test]
fn device_hits_equal_the_cpu_reference_for_every_structure() {
    let Some(ctx) = common::gpu() else { return };
    let rays = rays(4000);
    for kind in [
        AccelKind::BvhSah,
        AccelKind::Kdtree,
        AccelKind::Lbvh,
        AccelKind::Bvh8,
        AccelKind::Grid,
        AccelKind::Octree,
        AccelKind::None,
    ] {
        let mut s = scene(kind);
        let cpu = s.cast_rays_cpu(&rays).expect("cpu");
        let gpu = s.cast_rays(&ctx, &rays).expect("gpu");
        assert_eq!(gpu.geometry_ids, cpu.geometry_ids, "{kind:?}");
        assert_eq!(gpu.primitive_ids, cpu.primitive_ids, "{kind:?}");
        for k in 0..rays.len() {
            let (a, b) = (gpu.t_hit[k], cpu.t_hit[k]);
            assert!(a == b || (a - b).abs() <= 1e-5 * b.abs(), "{kind:?} ray {k}: t {a} against {b}");
        }
        let hits = cpu.geometry_ids.iter().filter(|&&g| g != INVALID_ID).count();
        assert!(hits > 1000 && hits < rays.len(), "{kind:?}: {hits} hits");
        for g in 0..3 {
            assert!(cpu.geometry_ids.contains(&g), "{kind:?}: geometry {g} never hit");
        }
    }
}

#[test]
fn outputs_follow_open3d() {
    let mut s = scene(AccelKind::BvhSah);
    // Straight down onto the floor's second triangle, with a direction of length 2.
    let r = s.cast_rays_cpu(&[[-1.5, 3.0, 1.5, 0.0, -2.0, 0.0], [5.0, 3.0, 5.0, 0.0, -1.0, 0.0]]).expect("cast");
    assert!((r.t_hit[0] - 1.5).abs() < 1e-6, "t in units of the direction: {}", r.t_hit[0]);
    assert_eq!((r.geometry_ids[0], r.primitive_ids[0]), (0, 1));
    assert_eq!(r.primitive_normals[0], [0.0, 1.0, 0.0]);
    let [u, v] = r.primitive_uvs[0];
    assert!(u >= 0.0 && v >= 0.0 && u + v <= 1.0);
    // A miss.
    assert_eq!(r.t_hit[1], f32::INFINITY);
    assert_eq!((r.geometry_ids[1], r.primitive_ids[1]), (INVALID_ID, INVALID_ID));
    assert_eq!(r.primitive_normals[1], [0.0; 3]);
    // The sphere, from above its centre: its outward normal.
    let r = s.cast_rays_cpu(&[[0.8, 3.0, 0.8, 0.0, -1.0, 0.0]]).expect("cast");
    assert_eq!(r.geometry_ids[0], 2);
    assert!((r.t_hit[0] - 2.1).abs() < 1e-5 && (r.primitive_normals[0][1] - 1.0).abs() < 1e-5, "{r:?}");
    // Zero rays, an empty scene.
    assert!(s.cast_rays_cpu(&[]).expect("none").t_hit.is_empty());
    let mut empty = RaycastingScene::new(AccelKind::BvhSah, AccelParams::default());
    assert_eq!(empty.cast_rays_cpu(&[[0.0, 0.0, 0.0, 0.0, 0.0, 1.0]]).expect("empty").geometry_ids, vec![INVALID_ID]);
    // Geometry added after a build is found by the next cast.
    let id = s.add_sphere([5.0, 0.5, 5.0], 0.5).expect("more");
    assert_eq!(s.cast_rays_cpu(&[[5.0, 3.0, 5.0, 0.0, -1.0, 0.0]]).expect("again").geometry_ids[0], id);
    assert!(s.build().expect("stats").nodes > 0);
}

#[test]
fn occlusions_between_tnear_and_tfar() {
    let Some(ctx) = common::gpu() else { return };
    let mut s = scene(AccelKind::BvhSah);
    // Down onto the floor (hit at t = 1.5 in units of a direction of length 2).
    let ray = [-1.5, 3.0, 1.5, 0.0, -2.0, 0.0];
    assert_eq!(s.test_occlusions(&ctx, &[ray], 0.0, f32::INFINITY).expect("occ"), vec![true]);
    assert_eq!(s.test_occlusions(&ctx, &[ray], 0.0, 1.4).expect("occ"), vec![false]);
    assert_eq!(s.test_occlusions(&ctx, &[ray], 1.6, 10.0).expect("occ"), vec![false]);
    assert!(s.test_occlusions(&ctx, &[], 0.0, 1.0).expect("none").is_empty());
    assert!(s.test_occlusions(&ctx, &[ray], 2.0, 1.0).is_err());
}

#[test]
fn bad_input_names_the_first_bad_row() {
    let mut s = RaycastingScene::new(AccelKind::BvhSah, AccelParams::default());
    let e = s.add_triangles(&[[0.0; 3], [1.0, f32::NAN, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2]]).unwrap_err();
    assert!(e.to_string().contains("vertices row 1"), "{e}");
    let e = s.add_triangles(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2], [0, 1, 3]]).unwrap_err();
    assert!(e.to_string().contains("triangles row 1") && e.to_string().contains("out of range"), "{e}");
    assert!(s.add_sphere([0.0; 3], -1.0).is_err());
    s.add_triangles(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2]]).expect("good");
    let e = s.cast_rays_cpu(&[[0.0; 6], [0.0, 0.0, 1.0, 0.0, 0.0, -1.0]]).unwrap_err();
    assert!(e.to_string().contains("rays row 0") && e.to_string().contains("zero"), "{e}");
    let e = s.cast_rays_cpu(&[[0.0, 0.0, 1.0, 0.0, 0.0, -1.0], [f32::INFINITY, 0.0, 0.0, 0.0, 0.0, 1.0]]).unwrap_err();
    assert!(e.to_string().contains("rays row 1"), "{e}");
}

/// A cast calls back between pieces with the rays done, and an error from the callback
/// ends it; `auto` builds the cost model's choice and names it.
#[test]
fn casts_call_back_between_pieces_and_auto_names_its_choice() {
    let Some(ctx) = common::gpu() else { return };
    let mut s = scene(AccelKind::BvhSah);
    let batch = rays(200_000);
    let mut done = Vec::new();
    let out = s
        .cast_rays_with(&ctx, &batch, &mut |n| {
            done.push(n);
            Ok(())
        })
        .expect("cast");
    assert_eq!(out.primitive_ids, s.cast_rays_cpu(&batch).expect("cpu").primitive_ids);
    assert!(done.len() >= 2, "pieces: {done:?}");
    assert!(done.windows(2).all(|w| w[0] < w[1]) && done.last() == Some(&batch.len()), "{done:?}");
    let mut calls = 0;
    let err = s
        .cast_rays_with(&ctx, &batch, &mut |_| {
            calls += 1;
            Err(arbor::Error::Failed("stop".into()))
        })
        .unwrap_err();
    assert_eq!((calls, err.to_string()), (1, "stop".to_string()));

    let mut auto = RaycastingScene::auto(AccelParams::default());
    auto.add_sphere([0.0, 0.0, 0.0], 1.0).expect("sphere");
    assert_eq!(auto.kind(), None);
    let stats = auto.build().expect("build");
    let kind = auto.kind().expect("chosen");
    assert_eq!(stats.kind, kind.name());
}
