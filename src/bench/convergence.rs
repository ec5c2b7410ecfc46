//! `arbor bench --reference REF.exr`: the speed-for-accuracy trade. For each structure
//! and integrator, a ladder of sample counts is rendered; each row has the time to
//! image (build + trace, wall clock), the error against the reference (relative MSE,
//! MSE, PSNR; `render::output::compare`) and the efficiency 1 / (relMSE x seconds), the figure
//! of merit for equal-time and equal-error comparisons. `--out DIR` adds
//! `convergence.csv` and a log-log plot of error against time.

use std::path::Path;
use std::time::Instant;

use crate::accel::{Accel, AccelKind, AccelParams};
use crate::error::{Error, Result};
use crate::gpu::Context;
use crate::render::output::compare::{compare, read_linear, ErrorStats};
use crate::render::output::OutputSet;
use crate::render::{Integrator, RenderSettings};
use crate::scene::Scene;

use super::Progress;

/// Default sample counts of the ladder.
pub const DEFAULT_LADDER: [u32; 4] = [1, 4, 16, 64];

/// Columns of convergence.csv.
pub const COLUMNS: &[&str] =
    &["scene", "accel", "integrator", "spp", "seconds", "build_ms", "trace_ms", "rel_mse", "mse", "psnr", "efficiency"];

/// One rendered rung of the ladder.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Rung {
    pub scene: String,
    pub accel: String,
    pub integrator: String,
    pub spp: u32,
    /// Wall time to image: structure build plus render, seconds.
    pub seconds: f64,
    pub build_ms: f64,
    /// GPU time of the trace (timestamps), when the device has them.
    pub trace_ms: Option<f64>,
    pub rel_mse: f64,
    pub mse: f64,
    pub psnr: f64,
    /// 1 / (relMSE x seconds).
    pub efficiency: f64,
}

/// What to run.
#[derive(Debug, Clone)]
pub struct Ladder {
    pub reference: std::path::PathBuf,
    pub accel: Vec<AccelKind>,
    pub params: AccelParams,
    pub integrators: Vec<Integrator>,
    pub spp: Vec<u32>,
    pub seed: u32,
}

/// The table header printed before the rows.
pub const HEADER: &str =
    "           scene            accel integrator      spp    seconds     relMSE        PSNR  efficiency";

fn line(r: &Rung) -> String {
    format!(
        "{:>16} {:>16} {:>10} {:>8} {:>10.3} {:>10.3e} {:>8.2} dB {:>11.1}",
        r.scene, r.accel, r.integrator, r.spp, r.seconds, r.rel_mse, r.psnr, r.efficiency
    )
}

/// Renders every rung of `ladder` on `scene` (whose film must be the reference's size),
/// printing a line per rung through `print`.
pub fn run(
    ctx: &Context,
    scene: &Scene,
    ladder: &Ladder,
    progress: &dyn Progress,
    mut print: impl FnMut(&str) -> Result<()>,
) -> Result<Vec<Rung>> {
    let (w, h, reference) = read_linear(&ladder.reference)?;
    if (w, h) != (scene.width, scene.height) {
        return Err(Error::Failed(format!(
            "{}: the reference is {w}x{h} but {} renders at {}x{}",
            ladder.reference.display(),
            scene.name,
            scene.width,
            scene.height
        )));
    }
    let short = scene.name.strip_prefix("builtin:").unwrap_or(&scene.name).to_string();
    let total = (ladder.accel.len() * ladder.integrators.len() * ladder.spp.len()) as u64;
    progress.set_length(total);
    let mut rows = Vec::new();
    for &kind in &ladder.accel {
        for &integrator in &ladder.integrators {
            for &spp in &ladder.spp {
                progress.message(format!("{} {} {} spp", kind.name(), integrator.name(), spp));
                let mut s = RenderSettings::for_size(w, h);
                s.integrator = integrator;
                s.spp = spp;
                s.seed = ladder.seed;
                s.accel = kind;
                s.params = ladder.params;
                let start = Instant::now();
                let accel = Accel::build_on(ctx, kind, scene, &ladder.params)?;
                let (frame, st) = crate::render::gpu::render_with(ctx, scene, &s, &accel, |_, _| {})?;
                let seconds = start.elapsed().as_secs_f64();
                let ErrorStats { mse, rel_mse, psnr, .. } = compare(&frame.radiance, &reference);
                let r = Rung {
                    scene: short.clone(),
                    accel: kind.name().to_string(),
                    integrator: integrator.name().to_string(),
                    spp,
                    seconds,
                    build_ms: st.build_ms,
                    trace_ms: st.trace_ms,
                    rel_mse,
                    mse,
                    psnr,
                    efficiency: if rel_mse > 0.0 { 1.0 / (rel_mse * seconds) } else { f64::INFINITY },
                };
                print(&line(&r))?;
                rows.push(r);
                progress.inc(1);
            }
        }
    }
    Ok(rows)
}

/// convergence.csv and the error-against-time plot (PNG and SVG) in `dir`.
pub fn write(dir: &Path, rows: &[Rung]) -> Result<()> {
    let mut csv = COLUMNS.join(",");
    csv.push('\n');
    for r in rows {
        let trace = r.trace_ms.map(|t| format!("{t}")).unwrap_or_default();
        csv += &format!(
            "{},{},{},{},{},{},{},{},{},{},{}\n",
            r.scene, r.accel, r.integrator, r.spp, r.seconds, r.build_ms, trace, r.rel_mse, r.mse, r.psnr, r.efficiency
        );
    }
    let mut set = OutputSet::new();
    set.add(&dir.join("convergence.csv"), csv.as_bytes())?;
    set.commit()?;
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for r in rows {
        let label = format!("{} {}", r.accel, r.integrator);
        match series.iter_mut().find(|s| s.0 == label) {
            Some(s) => s.1.push((r.seconds, r.rel_mse)),
            None => series.push((label, vec![(r.seconds, r.rel_mse)])),
        }
    }
    let title = rows.first().map(|r| format!("error against time: {}", r.scene)).unwrap_or_default();
    super::plots::loglog(&dir.join("convergence"), &title, "seconds to image", "relative MSE", &series)?;
    Ok(())
}
