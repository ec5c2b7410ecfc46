//! Resumed traces (docs/kernels.md, "Resumed traces"): a trace that runs out of its
//! step budget is continued in following dispatches, never an error. Every structure
//! renders every built-in scene with the AOVs of the CPU reference; a forced small
//! budget changes no bit of the image (both integrators, the probe kernel, packets,
//! instances, a crop, checkpoints, a pool with few records); a grid cell holding
//! thousands of primitives; the stats and the summary line count the resumes.

use crate::common;

use arbor::accel::{Accel, AccelKind, AccelParams, KernelFamily};
use arbor::gpu::Context;
use arbor::render::integrators::path;
use arbor::render::{cpu, gpu, Crop, Frame, Integrator, RenderSettings, RenderStats, Traversal};
use arbor::scene::{procedural, Light, Scene, SceneBuilder, Sphere};
use common::scenes::{gpu_matches_reference, scene_from, tris, Rng};
use glam::{Affine3A, Quat, Vec3};

/// The smallest budget a render may force.
const TINY: u32 = arbor::gpu::bindings::MIN_FORCED_TRACE_STEPS;

fn render_with(ctx: &Context, scene: &Scene, s: &RenderSettings, accel: &Accel) -> (Frame, RenderStats) {
    let (f, st) = gpu::render_with(ctx, scene, s, accel, |_, _| {}).expect("render");
    ctx.check_validation().expect("no validation errors");
    (f, st)
}

/// Every figure of two frames, bit for bit.
fn assert_same(a: &Frame, b: &Frame, what: &str) {
    assert_eq!((a.width, a.height), (b.width, b.height), "{what}");
    for k in 0..a.depth.len() {
        let same = a.sum[k].map(f32::to_bits) == b.sum[k].map(f32::to_bits)
            && a.sum_y2[k].to_bits() == b.sum_y2[k].to_bits()
            && a.samples[k] == b.samples[k]
            && a.depth[k].to_bits() == b.depth[k].to_bits()
            && a.prim[k] == b.prim[k]
            && a.normal[k].map(f32::to_bits) == b.normal[k].map(f32::to_bits)
            && a.albedo[k].map(f32::to_bits) == b.albedo[k].map(f32::to_bits)
            && (a.nodes[k], a.tests[k], a.rays[k]) == (b.nodes[k], b.tests[k], b.rays[k]);
        assert!(
            same,
            "{what}: pixel {k} differs: sum {:?} vs {:?}, samples {} vs {}, prim {} vs {}, depth {} vs {}, cost {:?} vs {:?}",
            a.sum[k],
            b.sum[k],
            a.samples[k],
            b.samples[k],
            a.prim[k],
            b.prim[k],
            a.depth[k],
            b.depth[k],
            (a.nodes[k], a.tests[k], a.rays[k]),
            (b.nodes[k], b.tests[k], b.rays[k])
        );
    }
}

/// The ways the kernel traces: Whitted, path, the probe kernel's camera rays and its
/// diffuse bounce, with settings `s` of `w` x `h` pixels.
fn modes(w: u32, h: u32, kind: AccelKind) -> Vec<(&'static str, RenderSettings)> {
    let mut out = Vec::new();
    for name in ["whitted", "path", "primary", "diffuse"] {
        let mut s = RenderSettings::for_size(w, h);
        s.accel = kind;
        s.seed = 5;
        match name {
            "whitted" => s.spp = 2,
            "path" => {
                s.integrator = Integrator::Path;
                s.spp = 2;
                s.max_depth = Some(4);
            }
            "primary" => s.primary_only = true,
            _ => s.diffuse_probe = true,
        }
        out.push((name, s));
    }
    out
}

/// Renders with the normal budget and with the smallest one; the frames must agree
/// bit for bit (with packets, but for the cost AOVs: the resume kernel continues a
/// packet's trace one ray per lane, which visits fewer nodes). Returns the samples the
/// small budget resumed.
fn same_with_tiny_budget(ctx: &Context, scene: &Scene, s: &RenderSettings, accel: &Accel, what: &str) -> u64 {
    same_with_tiny_budget_frame(ctx, scene, s, accel, what).0
}

