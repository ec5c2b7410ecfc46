//! `--accel auto`: the structure, and where to build it, with the lowest expected build
//! plus trace time for a scene, an image size and a sample count, from a cost model
//! whose constants were measured on this device by `arbor calibrate`
//! ([`super::calibrate`]) or, without that, with `arbor bench` on lavapipe (the
//! built-in ones below; docs/auto.md), among those whose buffers fit the device
//! ([`choose_on`]).
//!
//! Model, per structure: `time = build_ns · N + rays · (trace_ns · (1 + 0.1 log2(N / 1e5)))`
//! for trees, and `rays · test_ns · N` for brute force; `rays` is pixels x samples x
//! (1 camera ray + one shadow ray per light + one bounce). Only the ranking matters,
//! so the constants need only be right relative to each other.

use super::{AccelKind, BuildOn};
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
    // Not in that run: scaled from bvh4 by the ratios of `arbor bench --tris
    // 100000,1000000 --size 1024x1024 --repeat 3 --accel lbvh,trbvh,bvh4,bvh8,cwbvh`
    // (6 December 2026; builds 1.05x bvh4's, traces 1.5x and 1.45x on lavapipe, where
    // subgroups of 8 lanes gain nothing from wider nodes). Candidates for their size.
    (AccelKind::Bvh8, 775.0, 151.0),
    (AccelKind::Cwbvh, 775.0, 146.0),
    (AccelKind::Grid, 194.0, 205.4),
    (AccelKind::Octree, 1105.0, 169.8),
];

/// Brute force: ns per primitive test (780.9 ms for 63x63 rays over 99,224
/// triangles in the same run).
const BRUTE_TEST_NS: f64 = 2.0;

/// One candidate's constants: a structure built on the CPU or the device, its build
/// ns per primitive and its trace ns per ray at 100k primitives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TreeCost {
    /// The structure.
    pub kind: AccelKind,
    /// Where it is built.
    pub build: BuildOn,
    /// Build time per primitive, ns.
    pub build_ns: f64,
    /// Trace time per ray at 100k primitives, ns.
    pub trace_ns: f64,
}

/// The cost model's constants and where they come from.
#[derive(Debug, Clone, PartialEq)]
pub struct Costs {
    /// Every tree candidate.
    pub trees: Vec<TreeCost>,
    /// Brute force: ns per primitive test.
    pub brute_test_ns: f64,
    /// Where they were measured, for the `accel auto:` line.
    pub source: String,
}

impl Costs {
    /// The built-in constants (lavapipe, CPU builds only).
    pub fn builtin() -> Costs {
        Costs {
            trees: TREES
                .iter()
                .map(|&(kind, build_ns, trace_ns)| TreeCost { kind, build: BuildOn::Cpu, build_ns, trace_ns })
                .collect(),
            brute_test_ns: BRUTE_TEST_NS,
            source: "built-in costs measured on lavapipe; `arbor calibrate` measures this device's".into(),
        }
    }
}

/// A structure and where to build it.
pub type Candidate = (AccelKind, BuildOn);

/// The estimated cost of each candidate of `costs`, cheapest first (ms); with `build`,
/// only those built there. Device builds are no candidates for instanced scenes.
///
/// With instances, builds cost per primitive stored (each instanced mesh once) and
/// rays per primitive drawn (brute force tests every copy).
pub fn estimates_with(
    scene: &Scene,
    pixels: u64,
    spp: u32,
    costs: &Costs,
    build: Option<BuildOn>,
) -> Vec<(Candidate, f64)> {
    let spheres = scene.spheres.len() as f64;
    let n = (scene.drawn_triangles() as f64 + spheres).max(1.0);
    let stored = (scene.stored_triangles() as f64 + spheres).max(1.0);
    let rays_per_sample = 1.0 + scene.lights.len() as f64 + if scene.max_depth > 1 { 1.0 } else { 0.0 };
    let rays = pixels as f64 * f64::from(spp) * rays_per_sample;
    let mut out = Vec::new();
    if build != Some(BuildOn::Gpu) {
        out.push(((AccelKind::None, BuildOn::Cpu), rays * costs.brute_test_ns * n * 1e-6));
    }
    let depth_factor = (1.0 + 0.1 * (n / 1e5).log2()).max(0.3);
    // Device builds asked for but never measured: the CPU builds of the kinds the
    // device builds stand in (the device builds the same trees).
    let measured = costs.trees.iter().any(|t| t.build == BuildOn::Gpu);
    let stand_ins: Vec<TreeCost> = if build == Some(BuildOn::Gpu) && !measured {
        costs.trees.iter().filter(|t| t.kind.builds_on_gpu()).map(|t| TreeCost { build: BuildOn::Gpu, ..*t }).collect()
    } else {
        Vec::new()
    };
    for t in costs.trees.iter().chain(&stand_ins) {
        if build.is_some_and(|b| b != t.build) || (t.build == BuildOn::Gpu && scene.has_instances()) {
            continue;
        }
        out.push(((t.kind, t.build), (t.build_ns * stored + rays * t.trace_ns * depth_factor) * 1e-6));
    }
    out.sort_by(|a, b| a.1.total_cmp(&b.1));
    out
}

