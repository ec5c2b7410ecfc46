//! The benchmark's files: bench.csv (columns [`CSV_COLUMNS`]), bench.json (every row,
//! with build phases, and the time-to-image tables), and the plots.

use std::path::Path;

use crate::error::{Error, Result};
use crate::render::output::OutputSet;

use super::rows::{Heatmap, Row};
use super::{Options, Progress, RayKind};

/// Columns of bench.csv, in order (the fields of each bench.json row but the build
/// phases; docs/bench.md says what each means).
pub const CSV_COLUMNS: &[&str] = &[
    "scene",
    "triangles",
    "accel",
    "label",
    "intersect",
    "rays",
    "width",
    "height",
    "device",
    "driver",
    "build_ms",
    "build_ms_spread",
    "rebuild_ms",
    "trace_ms",
    "trace_ms_spread",
    "rays_traced",
    "mrays_per_s",
    "msamples_per_s",
    "speedup",
    "bytes",
    "sah_cost",
    "depth",
    "nodes_mean",
    "nodes_p99",
    "prims_mean",
    "prims_p99",
    "fetches_mean",
    "misses_per_million",
    "aimed_escapes_per_million",
    "disagree_per_million",
    "error",
];

fn csv_field(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::Null => String::new(),
        serde_json::Value::String(s) if s.contains([',', '"', '\n']) => format!("\"{}\"", s.replace('"', "\"\"")),
        serde_json::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// bench.csv: a header of [`CSV_COLUMNS`], then one line per row.
pub(super) fn to_csv(rows: &[Row]) -> Result<String> {
    let mut out = CSV_COLUMNS.join(",");
    out.push('\n');
    for r in rows {
        let v = serde_json::to_value(r).map_err(|e| Error::Failed(format!("bench CSV: {e}")))?;
        let line: Vec<String> = CSV_COLUMNS.iter().map(|c| csv_field(&v[*c])).collect();
        out.push_str(&line.join(","));
        out.push('\n');
    }
    Ok(out)
}

/// Time to image: build plus trace for `spp` samples per pixel, per structure, and the
/// samples per pixel from which each structure beats every one that builds faster.
pub(super) fn time_to_image(rows: &[Row]) -> Vec<serde_json::Value> {
    let mut list: Vec<&Row> = rows.iter().filter(|r| r.error.is_none() && !r.brute_force && r.trace_ms > 0.0).collect();
    list.sort_by(|a, b| a.build_ms.total_cmp(&b.build_ms));
    // Path-traced rows trace PATH_SPP samples per pixel; the others one.
    let per_spp =
        |r: &Row| if r.rays == RayKind::Path.name() { r.trace_ms / f64::from(super::PATH_SPP) } else { r.trace_ms };
    let mut out = Vec::new();
    for (k, r) in list.iter().enumerate() {
        // Against each faster-building structure: build_r + s trace_r < build_o + s trace_o.
        let mut wins_from: Option<f64> = Some(0.0);
        for o in &list[..k] {
            if per_spp(r) >= per_spp(o) {
                wins_from = None;
                break;
            }
            let s = (r.build_ms - o.build_ms) / (per_spp(o) - per_spp(r));
            wins_from = wins_from.map(|w| w.max(s));
        }
        let totals: Vec<(u32, f64)> =
            [1u32, 4, 16, 64, 256].iter().map(|&s| (s, r.build_ms + f64::from(s) * per_spp(r))).collect();
        out.push(serde_json::json!({
            "label": r.label, "build_ms": r.build_ms, "trace_ms_per_spp": per_spp(r),
            "beats_faster_builders_from_spp": wins_from, "total_ms": totals,
        }));
    }
    out
}

/// The time-to-image table of one scene and ray kind, as printed.
pub(super) fn time_to_image_text(short: &str, rays: RayKind, t: &[serde_json::Value]) -> String {
    let lines: Vec<String> = t
        .iter()
        .map(|v| {
            let from = match v["beats_faster_builders_from_spp"].as_f64() {
                Some(s) if s <= 0.0 => "always".to_string(),
                Some(s) => format!("from {s:.1} spp"),
                None => "never".to_string(),
            };
            let totals: Vec<String> = v["total_ms"]
                .as_array()
                .map(|a| a.iter().map(|p| format!("{:.0}", p[1].as_f64().unwrap_or(0.0))).collect())
                .unwrap_or_default();
            format!(
                "    {:>16}  total ms at 1/4/16/64/256 spp: {:<40} beats faster builders {from}",
                v["label"].as_str().unwrap_or(""),
                totals.join(" / ")
            )
        })
        .collect();
    format!("  time to image, {short}, {} rays:\n{}", rays.name(), lines.join("\n"))
}

/// Writes bench.json to `opts.json`, and bench.json, bench.csv and the plots into
/// `opts.out`.
pub(super) fn write(
    opts: &Options,
    rows: &[Row],
    tti: &[serde_json::Value],
    heatmaps: &[Heatmap],
    progress: &dyn Progress,
) -> Result<()> {
    let json = serde_json::to_vec_pretty(&serde_json::json!({ "rows": rows, "time_to_image": tti }))
        .map_err(|e| Error::Failed(format!("bench JSON: {e}")))?;
    // The JSON and CSV files appear together or not at all.
    let mut set = OutputSet::new();
    if let Some(p) = &opts.json {
        set.add(p, &json)?;
    }
    if let Some(d) = &opts.out {
        set.add(&d.join("bench.json"), &json)?;
        set.add(&d.join("bench.csv"), to_csv(rows)?.as_bytes())?;
    }
    let mut spans = None;
    if let Some(p) = &opts.trace_events {
        let trace = crate::timeline::take()
            .ok_or_else(|| Error::Failed(format!("{}: no timeline was recorded on this thread", p.display())))?;
        set.add(p, &crate::render::output::encode_trace(p, &trace)?)?;
        spans = Some((p, trace.events.len()));
    }
    set.commit()?;
    if let Some((p, n)) = spans {
        progress.note(&format!("wrote {} ({n} spans)", p.display()));
    }
    if let Some(d) = &opts.out {
        progress.note(&format!("wrote {} and {}", d.join("bench.csv").display(), d.join("bench.json").display()));
        let dir: &Path = &d.join("plots");
        let plots = super::plots::bench_plots(dir, rows, heatmaps, opts.intersect[0].name(), opts.heatmap_scale)?;
        progress.note(&format!("wrote {} plots in {}", plots.len(), dir.display()));
    }
    Ok(())
}
