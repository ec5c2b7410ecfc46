//! Benchmark plots (PNG and SVG, drawn with plotters): Mrays/s per structure, build
//! time against triangle count (log-log), time to image against samples per pixel,
//! and one cost figure per scene: the nodes each structure visits per pixel, side by side
//! on one colour scale ([`crate::render::output::heatmap`]).
//!
//! Text is drawn in the font built into the binary (DejaVu Sans), or the one
//! `ARBOR_FONT=path.ttf` names ([`crate::render::output::heatmap::font`]); no system font is
//! needed. SVG files name the family `sans-serif` and leave the font to the viewer.
//! `bench_plots` draws every chart of a run.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::error::{Error, Result};

/// Pixel size of the chart images.
pub const CHART_SIZE: (u32, u32) = (900, 560);

use crate::render::output::heatmap::{font, Figure, Panel, Scale};

fn plot_err(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Failed(format!("{}: drawing the plot failed: {e}", path.display()))
}

/// Draws `draw` into `stem.png` and `stem.svg`; returns both paths.
fn both(
    stem: &Path,
    draw: impl Fn(DrawingArea<SVGBackend, Shift>) -> std::result::Result<(), String> + Copy,
    draw_png: impl Fn(DrawingArea<BitMapBackend, Shift>) -> std::result::Result<(), String>,
) -> Result<Vec<PathBuf>> {
    font()?;
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    {
        let root = BitMapBackend::new(&png, CHART_SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(&png, e))?;
        draw_png(root.clone()).map_err(|e| plot_err(&png, e))?;
        root.present().map_err(|e| plot_err(&png, e))?;
    }
    {
        let root = SVGBackend::new(&svg, CHART_SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(&svg, e))?;
        draw(root.clone()).map_err(|e| plot_err(&svg, e))?;
        root.present().map_err(|e| plot_err(&svg, e))?;
    }
    Ok(vec![png, svg])
}

/// Series colour `k`: Tableau's ten, then four more, so that every structure of a full
/// bench (eleven, and the driver's) has its own.
fn color(k: usize) -> RGBColor {
    const C: [RGBColor; 14] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
        RGBColor(0, 0, 0),
        RGBColor(0, 0, 128),
        RGBColor(128, 128, 0),
        RGBColor(255, 215, 0),
    ];
    C[k % C.len()]
}

/// Horizontal bars: Mrays/s per structure.
pub fn mrays_bars(stem: &Path, title: &str, bars: &[(String, f64)]) -> Result<Vec<PathBuf>> {
    fn draw<DB: DrawingBackend>(
        root: DrawingArea<DB, Shift>,
        title: &str,
        bars: &[(String, f64)],
    ) -> std::result::Result<(), String> {
        let max = bars.iter().map(|b| b.1).fold(0.0f64, f64::max).max(1e-9) * 1.1;
        let n = bars.len().max(1);
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(190)
            // A segmented range a..b has a segment for each of a..=b, so n bars need
            // 0..n-1 (and one bar an empty slot above it: plotters draws 0..0 as nothing).
            .build_cartesian_2d(0.0..max, (0..n.max(2) - 1).into_segmented())
            .map_err(|e| e.to_string())?;
        // Bar k is drawn in segment n - 1 - k, so the first bar is at the top.
        let label = |v: &SegmentValue<usize>| match v {
            SegmentValue::CenterOf(i) if *i < n => bars[n - 1 - *i].0.clone(),
            _ => String::new(),
        };
        chart
            .configure_mesh()
            .x_desc("Mrays/s")
            .y_labels(n)
            .y_label_formatter(&label)
            .disable_y_mesh()
            .draw()
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(bars.iter().enumerate().map(|(k, (_, v))| {
                let y = n - 1 - k;
                let mut r = Rectangle::new(
                    [(0.0, SegmentValue::Exact(y)), (*v, SegmentValue::Exact(y + 1))],
                    color(k).filled(),
                );
                r.set_margin(3, 3, 0, 0);
                r
            }))
            .map_err(|e| e.to_string())?;
        Ok(())
    }
    both(stem, |a| draw(a, title, bars), |a| draw(a, title, bars))
}

/// Lines on log-log axes: one series of (x, y) points per label.
pub fn loglog(
    stem: &Path,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    series: &[(String, Vec<(f64, f64)>)],
) -> Result<Vec<PathBuf>> {
    fn draw<DB: DrawingBackend>(
        root: DrawingArea<DB, Shift>,
        title: &str,
        x_desc: &str,
        y_desc: &str,
        series: &[(String, Vec<(f64, f64)>)],
    ) -> std::result::Result<(), String> {
        let pts = series.iter().flat_map(|s| s.1.iter()).filter(|p| p.0 > 0.0 && p.1 > 0.0);
        let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
        for p in pts {
            x0 = x0.min(p.0);
            x1 = x1.max(p.0);
            y0 = y0.min(p.1);
            y1 = y1.max(p.1);
        }
        if !(x0.is_finite() && y0.is_finite()) {
            (x0, x1, y0, y1) = (1.0, 10.0, 1.0, 10.0);
        }
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d((x0 * 0.8..x1 * 1.25).log_scale(), (y0 * 0.8..y1 * 1.25).log_scale())
            .map_err(|e| e.to_string())?;
        chart.configure_mesh().x_desc(x_desc).y_desc(y_desc).draw().map_err(|e| e.to_string())?;
        for (k, (label, points)) in series.iter().enumerate() {
            let c = color(k);
            let pts: Vec<(f64, f64)> = points.iter().copied().filter(|p| p.0 > 0.0 && p.1 > 0.0).collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))
                .map_err(|e| e.to_string())?
                .label(label.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
            chart.draw_series(pts.iter().map(|p| Circle::new(*p, 3, c.filled()))).map_err(|e| e.to_string())?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(|e| e.to_string())?;
        Ok(())
    }
    both(stem, |a| draw(a, title, x_desc, y_desc, series), |a| draw(a, title, x_desc, y_desc, series))
}

