//! False-colour pictures of per-pixel counts: the `cost`, `nodes` and `tests` AOVs
//! written as PNG (`render --aov cost=heat.png`) and `arbor bench`'s side-by-side
//! figures (one panel per structure, one colour scale for all of them).
//!
//! A [`Figure`] is drawn into an RGB buffer and encoded as PNG bytes ([`Figure::png`]),
//! so that it joins an [`crate::render::output::OutputSet`] like every other output. The image
//! holds, from the top: the title; the maps (each panel titled, the counts at an integer
//! zoom, [`Layout::zoom`], so that a map's longer side is at least [`MIN_MAP_SIDE`]
//! pixels); on the right the colour bar with tick labels, the minimum at the bottom and
//! the maximum at the top; under it all, what is counted and the range and scale.
//!
//! Colours are viridis (van der Walt and Smith, matplotlib 1.5, 2015): perceptually
//! uniform, its lightness rising monotonically from dark purple to yellow, readable in
//! grey and by colour-blind readers. [`VIRIDIS`] holds 17 of the 256 entries of the
//! published table; [`viridis`] interpolates between them.
//!
//! Text is drawn in DejaVu Sans, compiled into the binary ([`embedded_font`]), so
//! pictures need no system font and look the same on every machine; `ARBOR_FONT=path.ttf`
//! draws them in another font instead. See [`font`].

use std::sync::OnceLock;

use plotters::prelude::*;
use plotters::style::{FontStyle, IntoFont, TextStyle};

use crate::error::{Error, Result};

/// A map's longer side is zoomed (by an integer factor) to at least this many pixels.
pub const MIN_MAP_SIDE: u32 = 256;

/// The font text is drawn in unless `ARBOR_FONT` names another: DejaVu Sans (Bitstream
/// Vera licence: free to use, embed and redistribute), 757 KB, from the `dejavu` crate.
/// It covers every character arbor writes (`µ`, `…` included), and plotters places its
/// glyphs evenly (plotters 0.3.7 drops each glyph's left side bearing, which fonts such
/// as Noto Sans show as uneven gaps inside words).
pub fn embedded_font() -> &'static [u8] {
    dejavu::sans::regular()
}

/// Registers the font plotters draws text with ("sans-serif"), once per process: the
/// file `ARBOR_FONT` names (an empty value counts as unset), else [`embedded_font`].
/// System fonts are never looked up (plotters reads fonts with ab_glyph, not
/// fontconfig). The error, for an `ARBOR_FONT` that cannot be read or is not a font,
/// names the file; commands that draw call this before any work, so that such an
/// error leaves no output behind.
pub fn font() -> Result<()> {
    static DONE: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        let (bytes, what): (&'static [u8], String) = match std::env::var_os("ARBOR_FONT").filter(|p| !p.is_empty()) {
            Some(p) => {
                let p = std::path::PathBuf::from(p);
                let bytes =
                    std::fs::read(&p).map_err(|e| format!("ARBOR_FONT={}: cannot read the font: {e}", p.display()))?;
                (Box::leak(bytes.into_boxed_slice()), format!("ARBOR_FONT={}", p.display()))
            }
            None => (embedded_font(), "the embedded DejaVu Sans".into()),
        };
        plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
            .map_err(|_| format!("{what}: not a TrueType/OpenType font"))
    })
    .clone()
    .map_err(Error::Failed)
}

