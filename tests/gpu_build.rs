//! The GPU BVH build (`--build gpu`): its trees equal the CPU builders' word for word
//! (so the same SAH cost and the same restructuring gains), pass validate(), and trace
//! like brute force, on edge cases and large meshes, on lavapipe with validation.

mod common;

use arbor::accel::bvh::gpu_build::GpuBuilder;
use arbor::accel::bvh::treelet::TreeletParams;
use arbor::accel::bvh::{Bvh, BvhBuilder};
use arbor::accel::params::Params;
use arbor::accel::{Accel, KernelFamily};
use arbor::scene::{procedural, Scene};
use common::scenes::{bvh_cases, compare_with_brute_force, scene_from, tris};
use glam::Vec3;

/// The BVH tests' edge cases, three primitives, and a 20k-triangle blob.
fn cases() -> Vec<Scene> {
    let v = Vec3::new;
    let mut out = bvh_cases();
    out.push(scene_from(
        "three",
        Some(tris(&[
            [v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)],
            [v(0., 0., 2.), v(1., 0., 2.), v(0., 1., 2.)],
            [v(5., 0., 2.), v(6., 0., 2.), v(5., 1., 2.)],
        ])),
        &[],
    ));
    out.push(scene_from("blob 20k", Some(procedural::blob(20_000, 0.3, 7)), &[]));
    out
}

fn assert_same(scene: &Scene, gpu: &Bvh, cpu: &Bvh) {
    let what = format!("{} ({})", scene.name, cpu.builder.name());
    assert_eq!(gpu.depth, cpu.depth, "{what}: depth");
    assert_eq!(gpu.nodes.len(), cpu.nodes.len(), "{what}: node count");
    if let Some(i) = gpu.nodes.iter().zip(&cpu.nodes).position(|(a, b)| a != b) {
        panic!("{what}: node {i} differs: GPU {:x?} CPU {:x?}", gpu.nodes[i], cpu.nodes[i]);
    }
    assert_eq!(gpu.indices, cpu.indices, "{what}: indices");
}

#[test]
fn gpu_builds_equal_cpu_builds() {
    let Some(ctx) = common::gpu() else { return };
    let mut builder = GpuBuilder::new(&ctx).expect("pipelines");
    for scene in cases() {
        for (b, tp) in [
            (BvhBuilder::Lbvh, TreeletParams::default()),
            (BvhBuilder::Trbvh, TreeletParams::default()),
            (BvhBuilder::Trbvh, TreeletParams::parse("leaves=5,gamma=1/2/1/4").expect("parameters")),
        ] {
            let cpu = Bvh::build_with(&scene, b, &tp);
            let gpu = builder.build(&ctx, &scene, b, &tp).unwrap_or_else(|e| panic!("{}: {e}", scene.name));
            gpu.validate(&scene).unwrap_or_else(|e| panic!("{} {}: {e}", scene.name, b.name()));
            assert_same(&scene, &gpu, &cpu);
            let (gs, cs) = (gpu.stats().sah_cost, cpu.stats().sah_cost);
            assert_eq!(gs, cs, "{}: SAH", scene.name);
        }
    }
}

#[test]
fn gpu_built_trees_trace_like_brute_force() {
    let Some(ctx) = common::gpu() else { return };
    let mut builder = GpuBuilder::new(&ctx).expect("pipelines");
    let v = Vec3::new;
    let scenes = [
        scene_from(
            "blob and spheres",
            Some(procedural::blob(3000, 0.3, 5)),
            &[(v(1.2, 0., 0.), 0.3), (v(0., 0., 0.), 0.5)],
        ),
        scene_from("spheres only", None, &[(v(0., 0., 0.), 1.0), (v(2., 0., 0.), 0.5), (v(0., 3., 0.), 0.25)]),
    ];
    for scene in &scenes {
        for b in [BvhBuilder::Lbvh, BvhBuilder::Trbvh] {
            let bvh = builder.build(&ctx, scene, b, &TreeletParams::default()).expect("build");
            bvh.validate(scene).unwrap_or_else(|e| panic!("{}: {e}", scene.name));
            compare_with_brute_force(scene, &Accel::Bvh(bvh), 4000, 23, &[]);
        }
    }
}

/// A million triangles: equal to the CPU build, and restructuring lowers the SAH cost
/// by the same amount on both.
#[test]
fn million_triangles_equal_cpu_build() {
    let Some(ctx) = common::gpu() else { return };
    let mut builder = GpuBuilder::new(&ctx).expect("pipelines");
    let scene = scene_from("blob 1M", Some(procedural::blob(1_000_000, 0.3, 3)), &[]);
    assert!(scene.triangles.len() >= 990_000);
    let tp = TreeletParams::default();
    let gpu_l = builder.build(&ctx, &scene, BvhBuilder::Lbvh, &tp).expect("gpu lbvh");
    let gpu_t = builder.build(&ctx, &scene, BvhBuilder::Trbvh, &tp).expect("gpu trbvh");
    let cpu_l = Bvh::build_with(&scene, BvhBuilder::Lbvh, &tp);
    let cpu_t = Bvh::build_with(&scene, BvhBuilder::Trbvh, &tp);
    assert_same(&scene, &gpu_l, &cpu_l);
    assert_same(&scene, &gpu_t, &cpu_t);
    gpu_t.validate(&scene).expect("valid");
    let (l, t) = (gpu_l.stats().sah_cost, gpu_t.stats().sah_cost);
    assert!(t < l * 0.95, "restructuring lowered the SAH cost only from {l} to {t}");
    // The GPU phases were timed and are named.
    let names: Vec<&str> = gpu_t.phases.iter().map(|p| p.name.as_str()).collect();
    for want in ["gpu morton", "gpu sort", "gpu hierarchy + fit", "gpu restructure round 3", "gpu emit"] {
        assert!(!ctx.has_timestamps() || names.contains(&want), "phase {want} missing from {names:?}");
    }
}

#[test]
fn gpu_built_tree_renders_like_the_cpu_reference() {
    use arbor::accel::{AccelKind, AccelParams, BuildOn};
    use arbor::render::{cpu, RenderSettings};
    let Some(ctx) = common::gpu() else { return };
    for scene in common::scenes::gpu_cases() {
        let reference = cpu::reference_aovs(&scene, 48, 40);
        for kind in [AccelKind::Lbvh, AccelKind::Trbvh] {
            let mut settings = RenderSettings::for_size(48, 40);
            settings.accel = kind;
            settings.params = AccelParams { build: BuildOn::Gpu, ..Default::default() };
            let what = format!("{} {kind} built on the GPU", scene.name);
            common::scenes::gpu_matches_reference(&ctx, &scene, &settings, &reference, KernelFamily::Bvh, &what);
        }
    }
}

#[test]
fn gpu_build_of_other_structures_is_a_clear_error() {
    use arbor::accel::{AccelKind, AccelParams, BuildOn};
    let Some(ctx) = common::gpu() else { return };
    let scene = scene_from("blob", Some(procedural::blob(500, 0.3, 5)), &[]);
    let params = AccelParams { build: BuildOn::Gpu, ..Default::default() };
    for kind in [AccelKind::Kdtree, AccelKind::BvhSah, AccelKind::Grid] {
        let e = Accel::build_on(&ctx, kind, &scene, &params).expect_err("refused");
        assert!(e.to_string().contains("--build gpu builds lbvh and trbvh"), "{e}");
    }
}
