//! SPPM's hash grid built on the device (src/photon/device.rs) equals the host's build
//! (`HashGrid::build`, itself checked against testing every point): the same box,
//! edge, cells, bucket starts, and the same points in every bucket; photons looked up
//! on the device, in the grid and in the kd-tree, find what testing every point finds.

use crate::common;
use crate::sampling::Rng;

use arbor::photon::{build_grid, tree_lookup_counts, upload_points, HashGrid, PointTree};
use glam::Vec3;

#[test]
fn the_device_builds_the_hosts_hash_grid() {
    let Some(ctx) = common::gpu() else { return };
    let mut rng = Rng(3);
    let mut sets: Vec<(&str, Vec<Vec3>, Vec<f32>)> = Vec::new();
    let n = 5000;
    let floor: Vec<Vec3> = (0..n).map(|_| Vec3::new(rng.next() * 4.0 - 2.0, 0.0, rng.next() * 4.0 - 2.0)).collect();
    let radii: Vec<f32> = (0..n).map(|_| 0.02 + rng.next() * 0.05).collect();
    sets.push(("floor", floor, radii));
    let cloud: Vec<Vec3> = (0..n).map(|_| Vec3::new(rng.next(), rng.next(), rng.next()) * 10.0).collect();
    let radii: Vec<f32> = (0..n).map(|_| 0.01 + rng.next() * rng.next()).collect();
    sets.push(("cloud", cloud, radii));
    sets.push(("one spot", vec![Vec3::new(1.0, 2.0, 3.0); 100], (0..100).map(|k| 0.01 + k as f32 * 1e-3).collect()));
    sets.push(("one point", vec![Vec3::splat(-1.5)], vec![0.25]));
    sets.push(("none", Vec::new(), Vec::new()));
    for (name, positions, radii) in sets {
        let host = HashGrid::build(&positions, &radii).expect("host build");
        let points = upload_points(&ctx, &positions, &radii).expect("upload");
        let grid = build_grid(&ctx, &points, positions.len() as u32).expect("device build");
        let device = grid.read_back(&ctx).expect("read back");
        assert_eq!(
            (device.min, device.max, device.edge, device.res),
            (host.min, host.max, host.edge, host.res),
            "{name}"
        );
        assert_eq!(device.starts, host.starts, "{name}: bucket starts");
        assert_eq!(device.entries, host.entries, "{name}: entries");
        if positions.len() >= n {
            assert!(host.entries.len() > positions.len(), "{name}: points span several cells");
        }
        // Photons near the points and anywhere around them find on the device what
        // testing every point finds.
        let mut queries: Vec<Vec3> = positions
            .iter()
            .zip(&radii)
            .take(2000)
            .map(|(&p, &r)| p + Vec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5) * (3.0 * r))
            .collect();
        queries.extend((0..1000).map(|_| Vec3::new(rng.next(), rng.next(), rng.next()) * 12.0 - Vec3::ONE));
        let found = grid.lookup_counts(&ctx, &points, &queries).expect("device lookups");
        // The kd-tree's lookup on the device finds the same.
        let tree = PointTree::build(&positions, &radii).expect("tree build");
        let in_tree = tree_lookup_counts(&ctx, &tree, &points, &queries).expect("device tree lookups");
        assert_eq!(in_tree, found, "{name}: the kd-tree and the grid on the device");
        let mut held = 0;
        for (q, f) in queries.iter().zip(&found) {
            let want = arbor::photon::brute_force(&positions, &radii, *q);
            let sum = want.iter().fold(0u32, |s, &i| s.wrapping_add(i + 1));
            assert_eq!(*f, [want.len() as u32, sum], "{name}: photon at {q}");
            held += want.len();
        }
        if positions.len() >= n {
            assert!(held > queries.len() / 2, "{name}: the photons near points find some");
        }
    }
    ctx.check_validation().expect("no validation errors");
}

#[test]
fn bad_points_are_refused_before_the_device_sees_them() {
    let Some(ctx) = common::gpu() else { return };
    let e = upload_points(&ctx, &[Vec3::ZERO], &[-1.0]).expect_err("a negative radius");
    assert!(e.to_string().contains("visible point 0 has radius -1"), "{e}");
    let points = upload_points(&ctx, &[Vec3::ZERO], &[1.0]).expect("upload");
    let too_many = arbor::photon::device::MAX_POINTS + 1;
    let e = build_grid(&ctx, &points, too_many).expect_err("more points than one build takes");
    assert!(e.to_string().contains("at most 4194304"), "{e}");
}