/// The estimated cost of each structure built on the CPU with the built-in constants,
/// cheapest first: (kind, ms).
pub fn estimates(scene: &Scene, pixels: u64, spp: u32) -> Vec<(AccelKind, f64)> {
    let est = estimates_with(scene, pixels, spp, &Costs::builtin(), Some(BuildOn::Cpu));
    est.into_iter().map(|((k, _), t)| (k, t)).collect()
}

/// The structure to use, and a sentence saying why, before the device is known: the
/// built-in constants, CPU builds.
pub fn choose(scene: &Scene, pixels: u64, spp: u32) -> (AccelKind, String) {
    choose_built(scene, pixels, spp, BuildOn::Cpu).expect("brute force is always a CPU candidate")
}

/// [`choose`] among the structures built on `build` (for `--build gpu`: lbvh, trbvh,
/// bvh4 and bvh8 of a scene without instances).
pub fn choose_built(scene: &Scene, pixels: u64, spp: u32, build: BuildOn) -> crate::error::Result<(AccelKind, String)> {
    let costs = Costs::builtin();
    let est = estimates_with(scene, pixels, spp, &costs, Some(build));
    let Some(&((kind, _), _)) = est.first() else { return Err(no_device_build()) };
    Ok((kind, why(scene, pixels, spp, &est, "", &costs)))
}

fn no_device_build() -> crate::error::Error {
    crate::error::Error::Usage(
        "--accel auto --build gpu: the device builds no structure of an instanced scene; use --build cpu, or --flatten with a structure named (--accel lbvh)"
            .into(),
    )
}

/// A candidate as the `accel auto:` line names it: `lbvh`, or `lbvh built on the device`.
fn named((kind, build): Candidate) -> String {
    match build {
        BuildOn::Cpu => kind.to_string(),
        BuildOn::Gpu => format!("{kind} built on the device"),
    }
}

fn why(scene: &Scene, pixels: u64, spp: u32, est: &[(Candidate, f64)], dropped: &str, costs: &Costs) -> String {
    let (best, ms) = est[0];
    let runner = est.get(1).map(|&(c, t)| format!(", then {} at {t:.0}", named(c))).unwrap_or_default();
    format!(
        "{} primitives, {pixels} pixels x {spp} spp: {} ranked fastest (model cost {ms:.0}{runner}: a ranking, not a forecast of the render's time){dropped} ({}; docs/auto.md)",
        scene.drawn_triangles() + scene.spheres.len() as u64,
        named(best),
        costs.source
    )
}

/// What a structure must fit on a device: the most bytes one of its buffers may hold
/// (its nodes and its indices are each bound as a texel buffer) and the device's
/// memory, which holds the scene's geometry too.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fit {
    /// The most bytes one buffer of the structure may hold.
    pub buffer_bytes: u64,
    /// The device's memory for the structure and the scene's geometry.
    pub memory_bytes: u64,
}

impl Fit {
    /// The limits of `ctx`'s device.
    pub fn of(ctx: &crate::gpu::Context) -> Fit {
        Fit { buffer_bytes: ctx.binding_limit(crate::gpu::BindingKind::Texel), memory_bytes: ctx.device_memory() }
    }
}

