//! What one case measured over its rounds ([`Case`]), and the row it becomes ([`Row`]):
//! medians, spreads, percentiles, the terminal table line.

use crate::accel::Phase;
use crate::render::RenderStats;

use super::{median, spread};

/// One measured case of the benchmark.
pub(super) struct Case {
    pub phases: Vec<Vec<Phase>>,
    pub build_ms: Vec<f64>,
    pub rebuild_ms: Vec<f64>,
    pub trace_ms: Vec<f64>,
    pub rates: Vec<f64>,
    pub stats: RenderStats,
    pub size: (u32, u32),
    /// Camera rays that hit nothing (last repeat; the same in every repeat).
    pub misses: u64,
    /// 99th percentile of nodes visited and primitives tested per camera ray.
    pub nodes_p99: u32,
    pub prims_p99: u32,
    /// Nodes visited per camera ray, per pixel (last repeat), for the cost heatmap.
    pub nodes: Vec<u32>,
    /// Primitive hit per pixel (last repeat), for the comparison with the reference.
    pub prims: Vec<u32>,
}

impl Case {
    /// A case with nothing measured yet, at camera size `size`.
    pub fn new(size: (u32, u32)) -> Case {
        Case {
            phases: Vec::new(),
            build_ms: Vec::new(),
            rebuild_ms: Vec::new(),
            trace_ms: Vec::new(),
            rates: Vec::new(),
            stats: Default::default(),
            size,
            misses: 0,
            nodes_p99: 0,
            prims_p99: 0,
            nodes: Vec::new(),
            prims: Vec::new(),
        }
    }

    /// Median Mrays/s over the timed rounds.
    pub fn rate(&self) -> f64 {
        median(&mut self.rates.clone())
    }
}

/// The median of each phase over repeats (phases matched by name, in first-seen order).
pub(super) fn median_phases(runs: &[Vec<Phase>]) -> Vec<Phase> {
    let Some(first) = runs.first() else { return Vec::new() };
    first
        .iter()
        .map(|p| {
            let mut v: Vec<f64> =
                runs.iter().filter_map(|r| r.iter().find(|q| q.name == p.name)).map(|q| q.ms).collect();
            Phase { name: p.name.clone(), ms: median(&mut v), detail: p.detail.clone() }
        })
        .collect()
}

/// The `q` quantile (0..=1) of `v` by the nearest-rank method.
pub(super) fn quantile(v: &[u32], q: f64) -> u32 {
    if v.is_empty() {
        return 0;
    }
    let mut s = v.to_vec();
    s.sort_unstable();
    let rank = ((q * s.len() as f64).ceil() as usize).clamp(1, s.len());
    s[rank - 1]
}

/// One structure's panel of a scene's cost figure: nodes per pixel of the camera rays.
pub(super) struct Heatmap {
    /// The scene's short name (no `builtin:`).
    pub scene: String,
    /// The structure's row label.
    pub label: String,
    pub width: u32,
    pub height: u32,
    pub nodes: Vec<u32>,
}

/// One row of the benchmark's output (bench.json, bench.csv; columns in docs/bench.md
/// and [`super::CSV_COLUMNS`]).
#[derive(serde::Serialize)]
pub(super) struct Row {
    pub scene: String,
    pub triangles: usize,
    pub accel: String,
    pub label: String,
    pub intersect: String,
    pub rays: String,
    pub width: u32,
    pub height: u32,
    pub device: String,
    pub driver: String,
    pub build_ms: f64,
    pub build_ms_spread: f64,
    pub rebuild_ms: f64,
    pub trace_ms: f64,
    pub trace_ms_spread: f64,
    pub rays_traced: u64,
    pub mrays_per_s: f64,
    /// Path-traced rows: million pixel samples per second (median trace time).
    pub msamples_per_s: Option<f64>,
    pub speedup: Option<f64>,
    pub bytes: u64,
    pub sah_cost: f64,
    pub depth: u32,
    /// Nodes visited and primitives tested per camera ray: mean and 99th percentile;
    /// null where the kernel cannot count them (`rayquery`: the driver's traversal).
    pub nodes_mean: Option<f64>,
    pub nodes_p99: Option<u32>,
    pub prims_mean: Option<f64>,
    pub prims_p99: Option<u32>,
    /// Texel fetches (nodes and triangle records) per camera ray: nodes_mean x the
    /// structure's texels per node + prims_mean x texels per test
    /// ([`crate::accel::AccelKind::texels_per_node`]); null where not counted.
    pub fetches_mean: Option<f64>,
    pub misses_per_million: f64,
    pub aimed_escapes_per_million: Option<f64>,
    pub disagree_per_million: Option<f64>,
    pub error: Option<String>,
    /// Median ms of each build phase (JSON only).
    pub build_phases: Vec<Phase>,
    /// Whether the structure is brute force (the baseline; not written).
    #[serde(skip)]
    pub brute_force: bool,
}

/// Where a row was measured: the columns that do not depend on the figures.
pub(super) struct RowKey<'a> {
    pub scene: &'a str,
    pub triangles: usize,
    pub accel: &'a str,
    pub brute_force: bool,
    pub label: &'a str,
    pub intersect: &'a str,
    pub rays: &'a str,
    pub size: (u32, u32),
    pub device: &'a str,
    pub driver: &'a str,
}

