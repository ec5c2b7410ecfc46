//! Every structure through its one surface (CPU only): validate, stats with one
//! meaning, the GPU image with its limits, and typed errors that name the node, cell
//! or primitive that is wrong.

use arbor::accel::{Accel, AccelKind, Site, Structure, Traverse};
use arbor::math::Ray;
use arbor::scene::Scene;
use glam::Vec3;

fn scenes() -> Vec<Scene> {
    ["builtin:blob:600", "builtin:cornell", "builtin:spheres"]
        .iter()
        .map(|s| Scene::load(s).unwrap_or_else(|e| panic!("{s}: {e}")))
        .collect()
}

#[test]
fn every_structure_has_the_same_surface() {
    for scene in scenes() {
        let n = scene.prim_count() as f64;
        for &kind in AccelKind::ALL {
            let accel = Accel::build(kind, &scene);
            let s: &dyn Structure = accel.surface();
            let what = format!("{} / {kind}", scene.name);
            s.validate(&scene).unwrap_or_else(|e| panic!("{what}: {e}"));
            let st = s.stats(&scene);
            assert_eq!(st.kind, kind.name(), "{what}");
            assert!(st.leaves >= 1 && st.empty_leaves <= st.leaves, "{what}: {st:?}");
            assert!(st.nodes >= st.leaves, "{what}: {st:?}");
            assert!(st.refs_per_prim >= 1.0, "{what}: every primitive is referenced: {st:?}");
            let full = st.leaves - st.empty_leaves;
            assert!((st.prims_per_leaf * full as f64 - st.refs_per_prim * n).abs() < 1e-6 * n, "{what}: {st:?}");
            let image = s.gpu_image(&scene).unwrap_or_else(|e| panic!("{what}: {e}"));
            assert_eq!(image.family, kind.kernel(), "{what}");
            assert_eq!(image.buffers.is_none(), kind.is_brute_force(), "{what}");
            assert!(image.stack_size >= 1 && image.cost_per_ray >= 1, "{what}");
            // CPU traversal through the surface agrees with brute force.
            let brute = Accel::build(AccelKind::None, &scene);
            for k in 0..64 {
                let a = k as f32 * 0.1;
                let ray = Ray {
                    origin: scene.camera.eye,
                    dir: (scene.camera.look_at - scene.camera.eye + Vec3::new(a.sin(), a.cos(), 0.0) * 0.3).normalize(),
                    tmin: 0.0,
                    tmax: f32::INFINITY,
                };
                assert_eq!(
                    accel.intersect(&scene, &ray).map(|h| h.prim),
                    brute.intersect(&scene, &ray).map(|h| h.prim),
                    "{what}: ray {k}"
                );
                assert_eq!(accel.occluded(&scene, &ray), brute.occluded(&scene, &ray), "{what}: ray {k}");
            }
        }
    }
}

#[test]
fn empty_leaves_mean_the_same_everywhere() {
    // One sphere: a BVH root has an empty child slot, which counts as an empty leaf as
    // the kd-tree's, grid's and octree's empty leaves do.
    let scene = Scene::load("builtin:blob:50").expect("blob");
    for &kind in AccelKind::ALL {
        let st = Accel::build(kind, &scene).stats(&scene);
        assert!(st.empty_leaves <= st.leaves, "{kind}: {st:?}");
        assert!(st.mean_leaf_depth <= f64::from(st.max_depth), "{kind}: {st:?}");
    }
}

#[test]
fn validate_names_what_is_wrong() {
    let scene = Scene::load("builtin:blob:600").expect("blob");
    let np = scene.prim_count() as u32;
    // A leaf that references a primitive past the end.
    let corrupt = |accel: &mut Accel| match accel {
        Accel::Kd(t) => t.indices[0] = np,
        Accel::Bvh(t) => t.indices[0] = np,
        Accel::Bvh4(t) => t.indices[0] = np,
        Accel::Bvh8(t) => t.indices[0] = np,
        Accel::Cwbvh(t) => t.indices[0] = np,
        Accel::Grid(t) => {
            let i = t.indices.len() - 1;
            t.indices[i] = np;
        }
        Accel::Octree(t) => t.indices[0] = np,
        Accel::None(t) => t.bounds = arbor::math::Aabb::EMPTY,
        Accel::TwoLevel(_) => unreachable!("the blob has no instances"),
        Accel::RayQuery(_) => unreachable!("AccelKind::ALL is arbor's own structures"),
        Accel::Device(_) => unreachable!("Accel::build builds on the host"),
    };
    for &kind in AccelKind::ALL {
        let mut accel = Accel::build(kind, &scene);
        corrupt(&mut accel);
        let e = accel.validate(&scene).expect_err("corrupted");
        match kind {
            AccelKind::None => assert_eq!(e.site, Site::Whole, "{kind}: {e}"),
            AccelKind::Grid => assert!(matches!(e.site, Site::Cell(_)), "{kind}: {e}"),
            _ => assert!(matches!(e.site, Site::Node(_)), "{kind}: {e}"),
        }
        assert!(e.to_string().contains(&np.to_string()) || kind.is_brute_force(), "{kind}: {e}");
    }
}

#[test]
fn gpu_image_checks_the_kernel_limits() {
    let scene = Scene::load("builtin:blob:600").expect("blob");
    let mut kd = Accel::build(AccelKind::Kdtree, &scene);
    let mut bvh = Accel::build(AccelKind::BvhSah, &scene);
    let mut bvh4 = Accel::build(AccelKind::Bvh4, &scene);
    if let Accel::Bvh4(t) = &mut bvh4 {
        t.depth = arbor::accel::bvh::MAX_BVH_DEPTH + 1;
    }
    let mut cwbvh = Accel::build(AccelKind::Cwbvh, &scene);
    if let Accel::Cwbvh(t) = &mut cwbvh {
        t.depth = arbor::accel::bvh::MAX_BVH_DEPTH + 1;
    }
    if let Accel::Kd(t) = &mut kd {
        t.depth = arbor::accel::kdtree::MAX_KD_DEPTH + 1;
    }
    if let Accel::Bvh(t) = &mut bvh {
        t.depth = arbor::accel::bvh::MAX_BVH_DEPTH + 1;
    }
    for a in [kd, bvh, bvh4, cwbvh] {
        let e = a.gpu_image(&scene).expect_err("too deep");
        assert!(e.to_string().contains("exceeds the kernel's stack"), "{e}");
    }
}