/// Device bytes per stored primitive of each structure (nodes and indices together),
/// from `arbor info builtin:blob:N --accel K` at 100k and 1M triangles (the larger of
/// the two); those whose references per primitive depend on the scene (kd-tree, grid,
/// octree) with room for more.
const BYTES_PER_PRIM: &[(AccelKind, f64)] = &[
    (AccelKind::None, 0.0),
    (AccelKind::Kdtree, 36.0),
    (AccelKind::BvhSah, 38.8),
    (AccelKind::Lbvh, 68.0),
    (AccelKind::Trbvh, 39.1),
    (AccelKind::Bvh4, 35.0),
    (AccelKind::Bvh8, 49.2),
    (AccelKind::Cwbvh, 23.4),
    (AccelKind::Grid, 27.0),
    (AccelKind::Octree, 64.0),
];

/// The estimated device bytes of `kind`'s structure over `scene`, or None for a kind
/// the model does not size.
pub fn structure_bytes(kind: AccelKind, scene: &Scene) -> Option<u64> {
    let stored = scene.stored_triangles() as f64 + scene.spheres.len() as f64;
    BYTES_PER_PRIM.iter().find(|(k, _)| *k == kind).map(|(_, b)| (b * stored * 1.05) as u64)
}

/// Device bytes of the scene's geometry: vertices (32 bytes), triangles (16), spheres
/// (32).
fn geometry_bytes(scene: &Scene) -> u64 {
    32 * scene.positions.len() as u64 + 16 * scene.stored_triangles() + 32 * scene.spheres.len() as u64
}

