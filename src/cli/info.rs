//! `arbor info` (included by main.rs only): one scene and the structure built over it.

use anyhow::Result;
use arbor::accel::{Accel, BuildOn};
use arbor::scene::Scene;

use crate::args::InfoArgs;
use crate::common::{context, flatten_if, print_out, resolve_accel, start_trace, trace_device};

/// `arbor info`: the scene, its structure's statistics and validation, as text or JSON;
/// a structure that fails validation fails the command after the report.
pub(crate) fn run(a: &InfoArgs) -> Result<()> {
    let params = a.structure.single()?;
    if let Some(p) = &a.trace.trace_events {
        arbor::render::output::check_outputs(std::iter::once(p.as_path()))?;
    }
    let _recording = start_trace(&a.trace, "info")?;
    let scene = Scene::load(&a.scene)?;
    crate::common::warn_scene(&scene);
    let pixels = u64::from(scene.width) * u64::from(scene.height);
    let (accel, why) = resolve_accel(&a.accel, &scene, pixels, crate::common::DEFAULT_PATH_SPP, params.build)?;
    let scene = flatten_if(scene, a.flatten, accel, true)?;
    // The driver's structure exists only on a device: it is built there, as on the GPU.
    let built = match params.build {
        BuildOn::Cpu if !accel.driver_built() => Accel::build_with(accel, &scene, &params),
        _ => {
            let ctx = context(&a.device)?;
            trace_device(&ctx);
            let mut built = Accel::build_on(&ctx, accel, &scene, &params)?;
            // A tree built on the GPU stays there; info's statistics and validation
            // need it on the host (the copy's time is a phase of the build).
            built.read_back(&ctx)?;
            built
        }
    };
    let report = {
        let _span = arbor::timeline::span("validate", || "statistics and validation");
        arbor::info::Report::new(&scene, accel, params.build, why, &built)
    };
    if let Some(p) = &a.trace.trace_events {
        let trace = arbor::timeline::take().unwrap_or_default();
        arbor::render::output::write_atomic(p, &arbor::render::output::encode_trace(p, &trace)?)?;
    }
    print_out(&if a.json { format!("{}\n", report.to_json()) } else { report.to_string() })?;
    report.validation.map_err(|e| anyhow::anyhow!("{}: structure failed validation: {e}", scene.name))
}
