//! The render loop (src/render/dispatch/): dispatches kept in flight give the same
//! bytes as dispatches waited for one by one, with traces that stop and resume and
//! pixels left behind by them; dispatch lengths follow the target they are sized to;
//! the stats say how busy the loop kept the device.

use crate::common;

use arbor::accel::AccelKind;
use arbor::render::dispatch::PacingChoice;
use arbor::render::{gpu, Frame, Integrator, RenderSettings, RenderStats};
use arbor::scene::Scene;

fn render(ctx: &arbor::gpu::Context, scene: &Scene, s: &RenderSettings) -> (Frame, RenderStats) {
    let out = gpu::render(ctx, scene, s, |_, _| {}).expect("render");
    ctx.check_validation().expect("no validation errors");
    out
}

fn same_bits(a: &Frame, b: &Frame, what: &str) {
    let bits = |f: &Frame| -> Vec<u32> {
        f.sum.iter().flatten().chain(&f.sum_y2).chain(&f.depth).map(|x| x.to_bits()).chain(f.samples.clone()).collect()
    };
    assert!(bits(a) == bits(b), "{what}: the frames differ");
    assert_eq!((&a.prim, &a.rays), (&b.prim, &b.rays), "{what}");
}

/// Depth 1 (each dispatch waited for) against 16 in flight, for both integrators,
/// with the smallest step budget: traces stop, and the dispatches in flight behind one
/// that stopped a pixel's sample find that pixel behind, skip it and have it resumed in
/// order. Seven dispatches of 64 pixels a sample wave (the smallest work budget), so
/// consecutive waves over the same pixels are in flight together.
#[test]
fn dispatches_in_flight_change_no_bit() {
    let Some(ctx) = common::gpu() else { return };
    // Whitted's short paths stop only on a bigger mesh.
    for (integrator, name) in [(Integrator::Path, "builtin:cornell"), (Integrator::Whitted, "builtin:blob:3000")] {
        let scene = Scene::load(name).expect("scene");
        let mut s = RenderSettings::for_size(24, 18);
        s.integrator = integrator;
        s.accel = AccelKind::Kdtree;
        s.spp = 5;
        s.seed = 3;
        s.max_depth = Some(4);
        s.trace_steps = Some(arbor::gpu::bindings::MIN_FORCED_TRACE_STEPS);
        s.pacing = PacingChoice { in_flight: Some(1), budget: Some(1), ..Default::default() };
        let (waited, st1) = render(&ctx, &scene, &s);
        s.pacing.in_flight = Some(16);
        let (ahead, st4) = render(&ctx, &scene, &s);
        let what = format!("{integrator:?}");
        same_bits(&waited, &ahead, &what);
        assert!(st1.resumed_samples > 0, "{what}: the small budget stops traces");
        assert_eq!((st1.in_flight, st4.in_flight), (1, 16), "{what}");
        // Pixels found behind a stopped sample are counted with the stopped ones.
        assert!(
            st4.resumed_samples > st1.resumed_samples,
            "{what}: no pixel was behind ({} vs {} resumed)",
            st4.resumed_samples,
            st1.resumed_samples
        );
    }
}

/// A short target cuts the same render into more, shorter dispatches, whose median
/// length stays near the target; the bytes do not change.
#[test]
fn dispatch_lengths_follow_their_target() {
    let Some(ctx) = common::gpu() else { return };
    let scene = Scene::load("builtin:cornell").expect("cornell");
    let mut s = RenderSettings::for_size(320, 240);
    s.integrator = Integrator::Path;
    s.accel = AccelKind::BvhSah;
    s.spp = 2;
    s.max_depth = Some(3);
    let mut runs = Vec::new();
    for target in [4.0, 32.0] {
        // No work budget: time alone sizes the dispatches.
        s.pacing = PacingChoice { target_ms: Some(target), budget: Some(u64::MAX), in_flight: None };
        let (frame, st) = render(&ctx, &scene, &s);
        assert_eq!(st.dispatch_target_ms, target);
        assert!(st.loop_ms > 0.0 && st.loop_ms <= st.wall_ms, "loop {} ms, wall {} ms", st.loop_ms, st.wall_ms);
        let busy = st.gpu_busy.expect("timestamps");
        assert!(busy > 0.0 && busy <= 1.0 + 1e-6, "busy {busy}");
        let median = st.dispatch_median_ms;
        eprintln!("target {target} ms: {} dispatches, median {median:.2} ms, busy {busy:.2}", st.dispatches);
        // Generous: a loaded machine slows some dispatches after they were sized.
        assert!(median > target / 4.0 && median < target * 4.0, "target {target} ms, median {median} ms");
        runs.push((frame, st));
    }
    let (short, long) = (&runs[0], &runs[1]);
    assert!(short.1.dispatches > 2 * long.1.dispatches, "{} vs {} dispatches", short.1.dispatches, long.1.dispatches);
    same_bits(&short.0, &long.0, "4 ms against 32 ms dispatches");
}

/// The pacing flags are checked before any work.
#[test]
fn bad_pacing_is_refused() {
    let mut s = RenderSettings::for_size(8, 8);
    for bad in [
        PacingChoice { target_ms: Some(0.0), ..Default::default() },
        PacingChoice { target_ms: Some(f64::NAN), ..Default::default() },
        PacingChoice { in_flight: Some(0), ..Default::default() },
        PacingChoice { in_flight: Some(17), ..Default::default() },
        PacingChoice { budget: Some(0), ..Default::default() },
    ] {
        s.pacing = bad;
        let err = s.check().expect_err("refused");
        assert!(err.to_string().starts_with("--"), "{err}");
    }
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_arbor"))
        .args(["render", "--in-flight", "0", "-o", "/nonexistent/x.png"])
        .output()
        .expect("run");
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
}
