//! Render-farm parts on the device: a crop renders exactly the pixels of the whole
//! image, sample ranges add up to the whole render, a resumed render equals an
//! uninterrupted one bit for bit, and merging parts gives the single render back.

use crate::common;

use arbor::accel::AccelKind;
use arbor::gpu::Context;
use arbor::render::{gpu, Crop, Frame, Integrator, RenderSettings};
use arbor::scene::Scene;
use std::sync::Arc;

fn settings(w: u32, h: u32, integrator: Integrator, spp: u32) -> RenderSettings {
    let mut s = RenderSettings::for_size(w, h);
    s.integrator = integrator;
    s.spp = spp;
    s.seed = 7;
    s.accel = AccelKind::BvhSah;
    s
}

fn render(ctx: &Context, scene: &Scene, s: &RenderSettings) -> Frame {
    let (frame, _) = gpu::render(ctx, scene, s, |_, _| {}).expect("render");
    ctx.check_validation().expect("no validation errors");
    frame
}

/// Pixel (x, y) of the full image from a frame of window `c`.
fn at(f: &Frame, c: &Crop, x: u32, y: u32) -> usize {
    ((y - c.y0) * f.width + (x - c.x0)) as usize
}

fn assert_window_equal(whole: &Frame, part: &Frame, c: &Crop, what: &str) {
    let full = Crop::full(whole.width, whole.height);
    for y in c.y0..c.y1 {
        for x in c.x0..c.x1 {
            let (a, b) = (at(whole, &full, x, y), at(part, c, x, y));
            let same = whole.sum[a] == part.sum[b]
                && whole.samples[a] == part.samples[b]
                && whole.sum_y2[a] == part.sum_y2[b]
                && whole.depth[a].to_bits() == part.depth[b].to_bits()
                && whole.prim[a] == part.prim[b]
                && whole.normal[a] == part.normal[b]
                && whole.albedo[a] == part.albedo[b]
                && (whole.nodes[a], whole.tests[a], whole.rays[a]) == (part.nodes[b], part.tests[b], part.rays[b]);
            assert!(same, "{what}: pixel ({x}, {y}) differs");
        }
    }
}

#[test]
fn crops_render_exactly_the_pixels_of_the_whole_image() {
    let Some(ctx) = common::gpu() else { return };
    let cornell = Scene::load("builtin:cornell").expect("cornell");
    let mixed = Scene::load("builtin:spheres").expect("spheres");
    for (scene, integrator) in [(&cornell, Integrator::Path), (&mixed, Integrator::Whitted)] {
        let s = settings(40, 30, integrator, 3);
        let whole = render(&ctx, scene, &s);
        for c in [
            Crop { x0: 0, x1: 40, y0: 0, y1: 11 },
            Crop { x0: 13, x1: 29, y0: 11, y1: 30 },
            Crop { x0: 39, x1: 40, y0: 29, y1: 30 },
        ] {
            let mut sc = s.clone();
            sc.crop = Some(c);
            let part = render(&ctx, scene, &sc);
            assert_eq!((part.width, part.height), (c.width(), c.height()));
            assert_window_equal(&whole, &part, &c, &format!("{} {c:?}", scene.name));
        }
    }
}

