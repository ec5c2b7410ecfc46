//! kd-tree: validate() on every preset and edge case, CPU traversal against brute
//! force on random and adversarial rays, GPU against CPU.

use crate::common;

use common::scenes::{self, edge_cases, gpu_cases, gpu_matches_reference, gpu_views, scene_from, tris};

use arbor::accel::kdtree::{KdParams, KdTree, MAX_KD_DEPTH};
use arbor::accel::{Accel, AccelKind, KernelFamily};
use arbor::math::Ray;
use arbor::render::{cpu, RenderSettings};
use arbor::scene::{procedural, Scene};
use glam::Vec3;

fn presets() -> Vec<(&'static str, KdParams)> {
    vec![
        ("default", KdParams::default()),
        ("quality", KdParams::quality()),
        ("fast", KdParams::fast()),
        ("shallow", KdParams { max_depth: Some(3), ..KdParams::default() }),
        ("big leaves", KdParams { leaf_size: 16, ..KdParams::default() }),
    ]
}

#[test]
fn validate_every_preset_on_every_edge_case() {
    for scene in edge_cases() {
        for (pname, p) in presets() {
            let t = KdTree::build(&scene, &p);
            t.validate(&scene).unwrap_or_else(|e| panic!("{} / {pname}: {e}", scene.name));
            assert!(t.depth <= p.depth_limit(scene.prim_count()), "{} / {pname}: depth {}", scene.name, t.depth);
        }
        let c = KdTree::build_course(&scene);
        c.validate(&scene).unwrap_or_else(|e| panic!("{} / bsp-course: {e}", scene.name));
        assert!(c.depth <= 20);
    }
}

#[test]
fn deep_trees_are_built_and_traversed() {
    // Triangles at geometrically shrinking distances from the origin, each cut off
    // by its own split: a tree deeper than the lecture's 20 levels.
    let mut list = Vec::new();
    for i in 0..36 {
        let x = 0.5f32.powi(i);
        let s = x * 0.1;
        for k in 0..3 {
            let y = k as f32 * 2.0 * s;
            list.push([Vec3::new(x, y, 0.0), Vec3::new(x + s, y, 0.0), Vec3::new(x, y + s, s)]);
        }
    }
    let scene = scene_from("line", Some(tris(&list)), &[]);
    let t = KdTree::build(&scene, &KdParams { max_depth: Some(40), ..KdParams::quality() });
    t.validate(&scene).expect("valid");
    assert!(t.depth > 20, "depth {}", t.depth);
    assert!(t.depth <= MAX_KD_DEPTH);
    compare_with_brute_force(&scene, &t, 2000, 7);
}

#[test]
fn build_is_identical_for_any_thread_count() {
    let scene = scene_from("blob", Some(procedural::blob(20_000, 0.2, 9)), &[(Vec3::ZERO, 0.7)]);
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
    let four = rayon::ThreadPoolBuilder::new().num_threads(4).build().expect("pool");
    let a = one.install(|| KdTree::build(&scene, &KdParams::default()));
    let b = four.install(|| KdTree::build(&scene, &KdParams::default()));
    assert_eq!(a.nodes, b.nodes);
    assert_eq!(a.indices, b.indices);
}

/// Brute-force comparison with rays through the root's split plane added.
fn compare_with_brute_force(scene: &Scene, tree: &KdTree, n: usize, seed: u64) {
    let b = scene.bounds();
    let c = b.center();
    let r = b.extent().length().max(1e-30);
    let mut extra = Vec::new();
    let [w0, w1] = tree.nodes[0];
    if w1 & 3 != 3 {
        let axis = (w1 & 3) as usize;
        let mut o = c + Vec3::splat(r * 2.0);
        o[axis] = f32::from_bits(w0);
        let mut d = -Vec3::ONE;
        d[axis] = 0.0;
        extra.push(Ray { origin: o, dir: d.normalize(), tmin: 0.0, tmax: f32::INFINITY });
        let mut d2 = -Vec3::ONE;
        d2[axis] = -0.0;
        extra.push(Ray { origin: o, dir: d2.normalize(), tmin: 0.0, tmax: f32::INFINITY });
    }
    scenes::compare_with_brute_force(scene, &Accel::Kd(tree.clone()), n, seed, &extra);
}

#[test]
fn cpu_traversal_equals_brute_force() {
    for scene in edge_cases() {
        for (pname, p) in presets() {
            let t = KdTree::build(&scene, &p);
            let _ = pname;
            compare_with_brute_force(&scene, &t, 1500, 42);
        }
        // The lecture's builder turns 50 identical triangles into a complete tree of
        // 2^20 leaves (it splits until 20 levels whenever a leaf holds more than 4),
        // and a ray lying in their plane visits all of it: fewer rays there.
        let n = if scene.name == "identical" { 100 } else { 1500 };
        compare_with_brute_force(&scene, &KdTree::build_course(&scene), n, 43);
    }
}

#[test]
fn gpu_equals_cpu_for_kd_trees() {
    let Some(ctx) = common::gpu() else { return };
    for scene in gpu_cases().iter().flat_map(gpu_views) {
        let reference = cpu::reference_aovs(&scene, 48, 40);
        for kind in [AccelKind::Kdtree, AccelKind::BspCourse] {
            let mut s = RenderSettings::for_size(48, 40);
            s.accel = kind;
            let what = format!("{} {kind}", scene.name);
            let (_, st) = gpu_matches_reference(&ctx, &scene, &s, &reference, KernelFamily::Kdtree, &what);
            // Trees visit far fewer primitives than brute force.
            if scene.prim_count() > 1000 {
                let tested = st.mean_prims_tested.expect("kd-tree kernels count tests");
                assert!(tested < scene.prim_count() as f64 / 10.0, "{what}: {tested}");
            }
        }
    }
}