/// The cost figure of one scene: a panel per structure (`maps`: label and nodes per
/// pixel, all `width` x `height`, the same camera rays), on one colour scale from the
/// least to the most nodes any structure visited, so that the panels compare. PNG bytes.
pub fn cost_figure(scene: &str, width: u32, height: u32, maps: &[(String, Vec<f32>)], scale: Scale) -> Result<Vec<u8>> {
    let panels = maps.iter().map(|(label, v)| Panel { title: label.clone(), width, height, values: v }).collect();
    Figure {
        title: format!("nodes visited per camera ray: {scene}, {width}x{height}"),
        counted: "nodes visited by the camera ray through each pixel's centre (tree nodes, boxes or cells, \
                  as the structure's row in bench.csv counts them); one colour scale for every panel"
            .into(),
        scale,
        panels,
    }
    .png()
}

/// Draws the benchmark plots into `dir`; returns the files written. Charts use the rows
/// of the first intersection mode, `first_mode`.
pub(super) fn bench_plots(
    dir: &Path,
    rows: &[super::rows::Row],
    heatmaps: &[super::rows::Heatmap],
    first_mode: &str,
    scale: Scale,
) -> Result<Vec<PathBuf>> {
    use super::file_part;
    std::fs::create_dir_all(dir).map_err(|cause| Error::Io { path: dir.to_path_buf(), cause })?;
    let mut files = Vec::new();
    let ok: Vec<&super::rows::Row> = rows.iter().filter(|r| r.error.is_none() && r.intersect == first_mode).collect();
    // Per scene and ray kind: Mrays/s bars and time-to-image curves.
    let mut groups: Vec<(&str, &str)> = ok.iter().map(|r| (r.scene.as_str(), r.rays.as_str())).collect();
    groups.dedup();
    for (scene, rays) in groups {
        let g: Vec<&&super::rows::Row> = ok.iter().filter(|r| r.scene == scene && r.rays == rays).collect();
        let short = scene.strip_prefix("builtin:").unwrap_or(scene);
        let bars: Vec<(String, f64)> = g.iter().map(|r| (r.label.clone(), r.mrays_per_s)).collect();
        let stem = dir.join(format!("mrays_{}_{rays}", file_part(short)));
        files.extend(mrays_bars(&stem, &format!("Mrays/s, {short}, {rays} rays"), &bars)?);
        let spp: Vec<f64> = (0..=10).map(|k| f64::from(1u32 << k)).collect();
        let series: Vec<(String, Vec<(f64, f64)>)> = g
            .iter()
            .filter(|r| !r.brute_force)
            .map(|r| (r.label.clone(), spp.iter().map(|&s| (s, r.build_ms + s * r.trace_ms)).collect()))
            .collect();
        let stem = dir.join(format!("time_to_image_{}_{rays}", file_part(short)));
        let title = format!("time to image, {short}, {rays} rays");
        files.extend(loglog(&stem, &title, "samples per pixel", "build + trace ms", &series)?);
    }
    // Build time against triangle count over the blobs, per structure.
    let blobs: Vec<&&super::rows::Row> =
        ok.iter().filter(|r| r.scene.starts_with("builtin:blob:") && !r.brute_force).collect();
    let mut labels: Vec<&str> = blobs.iter().map(|r| r.accel.as_str()).collect();
    labels.sort_unstable();
    labels.dedup();
    let series: Vec<(String, Vec<(f64, f64)>)> = labels
        .iter()
        .map(|l| {
            let mut pts: Vec<(f64, f64)> =
                blobs.iter().filter(|r| r.accel == *l).map(|r| (r.triangles as f64, r.build_ms)).collect();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            pts.dedup_by(|a, b| a.0 == b.0);
            (l.to_string(), pts)
        })
        .collect();
    if series.iter().any(|s| s.1.len() > 1) {
        let stem = dir.join("build_vs_triangles");
        files.extend(loglog(&stem, "build time", "triangles", "build ms", &series)?);
    }
    // One cost figure per scene: a panel per structure, side by side.
    let mut scenes: Vec<&str> = heatmaps.iter().map(|m| m.scene.as_str()).collect();
    scenes.dedup();
    for scene in scenes {
        let group: Vec<&super::rows::Heatmap> = heatmaps.iter().filter(|m| m.scene == scene).collect();
        let (w, h) = (group[0].width, group[0].height);
        let maps: Vec<(String, Vec<f32>)> =
            group.iter().map(|m| (m.label.clone(), m.nodes.iter().map(|&n| n as f32).collect())).collect();
        let path = dir.join(format!("cost_{}.png", file_part(scene)));
        crate::render::output::write_atomic(&path, &cost_figure(scene, w, h, &maps, scale)?)?;
        files.push(path);
    }
    Ok(files)
}