#[test]
fn resumed_render_equals_the_uninterrupted_one() {
    let Some(ctx) = common::gpu() else { return };
    let scene = Scene::load("builtin:cornell").expect("cornell");
    let c = Crop { x0: 5, x1: 37, y0: 3, y1: 20 };
    let mut s = settings(40, 30, Integrator::Path, 5);
    s.crop = Some(c);
    let whole = render(&ctx, &scene, &s);
    // Two of the five samples, then the rest from those sums.
    let mut first = s.clone();
    first.spp = 2;
    let part = render(&ctx, &scene, &first);
    assert!(part.samples.iter().all(|&n| n == 2));
    let mut rest = s.clone();
    rest.resume = Some(Arc::new(part.clone()));
    let resumed = render(&ctx, &scene, &rest);
    assert_window_equal(&whole, &resumed, &Crop::full(c.width(), c.height()), "resumed");
    assert_eq!(whole.radiance, resumed.radiance);
    // Pixels holding different counts (an interrupted chunk): each traces what it lacks.
    let mut uneven = part;
    for k in (0..uneven.samples.len()).step_by(3) {
        uneven.samples[k] = 0;
        uneven.sum[k] = [0.0; 3];
        uneven.sum_y2[k] = 0.0;
        uneven.rays[k] = 0;
        uneven.depth[k] = f32::INFINITY;
        uneven.prim[k] = u32::MAX;
        uneven.normal[k] = [0.0; 3];
        uneven.albedo[k] = [0.0; 3];
        uneven.nodes[k] = 0;
        uneven.tests[k] = 0;
    }
    rest.resume = Some(Arc::new(uneven));
    let resumed = render(&ctx, &scene, &rest);
    assert_window_equal(&whole, &resumed, &Crop::full(c.width(), c.height()), "resumed from uneven counts");
}

#[test]
fn sample_ranges_add_up_to_the_whole_render() {
    let Some(ctx) = common::gpu() else { return };
    let scene = Scene::load("builtin:cornell").expect("cornell");
    let s = settings(24, 24, Integrator::Path, 6);
    let whole = render(&ctx, &scene, &s);
    let mut parts = Vec::new();
    for (first, n) in [(0, 2), (2, 1), (3, 3)] {
        let mut p = s.clone();
        p.first_sample = first;
        p.spp = n;
        parts.push(render(&ctx, &scene, &p));
    }
    for k in 0..whole.sum.len() {
        let n: u32 = parts.iter().map(|p| p.samples[k]).sum();
        assert_eq!(n, whole.samples[k]);
        for ch in 0..3 {
            let sum: f32 = parts.iter().map(|p| p.sum[k][ch]).sum();
            let w = whole.sum[k][ch];
            assert!((sum - w).abs() <= 1e-5 * w.abs().max(1.0), "pixel {k}: {sum} against {w}");
        }
    }
    // Sample 0's AOVs come from the part that holds sample 0; the others keep misses.
    assert_eq!(parts[0].depth, whole.depth);
    assert_eq!(parts[0].prim, whole.prim);
    assert!(parts[1].prim.iter().all(|&p| p == u32::MAX));
}

// ---- The command line: render parts, merge them, resume.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn arbor(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_arbor"));
    c.args(args).env_remove("SLURM_ARRAY_TASK_ID").env_remove("JOB_COMPLETION_INDEX");
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("run arbor")
}

