//! `arbor calibrate`'s measurement: the cost model of `--accel auto`
//! ([`crate::accel::auto::Costs`]) on one device; [`crate::accel::calibrate`] keeps it.
//!
//! It builds a 100k-triangle blob with every structure on the CPU (and, where the
//! device builds, lbvh, trbvh, bvh4 and bvh8 there) and traces its camera rays with
//! each, the faster of two runs after one that compiles; brute force traces a
//! 2000-triangle blob. Device builds make the same trees as the CPU's (bvh4 and bvh8
//! collapse trbvh's), so their trace costs are the CPU-built ones'.

use std::time::Instant;

use crate::accel::auto::{Costs, TreeCost};
use crate::accel::{Accel, AccelKind, AccelParams, BuildOn};
use crate::error::Result;
use crate::gpu::Context;
use crate::render::{gpu, RenderSettings};
use crate::scene::{procedural, Scene, SceneBuilder};

/// Triangles of the scene built and traced, and of brute force's.
const TRIS: usize = 100_000;
const BRUTE_TRIS: usize = 2_000;
/// Side of the traced image (camera rays, one per pixel): large enough that a
/// dispatch's fixed cost is a small part of its time.
const TRACE_SIDE: u32 = 384;
const BRUTE_SIDE: u32 = 48;

fn blob(tris: usize) -> Result<Scene> {
    let mut b = SceneBuilder::new(&format!("calibration blob of {tris}"));
    b.mesh(&procedural::blob(tris, 0.1, 1), 1.0, glam::Vec3::ZERO, None);
    b.finish()
}

/// GPU ns per camera ray of `kind` over `scene` at `side` x `side`: the faster of two
/// timed runs after one that compiles.
fn trace_ns(ctx: &Context, scene: &Scene, accel: &Accel, kind: AccelKind, side: u32) -> Result<f64> {
    let mut s = RenderSettings::for_size(side, side);
    s.accel = kind;
    s.primary_only = true;
    let mut times = Vec::new();
    for run in 0..3 {
        let (_, st) = gpu::render_with(ctx, scene, &s, accel, |_, _| {})?;
        let ms = st.trace_ms.unwrap_or(st.loop_ms);
        if run > 0 {
            times.push(ms * 1e6 / st.rays.max(1) as f64);
        }
    }
    Ok(times.into_iter().fold(f64::INFINITY, f64::min))
}

/// Measures every candidate's costs on `ctx`; `progress` gets a line per structure.
pub fn measure(ctx: &Context, progress: &mut dyn FnMut(&str)) -> Result<Costs> {
    let scene = blob(TRIS)?;
    let n = scene.prim_count() as f64;
    let params = AccelParams::default();
    // The structures the model ranks, each built on the CPU.
    let kinds: Vec<AccelKind> = Costs::builtin().trees.iter().map(|t| t.kind).collect();
    let mut trees = Vec::new();
    for (k, &kind) in kinds.iter().enumerate() {
        let start = Instant::now();
        let accel = Accel::build_with(kind, &scene, &params);
        let build_ns = start.elapsed().as_secs_f64() * 1e9 / n;
        let trace = trace_ns(ctx, &scene, &accel, kind, TRACE_SIDE)?;
        progress(&format!(
            "{}/{}: {kind}: build {build_ns:.0} ns a primitive, trace {trace:.1} ns a ray",
            k + 1,
            kinds.len()
        ));
        trees.push(TreeCost { kind, build: BuildOn::Cpu, build_ns, trace_ns: trace });
    }
    let mut pipelines = None;
    let gpu_params = AccelParams { build: BuildOn::Gpu, ..AccelParams::default() };
    // A first build creates the builder's pipelines, shared by every kind.
    if let Err(e) = Accel::build_on_reusing(ctx, AccelKind::Lbvh, &scene, &gpu_params, &mut pipelines) {
        progress(&format!("device builds: none ({e})"));
        return finish(ctx, trees, progress);
    }
    for kind in kinds.into_iter().filter(|k| k.builds_on_gpu()) {
        let start = Instant::now();
        drop(Accel::build_on_reusing(ctx, kind, &scene, &gpu_params, &mut pipelines)?);
        let best = start.elapsed().as_secs_f64() * 1e9 / n;
        let trace = trees.iter().find(|t| t.kind == kind && t.build == BuildOn::Cpu).map_or(f64::NAN, |t| t.trace_ns);
        progress(&format!("device build: {kind}: {best:.0} ns a primitive"));
        trees.push(TreeCost { kind, build: BuildOn::Gpu, build_ns: best, trace_ns: trace });
    }
    finish(ctx, trees, progress)
}

fn finish(ctx: &Context, trees: Vec<TreeCost>, progress: &mut dyn FnMut(&str)) -> Result<Costs> {
    let scene = blob(BRUTE_TRIS)?;
    let accel = Accel::build_with(AccelKind::None, &scene, &AccelParams::default());
    let per_ray = trace_ns(ctx, &scene, &accel, AccelKind::None, BRUTE_SIDE)?;
    let brute_test_ns = per_ray / scene.prim_count() as f64;
    progress(&format!("brute force: {brute_test_ns:.2} ns a primitive test"));
    Ok(Costs { trees, brute_test_ns, source: "costs measured on this device by `arbor calibrate`".into() })
}
