//! BVHs (bvh-sah, lbvh, trbvh): validate() on edge cases, treelet restructuring never
//! raising the SAH cost, CPU traversal against brute force, identical builds for any
//! thread count, GPU against the CPU reference.

use crate::common;

use arbor::accel::bvh::{lbvh, treelet, Binary, Bvh, BvhBuilder, PrimRefs, EMPTY_REF, LEAF_REF, MAX_BVH_DEPTH};
use arbor::accel::sah::SahCosts;
use arbor::accel::{Accel, AccelKind, KernelFamily, Traverse};
use arbor::render::{cpu, RenderSettings};
use arbor::scene::procedural;
use common::scenes::{
    bvh_cases, compare_with_brute_force, edge_cases, gpu_cases, gpu_matches_reference, gpu_views, scene_from,
};
use glam::Vec3;

const BUILDERS: [BvhBuilder; 3] = [BvhBuilder::Sah, BvhBuilder::Lbvh, BvhBuilder::Trbvh];

#[test]
fn validate_every_builder_on_every_edge_case() {
    for scene in bvh_cases() {
        for b in BUILDERS {
            let t = Bvh::build(&scene, b);
            t.validate(&scene).unwrap_or_else(|e| panic!("{} / {}: {e}", scene.name, b.name()));
            assert!(t.depth <= MAX_BVH_DEPTH);
            let st = t.stats();
            assert_eq!(st.refs_per_prim, 1.0, "{} / {}", scene.name, b.name());
            assert!(st.sah_cost > 0.0 && st.sah_cost.is_finite(), "{} / {}: {}", scene.name, b.name(), st.sah_cost);
        }
    }
}

/// The BVHs' scene box, made from the primitive boxes, is the scene's own, bit for bit
/// (spheres, signed zeros, tiny and huge coordinates, no primitives).
#[test]
fn scene_box_from_primitive_boxes_is_the_scenes() {
    let mut scenes = bvh_cases();
    scenes.extend(edge_cases());
    let mut empty = edge_cases().remove(0);
    empty.triangles.clear();
    scenes.push(empty);
    scenes.push(scene_from(
        "signed zeros",
        Some(common::scenes::tris(&[[
            Vec3::new(-0.0, 0.0, 1.0),
            Vec3::new(0.0, -0.0, 2.0),
            Vec3::new(-0.0, 1.0, 0.0),
        ]])),
        &[(Vec3::new(0.0, 0.0, -0.0), 0.5)],
    ));
    for scene in &scenes {
        let (a, b) = (PrimRefs::new(scene).scene_box(), scene.bounds());
        let bits = |x: &arbor::math::Aabb| [x.min.to_array(), x.max.to_array()].map(|v| v.map(f32::to_bits));
        assert_eq!(bits(&a), bits(&b), "{}", scene.name);
    }
}

#[test]
fn empty_scene_builds_a_root_with_no_children() {
    let mut scene = edge_cases().remove(0);
    scene.triangles.clear();
    for b in BUILDERS {
        let t = Bvh::build(&scene, b);
        t.validate(&scene).unwrap_or_else(|e| panic!("empty / {}: {e}", b.name()));
        assert_eq!(t.nodes.len(), 1);
        assert_eq!(t.children(0).map(|(r, _)| r), [EMPTY_REF, EMPTY_REF]);
        let ray = arbor::math::Ray { origin: Vec3::ZERO, dir: Vec3::X, tmin: 0.0, tmax: f32::INFINITY };
        assert!(t.intersect(&scene, &ray).is_none());
    }
}

#[test]
fn restructuring_never_raises_sah_and_keeps_every_primitive() {
    let costs = SahCosts::default();
    let mut scenes = bvh_cases();
    scenes.push(scene_from("blob", Some(procedural::blob(20_000, 0.2, 5)), &[(Vec3::ZERO, 0.6)]));
    for (scene, leaves) in scenes.into_iter().flat_map(|s| [3usize, 5, 7].map(|l| (s.clone(), l))) {
        let refs = PrimRefs::new(&scene);
        let mut phases = Vec::new();
        let mut t = std::time::Instant::now();
        let mut bin = lbvh::build_fitted(&refs, &mut phases, &mut t);
        let mut work = treelet::Restructure::with_leaves(&bin, &costs, leaves);
        let tp = treelet::TreeletParams { leaves, ..Default::default() };
        let mut before = bin.sah_cost(&costs, true);
        let start = before;
        for round in 0..tp.rounds {
            let rs = work.round(tp.gamma(round));
            assert!(rs.rewritten <= rs.optimised, "{}: {rs:?}", scene.name);
            if round == 0 {
                // Nothing is settled before the first round.
                assert_eq!(rs.skipped, 0, "{}", scene.name);
            }
            work.write_back(&mut bin);
            let after = bin.sah_cost(&costs, true);
            assert!(after <= before * (1.0 + 1e-5), "{} round {round}: {before} -> {after}", scene.name);
            // The incremental cost agrees with a recomputation.
            let inc = work.root_cost();
            assert!((inc - after).abs() <= 1e-3 * after.max(1e-30), "{}: {inc} vs {after}", scene.name);
            before = after;
            let mut all = Vec::new();
            bin.gather(bin.root, &mut all);
            all.sort_unstable();
            assert_eq!(all, (0..scene.prim_count() as u32).collect::<Vec<_>>(), "{}", scene.name);
            check_boxes(&bin);
        }
        if scene.name == "blob" {
            assert!(before < start * 0.97, "{leaves}-leaf treelets should improve a 20k LBVH: {start} -> {before}");
        }
    }
}