/// [`same_with_tiny_budget`], with the small budget's frame.
fn same_with_tiny_budget_frame(
    ctx: &Context,
    scene: &Scene,
    s: &RenderSettings,
    accel: &Accel,
    what: &str,
) -> (u64, Frame) {
    let (a, _) = render_with(ctx, scene, s, accel);
    let mut t = s.clone();
    t.trace_steps = Some(TINY);
    let (mut b, st) = render_with(ctx, scene, &t, accel);
    if s.traversal == Traversal::Packet {
        b.nodes.clone_from(&a.nodes);
        b.tests.clone_from(&a.tests);
    }
    assert_same(&a, &b, what);
    assert_eq!(st.resumed_samples > 0, st.resume_dispatches > 0, "{what}");
    assert!(st.resume_jobs >= st.resumed_samples, "{what}: {} jobs for {} samples", st.resume_jobs, st.resumed_samples);
    eprintln!("{what}: {} samples resumed in {} dispatches", st.resumed_samples, st.resume_dispatches);
    (st.resumed_samples, b)
}

/// Resumes by key; every key must have some.
#[derive(Default)]
struct Tally(std::collections::BTreeMap<String, u64>);

impl Tally {
    fn add(&mut self, key: impl Into<String>, n: u64) {
        *self.0.entry(key.into()).or_default() += n;
    }
    fn assert_all(&self, what: &str) {
        for (k, n) in &self.0 {
            assert!(*n > 0, "{what} {k}: the small budget resumed nothing");
        }
    }
}

#[test]
fn every_structure_renders_every_builtin_scene_like_the_cpu_reference() {
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (64, 48);
    // Brute force over builtin:default's 26,000 triangles and its octree (whose SAH
    // stops at depth 1, so one leaf holds them all) trace so long on lavapipe (10 s
    // and 7 s, every sample resumed) that they render a quarter of the width: the
    // same code, still every sample resumed, in a sixteenth of the time.
    let (w_slow, h_slow) = (16, 12);
    for name in ["default", "cornell", "spheres", "blob:3000", "inside:3000", "stadium:3000"] {
        let scene = Scene::load(&format!("builtin:{name}")).expect("builtin scene");
        let reference = cpu::reference_aovs(&scene, w, h);
        let small = cpu::reference_aovs(&scene, w_slow, h_slow);
        for &kind in AccelKind::ALL {
            let slow = name == "default" && matches!(kind, AccelKind::None | AccelKind::Octree);
            let (mut s, reference) = match slow {
                true => (RenderSettings::for_size(w_slow, h_slow), &small),
                false => (RenderSettings::for_size(w, h), &reference),
            };
            s.accel = kind;
            let what = format!("builtin:{name} {kind}");
            let started = std::time::Instant::now();
            let (_, st) = gpu_matches_reference(&ctx, &scene, &s, reference, kind.kernel(), &what);
            eprintln!(
                "{what}: {:.0} ms, {} samples resumed in {} dispatches",
                started.elapsed().as_secs_f64() * 1e3,
                st.resumed_samples,
                st.resume_dispatches
            );
        }
    }
}

#[test]
fn a_small_step_budget_changes_no_bit_of_the_image() {
    let Some(ctx) = common::gpu() else { return };
    let default = Scene::load("builtin:default").expect("default");
    // The octree of builtin:default keeps some 26,000 triangles a leaf (its SAH stops
    // at depth 1), so every trace there is long: the stadium instead.
    let stadium = Scene::load("builtin:stadium:3000").expect("stadium");
    let (w, h) = (40, 30);
    let (mut by_kind, mut by_mode) = (Tally::default(), Tally::default());
    for kind in [
        AccelKind::BvhSah,
        AccelKind::Kdtree,
        AccelKind::Bvh4,
        AccelKind::Bvh8,
        AccelKind::Cwbvh,
        AccelKind::Grid,
        AccelKind::Octree,
    ] {
        let scene = if kind == AccelKind::Octree { &stadium } else { &default };
        let accel = Accel::build(kind, scene);
        for (mode, s) in modes(w, h, kind) {
            let n = same_with_tiny_budget(&ctx, scene, &s, &accel, &format!("{} {kind} {mode}", scene.name));
            by_kind.add(kind.name(), n);
            by_mode.add(mode, n);
        }
    }
    // Packets (BVHs): the resume kernel continues a packet's trace one ray per lane.
    let accel = Accel::build(AccelKind::BvhSah, &default);
    for (mode, mut s) in modes(w, h, AccelKind::BvhSah) {
        s.traversal = Traversal::Packet;
        by_kind.add("packet", same_with_tiny_budget(&ctx, &default, &s, &accel, &format!("packet {mode}")));
    }
    by_kind.assert_all("structure");
    by_mode.assert_all("mode");
}