/// Viridis control points: (index in the published 256-entry table, sRGB in [0, 1]),
/// entries 0, 16, ..., 240 and 255. Entry `i` is the colour at `t = i / 255`.
pub const VIRIDIS: [(u8, [f32; 3]); 17] = [
    (0, [0.267004, 0.004874, 0.329415]),
    (16, [0.282327, 0.094955, 0.417331]),
    (32, [0.278826, 0.175490, 0.483397]),
    (48, [0.258965, 0.251537, 0.524736]),
    (64, [0.229739, 0.322361, 0.545706]),
    (80, [0.199430, 0.387607, 0.554642]),
    (96, [0.172719, 0.448791, 0.557885]),
    (112, [0.149039, 0.508051, 0.557250]),
    (128, [0.127568, 0.566949, 0.550556]),
    (144, [0.120638, 0.625828, 0.533488]),
    (160, [0.157851, 0.683765, 0.501686]),
    (176, [0.246070, 0.738910, 0.452024]),
    (192, [0.369214, 0.788888, 0.382914]),
    (208, [0.515992, 0.831158, 0.294279]),
    (224, [0.678489, 0.863742, 0.189503]),
    (240, [0.845561, 0.887322, 0.099702]),
    (255, [0.993248, 0.906157, 0.143936]),
];

/// Viridis at `t` in [0, 1] (clamped; NaN is 0) as 8-bit sRGB: linear interpolation in
/// sRGB between the two [`VIRIDIS`] points around `t`.
pub fn viridis(t: f64) -> [u8; 3] {
    viridis_srgb(t).map(|c| (c * 255.0).round() as u8)
}

/// [`viridis`] before rounding: sRGB in [0, 1].
fn viridis_srgb(t: f64) -> [f64; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) } * 255.0;
    let k = VIRIDIS.iter().position(|p| f64::from(p.0) >= t).unwrap_or(VIRIDIS.len() - 1).max(1);
    let ((i0, a), (i1, b)) = (VIRIDIS[k - 1], VIRIDIS[k]);
    let f = ((t - f64::from(i0)) / f64::from(i1 - i0)).clamp(0.0, 1.0);
    std::array::from_fn(|c| f64::from(a[c]) + (f64::from(b[c]) - f64::from(a[c])) * f)
}

/// How counts map to colours.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    /// Colour position proportional to the count.
    #[default]
    Linear,
    /// Colour position proportional to log(1 + count): detail among the cheap pixels
    /// next to a few very expensive ones.
    Log,
}

impl Scale {
    pub fn name(self) -> &'static str {
        match self {
            Scale::Linear => "linear",
            Scale::Log => "log",
        }
    }

    /// The count `v` on the axis the colours are spread over.
    fn axis(self, v: f64) -> f64 {
        match self {
            Scale::Linear => v,
            Scale::Log => v.max(0.0).ln_1p(),
        }
    }

    /// What the scale is, as written under the maps.
    fn describe(self) -> &'static str {
        match self {
            Scale::Linear => "linear scale",
            Scale::Log => "log scale: colour follows log(1 + value)",
        }
    }
}

impl std::str::FromStr for Scale {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "linear" => Ok(Scale::Linear),
            "log" => Ok(Scale::Log),
            _ => Err(format!("unknown scale '{s}' (expected linear or log)")),
        }
    }
}

/// The colour of the count `v` on a scale from `lo` (viridis 0) to `hi` (viridis 1);
/// every value is `lo`'s colour when `hi <= lo`.
pub fn colour(v: f64, lo: f64, hi: f64, scale: Scale) -> [u8; 3] {
    let (a, b) = (scale.axis(lo), scale.axis(hi));
    if b <= a {
        return viridis(0.0);
    }
    viridis((scale.axis(v) - a) / (b - a))
}

/// One map of a figure: `values` row-major, row 0 at the top, `width` x `height`.
#[derive(Debug, Clone)]
pub struct Panel<'a> {
    /// Drawn above the map (e.g. the structure); empty for none.
    pub title: String,
    pub width: u32,
    pub height: u32,
    pub values: &'a [f32],
}

/// One picture: panels side by side (at most [`Figure::COLUMNS`] a row) on one colour
/// scale, from the least to the greatest value of all panels.
#[derive(Debug, Clone)]
pub struct Figure<'a> {
    /// The first line (e.g. the scene and the image size).
    pub title: String,
    /// What a value counts, written under the maps (wrapped to the figure's width).
    pub counted: String,
    pub scale: Scale,
    pub panels: Vec<Panel<'a>>,
}