impl Row {
    /// A row with every figure zero (or empty).
    pub fn new(k: &RowKey) -> Row {
        Row {
            scene: k.scene.into(),
            triangles: k.triangles,
            accel: k.accel.into(),
            label: k.label.into(),
            intersect: k.intersect.into(),
            rays: k.rays.into(),
            width: k.size.0,
            height: k.size.1,
            device: k.device.into(),
            driver: k.driver.into(),
            build_ms: 0.0,
            build_ms_spread: 0.0,
            rebuild_ms: 0.0,
            trace_ms: 0.0,
            trace_ms_spread: 0.0,
            rays_traced: 0,
            mrays_per_s: 0.0,
            msamples_per_s: None,
            speedup: None,
            bytes: 0,
            sah_cost: 0.0,
            depth: 0,
            nodes_mean: None,
            nodes_p99: None,
            prims_mean: None,
            prims_p99: None,
            fetches_mean: None,
            misses_per_million: 0.0,
            aimed_escapes_per_million: None,
            disagree_per_million: None,
            error: None,
            build_phases: Vec::new(),
            brute_force: k.brute_force,
        }
    }

    /// Fills the figures from the case's rounds; `brute_rate` is brute force's Mrays/s
    /// in the same intersection mode, if it ran.
    pub fn fill(&mut self, c: &Case, brute_rate: Option<f64>) {
        let st = &c.stats;
        let rate = c.rate();
        let pixels = u64::from(c.size.0) * u64::from(c.size.1);
        self.build_ms = median(&mut c.build_ms.clone());
        self.build_ms_spread = spread(&c.build_ms);
        self.rebuild_ms = median(&mut c.rebuild_ms.clone());
        self.trace_ms = median(&mut c.trace_ms.clone());
        self.trace_ms_spread = spread(&c.trace_ms);
        self.rays_traced = st.rays;
        self.mrays_per_s = rate;
        if st.integrator == "path" && self.trace_ms > 0.0 {
            self.msamples_per_s = Some((pixels * u64::from(st.spp)) as f64 / (self.trace_ms * 1e3));
        }
        self.speedup = brute_rate.map(|b| rate / b);
        self.bytes = st.build.bytes;
        self.sah_cost = st.build.sah_cost;
        self.depth = st.build.max_depth;
        let counted = st.mean_nodes_visited.is_some();
        self.nodes_mean = st.mean_nodes_visited;
        self.nodes_p99 = counted.then_some(c.nodes_p99);
        self.prims_mean = st.mean_prims_tested;
        self.prims_p99 = counted.then_some(c.prims_p99);
        let kind = self.accel.parse::<crate::accel::AccelKind>();
        self.fetches_mean = match (self.nodes_mean, self.prims_mean, kind) {
            (Some(n), Some(p), Ok(kind)) => {
                let per_node = kind.texels_per_node().unwrap_or(0);
                Some(n * f64::from(per_node) + p * f64::from(kind.texels_per_test()))
            }
            _ => None,
        };
        self.misses_per_million = c.misses as f64 * 1e6 / pixels.max(1) as f64;
        self.build_phases = median_phases(&c.phases);
    }

    /// The row's line of the terminal table (columns of [`super::HEADER`]).
    pub fn table_line(&self, short: &str) -> String {
        let nt = self.triangles;
        let opt = |v: Option<f64>| v.map(|a| format!("{a:.0}")).unwrap_or_else(|| "-".into());
        let mean = |v: Option<f64>| v.map(|a| format!("{a:.1}")).unwrap_or_else(|| "-".into());
        let p99 = |v: Option<u32>| v.map(|a| a.to_string()).unwrap_or_else(|| "-".into());
        format!(
            "{:>16} {:>9} {:>16} {:>9} {:>10.2} {:>10.2} {:>10.2} {:>9.2} {:>11.4} {:>9} {:>8} {:>7} {:>8} {:>7} {:>8.1} {:>7.1} {:>5} {:>9.1} {:>9} {:>9}",
            short,
            nt,
            self.label,
            format!("{}x{}", self.width, self.height),
            self.build_ms,
            self.rebuild_ms,
            self.trace_ms,
            self.trace_ms_spread,
            self.mrays_per_s,
            self.speedup.map(|s| format!("{s:.0}x")).unwrap_or_else(|| "-".into()),
            mean(self.nodes_mean),
            p99(self.nodes_p99),
            mean(self.prims_mean),
            p99(self.prims_p99),
            self.bytes as f64 / nt.max(1) as f64,
            self.sah_cost,
            self.depth,
            self.misses_per_million,
            opt(self.aimed_escapes_per_million),
            opt(self.disagree_per_million)
        )
    }

    /// The build phases with their Mtris/s and the GPU phases' total, for comparing a
    /// GPU build with the CPU's.
    pub fn phases_line(&self) -> String {
        let nt = self.triangles as f64;
        let list: Vec<String> = self
            .build_phases
            .iter()
            .map(|p| format!("{} {:.2} ({:.0})", p.name, p.ms, nt / (p.ms * 1e3).max(1e-9)))
            .collect();
        let gpu: f64 = self.build_phases.iter().filter(|p| p.name.starts_with("gpu ")).map(|p| p.ms).sum();
        let gpu = if gpu > 0.0 {
            format!("; GPU total {gpu:.2} ms ({:.1} Mtris/s)", nt / (gpu * 1e3))
        } else {
            String::new()
        };
        format!("    build phases, ms (Mtris/s): {}{gpu}", list.join(", "))
    }
}