/// A ground quad and a sphere of the scene's own, and nine instances of a blob under
/// rotations, non-uniform and mirroring scales.
fn instanced() -> Scene {
    let mut b = SceneBuilder::new("instances");
    let g = 20.0;
    let ground = procedural::quad([
        Vec3::new(-g, -1.5, -g),
        Vec3::new(g, -1.5, -g),
        Vec3::new(g, -1.5, g),
        Vec3::new(-g, -1.5, g),
    ]);
    b.mesh(&ground, 1.0, Vec3::ZERO, None);
    b.scene.spheres.push(Sphere { center: Vec3::new(0.0, 2.2, 0.0), radius: 0.6, material: 0 });
    let p = b.prototype("blob", &procedural::blob(8000, 0.3, 7), &Affine3A::IDENTITY, None);
    let mut k = 0;
    for x in -1..=1 {
        for z in -1..=1 {
            k += 1;
            let s = match k % 3 {
                0 => Vec3::splat(0.5),
                1 => Vec3::new(0.6, 0.35, 0.45),
                _ => Vec3::new(-0.5, 0.5, 0.5),
            };
            let r = Quat::from_axis_angle(Vec3::new(0.2, 1.0, 0.4).normalize(), k as f32 * 0.7);
            let t = Vec3::new(x as f32 * 1.4, 0.15 * (k % 3) as f32, z as f32 * 1.4);
            b.instance(p, Affine3A::from_scale_rotation_translation(s, r, t));
        }
    }
    b.scene.lights.push(Light::Directional { direction: Vec3::new(-0.3, -1.0, -0.5), radiance: Vec3::ONE });
    b.scene.lights.push(Light::Point { position: Vec3::new(1.0, 3.0, 2.0), intensity: Vec3::splat(4.0) });
    b.scene.camera.eye = Vec3::new(0.5, 4.0, 6.5);
    b.scene.camera.look_at = Vec3::ZERO;
    b.finish().expect("valid scene")
}

#[test]
fn instanced_traces_resume_at_both_levels() {
    let Some(ctx) = common::gpu() else { return };
    let scene = instanced();
    let flat = scene.flattened().expect("flattened");
    let (w, h) = (32, 24);
    let reference = cpu::reference_aovs(&flat, w, h);
    let mut by_kind = Tally::default();
    // One structure of each kernel family (brute force has no instance level).
    for kind in [
        AccelKind::BvhSah,
        AccelKind::Kdtree,
        AccelKind::Bvh4,
        AccelKind::Bvh8,
        AccelKind::Cwbvh,
        AccelKind::Grid,
        AccelKind::Octree,
    ] {
        let accel = Accel::build(kind, &scene);
        for (mode, s) in modes(w, h, kind).into_iter().filter(|(m, _)| *m != "diffuse") {
            let what = format!("instanced {kind} {mode}");
            let (n, g) = same_with_tiny_budget_frame(&ctx, &scene, &s, &accel, &what);
            by_kind.add(kind.name(), n);
            // The resumed camera rays (through the pixel centres but for the path
            // integrator's) still hit where the flattened copies do; only pixels on
            // shared edges may name the neighbouring triangle.
            if mode != "path" {
                let differ = (0..g.prim.len()).filter(|&i| g.prim[i] != reference.prim[i]).count();
                assert!(differ * 200 <= g.prim.len(), "{what}: {differ} of {} pixels differ", g.prim.len());
            }
        }
    }
    by_kind.assert_all("instanced");
}

/// The traversals' own edge cases under a small budget: kd-tree rays inside split
/// planes (IN_PLANE entries on the stack), octree descents cut short, grid searches.
#[test]
fn edge_case_scenes_resume_exactly() {
    let Some(ctx) = common::gpu() else { return };
    let mut scenes = common::scenes::edge_cases();
    scenes.retain(|s| ["coplanar grid", "axis planes", "blob and spheres", "identical"].contains(&s.name.as_str()));
    for scene in scenes.iter().flat_map(common::scenes::gpu_views) {
        for kind in [AccelKind::Kdtree, AccelKind::Octree, AccelKind::Grid, AccelKind::BvhSah] {
            let accel = Accel::build(kind, &scene);
            let mut s = RenderSettings::for_size(32, 24);
            s.accel = kind;
            s.spp = 2;
            let (a, _) = render_with(&ctx, &scene, &s, &accel);
            s.trace_steps = Some(TINY);
            let (b, _) = render_with(&ctx, &scene, &s, &accel);
            assert_same(&a, &b, &format!("{} {kind}", scene.name));
        }
    }
}