/// The pick on a device: the candidates of `costs` (with `build`, only those built
/// there) whose buffers fit `fit`, cheapest first. An error, naming the smallest
/// structure's need and the device's limit, when no structure that could trace the
/// scene in reasonable time fits (brute force stands in only where it was the pick
/// anyway).
pub fn choose_on(
    scene: &Scene,
    pixels: u64,
    spp: u32,
    fit: &Fit,
    costs: &Costs,
    build: Option<BuildOn>,
) -> crate::error::Result<(Candidate, String)> {
    let all = estimates_with(scene, pixels, spp, costs, build);
    if all.is_empty() {
        return Err(no_device_build());
    }
    // Geometry that does not fit fails whatever the structure, at its upload, which
    // names the buffer.
    let buffers = [32 * scene.positions.len() as u64, 16 * scene.stored_triangles(), 32 * scene.spheres.len() as u64];
    if buffers.iter().any(|&b| b > fit.buffer_bytes) {
        return Ok((all[0].0, why(scene, pixels, spp, &all, "", costs)));
    }
    let geometry = geometry_bytes(scene);
    let fits = |k: AccelKind| {
        structure_bytes(k, scene).is_some_and(|b| b <= fit.buffer_bytes && b + geometry <= fit.memory_bytes)
    };
    let kept: Vec<(Candidate, f64)> = all.iter().copied().filter(|&((k, _), _)| fits(k)).collect();
    let usable = kept.first().is_some_and(|&((k, _), _)| k != AccelKind::None || all[0].0 .0 == AccelKind::None);
    if !usable {
        let (smallest, need) = BYTES_PER_PRIM
            .iter()
            .filter(|(k, _)| *k != AccelKind::None)
            .filter_map(|&(k, _)| structure_bytes(k, scene).map(|b| (k, b)))
            .min_by_key(|&(_, b)| b)
            .unwrap_or((AccelKind::Cwbvh, 0));
        return Err(crate::error::Error::Failed(format!(
            "--accel auto: no structure fits this device: the smallest, {smallest}, needs about {need} bytes in one buffer and {} with the geometry; the device allows {} bytes per buffer and has {} bytes of memory",
            need + geometry,
            fit.buffer_bytes,
            fit.memory_bytes
        )));
    }
    let mut dropped: Vec<String> = Vec::new();
    for ((k, _), _) in &all {
        if !fits(*k) && !dropped.contains(&k.to_string()) {
            dropped.push(k.to_string());
        }
    }
    let note =
        if dropped.is_empty() { String::new() } else { format!(" ({} would not fit the device)", dropped.join(", ")) };
    Ok((kept[0].0, why(scene, pixels, spp, &kept, &note, costs)))
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

    /// A buffer limit that lbvh's 68 bytes per primitive exceed: auto takes the next
    /// fastest that fits, says what it dropped, and fails, naming the smallest
    /// structure's need, when nothing fits.
    #[test]
    fn structures_that_do_not_fit_are_dropped() {
        let s = scene(100_000);
        let n = (s.stored_triangles() + s.spheres.len() as u64) as f64;
        let on = |spp: u32, fit: &Fit| {
            choose_on(&s, 640 * 480, spp, fit, &Costs::builtin(), None).map(|((k, _), why)| (k, why))
        };
        let roomy = Fit { buffer_bytes: 1 << 40, memory_bytes: 1 << 40 };
        assert_eq!(on(1, &roomy).expect("fits").0, AccelKind::Lbvh);
        let tight = Fit { buffer_bytes: (60.0 * n) as u64, memory_bytes: 1 << 40 };
        let (k, why) = on(1, &tight).expect("fits");
        assert_ne!(k, AccelKind::Lbvh, "{why}");
        assert!(structure_bytes(k, &s).expect("sized") <= tight.buffer_bytes, "{why}");
        assert!(why.contains("lbvh") && why.contains("would not fit"), "{why}");
        // Only cwbvh (23.4 bytes a primitive) and the grid (27) fit 30.
        let (k, why) = on(64, &Fit { buffer_bytes: (30.0 * n) as u64, memory_bytes: 1 << 40 }).expect("fits");
        assert!(matches!(k, AccelKind::Cwbvh | AccelKind::Grid), "{why}");
        let err = on(1, &Fit { buffer_bytes: (20.0 * n) as u64, memory_bytes: 1 << 40 }).expect_err("nothing fits");
        let err = err.to_string();
        assert!(err.contains("cwbvh") && err.contains("per buffer"), "{err}");
        // Memory counts the geometry too.
        let err = on(1, &Fit { buffer_bytes: 1 << 40, memory_bytes: 1 << 20 }).expect_err("no memory").to_string();
        assert!(err.contains("memory"), "{err}");
        // A handful of triangles: brute force needs no structure and still wins.
        let few = choose_on(&scene(10), 640 * 480, 1, &tight, &Costs::builtin(), None).expect("fits");
        assert_eq!(few.0 .0, AccelKind::None);
    }

    /// Measured device builds are candidates where they are cheaper; `--build` keeps
    /// auto to one side.
    #[test]
    fn device_builds_are_candidates_when_measured() {
        let s = scene(100_000);
        let roomy = Fit { buffer_bytes: 1 << 40, memory_bytes: 1 << 40 };
        let mut costs = Costs::builtin();
        costs.trees.push(TreeCost { kind: AccelKind::Bvh4, build: BuildOn::Gpu, build_ns: 5.0, trace_ns: 100.9 });
        let ((k, b), why) = choose_on(&s, 640 * 480, 1, &roomy, &costs, None).expect("fits");
        assert_eq!((k, b), (AccelKind::Bvh4, BuildOn::Gpu), "{why}");
        assert!(why.contains("bvh4 built on the device"), "{why}");
        let ((_, b), _) = choose_on(&s, 640 * 480, 1, &roomy, &costs, Some(BuildOn::Cpu)).expect("fits");
        assert_eq!(b, BuildOn::Cpu);
        // --build gpu: only the measured device build is a candidate.
        let ((k, b), _) = choose_on(&s, 640 * 480, 1, &roomy, &costs, Some(BuildOn::Gpu)).expect("fits");
        assert_eq!((k, b), (AccelKind::Bvh4, BuildOn::Gpu));
        // Without a measured device build, --build gpu ranks the kinds the device builds
        // by their CPU builds' costs.
        let ((k, b), _) = choose_on(&s, 640 * 480, 1, &roomy, &Costs::builtin(), Some(BuildOn::Gpu)).expect("fits");
        assert_eq!((k, b), (AccelKind::Lbvh, BuildOn::Gpu));
    }
}
