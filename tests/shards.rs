//! Render-farm parts on the device: a crop renders exactly the pixels of the whole
//! image, sample ranges add up to the whole render, a resumed render equals an
//! uninterrupted one bit for bit, and merging parts gives the single render back.

mod common;

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