/// A grid whose cell holds 20,000 triangles: every ray from the camera inside it tests
/// them all, several budgets' worth, and the image is brute force's.
#[test]
fn a_grid_cell_holding_thousands_of_primitives() {
    let Some(ctx) = common::gpu() else { return };
    let v = Vec3::new;
    let mut list = Vec::new();
    let mut rng = Rng(3);
    for _ in 0..20_000 {
        let c = v(rng.next(), rng.next(), rng.next()) * 0.05;
        list.push([c, c + v(0.004, 0.0, 0.0), c + v(0.0, 0.004, 0.002)]);
    }
    // A far triangle sets the box, so that the cluster falls in one of about 2N cells.
    list.push([v(50.0, 50.0, 50.0), v(51.0, 50.0, 50.0), v(50.0, 51.0, 50.0)]);
    let mut scene = scene_from("cluster", Some(tris(&list)), &[(v(0.1, 0.0, 0.02), 0.01)]);
    scene.camera =
        arbor::scene::Camera { eye: v(0.025, 0.025, 0.12), look_at: v(0.025, 0.025, 0.0), up: Vec3::Y, vfov: 50.0 };
    let grid = Accel::build(AccelKind::Grid, &scene);
    if let Accel::Grid(g) = &grid {
        let cell = g.res.iter().zip(0..3).map(|(&r, a)| g.bounds.extent()[a] / r as f32).fold(f32::INFINITY, f32::min);
        assert!(cell > 0.2, "the cluster (0.05 wide) and the camera lie in one cell of {cell}");
    }
    let (w, h) = (32, 24);
    let reference = cpu::reference_aovs(&scene, w, h);
    let mut s = RenderSettings::for_size(w, h);
    s.accel = AccelKind::Grid;
    let (g, st) = gpu_matches_reference(&ctx, &scene, &s, &reference, KernelFamily::Grid, "cluster grid");
    assert!(st.resumed_samples > 0, "20,000 tests a ray exceed the budget: traces must have been resumed");
    assert!(g.tests.iter().all(|&t| t >= 20_000), "every camera ray tests the whole cell");
    s.accel = AccelKind::None;
    let (b, _) = render_with(&ctx, &scene, &s, &Accel::build(AccelKind::None, &scene));
    assert_eq!(g.radiance, b.radiance, "the grid's image is brute force's");
    assert_eq!(g.prim, b.prim);
    eprintln!("cluster grid: {} samples resumed in {} dispatches", st.resumed_samples, st.resume_dispatches);
}

/// A pool of few records: samples that find none run again from their start, and the
/// image stays the same.
#[test]
fn samples_without_a_record_start_over() {
    let Some(ctx) = common::gpu() else { return };
    let scene = Scene::load("builtin:blob:20000").expect("blob");
    let accel = Accel::build(AccelKind::Kdtree, &scene);
    for (mode, s) in modes(40, 30, AccelKind::Kdtree).into_iter().take(2) {
        let (a, _) = render_with(&ctx, &scene, &s, &accel);
        let mut t = s.clone();
        t.trace_steps = Some(TINY);
        t.resume_records = Some(3);
        let (b, st) = render_with(&ctx, &scene, &t, &accel);
        assert_same(&a, &b, mode);
        assert!(st.resume_jobs > st.resumed_samples + 3, "{mode}: samples must have waited for a record");
    }
}