/// Every inner node's box is the union of its children's.
fn check_boxes(bin: &Binary) {
    for (i, n) in bin.nodes.iter().enumerate() {
        if !n.is_leaf() {
            let u = bin.nodes[n.left as usize].bounds.union(&bin.nodes[n.right as usize].bounds);
            assert_eq!(u, n.bounds, "node {i}");
        }
    }
}

#[test]
fn trbvh_is_close_to_bvh_sah_and_better_than_lbvh() {
    let scene = scene_from("blob", Some(procedural::blob(30_000, 0.25, 3)), &[]);
    let sah = Bvh::build(&scene, BvhBuilder::Sah).stats().sah_cost;
    let lb = Bvh::build(&scene, BvhBuilder::Lbvh).stats().sah_cost;
    let tr = Bvh::build(&scene, BvhBuilder::Trbvh).stats().sah_cost;
    assert!(tr < lb, "trbvh {tr} vs lbvh {lb}");
    assert!(tr < sah * 1.10, "trbvh {tr} vs bvh-sah {sah}");
}

#[test]
fn cpu_traversal_equals_brute_force() {
    for scene in bvh_cases() {
        for b in BUILDERS {
            let t = Bvh::build(&scene, b);
            compare_with_brute_force(&scene, &Accel::Bvh(t), 1500, 42, &[]);
        }
    }
}

/// What every collapse into wide nodes keeps: the binary tree's index array and leaves,
/// no more nodes than the binary tree, and a free slot only in a node whose children
/// are all leaves (nothing left to open).
fn assert_collapsed<const W: usize>(
    name: &str,
    bin: &Bvh,
    indices: &[u32],
    node_count: usize,
    children: impl Fn(usize) -> [(u32, arbor::math::Aabb); W],
) {
    assert_eq!(indices, bin.indices, "{name}");
    assert!(node_count <= bin.nodes.len(), "{name}");
    let leaves = |refs: Vec<u32>| {
        let mut l: Vec<u32> = refs.into_iter().filter(|r| *r != EMPTY_REF && r & LEAF_REF != 0).collect();
        l.sort_unstable();
        l
    };
    let bin_refs = (0..bin.nodes.len()).flat_map(|n| bin.children(n).map(|c| c.0)).collect();
    let wide_refs = (0..node_count).flat_map(|n| children(n).map(|c| c.0)).collect();
    assert_eq!(leaves(wide_refs), leaves(bin_refs), "{name}: leaves differ");
    for n in 0..node_count {
        let kids = children(n);
        if kids.iter().any(|c| c.0 == EMPTY_REF) {
            assert!(
                kids.iter().all(|c| c.0 == EMPTY_REF || c.0 & LEAF_REF != 0),
                "{name}: node {n} has a free slot and an inner child"
            );
        }
    }
}

fn check_wide<const W: usize>() {
    use arbor::accel::bvh::wide::WideBvh;
    for scene in bvh_cases() {
        for b in BUILDERS {
            let bin = Bvh::build(&scene, b);
            let wide = WideBvh::<W>::collapse(&bin);
            wide.validate(&scene).unwrap_or_else(|e| panic!("{} {} {W}: {e}", scene.name, b.name()));
            assert_collapsed(&scene.name, &bin, &wide.indices, wide.node_count(), |n| wide.children(n));
            assert!(wide.depth <= bin.depth && WideBvh::<W>::WIDTH == W);
            let accel = if W == 4 {
                Accel::Bvh4(arbor::accel::bvh::wide::Bvh4::collapse(&bin))
            } else {
                Accel::Bvh8(arbor::accel::bvh::wide::Bvh8::collapse(&bin))
            };
            compare_with_brute_force(&scene, &accel, 800, 7, &[]);
        }
    }
}

#[test]
fn bvh4_and_bvh8_keep_the_binary_leaves_in_fewer_wider_nodes() {
    check_wide::<4>();
    check_wide::<8>();
}