fn ok(args: &[&str], env: &[(&str, &str)]) {
    let out = arbor(args, env);
    assert!(out.status.success(), "arbor {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

/// One line on stderr, exit status `code`, naming `what`.
fn refused(args: &[&str], code: i32, what: &str) -> String {
    let out = arbor(args, &[]);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(code), "arbor {args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(err.contains(what), "{err} should name {what}");
    err
}

fn read(p: &Path) -> (arbor::render::output::part::PartInfo, Frame) {
    arbor::render::output::part::read(p).expect("a part")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

const SCENE: [&str; 6] = ["builtin:cornell", "--size", "64x48", "--spp", "6", "-q"];

fn render_part(out: &Path, extra: &[&str], env: &[(&str, &str)]) {
    let mut args = vec!["render"];
    args.extend(SCENE);
    args.extend(["-o", s(out)]);
    args.extend(extra);
    ok(&args, env);
}

#[test]
fn merged_tiles_equal_the_single_render_bit_for_bit() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let p = |n: &str| -> PathBuf { dir.path().join(n) };
    render_part(&p("whole.exr"), &[], &[]);
    let mut parts = Vec::new();
    for i in 0..3 {
        let name = format!("tile{i}.exr");
        render_part(&p(&name), &["--shard", &format!("{i}/3")], &[]);
        parts.push(p(&name));
    }
    let merged = p("merged.exr");
    let mut args = vec!["merge", "-q", "-o", s(&merged)];
    args.extend(parts.iter().rev().map(|x| s(x)));
    ok(&args, &[]);
    let (wi, w) = read(&p("whole.exr"));
    let (mi, m) = read(&p("merged.exr"));
    assert_eq!((mi.crop, mi.first_sample, mi.samples, &mi.hash), (wi.crop, 0, 6, &wi.hash));
    assert_eq!(w.sum, m.sum);
    assert_eq!(w.radiance, m.radiance);
    assert_eq!(w.samples, m.samples);
    assert_eq!(w.variance, m.variance);
    assert_eq!(w.prim, m.prim);
    assert_eq!(w.normal, m.normal);
    assert_eq!(w.albedo, m.albedo);
    assert_eq!((&w.nodes, &w.tests, &w.rays), (&m.nodes, &m.tests, &m.rays));
    assert!(w.depth.iter().zip(&m.depth).all(|(a, b)| a.to_bits() == b.to_bits()));
    // A tile is the window of the whole image, with its data window in the header.
    let (ti, t) = read(&parts[1]);
    assert_eq!((ti.width, ti.height, ti.crop), (64, 48, Crop { x0: 0, x1: 64, y0: 16, y1: 32 }));
    assert_eq!(t.sum[..], w.sum[16 * 64..32 * 64]);
    // A rerun writes the same bytes.
    let before = std::fs::read(&parts[1]).expect("tile");
    render_part(&parts[1], &["--shard", "1/3"], &[]);
    assert_eq!(before, std::fs::read(&parts[1]).expect("tile"), "a rerun shard writes the same bytes");
    // PNG output of the merge.
    ok(&["merge", "-q", "-o", s(&p("merged.png")), s(&parts[0]), s(&parts[1]), s(&parts[2])], &[]);
    assert!(p("merged.png").exists());
}

#[test]
fn merged_sample_shards_equal_the_single_render_to_rounding() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let p = |n: &str| -> PathBuf { dir.path().join(n) };
    render_part(&p("whole.exr"), &[], &[]);
    for i in 0..3 {
        render_part(&p(&format!("s{i}.exr")), &["--shard", &format!("{i}/3"), "--shard-by", "samples"], &[]);
    }
    ok(&["merge", "-q", "-o", s(&p("m.exr")), s(&p("s2.exr")), s(&p("s0.exr")), s(&p("s1.exr"))], &[]);
    let (_, w) = read(&p("whole.exr"));
    let (_, m) = read(&p("m.exr"));
    assert_eq!(w.samples, m.samples);
    for k in 0..w.sum.len() {
        for c in 0..3 {
            let (a, b) = (w.radiance[k][c], m.radiance[k][c]);
            assert!((a - b).abs() <= 1e-5 * a.abs().max(1.0), "pixel {k}: {a} against {b}");
        }
    }
    assert_eq!(w.prim, m.prim, "sample 0's AOVs come from the shard that traced it");
    assert_eq!(w.rays, m.rays);
    // Explicit ranges (--sample-offset) merge the same way.
    let (o0, o1) = (p("o0.exr"), p("o1.exr"));
    ok(&["render", "builtin:cornell", "--size", "64x48", "--spp", "4", "-q", "-o", s(&o0)], &[]);
    ok(
        &["render", "builtin:cornell", "--size", "64x48", "--spp", "2", "--sample-offset", "4", "-q", "-o", s(&o1)],
        &[],
    );
    ok(&["merge", "-q", "-o", s(&p("o.exr")), s(&p("o0.exr")), s(&p("o1.exr"))], &[]);
    let (_, o) = read(&p("o.exr"));
    assert_eq!(o.samples, w.samples);
}

#[test]
fn shard_auto_follows_the_scheduler_variables() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let p = |n: &str| -> PathBuf { dir.path().join(n) };
    render_part(&p("given.exr"), &["--shard", "2/4"], &[]);
    render_part(&p("slurm.exr"), &["--shard", "auto/4"], &[("SLURM_ARRAY_TASK_ID", "2")]);
    render_part(&p("k8s.exr"), &["--shard", "auto/4"], &[("JOB_COMPLETION_INDEX", "2")]);
    render_part(&p("both.exr"), &["--shard", "auto/4"], &[("SLURM_ARRAY_TASK_ID", "2"), ("JOB_COMPLETION_INDEX", "0")]);
    let given = std::fs::read(p("given.exr")).expect("part");
    for f in ["slurm.exr", "k8s.exr", "both.exr"] {
        assert!(given == std::fs::read(p(f)).expect("part"), "{f} is shard 2/4");
    }
    let out = p("none.exr");
    let mut args = vec!["render"];
    args.extend(SCENE);
    args.extend(["-o", s(&out), "--shard", "auto/4"]);
    refused(&args, 2, "SLURM_ARRAY_TASK_ID");
    assert!(!out.exists());
}