/// The render farm's parts and the progressive path loop: a crop, a sample range and
/// checkpoints under a small budget give the pixels of the whole normal render.
#[test]
fn crops_sample_ranges_and_checkpoints_under_a_small_budget() {
    let Some(ctx) = common::gpu() else { return };
    let scene = Scene::load("builtin:default").expect("default");
    let accel = Accel::build(AccelKind::Kdtree, &scene);
    let mut s = RenderSettings::for_size(40, 30);
    s.accel = AccelKind::Kdtree;
    s.integrator = Integrator::Path;
    s.spp = 4;
    s.max_depth = Some(3);
    let (whole, _) = render_with(&ctx, &scene, &s, &accel);
    let c = Crop { x0: 7, x1: 31, y0: 4, y1: 22 };
    let mut t = s.clone();
    t.trace_steps = Some(TINY);
    t.crop = Some(c);
    let (part, st) = render_with(&ctx, &scene, &t, &accel);
    assert!(st.resumed_samples > 0);
    for y in c.y0..c.y1 {
        for x in c.x0..c.x1 {
            let (k, p) = ((y * 40 + x) as usize, ((y - c.y0) * c.width() + (x - c.x0)) as usize);
            assert_eq!(whole.sum[k], part.sum[p], "pixel ({x}, {y})");
            assert_eq!((whole.prim[k], whole.tests[k], whole.rays[k]), (part.prim[p], part.tests[p], part.rays[p]));
        }
    }
    // Samples 1..4 of every pixel, as a sample shard renders them.
    let mut range = s.clone();
    range.first_sample = 1;
    range.spp = 3;
    let (a, _) = render_with(&ctx, &scene, &range, &accel);
    range.trace_steps = Some(TINY);
    let (b, _) = render_with(&ctx, &scene, &range, &accel);
    assert_same(&a, &b, "samples 1..4");
    // Checkpoints read the chunk after every sample wave; the end is the same.
    let mut seen = 0;
    let control = arbor::render::Control {
        progress: Box::new(|_, _| {}),
        interrupted: Box::new(|| false),
        checkpoint: Some((
            0.0,
            Box::new(|f: &Frame| {
                seen += 1;
                assert!(f.samples.iter().all(|&n| n == f.samples[0]), "a checkpoint holds whole waves");
                Ok(())
            }),
        )),
    };
    // Nine samples: waves of four, a checkpoint after each of the first two.
    s.spp = 9;
    let (whole, _) = render_with(&ctx, &scene, &s, &accel);
    let mut t = s.clone();
    t.trace_steps = Some(TINY);
    let (checked, st) = path::render_with(&ctx, &scene, &t, &accel, control).expect("render");
    ctx.check_validation().expect("no validation errors");
    assert!(st.resumed_samples > 0);
    assert_same(&whole, &checked, "checkpointed");
    assert!(seen > 0, "no checkpoint was written");
}

#[test]
fn stats_and_the_summary_line_count_resumes() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let stats = dir.path().join("s.json");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_arbor"))
        .args(["render", "builtin:blob:5000", "--accel", "kdtree", "--size", "32x24", "--spp", "2", "--trace-steps"])
        .arg(TINY.to_string())
        .arg("-o")
        .arg(dir.path().join("i.png"))
        .arg("--stats")
        .arg(&stats)
        .output()
        .expect("run arbor");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&stats).expect("stats")).expect("json");
    let resumed = v["resumed_samples"].as_u64().expect("resumed_samples");
    let passes = v["resume_dispatches"].as_u64().expect("resume_dispatches");
    assert!(resumed > 0 && passes > 0, "{v}");
    assert!(v["resume_jobs"].as_u64().expect("resume_jobs") >= resumed);
    assert!(v["resume_ms"].as_f64().is_some_and(|ms| ms <= v["trace_ms"].as_f64().expect("trace_ms")));
    assert!(
        err.contains(&format!("{resumed} pixel samples ran out of traversal steps and were resumed in {passes} more")),
        "{err}"
    );
    // Below the least budget: refused.
    let low = std::process::Command::new(env!("CARGO_BIN_EXE_arbor"))
        .args(["render", "builtin:blob:500", "--size", "8x8", "--trace-steps", "30", "-o"])
        .arg(dir.path().join("j.png"))
        .output()
        .expect("run arbor");
    assert!(!low.status.success());
    assert!(String::from_utf8_lossy(&low.stderr).contains(&format!("--trace-steps must be at least {TINY}")));
}

/// Builder parameters do not matter to resuming: a coarse grid (long cells) resumes
/// exactly too.
#[test]
fn a_coarse_grid_resumes_exactly() {
    let Some(ctx) = common::gpu() else { return };
    let scene = Scene::load("builtin:blob:20000").expect("blob");
    let params = AccelParams {
        grid: arbor::accel::grid::GridParams { lambda: 0.02, ..Default::default() },
        ..Default::default()
    };
    let accel = Accel::build_with(AccelKind::Grid, &scene, &params);
    let mut s = RenderSettings::for_size(32, 24);
    s.accel = AccelKind::Grid;
    s.params = params;
    s.spp = 2;
    same_with_tiny_budget(&ctx, &scene, &s, &accel, "coarse grid");
}