#[test]
fn bvh4_validate_finds_a_child_box_that_does_not_contain_its_subtree() {
    use arbor::accel::bvh::wide::Bvh4;
    let scene = scene_from("blob", Some(procedural::blob(2000, 0.25, 5)), &[]);
    let mut wide = Bvh4::build(&scene, BvhBuilder::Sah);
    wide.validate(&scene).expect("valid");
    // Shrink child 0's box of the root to a point: its subtree sticks out (node 0's
    // rows are its first 7 texels, one per row at width 4).
    for row in 0..6 {
        wide.nodes[row][0] = 0.0f32.to_bits();
    }
    let e = wide.validate(&scene).expect_err("a shrunken box must be found");
    assert!(e.to_string().contains("does not contain"), "{e}");
}

#[test]
fn cwbvh_keeps_the_binary_leaves_under_quantised_boxes_that_contain_them() {
    use arbor::accel::bvh::cwbvh::{Cwbvh, WIDTH};
    for scene in bvh_cases() {
        for b in BUILDERS {
            let bin = Bvh::build(&scene, b);
            let wide = Cwbvh::collapse(&bin);
            wide.validate(&scene).unwrap_or_else(|e| panic!("{} {}: {e}", scene.name, b.name()));
            assert_collapsed(&scene.name, &bin, &wide.indices, wide.nodes.len(), |n| wide.children(n));
            for n in 0..wide.nodes.len() {
                let kids = wide.children(n);
                // The decoded box contains the exact one (validate) and is no more than
                // about one grid step per side larger (255 steps span the node).
                for (k, (r, decoded)) in kids.iter().enumerate() {
                    if *r == EMPTY_REF {
                        continue;
                    }
                    let exact = wide.exact[n][k];
                    let node_box = wide.exact[n].iter().fold(arbor::math::Aabb::EMPTY, |a, b| a.union(b));
                    let slack = (node_box.max - node_box.min) * (2.0 / 255.0) + Vec3::splat(1e-30);
                    assert!(
                        (exact.min - decoded.min).cmple(slack + exact.min.abs() * 1e-6).all()
                            && (decoded.max - exact.max).cmple(slack + exact.max.abs() * 1e-6).all(),
                        "{}: node {n} child {k}: {decoded:?} is loose around {exact:?}",
                        scene.name
                    );
                }
            }
            assert!(wide.depth <= bin.depth && WIDTH == 8);
            compare_with_brute_force(&scene, &Accel::Cwbvh(wide), 800, 7, &[]);
        }
    }
}

#[test]
fn cwbvh_validate_finds_a_quantised_box_that_does_not_contain_its_exact_box() {
    use arbor::accel::bvh::cwbvh::Cwbvh;
    let scene = scene_from("blob", Some(procedural::blob(2000, 0.25, 5)), &[]);
    let mut wide = Cwbvh::build(&scene, BvhBuilder::Sah);
    wide.validate(&scene).expect("valid");
    // Child 0's qhi x (texel 2, third word, byte 0) to 0: its box ends at the grid origin.
    wide.nodes[0][2][2] &= !0xff;
    let e = wide.validate(&scene).expect_err("a shrunken box must be found");
    assert!(e.to_string().contains("does not contain"), "{e}");
    // A grid exponent of zero (a denormal step) is refused by itself.
    let mut wide = Cwbvh::build(&scene, BvhBuilder::Sah);
    wide.nodes[0][0][3] &= !0xff;
    let e = wide.validate(&scene).expect_err("exponent 0");
    assert!(e.to_string().contains("exponent"), "{e}");
}

#[test]
fn build_is_identical_for_any_thread_count() {
    let scene = scene_from("blob", Some(procedural::blob(150_000, 0.2, 9)), &[(Vec3::ZERO, 0.7)]);
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
    let four = rayon::ThreadPoolBuilder::new().num_threads(4).build().expect("pool");
    for b in BUILDERS {
        let x = one.install(|| Bvh::build(&scene, b));
        let y = four.install(|| Bvh::build(&scene, b));
        assert_eq!(x.nodes, y.nodes, "{}", b.name());
        assert_eq!(x.indices, y.indices, "{}", b.name());
    }
}

#[test]
fn gpu_equals_cpu_for_every_builder() {
    let Some(ctx) = common::gpu() else { return };
    for scene in gpu_cases().iter().flat_map(gpu_views) {
        let reference = cpu::reference_aovs(&scene, 48, 40);
        for kind in [AccelKind::BvhSah, AccelKind::Lbvh, AccelKind::Trbvh] {
            let mut s = RenderSettings::for_size(48, 40);
            s.accel = kind;
            let what = format!("{} {kind}", scene.name);
            let (_, st) = gpu_matches_reference(&ctx, &scene, &s, &reference, KernelFamily::Bvh, &what);
            if scene.prim_count() > 1000 {
                let tested = st.mean_prims_tested.expect("BVH kernels count tests");
                assert!(tested < scene.prim_count() as f64 / 10.0, "{what}: {tested}");
            }
        }
    }
}
