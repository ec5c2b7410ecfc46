//! `--accel auto`: the structure with the lowest expected build plus trace time for a
//! scene, an image size and a sample count, from a cost model whose constants were
//! measured with `arbor bench` on lavapipe (docs/auto.md).
//!
//! Model, per structure: `time = build_ns · N + rays · (trace_ns · (1 + 0.1 log2(N / 1e5)))`
//! for trees, and `rays · test_ns · N` for brute force; `rays` is pixels x samples x
//! (1 camera ray + one shadow ray per light + one bounce). Only the ranking matters,
//! so the constants need only be right relative to each other.

use super::AccelKind;
use crate::scene::Scene;

/// (kind, build ns per primitive, trace ns per ray at 100k primitives), measured with
/// `arbor bench --tris 100000,1000000 --size 1024x1024 --repeat 3 --accel
/// none,kdtree,bvh-sah,lbvh,trbvh,bvh4,grid,octree` on lavapipe (2 cores, 2 December
/// 2026, after the texel-buffer kernels): build as the mean of the first-build medians
/// per primitive at 100k and 1M triangles, trace as the median per camera ray at 100k.
/// bvh4 traced fastest there (100.9 against trbvh's 106.5 ns) but builds 3.4x slower:
/// lbvh wins at one sample, trbvh at a few, bvh4 once many samples repay its build.
const TREES: &[(AccelKind, f64, f64)] = &[
    (AccelKind::Kdtree, 2112.0, 142.5),
    (AccelKind::BvhSah, 700.0, 115.2),
    (AccelKind::Lbvh, 86.0, 115.7),
    (AccelKind::Trbvh, 215.0, 106.5),
    (AccelKind::Bvh4, 738.0, 100.9),
    (AccelKind::Grid, 194.0, 205.4),
    (AccelKind::Octree, 1105.0, 169.8),
];

/// Brute force: ns per primitive test (780.9 ms for 63x63 rays over 99,224
/// triangles in the same run).
const BRUTE_TEST_NS: f64 = 2.0;

/// The estimated cost of each candidate, cheapest first: (kind, ms).
///
/// With instances, builds cost per primitive stored (each instanced mesh once) and
/// rays per primitive drawn (brute force tests every copy).
pub fn estimates(scene: &Scene, pixels: u64, spp: u32) -> Vec<(AccelKind, f64)> {
    let spheres = scene.spheres.len() as f64;
    let n = (scene.drawn_triangles() as f64 + spheres).max(1.0);
    let stored = (scene.stored_triangles() as f64 + spheres).max(1.0);
    let rays_per_sample = 1.0 + scene.lights.len() as f64 + if scene.max_depth > 1 { 1.0 } else { 0.0 };
    let rays = pixels as f64 * f64::from(spp) * rays_per_sample;
    let mut out = vec![(AccelKind::None, rays * BRUTE_TEST_NS * n * 1e-6)];
    let depth_factor = (1.0 + 0.1 * (n / 1e5).log2()).max(0.3);
    for &(kind, build_ns, trace_ns) in TREES {
        out.push((kind, (build_ns * stored + rays * trace_ns * depth_factor) * 1e-6));
    }
    out.sort_by(|a, b| a.1.total_cmp(&b.1));
    out
}

/// The structure to use, and a sentence saying why.
pub fn choose(scene: &Scene, pixels: u64, spp: u32) -> (AccelKind, String) {
    let est = estimates(scene, pixels, spp);
    let (best, ms) = est[0];
    let runner = est.get(1).map(|(k, t)| format!(", then {k} at {t:.0} ms")).unwrap_or_default();
    let why = format!(
        "{} primitives, {pixels} pixels x {spp} spp: {best} expected fastest at {ms:.0} ms build + trace{runner} (cost model in src/accel/auto.rs)",
        scene.drawn_triangles() + scene.spheres.len() as u64
    );
    (best, why)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{procedural, SceneBuilder};

    fn scene(n: usize) -> Scene {
        let mut b = SceneBuilder::new("auto");
        b.mesh(&procedural::blob(n, 0.1, 1), 1.0, glam::Vec3::ZERO, None);
        b.finish().expect("scene")
    }

    #[test]
    fn brute_force_for_a_handful_and_a_tree_for_many() {
        let (k, why) = choose(&scene(10), 640 * 480, 1);
        assert_eq!(k, AccelKind::None, "{why}");
        // One sample: the fastest build; a few: trbvh's better tree repays its build;
        // many: the fastest tracer's slowest build pays off too.
        let (k, why) = choose(&scene(100_000), 640 * 480, 1);
        assert_eq!(k, AccelKind::Lbvh, "{why}");
        let (k, why) = choose(&scene(100_000), 640 * 480, 4);
        assert_eq!(k, AccelKind::Trbvh, "{why}");
        let (k, why) = choose(&scene(100_000), 1920 * 1080, 256);
        assert_eq!(k, AccelKind::Bvh4, "{why}");
    }
}
