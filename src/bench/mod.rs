//! `arbor bench`: builds and traces every requested structure on every scene, ray kind
//! and intersection mode, and reports build and GPU trace times, Mrays/s, speedup over
//! brute force, per-ray cost (mean and p99), cracks, disagreement with the watertight
//! reference, time to image; as a terminal table, `bench.csv`, `bench.json` and plots.
//! Column meanings: docs/bench.md.
//!
//! The parts: [`options`] (defaults, one row per build device and swept parameter),
//! `run` (the rounds), `rows` (figures of a case, table lines), `files` (CSV, JSON),
//! [`plots`]; and [`calibrate`], `arbor calibrate`'s measurement of `--accel auto`'s
//! costs.

#![forbid(unsafe_code)]

use std::path::PathBuf;

use crate::accel::{AccelKind, AccelParams};
use crate::math::intersect::IntersectMode;

pub mod calibrate;
pub mod convergence;
mod files;
pub mod options;
mod photon;
pub mod plots;
mod rows;
mod run;

pub use files::CSV_COLUMNS;
pub use options::Request;
pub use run::{load_scenes, run};

/// Where the benchmark reports as it goes (the CLI's progress bar).
pub trait Progress {
    fn set_length(&self, n: u64);
    fn message(&self, m: String);
    fn inc(&self, n: u64);
    /// A line of the results table (stdout). An error (a closed pipe) ends the run.
    fn line(&self, l: &str) -> std::io::Result<()>;
    /// A note about files written (stderr).
    fn note(&self, l: &str);
}

/// What to run.
#[derive(Debug, Clone)]
pub struct Options {
    /// Scene arguments, in order.
    pub scenes: Vec<String>,
    /// (structure, parameters, row label) to run on every scene.
    pub variants: Vec<(AccelKind, AccelParams, String)>,
    pub rays: Vec<RayKind>,
    pub intersect: Vec<IntersectMode>,
    /// Traversal of coherent rays in the BVH kernels.
    pub traversal: crate::render::Traversal,
    /// How dispatches are sized and kept in flight.
    pub pacing: crate::render::dispatch::PacingChoice,
    /// Camera image size.
    pub size: (u32, u32),
    /// Timed repeats after one warm-up.
    pub repeat: usize,
    /// Directory for bench.csv, bench.json and plots/.
    pub out: Option<PathBuf>,
    /// Extra copy of bench.json.
    pub json: Option<PathBuf>,
    /// Where to write this thread's timeline ([`crate::timeline`], recorded by the
    /// caller) with bench.json and bench.csv: all of them or none.
    pub trace_events: Option<PathBuf>,
    /// Colour scale of the cost figures (`plots/cost_<scene>.png`).
    pub heatmap_scale: crate::render::output::heatmap::Scale,
    /// The structures were not named (`--accel` left at its default): the driver's
    /// structure (`rayquery`) joins them on a device that has ray queries.
    pub with_driver: bool,
}

/// A kind of ray the benchmark traces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RayKind {
    /// Camera rays.
    Primary,
    /// Camera rays, and a shadow ray toward each light from every hit.
    Shadow,
    /// Camera rays, and one cosine-distributed ray from every hit (incoherent).
    Diffuse,
    /// The path tracer at 4 samples per pixel (`PATH_SPP`): camera, bounce and shadow
    /// rays together.
    Path,
}

/// Samples per pixel of the benchmark's path-traced rows.
pub const PATH_SPP: u32 = 4;

impl RayKind {
    pub fn name(self) -> &'static str {
        match self {
            RayKind::Primary => "primary",
            RayKind::Shadow => "shadow",
            RayKind::Diffuse => "diffuse",
            RayKind::Path => "path",
        }
    }
}

/// Median (sorts `v`).
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Max - min.
pub fn spread(v: &[f64]) -> f64 {
    v.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - v.iter().cloned().fold(f64::INFINITY, f64::min)
}

/// The terminal table's header line.
pub const HEADER: &str = "           scene triangles            accel    pixels   build_ms rebuild_ms   trace_ms    spread     Mrays/s   speedup nodes/ray   p99 prims/ray   p99 bytes/tri     SAH depth    miss/M  aimed/M  differ/M";

/// A file-name-safe version of `s` (plot and heatmap file names).
fn file_part(s: &str) -> String {
    s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '.' { c } else { '_' }).collect()
}