/// Where a [`Figure`]'s parts are, in pixels from the top-left corner.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    pub width: u32,
    pub height: u32,
    /// Every map is drawn at `zoom` x its size (nearest neighbour).
    pub zoom: u32,
    /// The top-left corner of each panel's map.
    pub maps: Vec<(u32, u32)>,
    /// The colour bar: x, y, width, height (maximum at the top row, minimum at the bottom).
    pub bar: (u32, u32, u32, u32),
    /// Tick labels: (value, text, y of the tick).
    pub ticks: Vec<(f64, String, u32)>,
    /// The lines under the maps, and the y of the first.
    pub footer: (Vec<String>, u32),
}

const MARGIN: u32 = 12;
const GAP: u32 = 16;
const TITLE_FONT: f64 = 18.0;
const TITLE_LINE: u32 = 28;
const PANEL_FONT: f64 = 15.0;
const PANEL_LINE: u32 = 22;
const TEXT_FONT: f64 = 13.0;
const TEXT_LINE: u32 = 18;
const BAR_GAP: u32 = 18;
const BAR_WIDTH: u32 = 18;
const MIN_BAR: u32 = 160;
const MIN_WIDTH: u32 = 460;

fn style(size: f64) -> TextStyle<'static> {
    ("sans-serif", size).into_font().color(&BLACK)
}

/// The width of `text` in pixels at `size`.
fn text_width(text: &str, size: f64) -> Result<u32> {
    let (w, _) = ("sans-serif", size)
        .into_font()
        .box_size(text)
        .map_err(|e| Error::Failed(format!("heatmap: measuring text failed: {e:?}")))?;
    Ok(w)
}

/// `text` in lines of at most `width` pixels, broken between words (a word wider than
/// the line stands alone).
fn wrap(text: &str, size: f64, width: u32) -> Result<Vec<String>> {
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        let candidate = if line.is_empty() { word.to_string() } else { format!("{line} {word}") };
        if !line.is_empty() && text_width(&candidate, size)? > width {
            lines.push(std::mem::replace(&mut line, word.to_string()));
        } else {
            line = candidate;
        }
    }
    if !line.is_empty() {
        lines.push(line);
    }
    Ok(lines)
}

/// A count as written on the bar: an integer when it is one, else 3 significant digits.
pub fn label(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 {
        format!("{v:.0}")
    } else {
        format!("{:.*}", (2 - v.abs().log10().floor().clamp(-3.0, 2.0) as i32).max(0) as usize, v)
    }
}

