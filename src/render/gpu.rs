//! GPU rendering: build (or take) the structure, then run the settings' integrator.
//! The scene is uploaded once and traced in short dispatches (pixel ranges x sample
//! waves); each pixel sums its samples in index order inside the kernel, so the
//! image is bit-identical whatever the split.

use super::{Control, Frame, Integrator, RenderSettings, RenderStats};
use crate::accel::Accel;
use crate::error::Result;
use crate::gpu::Context;
use crate::scene::Scene;

pub use super::dispatch::dispatch_shape;
pub use super::dispatch::kernel::{kernel_geometry, trace_bindings};
pub use super::dispatch::upload::GpuScene;

/// Renders `scene` on `ctx`. `progress(done, total)` is called after each dispatch.
pub fn render(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    progress: impl FnMut(u64, u64),
) -> Result<(Frame, RenderStats)> {
    settings.check()?;
    // validate() is for tests and `arbor info`: on a 1M-triangle tree it costs more
    // than the build, and gpu_image() checks what the kernel depends on (depth).
    let accel = Accel::build_on(ctx, settings.accel, scene, &settings.params)?;
    render_with(ctx, scene, settings, &accel, progress)
}

/// Renders `scene` with an already built structure.
pub fn render_with(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    accel: &Accel,
    progress: impl FnMut(u64, u64),
) -> Result<(Frame, RenderStats)> {
    run(ctx, scene, settings, accel, Control::progress_only(progress))
}

/// Builds the structure and renders with `control`: progress, and for the path
/// integrator interruption, checkpoints and the time budget (the Whitted integrator
/// reports progress only).
pub fn render_controlled(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    control: Control<'_>,
) -> Result<(Frame, RenderStats)> {
    settings.check()?;
    let accel = Accel::build_on(ctx, settings.accel, scene, &settings.params)?;
    run(ctx, scene, settings, &accel, control)
}

/// The settings' integrator over `accel` (the one place that chooses it).
fn run(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    accel: &Accel,
    control: Control<'_>,
) -> Result<(Frame, RenderStats)> {
    match settings.integrator {
        Integrator::Whitted => super::integrators::whitted::render_with(ctx, scene, settings, accel, control.progress),
        Integrator::Path => super::integrators::path::render_with(ctx, scene, settings, accel, control),
        Integrator::Sppm => super::integrators::sppm::render_with(ctx, scene, settings, accel, control),
    }
}