#[test]
fn resumed_render_writes_the_bytes_of_an_uninterrupted_one() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let p = |n: &str| -> PathBuf { dir.path().join(n) };
    render_part(&p("whole.exr"), &[], &[]);
    // A time budget stops after the first sample wave: an unfinished part.
    render_part(&p("r.exr"), &["--time", "0.000001"], &[]);
    let (_, first) = read(&p("r.exr"));
    assert!(first.samples[0] < 6, "the first run stopped early");
    let r = p("r.exr");
    render_part(&r, &["--resume", s(&r)], &[]);
    assert!(std::fs::read(p("whole.exr")).expect("a") == std::fs::read(&r).expect("b"), "resumed != whole");
    // A larger --spp continues a finished render.
    let mut more = vec!["render", "builtin:cornell", "--size", "64x48", "--spp", "9", "-q"];
    more.extend(["-o", s(&r), "--resume"]);
    more.push(s(&r));
    ok(&more, &[]);
    assert!(read(&r).1.samples.iter().all(|&n| n == 9));
    // Another seed is another image.
    let mut other = vec!["render"];
    other.extend(SCENE);
    let (x, whole) = (p("x.exr"), p("whole.exr"));
    other.extend(["-o", s(&x), "--seed", "5", "--resume", s(&whole)]);
    refused(&other, 1, "whole.exr");
}

#[test]
fn bad_or_foreign_parts_give_one_line_and_no_output() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let p = |n: &str| -> PathBuf { dir.path().join(n) };
    for i in 0..2 {
        render_part(&p(&format!("t{i}.exr")), &["--shard", &format!("{i}/2")], &[]);
    }
    render_part(&p("seed.exr"), &["--shard", "1/2", "--seed", "3"], &[]);
    let size = p("size.exr");
    ok(&["render", "builtin:cornell", "--size", "64x40", "--spp", "6", "-q", "-o", s(&size), "--shard", "1/2"], &[]);
    render_part(&p("third.exr"), &["--shard", "1/3"], &[]);
    ok(&["render", "builtin:cornell", "--size", "64x48", "-q", "-o", s(&p("plain.png"))], &[]);
    let bytes = std::fs::read(p("t1.exr")).expect("part");
    std::fs::write(p("trunc.exr"), &bytes[..bytes.len() / 2]).expect("write");
    let out = p("out.exr");
    let o = s(&out);
    let (t0, t1) = (p("t0.exr"), p("t1.exr"));
    for (second, what) in [
        (p("seed.exr"), "seed.exr"),
        (p("size.exr"), "size.exr"),
        (p("third.exr"), "third.exr"),
        (p("trunc.exr"), "trunc.exr"),
        (p("plain.png"), "plain.png"),
        (p("missing.exr"), "missing.exr"),
    ] {
        refused(&["merge", "-o", o, s(&t0), s(&second)], 1, what);
        assert!(!out.exists(), "nothing written for {what}");
    }
    refused(&["merge", "-o", o, s(&t0)], 1, "tiles are missing");
    refused(&["merge", "-o", o, s(&t0), s(&t1), s(&t1)], 1, "t1.exr");
    assert!(!out.exists());
    ok(&["merge", "-q", "--allow-partial", "-o", o, s(&t0)], &[]);
    let (_, f) = read(&out);
    assert_eq!(f.samples[0], 6);
    assert_eq!(*f.samples.last().expect("pixels"), 0, "the missing tile holds no samples");
}
