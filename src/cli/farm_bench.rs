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

/// Runs the benchmark: `base` is the render command line after `render` (scene, size,
/// spp, structure); prints one row per shard count.
pub(crate) fn run(base: &[String], counts: &[u32], by: &str, quiet: bool) -> Result<String> {
    let exe = std::env::current_exe().context("cannot find the arbor binary")?;
    let dir = tempfile_dir()?;
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
        let wall_max = runs.iter().map(|r| r.wall_s).fold(0.0, f64::max);
        let loop_max = runs.iter().map(|r| r.trace_s).fold(0.0, f64::max);
        let fixed = median(runs.iter().map(|r| r.wall_s - r.trace_s).collect());
        let build = median(runs.iter().map(|r| r.build_s).collect());
        let load = median(runs.iter().map(|r| r.load_s).collect());
        let device = median(runs.iter().map(|r| r.device_s).collect());
        let kernel = median(runs.iter().map(|r| r.kernel_s).collect());
        let base_sum = *single.get_or_insert(wall_sum);
        text += &format!(
            "{n:>6} {by:>8} {wall_sum:>10.3} {wall_max:>10.3} {loop_max:>10.3} {fixed:>8.3} {load:>7.3} {device:>7.3} {kernel:>7.3} {build:>7.3} {merge_s:>8.3} {:>8.1}%\n",
            100.0 * (wall_sum / base_sum - 1.0)
        );
    }
    if !quiet {
        eprintln!();
    }
    let _ = std::fs::remove_dir_all(&dir);
    text += "# wall sum: the machine time of all shards; wall max: the longest shard (a farm's time to image,\n\
             # one shard per node); loop max: its render loop; overhead: wall sum against the first row's\n";
    Ok(text)
}

fn tempfile_dir() -> Result<std::path::PathBuf> {
    let dir = std::env::temp_dir().join(format!("arbor-bench-shards-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    Ok(dir)
}
