//! What several commands share (included by main.rs only): opening the device, the
//! `--accel`, `--size` and `--aov-scale` values, flattening instances, writing to stdout, and
//! [`usage`], the error of a command-line mistake (exit status 2).

use std::io::Write;
use std::time::Instant;

use anyhow::{Context as _, Result};
use arbor::accel::AccelKind;
use arbor::gpu::{Context, ContextOptions};
use arbor::scene::Scene;

use crate::args::{DeviceArgs, TraceArgs};

/// A mistake on the command line (a flag's value, or flags that contradict each other):
/// `arbor::Error::Usage`, which main.rs turns into exit status 2. Failures reading,
/// building or rendering exit with 1.
pub(crate) fn usage(what: impl std::fmt::Display) -> anyhow::Error {
    arbor::Error::Usage(what.to_string()).into()
}

/// Writes `text` to stdout (an error, not a panic, when the reader has gone).
pub(crate) fn print_out(text: &str) -> std::io::Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())?;
    out.flush()
}

/// Opens the Vulkan device `--device` names, with validation when asked (`--validation`
/// or `ARBOR_VALIDATION=1`) and `ARBOR_MAX_STORAGE_RANGE` applied.
pub(crate) fn context(d: &DeviceArgs) -> Result<Context> {
    let validation = d.validation || std::env::var("ARBOR_VALIDATION").is_ok_and(|v| v == "1");
    let max_storage_range = match std::env::var("ARBOR_MAX_STORAGE_RANGE") {
        Ok(v) => Some(v.parse::<u64>().with_context(|| format!("ARBOR_MAX_STORAGE_RANGE={v:?} is not a byte count"))?),
        Err(_) => None,
    };
    Ok(Context::new(&ContextOptions { device: d.device.clone(), validation, max_storage_range })?)
}

/// `--accel`: a structure name, or `auto` resolved by the cost model (with its reason).
/// With `--build gpu`, auto picks among the kinds the device builds.
pub(crate) fn resolve_accel(
    s: &str,
    scene: &Scene,
    pixels: u64,
    spp: u32,
    build: arbor::accel::BuildOn,
) -> Result<(AccelKind, Option<String>)> {
    if s == "auto" {
        let (k, why) = arbor::accel::auto::choose_built(scene, pixels, spp, build)?;
        return Ok((k, Some(why)));
    }
    let k: AccelKind = s.parse().map_err(|e: String| usage(format!("--accel {s}: {e}, or auto")))?;
    Ok((k, None))
}

/// The cost model for `--accel auto` on `ctx`'s device: its `arbor calibrate` file if
/// there is a sound one (a foreign or corrupt one is named in a warning), else the
/// built-in constants.
pub(crate) fn device_costs(ctx: &Context) -> arbor::accel::auto::Costs {
    let (costs, warning) = arbor::accel::calibrate::device_costs(ctx.info());
    if let Some(w) = warning {
        eprintln!("arbor: warning: {w}");
    }
    costs
}

/// `--size WIDTHxHEIGHT`, each side within the film limit.
pub(crate) fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) =
        s.split_once(['x', 'X']).ok_or_else(|| usage(format!("--size {s:?}: expected WIDTHxHEIGHT, e.g. 640x480")))?;
    let w: u32 = w.trim().parse().map_err(|e| usage(format!("--size {s:?}: bad width: {e}")))?;
    let h: u32 = h.trim().parse().map_err(|e| usage(format!("--size {s:?}: bad height: {e}")))?;
    if w == 0 || h == 0 || w > arbor::scene::MAX_FILM_SIDE || h > arbor::scene::MAX_FILM_SIDE {
        return Err(usage(format!("--size {s}: each side must be 1..={}", arbor::scene::MAX_FILM_SIDE)));
    }
    Ok((w, h))
}

/// Milliseconds since `since`.
pub(crate) fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// Samples per pixel of `arbor render --integrator path` without --spp: enough for a
/// clean image of the built-in scenes (README, "Path tracing").
pub(crate) const DEFAULT_PATH_SPP: u32 = 64;

/// The scene with its instances flattened into copies where asked, or where brute
/// force (which has no instance level) will trace it.
pub(crate) fn flatten_if(scene: Scene, asked: bool, accel: AccelKind, quiet: bool) -> Result<Scene> {
    if !scene.has_instances() || !(asked || accel.is_brute_force()) {
        return Ok(scene);
    }
    if !asked && !quiet {
        eprintln!("accel none: brute force has no instance level; drawing the instances as copies");
    }
    Ok(scene.flattened()?)
}

/// Starts recording the timeline `--trace-events` asks for (checking its name, and for
/// a picture the font, first): the process is named `arbor COMMAND`.
pub(crate) fn start_trace(t: &TraceArgs, command: &str) -> Result<Option<arbor::timeline::Recording>> {
    let Some(path) = &t.trace_events else { return Ok(None) };
    if arbor::render::output::trace_is_png(path)? {
        arbor::render::output::heatmap::font()?;
    }
    let opts = arbor::timeline::Options { align_at_submit: t.trace_align_submit, process: format!("arbor {command}") };
    let rec = arbor::timeline::start(opts)?;
    arbor::timeline::meta("arbor_version", env!("CARGO_PKG_VERSION"));
    let args: Vec<String> = std::env::args_os().map(|s| s.to_string_lossy().into_owned()).collect();
    arbor::timeline::meta("command_line", args);
    Ok(Some(rec))
}

/// Adds the device's facts to the timeline being recorded (if any).
pub(crate) fn trace_device(ctx: &Context) {
    let i = ctx.info();
    arbor::timeline::meta("device", i.name.as_str());
    arbor::timeline::meta("driver", i.driver.as_str());
    arbor::timeline::meta("timestamp_period_ns", f64::from(i.timestamp_period_ns));
    arbor::timeline::meta("gpu_timestamps", ctx.has_timestamps());
}

/// `--aov-scale`: the scale of the heatmap PNGs; refused when no AOV is a PNG. With
/// one, the font is checked now rather than after the render.
pub(crate) fn aov_scale(
    arg: Option<&str>,
    aovs: &[(String, std::path::PathBuf)],
) -> Result<arbor::render::output::heatmap::Scale> {
    if arbor::render::output::has_heatmap(aovs) {
        arbor::render::output::heatmap::font()?;
    } else if let Some(s) = arg {
        return Err(usage(format!(
            "--aov-scale {s}: it sets the colour scale of the heatmap AOVs written as .png ({}), and no --aov is one",
            arbor::render::output::HEATMAP_AOVS.join(", ")
        )));
    }
    Ok(arg.map(str::parse).transpose().map_err(usage)?.unwrap_or_default())
}

/// Prints what the scene's files have that arbor does not read, one line each.
pub fn warn_scene(scene: &arbor::scene::Scene) {
    for w in &scene.warnings {
        eprintln!("arbor: warning: {w}");
    }
}
