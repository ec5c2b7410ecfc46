//! `arbor bench --shards 1,2,4,8`: what splitting a render into shards costs. Each
//! shard is its own `arbor render` process, run one after the other (on a farm they
//! run at once on their own nodes), so that process start, scene load, structure
//! build and Vulkan set-up are paid as a farm pays them; then `arbor merge`.
//! docs/farm.md turns the figures into a model of the efficiency on many nodes.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use anyhow::{bail, Context as _, Result};

/// One shard's figures.
#[derive(Debug, Clone, Copy)]
struct ShardRun {
    /// Process wall time, start to exit.
    wall_s: f64,
    /// The render loop's wall time (uploads, dispatches, readback): `wall_ms` of the
    /// stats.
    trace_s: f64,
    build_s: f64,
    /// Scene load, device opening and kernel compilation.
    load_s: f64,
    device_s: f64,
    kernel_s: f64,
}

fn run_shard(exe: &Path, base: &[String], i: u32, n: u32, by: &str, dir: &Path) -> Result<ShardRun> {
    let part = dir.join(format!("part-{i}.exr"));
    let stats = dir.join(format!("stats-{i}.json"));
    let start = Instant::now();
    let out = Command::new(exe)
        .arg("render")
        .args(base)
        .args(["--shard", &format!("{i}/{n}"), "--shard-by", by, "-q", "-o"])
        .arg(&part)
        .arg("--stats")
        .arg(&stats)
        .output()
        .context("cannot run arbor render")?;
    let wall_s = start.elapsed().as_secs_f64();
    if !out.status.success() {
        bail!("shard {i}/{n}: {}", String::from_utf8_lossy(&out.stderr).trim());
    }
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&stats)?)?;
    let num = |k: &str| json.get(k).and_then(serde_json::Value::as_f64).unwrap_or(0.0) / 1e3;
    Ok(ShardRun {
        wall_s,
        trace_s: num("wall_ms"),
        build_s: num("build_ms"),
        load_s: num("load_ms"),
        device_s: num("device_ms"),
        kernel_s: num("kernel_ms"),
    })
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// One row of the table: the figures of one shard count, in seconds.
#[derive(Debug, Clone, serde::Serialize)]
pub(crate) struct Row {
    pub(crate) shards: u32,
    pub(crate) by: String,
    pub(crate) wall_sum_s: f64,
    pub(crate) wall_max_s: f64,
    pub(crate) loop_max_s: f64,
    pub(crate) fixed_s: f64,
    pub(crate) load_s: f64,
    pub(crate) device_s: f64,
    pub(crate) kernel_s: f64,
    pub(crate) build_s: f64,
    pub(crate) merge_s: f64,
    /// Wall sum against the first row's, in percent.
    pub(crate) overhead_pct: f64,
}

/// The CSV columns of [`Row`], in order.
pub(crate) const CSV_HEADER: &str =
    "shards,by,wall_sum_s,wall_max_s,loop_max_s,fixed_s,load_s,device_s,kernel_s,build_s,merge_s,overhead_pct";

impl Row {
    pub(crate) fn csv(&self) -> String {
        format!(
            "{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.2}",
            self.shards,
            self.by,
            self.wall_sum_s,
            self.wall_max_s,
            self.loop_max_s,
            self.fixed_s,
            self.load_s,
            self.device_s,
            self.kernel_s,
            self.build_s,
            self.merge_s,
            self.overhead_pct
        )
    }
}

/// Removes the shards' scratch directory however the run ends.
struct Scratch(std::path::PathBuf);

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Runs the benchmark: `base` is the render command line after `render` (scene, size,
/// spp, structure); returns the table (one row per shard count) and its rows.
pub(crate) fn run(base: &[String], counts: &[u32], by: &str, quiet: bool) -> Result<(String, Vec<Row>)> {
    let exe = std::env::current_exe().context("cannot find the arbor binary")?;
    let scratch = Scratch(tempfile_dir()?);
    let dir = &scratch.0;
    let mut text = format!(
        "# arbor bench --shards: every shard its own process, one after the other; times in seconds\n\
         # fixed = process wall - render loop, of which load, device, kernel, build (medians); the rest is\n\
         # process start and writing the part\n\
         {:>6} {:>8} {:>10} {:>10} {:>10} {:>8} {:>7} {:>7} {:>7} {:>7} {:>8} {:>9}\n",
        "shards",
        "by",
        "wall sum",
        "wall max",
        "loop max",
        "fixed",
        "load",
        "device",
        "kernel",
        "build",
        "merge",
        "overhead"
    );
    let mut single = None;
    let mut rows = Vec::new();
    for &n in counts {
        let sub = dir.join(format!("n{n}"));
        std::fs::create_dir_all(&sub)?;
        let mut runs = Vec::new();
        for i in 0..n {
            if !quiet {
                eprint!("\rbench --shards: {n} shards, shard {}/{n}   ", i + 1);
            }
            runs.push(run_shard(&exe, base, i, n, by, &sub)?);
        }
        let parts: Vec<_> = (0..n).map(|i| sub.join(format!("part-{i}.exr"))).collect();
        let start = Instant::now();
        let out = Command::new(&exe).args(["merge", "-q", "-o"]).arg(sub.join("merged.exr")).args(&parts).output()?;
        let merge_s = start.elapsed().as_secs_f64();
        if !out.status.success() {
            bail!("merge of {n} shards: {}", String::from_utf8_lossy(&out.stderr).trim());
        }
        let wall_sum: f64 = runs.iter().map(|r| r.wall_s).sum();
        let base_sum = *single.get_or_insert(wall_sum);
        let row = Row {
            shards: n,
            by: by.to_string(),
            wall_sum_s: wall_sum,
            wall_max_s: runs.iter().map(|r| r.wall_s).fold(0.0, f64::max),
            loop_max_s: runs.iter().map(|r| r.trace_s).fold(0.0, f64::max),
            fixed_s: median(runs.iter().map(|r| r.wall_s - r.trace_s).collect()),
            load_s: median(runs.iter().map(|r| r.load_s).collect()),
            device_s: median(runs.iter().map(|r| r.device_s).collect()),
            kernel_s: median(runs.iter().map(|r| r.kernel_s).collect()),
            build_s: median(runs.iter().map(|r| r.build_s).collect()),
            merge_s,
            overhead_pct: 100.0 * (wall_sum / base_sum - 1.0),
        };
        text += &format!(
            "{:>6} {:>8} {:>10.3} {:>10.3} {:>10.3} {:>8.3} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>8.3} {:>8.1}%\n",
            row.shards,
            row.by,
            row.wall_sum_s,
            row.wall_max_s,
            row.loop_max_s,
            row.fixed_s,
            row.load_s,
            row.device_s,
            row.kernel_s,
            row.build_s,
            row.merge_s,
            row.overhead_pct
        );
        rows.push(row);
    }
    if !quiet {
        eprintln!();
    }
    text += "# wall sum: the machine time of all shards; wall max: the longest shard (a farm's time to image,\n\
             # one shard per node); loop max: its render loop; overhead: wall sum against the first row's\n";
    Ok((text, rows))
}

fn tempfile_dir() -> Result<std::path::PathBuf> {
    let dir = std::env::temp_dir().join(format!("arbor-bench-shards-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    Ok(dir)
}