/// Values between `lo` and `hi` (exclusive) worth a tick: 1-2-5 steps (linear), or
/// 0 and 1, 2, 5, 10, 20, 50, ... (log; only the powers of ten when that is too many).
fn tick_values(lo: f64, hi: f64, scale: Scale) -> Vec<f64> {
    let inside = |v: &f64| *v > lo && *v < hi;
    match scale {
        Scale::Linear => {
            let raw = (hi - lo) / 5.0;
            if !(raw > 0.0 && raw.is_finite()) {
                return Vec::new();
            }
            let mag = 10f64.powf(raw.log10().floor());
            let step = [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
            let first = (lo / step).floor() as i64 + 1;
            (first..).map(|k| k as f64 * step).take_while(|v| *v < hi).filter(inside).collect()
        }
        Scale::Log => {
            let mut all = vec![0.0];
            let mut decade = 1.0;
            while decade <= hi && all.len() < 64 {
                all.extend([decade, 2.0 * decade, 5.0 * decade]);
                decade *= 10.0;
            }
            let some: Vec<f64> = all.iter().copied().filter(inside).collect();
            if some.len() <= 8 {
                some
            } else {
                some.into_iter().filter(|v| *v == 0.0 || v.log10().fract() == 0.0).collect()
            }
        }
    }
}

impl Figure<'_> {
    /// Panels a row holds at most.
    pub const COLUMNS: usize = 4;

    /// The least and greatest value of all panels (non-finite values are skipped; (0, 0)
    /// when there is none).
    pub fn range(&self) -> (f64, f64) {
        let vals = self.panels.iter().flat_map(|p| p.values.iter()).filter(|v| v.is_finite()).map(|&v| f64::from(v));
        let (lo, hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        if lo <= hi {
            (lo, hi)
        } else {
            (0.0, 0.0)
        }
    }

    /// Checks the panels: at least one, every one the same non-zero size, with as many
    /// values as pixels. Returns that size.
    fn panel_size(&self) -> Result<(u32, u32)> {
        let first = self.panels.first().ok_or_else(|| Error::Failed("heatmap: no panel to draw".into()))?;
        let (w, h) = (first.width, first.height);
        for p in &self.panels {
            if (p.width, p.height) != (w, h) || w == 0 || h == 0 {
                return Err(Error::Failed(format!(
                    "heatmap: panel '{}' is {}x{}; every panel must be the same non-empty size ({w}x{h})",
                    p.title, p.width, p.height
                )));
            }
            if p.values.len() as u64 != u64::from(w) * u64::from(h) {
                return Err(Error::Failed(format!(
                    "heatmap: panel '{}' holds {} values for {w}x{h} pixels",
                    p.title,
                    p.values.len()
                )));
            }
        }
        Ok((w, h))
    }

    /// Where everything goes (needs the font: text is measured).
    pub fn layout(&self) -> Result<Layout> {
        font()?;
        let (w, h) = self.panel_size()?;
        let zoom = MIN_MAP_SIDE.div_ceil(w.max(h)).max(1);
        let (mw, mh) = (w * zoom, h * zoom);
        let n = self.panels.len() as u32;
        let cols = n.min(Self::COLUMNS as u32);
        let rows = n.div_ceil(cols);
        let ptitle = if self.panels.iter().any(|p| !p.title.is_empty()) { PANEL_LINE } else { 0 };
        let top = MARGIN + TITLE_LINE;
        let maps: Vec<(u32, u32)> = (0..n)
            .map(|k| (MARGIN + (k % cols) * (mw + GAP), top + (k / cols) * (ptitle + mh + GAP) + ptitle))
            .collect();
        let maps_right = MARGIN + cols * mw + (cols - 1) * GAP;
        let maps_bottom = top + rows * (ptitle + mh) + (rows - 1) * GAP;
        let bar_y = top + ptitle;
        let bar_h = (maps_bottom - bar_y).max(MIN_BAR);
        let bar_x = maps_right + BAR_GAP;
        let (lo, hi) = self.range();
        // Tick labels: the ends always, inner ticks where they keep clear of the others.
        let y_of = |v: f64| -> u32 {
            let (a, b) = (self.scale.axis(lo), self.scale.axis(hi));
            let t = if b > a { (self.scale.axis(v) - a) / (b - a) } else { 0.0 };
            bar_y + ((1.0 - t) * f64::from(bar_h - 1)).round() as u32
        };
        let mut ticks = vec![(hi, label(hi), y_of(hi))];
        if hi > lo {
            ticks.push((lo, label(lo), y_of(lo)));
        }
        for v in tick_values(lo, hi, self.scale) {
            let y = y_of(v);
            if ticks.iter().all(|t| t.2.abs_diff(y) >= 16) {
                ticks.push((v, label(v), y));
            }
        }
        let mut label_w = 0;
        for t in &ticks {
            label_w = label_w.max(text_width(&t.1, TEXT_FONT)?);
        }
        let width = (bar_x + BAR_WIDTH + 10 + label_w + MARGIN).max(MIN_WIDTH);
        let mut lines = wrap(&self.counted, TEXT_FONT, width - 2 * MARGIN)?;
        let range = format!("min {}, max {}; {}", label(lo), label(hi), self.scale.describe());
        lines.extend(wrap(&range, TEXT_FONT, width - 2 * MARGIN)?);
        let footer_y = maps_bottom.max(bar_y + bar_h) + 10;
        let height = footer_y + lines.len() as u32 * TEXT_LINE + MARGIN;
        Ok(Layout {
            width,
            height,
            zoom,
            maps,
            bar: (bar_x, bar_y, BAR_WIDTH, bar_h),
            ticks,
            footer: (lines, footer_y),
        })
    }

    /// The figure as an RGB8 buffer (row-major, 3 bytes a pixel) and its layout.
    pub fn draw(&self) -> Result<(Layout, Vec<u8>)> {
        let l = self.layout()?;
        let (lo, hi) = self.range();
        let stride = l.width as usize * 3;
        let bytes = stride
            .checked_mul(l.height as usize)
            .ok_or_else(|| Error::Failed(format!("heatmap: {}x{} pixels is too large", l.width, l.height)))?;
        let mut buf = Vec::new();
        buf.try_reserve_exact(bytes)
            .map_err(|_| Error::Failed(format!("heatmap: no memory for a {}x{} picture", l.width, l.height)))?;
        buf.resize(bytes, 255u8);
        let put = |buf: &mut [u8], x: u32, y: u32, c: [u8; 3]| {
            let i = y as usize * stride + x as usize * 3;
            buf[i..i + 3].copy_from_slice(&c);
        };
        for (p, &(x0, y0)) in self.panels.iter().zip(&l.maps) {
            for y in 0..p.height * l.zoom {
                let row = (y / l.zoom) as usize * p.width as usize;
                for x in 0..p.width * l.zoom {
                    let v = p.values[row + (x / l.zoom) as usize];
                    put(&mut buf, x0 + x, y0 + y, colour(f64::from(v), lo, hi, self.scale));
                }
            }
        }
        let (bx, by, bw, bh) = l.bar;
        for y in 0..bh {
            let c = viridis(1.0 - f64::from(y) / f64::from((bh - 1).max(1)));
            for x in 0..bw {
                put(&mut buf, bx + x, by + y, c);
            }
        }
        self.draw_text(&l, &mut buf)?;
        Ok((l, buf))
    }

    /// The title, panel titles, bar outline, ticks and footer, drawn over `buf`.
    fn draw_text(&self, l: &Layout, buf: &mut [u8]) -> Result<()> {
        let err = |e: &dyn std::fmt::Debug| Error::Failed(format!("heatmap: drawing failed: {e:?}"));
        let root = BitMapBackend::with_buffer(buf, (l.width, l.height)).into_drawing_area();
        let i = |v: u32| v as i32;
        root.draw(&Text::new(self.title.clone(), (i(MARGIN), i(MARGIN)), style(TITLE_FONT))).map_err(|e| err(&e))?;
        for (p, &(x, y)) in self.panels.iter().zip(&l.maps) {
            if !p.title.is_empty() {
                let at = (i(x), i(y) - i(PANEL_LINE) + 2);
                root.draw(&Text::new(p.title.clone(), at, style(PANEL_FONT))).map_err(|e| err(&e))?;
            }
        }
        let (bx, by, bw, bh) = l.bar;
        let outline = Rectangle::new([(i(bx) - 1, i(by) - 1), (i(bx + bw), i(by + bh))], BLACK.stroke_width(1));
        root.draw(&outline).map_err(|e| err(&e))?;
        let half = (TEXT_FONT / 2.0) as i32 + 1;
        for (_, text, y) in &l.ticks {
            let tick = PathElement::new(vec![(i(bx + bw), i(*y)), (i(bx + bw + 5), i(*y))], BLACK.stroke_width(1));
            root.draw(&tick).map_err(|e| err(&e))?;
            let at = (i(bx + bw + 8), (i(*y) - half).max(0));
            root.draw(&Text::new(text.clone(), at, style(TEXT_FONT))).map_err(|e| err(&e))?;
        }
        for (k, line) in l.footer.0.iter().enumerate() {
            let at = (i(MARGIN), i(l.footer.1 + k as u32 * TEXT_LINE));
            root.draw(&Text::new(line.clone(), at, style(TEXT_FONT))).map_err(|e| err(&e))?;
        }
        root.present().map_err(|e| err(&e))?;
        Ok(())
    }

    /// The figure as PNG bytes.
    pub fn png(&self) -> Result<Vec<u8>> {
        let (l, buf) = self.draw()?;
        encode_png("heatmap", l.width, l.height, buf)
    }
}

/// An RGB8 picture (row-major, 3 bytes a pixel) as PNG bytes; `what` names it in errors.
pub fn encode_png(what: &str, width: u32, height: u32, rgb: Vec<u8>) -> Result<Vec<u8>> {
    let img = image::RgbImage::from_raw(width, height, rgb)
        .ok_or_else(|| Error::Failed(format!("{what}: image buffer size mismatch")))?;
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).map_err(|e| Error::Failed(format!("{what}: PNG: {e}")))?;
    Ok(out.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Relative luminance of sRGB in [0, 1].
    fn luminance(c: [f64; 3]) -> f64 {
        let lin = |s: f64| if s <= 0.04045 { s / 12.92 } else { ((s + 0.055) / 1.055).powf(2.4) };
        0.2126 * lin(c[0]) + 0.7152 * lin(c[1]) + 0.0722 * lin(c[2])
    }

    #[test]
    fn viridis_endpoints_and_midpoint() {
        assert_eq!(viridis(0.0), [68, 1, 84]);
        assert_eq!(viridis(1.0), [253, 231, 37]);
        // Entry 128 of the table, at t = 128/255.
        assert_eq!(viridis(128.0 / 255.0), [33, 145, 140]);
        assert_eq!(viridis(-3.0), viridis(0.0));
        assert_eq!(viridis(7.0), viridis(1.0));
        assert_eq!(viridis(f64::NAN), viridis(0.0));
    }

    /// Luminance rises along the interpolated map; along its 8-bit colours it never
    /// falls by more than 8-bit rounding can (a dip of 1e-4 where red falls a unit).
    #[test]
    fn viridis_luminance_rises_monotonically() {
        let mut last = -1.0;
        for k in 0..=1000 {
            let y = luminance(viridis_srgb(f64::from(k) / 1000.0));
            assert!(y > last, "luminance falls at t = {}: {y} <= {last}", f64::from(k) / 1000.0);
            last = y;
        }
        let mut last = -1.0;
        for k in 0..=1000 {
            let y = luminance(viridis(f64::from(k) / 1000.0).map(|c| f64::from(c) / 255.0));
            assert!(y >= last - 5e-4, "8-bit luminance falls at t = {}: {y} < {last}", f64::from(k) / 1000.0);
            last = last.max(y);
        }
        assert!(luminance(viridis_srgb(1.0)) > 10.0 * luminance(viridis_srgb(0.0)));
    }

    #[test]
    fn control_points_are_ordered() {
        assert!(VIRIDIS.windows(2).all(|w| w[0].0 < w[1].0));
        assert_eq!((VIRIDIS[0].0, VIRIDIS[16].0), (0, 255));
    }

    #[test]
    fn colour_scales() {
        assert_eq!(colour(0.0, 0.0, 100.0, Scale::Linear), viridis(0.0));
        assert_eq!(colour(100.0, 0.0, 100.0, Scale::Linear), viridis(1.0));
        assert_eq!(colour(50.0, 0.0, 100.0, Scale::Linear), viridis(0.5));
        // log(1 + 9) / log(1 + 99) = 1/2.
        assert_eq!(colour(9.0, 0.0, 99.0, Scale::Log), viridis(0.5));
        assert_ne!(colour(9.0, 0.0, 99.0, Scale::Log), colour(9.0, 0.0, 99.0, Scale::Linear));
        assert_eq!(colour(5.0, 5.0, 5.0, Scale::Linear), viridis(0.0));
        assert_eq!("log".parse::<Scale>(), Ok(Scale::Log));
        assert!("lin".parse::<Scale>().is_err());
    }

    #[test]
    fn labels_and_ticks() {
        assert_eq!(label(412.0), "412");
        assert_eq!(label(0.5), "0.500");
        assert_eq!(tick_values(0.0, 412.0, Scale::Linear), [100.0, 200.0, 300.0, 400.0]);
        assert_eq!(tick_values(3.0, 60.0, Scale::Log), [5.0, 10.0, 20.0, 50.0]);
        assert!(tick_values(4.0, 4.0, Scale::Linear).is_empty());
    }

    /// The embedded font is one plotters can draw with, whatever `ARBOR_FONT` says.
    #[test]
    fn embedded_font_is_a_font() {
        assert!(plotters::style::register_font("arbor-embedded", FontStyle::Normal, embedded_font()).is_ok());
        let (w, h) = ("arbor-embedded", 13.0).into_font().box_size("µs …").expect("measure");
        assert!(w > 10 && h > 5, "{w}x{h}");
    }

    /// Two panels share the scale; the maps hold exactly the colours of their values.
    #[test]
    fn figure_draws_maps_bar_and_text() {
        font().expect("the embedded font, or ARBOR_FONT");
        let a: Vec<f32> = (0..40 * 30).map(|k| (k % 40) as f32).collect();
        let b: Vec<f32> = vec![80.0; 40 * 30];
        let fig = Figure {
            title: "test".into(),
            counted: "nodes visited".into(),
            scale: Scale::Linear,
            panels: vec![
                Panel { title: "a".into(), width: 40, height: 30, values: &a },
                Panel { title: "b".into(), width: 40, height: 30, values: &b },
            ],
        };
        let (l, buf) = fig.draw().expect("draw");
        assert_eq!(l.zoom, 7);
        assert_eq!(buf.len(), (l.width * l.height * 3) as usize);
        let px = |x: u32, y: u32| {
            let i = ((y * l.width + x) * 3) as usize;
            [buf[i], buf[i + 1], buf[i + 2]]
        };
        for (p, &(x0, y0)) in fig.panels.iter().zip(&l.maps) {
            for y in 0..30 {
                for x in 0..40 {
                    let want = colour(f64::from(p.values[(y * 40 + x) as usize]), 0.0, 80.0, Scale::Linear);
                    assert_eq!(px(x0 + x * 7 + 3, y0 + y * 7 + 3), want, "{} ({x}, {y})", p.title);
                }
            }
        }
        // The shared maximum is panel b's: it is all yellow.
        assert_eq!(px(l.maps[1].0, l.maps[1].1), viridis(1.0));
        let (bx, by, _, bh) = l.bar;
        assert_eq!(px(bx + 5, by), viridis(1.0));
        assert_eq!(px(bx + 5, by + bh - 1), viridis(0.0));
        assert!(l.ticks.iter().any(|t| t.1 == "80") && l.ticks.iter().any(|t| t.1 == "0"));
        // Text is drawn: dark pixels in the title strip and the footer.
        let dark = |y0: u32, y1: u32| (y0..y1).any(|y| (0..l.width).any(|x| px(x, y)[0] < 100 && px(x, y)[2] < 100));
        assert!(dark(0, l.maps[0].1 - PANEL_LINE), "title");
        assert!(dark(l.footer.1, l.height), "footer");
        assert!(fig.png().expect("png").starts_with(b"\x89PNG"));
    }

    #[test]
    fn bad_panels_are_errors() {
        font().expect("the embedded font, or ARBOR_FONT");
        let v = vec![1.0f32; 6];
        let mut fig = Figure { title: String::new(), counted: String::new(), scale: Scale::Log, panels: Vec::new() };
        assert!(fig.layout().is_err());
        fig.panels.push(Panel { title: "x".into(), width: 2, height: 2, values: &v });
        assert!(fig.layout().expect_err("size").to_string().contains("6 values"));
        fig.panels[0].height = 3;
        fig.panels.push(Panel { title: "y".into(), width: 3, height: 2, values: &v });
        assert!(fig.layout().expect_err("size").to_string().contains("same"));
    }
}
