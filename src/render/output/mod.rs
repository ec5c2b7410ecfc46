//! Writers for images (PNG 8-bit sRGB, EXR linear float), AOVs (PFM, EXR; [`aov_channels`]
//! turns a frame into them; the counting AOVs [`HEATMAP_AOVS`] also as false-colour PNG
//! pictures, [`aov_heatmap`]) and the statistics JSON (with its [`Provenance`]). Every
//! file is written whole to a temporary file beside the target, then renamed, so a
//! failed run never leaves a truncated file or clobbers an existing one. The outputs of
//! one run form an [`OutputSet`]: every path is checked before the work starts
//! ([`check_writable`]), every file is written to its temporary file, and only when all
//! of them are written are they renamed; a failure removes the temporary files, so a
//! run leaves either every output or none.

//!
//! Beside them, the other things a render leaves: [`heatmap`] pictures, [`timeline_png`],
//! [`part`]s of a farm render and their [`merge`], [`shard`] plans, [`compare`] of two
//! images, and [`memory`] estimates of what a render's outputs take.

pub mod compare;
pub mod heatmap;
pub mod memory;
pub mod merge;
pub mod part;
pub mod shard;
pub mod timeline_png;

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::render::{Frame, RenderStats};

/// Output formats by extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Png,
    Exr,
    Pfm,
}

/// The format of `path`, checking it is allowed for `what` ("image" or "aov").
pub fn format_of(path: &Path, what: &str) -> Result<Format> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase()).unwrap_or_default();
    match (ext.as_str(), what) {
        ("png", _) => Ok(Format::Png),
        ("exr", _) => Ok(Format::Exr),
        ("pfm", "aov") => Ok(Format::Pfm),
        // An output's name comes from the command line (or its library twin, a setting):
        // a wrong extension is a usage mistake (exit status 2).
        (_, "image") => Err(Error::Usage(format!("{}: the image output must end in .png or .exr", path.display()))),
        _ => Err(Error::Usage(format!(
            "{}: an AOV output must end in .pfm or .exr (or .png, a heatmap, for {})",
            path.display(),
            HEATMAP_AOVS.join(", ")
        ))),
    }
}

/// The directory `path` is written in ("." for a bare file name).
fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A name beside `path` for its temporary file, unique within this process.
fn temp_path(path: &Path) -> PathBuf {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    parent_dir(path).join(format!(".{name}.{}.{n}.tmp", std::process::id()))
}

/// Fails, before any work, if `path` could not be written later: a name ending in `/`,
/// a directory or other non-file at `path`, a parent that is missing or not a directory,
/// or a parent where no file can be created (checked by creating and removing a
/// temporary file there).
pub fn check_writable(path: &Path) -> Result<()> {
    let bad = |msg: String| Err(Error::invalid(path, msg));
    if path.as_os_str().is_empty() {
        return Err(Error::Usage("an output path is empty".into()));
    }
    if path.as_os_str().to_string_lossy().ends_with(['/', std::path::MAIN_SEPARATOR]) || path.file_name().is_none() {
        return bad("names a directory (ends in '/' or '..'); expected a file name".into());
    }
    let dir = parent_dir(path);
    match std::fs::metadata(&dir) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => return bad(format!("{} is not a directory", dir.display())),
        Err(_) => return bad(format!("the directory {} does not exist", dir.display())),
    }
    if let Ok(m) = std::fs::symlink_metadata(path) {
        if m.is_dir() {
            return bad("is a directory".into());
        }
        if !m.is_file() && !m.file_type().is_symlink() {
            return bad("exists and is not a regular file".into());
        }
    }
    let probe = temp_path(path);
    match std::fs::OpenOptions::new().write(true).create_new(true).open(&probe) {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => bad(format!("cannot create a file in {}: {e}", dir.display())),
    }
}

/// Checks every path of one run's outputs ([`check_writable`]) and that no two are the same.
pub fn check_outputs<'a>(paths: impl IntoIterator<Item = &'a Path>) -> Result<()> {
    let mut seen: Vec<&Path> = Vec::new();
    for p in paths {
        check_writable(p)?;
        if seen.contains(&p) {
            return Err(Error::Usage(format!("{}: is given as two outputs", p.display())));
        }
        seen.push(p);
    }
    Ok(())
}

/// The files of one run, written together or not at all: [`OutputSet::add`] writes a
/// file's bytes to a temporary file beside it; [`OutputSet::commit`] renames every
/// temporary file onto its target. Dropping the set uncommitted (an error, a panic)
/// removes the temporary files written so far.
#[derive(Debug, Default)]
pub struct OutputSet {
    /// (temporary file, target), in the order added.
    pending: Vec<(PathBuf, PathBuf)>,
}

impl OutputSet {
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes `bytes` (whole, synced) to a temporary file beside `path`.
    pub fn add(&mut self, path: &Path, bytes: &[u8]) -> Result<()> {
        let span = crate::timeline::span("output", || format!("write {}", path.display()));
        span.arg("bytes", bytes.len());
        let tmp = temp_path(path);
        let written = (|| -> std::io::Result<()> {
            let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
            f.write_all(bytes)?;
            f.sync_all()
        })();
        if let Err(e) = written {
            let _ = std::fs::remove_file(&tmp);
            return Err(Error::io(path, e));
        }
        self.pending.push((tmp, path.to_path_buf()));
        Ok(())
    }

    /// Renames every temporary file onto its target. A rename that fails (after every
    /// file was written: the target turned into a directory meanwhile) removes the
    /// temporary files not yet renamed.
    pub fn commit(mut self) -> Result<()> {
        while !self.pending.is_empty() {
            let (tmp, path) = self.pending.remove(0);
            if let Err(e) = std::fs::rename(&tmp, &path) {
                let _ = std::fs::remove_file(&tmp);
                return Err(Error::io(path, e)); // Drop removes the rest.
            }
        }
        Ok(())
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        for (tmp, _) in &self.pending {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Writes `bytes` to `path` atomically (temporary file + rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut set = OutputSet::new();
    set.add(path, bytes)?;
    set.commit()
}

/// Linear to sRGB-encoded 8-bit.
pub fn srgb8(x: f32) -> u8 {
    let x = if x.is_finite() { x.clamp(0.0, 1.0) } else { 0.0 };
    let s = if x <= 0.003_130_8 { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// Encodes an RGB linear image (row 0 at the top) as PNG or EXR bytes.
pub fn encode_image(format: Format, width: u32, height: u32, rgb: &[[f32; 3]]) -> Result<Vec<u8>> {
    let mut out = std::io::Cursor::new(Vec::new());
    let res = match format {
        Format::Png => {
            let data: Vec<u8> = rgb.iter().flat_map(|p| p.map(srgb8)).collect();
            image::RgbImage::from_raw(width, height, data)
                .ok_or_else(|| Error::Failed("image buffer size mismatch".into()))?
                .write_to(&mut out, image::ImageFormat::Png)
        }
        Format::Exr => {
            let data: Vec<f32> = rgb.iter().flatten().copied().collect();
            image::Rgb32FImage::from_raw(width, height, data)
                .ok_or_else(|| Error::Failed("image buffer size mismatch".into()))?
                .write_to(&mut out, image::ImageFormat::OpenExr)
        }
        Format::Pfm => return Ok(encode_pfm(width, height, 3, &rgb.iter().flatten().copied().collect::<Vec<_>>())),
    };
    res.map_err(|e| Error::Failed(format!("encoding failed: {e}")))?;
    Ok(out.into_inner())
}

/// PFM: "PF" (3 channels) or "Pf" (1), "W H", scale -1.0 (little-endian), then rows
/// from the bottom row to the top row. `data` is row-major with row 0 at the top.
pub fn encode_pfm(width: u32, height: u32, channels: usize, data: &[f32]) -> Vec<u8> {
    let mut out = format!("{}\n{} {}\n-1.0\n", if channels == 3 { "PF" } else { "Pf" }, width, height).into_bytes();
    let row = width as usize * channels;
    for j in (0..height as usize).rev() {
        for v in &data[j * row..(j + 1) * row] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

/// A timeline ([`crate::timeline`]) as the file `path` names: Chrome trace-event JSON
/// (`.json`) or a picture of it (`.png`, [`crate::render::output::timeline_png`]).
pub fn encode_trace(path: &Path, trace: &crate::timeline::Trace) -> Result<Vec<u8>> {
    let _span = encode_span(path);
    if trace_is_png(path)? {
        crate::render::output::timeline_png::png(trace)
    } else {
        Ok(trace.to_chrome_json())
    }
}

/// Whether the timeline file `path` is a picture (`.png`) rather than JSON (`.json`);
/// an error for any other name.
pub fn trace_is_png(path: &Path) -> Result<bool> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase()).unwrap_or_default();
    match ext.as_str() {
        "json" => Ok(false),
        "png" => Ok(true),
        _ => Err(Error::invalid(
            path,
            "--trace-events writes Chrome trace-event JSON (FILE.json) or a picture of the timeline (FILE.png)",
        )),
    }
}

/// The timeline span of encoding the output `path` (its writing nests inside).
fn encode_span(path: &Path) -> crate::timeline::Span {
    crate::timeline::span("output", || format!("encode {}", path.display()))
}

/// Adds the image `rgb` as `path` (PNG or EXR by extension) to `set`.
pub fn write_image(set: &mut OutputSet, path: &Path, width: u32, height: u32, rgb: &[[f32; 3]]) -> Result<()> {
    let f = format_of(path, "image")?;
    set.add(path, &encode_image(f, width, height, rgb)?)
}

/// Adds a rendered frame as `path` to `set`: a PNG of its radiance, or an EXR part
/// ([`crate::render::output::part`]: the window in the full image, every sum and AOV, the header
/// `info`) that `arbor merge` and `--resume` read.
pub fn write_frame(
    set: &mut OutputSet,
    path: &Path,
    info: &crate::render::output::part::PartInfo,
    frame: &Frame,
) -> Result<()> {
    let _span = encode_span(path);
    match format_of(path, "image")? {
        Format::Exr => set.add(path, &crate::render::output::part::encode(info, frame)?),
        f => set.add(path, &encode_image(f, frame.width, frame.height, &frame.radiance)?),
    }
}

/// Adds a 1- or 3-channel AOV as `path` (PFM or EXR by extension; an EXR of a
/// 1-channel AOV repeats the value in R, G and B) to `set`. PNG is refused here: a
/// heatmap is drawn from the frame ([`aov_heatmap`]).
pub fn write_aov(
    set: &mut OutputSet,
    path: &Path,
    width: u32,
    height: u32,
    channels: usize,
    data: &[f32],
) -> Result<()> {
    let bytes = match format_of(path, "aov")? {
        Format::Pfm => encode_pfm(width, height, channels, data),
        Format::Png => return Err(Error::invalid(path, "an AOV's values cannot be written as PNG")),
        Format::Exr => {
            let rgb: Vec<[f32; 3]> = if channels == 3 {
                data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
            } else {
                data.iter().map(|&v| [v, v, v]).collect()
            };
            encode_image(Format::Exr, width, height, &rgb)?
        }
    };
    set.add(path, &bytes)
}

/// The AOVs `render --aov` writes, by name.
pub const AOV_NAMES: [&str; 9] = ["depth", "normal", "prim", "cost", "nodes", "tests", "albedo", "variance", "samples"];

/// The AOVs that may also be written as a false-colour PNG heatmap ([`aov_heatmap`]).
pub const HEATMAP_AOVS: [&str; 3] = ["cost", "nodes", "tests"];

/// Parses `--aov` values (NAME=PATH pairs, comma-separated or repeated): each name one
/// of [`AOV_NAMES`] and given once, each path a .pfm or .exr, or a .png for one of
/// [`HEATMAP_AOVS`].
pub fn parse_aovs(args: &[String]) -> Result<Vec<(String, PathBuf)>> {
    let mut out: Vec<(String, PathBuf)> = Vec::new();
    for item in args.iter().flat_map(|a| a.split(',')).filter(|s| !s.is_empty()) {
        let (name, path) =
            item.split_once('=').ok_or_else(|| Error::Usage(format!("--aov {item:?}: expected NAME=PATH")))?;
        if !AOV_NAMES.contains(&name) {
            return Err(Error::Usage(format!(
                "--aov {item:?}: unknown AOV '{name}' (known: {})",
                AOV_NAMES.join(", ")
            )));
        }
        if out.iter().any(|(n, _)| n == name) {
            return Err(Error::Usage(format!("--aov: '{name}' given twice")));
        }
        let path = PathBuf::from(path);
        if format_of(&path, "aov")? == Format::Png && !HEATMAP_AOVS.contains(&name) {
            return Err(Error::invalid(
                &path,
                format!(
                    "--aov {name}: only {} can be written as .png (a false-colour heatmap); write {name} as .pfm or .exr",
                    HEATMAP_AOVS.join(", ")
                ),
            ));
        }
        out.push((name.to_string(), path));
    }
    Ok(out)
}

/// Whether `aovs` ([`parse_aovs`]) asks for a heatmap PNG.
pub fn has_heatmap(aovs: &[(String, PathBuf)]) -> bool {
    aovs.iter().any(|(_, p)| format_of(p, "aov").is_ok_and(|f| f == Format::Png))
}

/// Channels of the AOV `name` (see [`aov_channels`]); 3 for a name not known.
pub fn aov_channel_count(name: &str) -> u64 {
    match name {
        "depth" | "prim" | "nodes" | "tests" | "variance" | "samples" => 1,
        _ => 3,
    }
}

/// The AOV `name` of `frame` as (channels, row-major values): depth (1), normal (3),
/// prim (1; -1 where the ray missed), cost (3: nodes visited, primitives tested, 0),
/// nodes (1), tests (1).
pub fn aov_channels(frame: &Frame, name: &str) -> Result<(usize, Vec<f32>)> {
    Ok(match name {
        "depth" => (1, frame.depth.clone()),
        "normal" => (3, frame.normal.iter().flatten().copied().collect()),
        "prim" => (1, frame.prim.iter().map(|&p| if p == u32::MAX { -1.0 } else { p as f32 }).collect()),
        "cost" => (3, frame.nodes.iter().zip(&frame.tests).flat_map(|(&n, &t)| [n as f32, t as f32, 0.0]).collect()),
        "nodes" => (1, frame.nodes.iter().map(|&n| n as f32).collect()),
        "tests" => (1, frame.tests.iter().map(|&t| t as f32).collect()),
        "albedo" => (3, frame.albedo.iter().flatten().copied().collect()),
        "variance" => (1, frame.variance.clone()),
        "samples" => (1, frame.samples.iter().map(|&n| n as f32).collect()),
        _ => return Err(Error::Usage(format!("unknown AOV '{name}' (known: {})", AOV_NAMES.join(", ")))),
    })
}

/// What a heatmap PNG says besides its counts.
#[derive(Debug, Clone, Default)]
pub struct HeatmapInfo {
    /// Written in the title after the AOV's name: the scene and the structure.
    pub subject: String,
    pub scale: crate::render::output::heatmap::Scale,
}

/// What each pixel's count is, as the picture says (the frame holds the counts of the
/// pixel's first camera ray only, sample 0: not a sum over samples).
const ONE_RAY: &str = "by the pixel's first camera ray (sample 0: one ray per pixel, not a sum over samples)";

/// The heatmap AOV `name` (one of [`HEATMAP_AOVS`]) of `frame` as PNG bytes: cost =
/// nodes visited + primitives tested, nodes, or tests, per pixel.
pub fn aov_heatmap(frame: &Frame, name: &str, info: &HeatmapInfo) -> Result<Vec<u8>> {
    let (values, counted): (Vec<f32>, String) = match name {
        "cost" => (
            frame.nodes.iter().zip(&frame.tests).map(|(&n, &t)| (f64::from(n) + f64::from(t)) as f32).collect(),
            format!("cost = nodes visited + primitives tested, {ONE_RAY}"),
        ),
        "nodes" => (
            frame.nodes.iter().map(|&n| n as f32).collect(),
            format!("nodes visited (tree nodes, boxes or cells, as the structure counts them), {ONE_RAY}"),
        ),
        "tests" => (frame.tests.iter().map(|&t| t as f32).collect(), format!("primitives tested, {ONE_RAY}")),
        _ => {
            return Err(Error::Usage(format!("the AOV '{name}' has no heatmap (only {} do)", HEATMAP_AOVS.join(", "))))
        }
    };
    let (w, h) = (frame.width, frame.height);
    let title = if info.subject.is_empty() {
        format!("{name} per pixel, {w}x{h}")
    } else {
        format!("{name} per pixel: {}, {w}x{h}", info.subject)
    };
    let panel = crate::render::output::heatmap::Panel { title: String::new(), width: w, height: h, values: &values };
    crate::render::output::heatmap::Figure { title, counted, scale: info.scale, panels: vec![panel] }.png()
}

/// Adds each (name, path) of `aovs` from `frame` (`width` x `height`) to `set`; a .png
/// is a heatmap ([`aov_heatmap`]) that says what `info` holds.
pub fn write_aovs(
    set: &mut OutputSet,
    aovs: &[(String, PathBuf)],
    frame: &Frame,
    width: u32,
    height: u32,
    info: &HeatmapInfo,
) -> Result<()> {
    for (name, path) in aovs {
        let _span = encode_span(path);
        if format_of(path, "aov")? == Format::Png {
            set.add(path, &aov_heatmap(frame, name, info)?)?;
            continue;
        }
        let (channels, data) = aov_channels(frame, name)?;
        write_aov(set, path, width, height, channels, &data)?;
    }
    Ok(())
}

/// The statistics JSON of a render: the [`RenderStats`] fields, then `provenance`.
#[derive(Debug, serde::Serialize)]
pub struct StatsFile<'a> {
    #[serde(flatten)]
    pub stats: &'a RenderStats,
    pub provenance: Provenance,
}

/// What a stats JSON needs to rerun its result.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Provenance {
    /// arbor's version (`CARGO_PKG_VERSION`).
    pub version: String,
    pub seed: u32,
    pub spp: u32,
    pub width: u32,
    pub height: u32,
    pub integrator: String,
    /// The command line, program name first.
    pub command_line: Vec<String>,
}

/// Adds the statistics JSON (`stats` and `provenance`) as `path` to `set`.
pub fn write_stats(set: &mut OutputSet, path: &Path, stats: &RenderStats, provenance: Provenance) -> Result<()> {
    let _span = encode_span(path);
    let json = serde_json::to_vec_pretty(&StatsFile { stats, provenance })
        .map_err(|e| Error::Failed(format!("stats JSON: {e}")))?;
    set.add(path, &json)
}

/// Reads a PFM written by [`encode_pfm`] (or any standard PFM): (width, height,
/// channels, row-major data with row 0 at the top).
pub fn read_pfm(path: &Path) -> Result<(u32, u32, usize, Vec<f32>)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let mut fields = Vec::new();
    let mut pos = 0;
    while fields.len() < 4 && pos < bytes.len() {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        fields.push(String::from_utf8_lossy(&bytes[start..pos]).into_owned());
    }
    pos += 1;
    let bad = || Error::invalid(path, "not a PFM file");
    if fields.len() < 4 {
        return Err(bad());
    }
    let channels = match fields[0].as_str() {
        "PF" => 3,
        "Pf" => 1,
        _ => return Err(bad()),
    };
    let w: u32 = fields[1].parse().map_err(|_| bad())?;
    let h: u32 = fields[2].parse().map_err(|_| bad())?;
    let scale: f32 = fields[3].parse().map_err(|_| bad())?;
    let n = w as usize * h as usize * channels;
    let body = bytes.get(pos..pos + 4 * n).ok_or_else(|| Error::invalid(path, "PFM data is truncated"))?;
    let vals: Vec<f32> = body
        .chunks_exact(4)
        .map(|c| {
            let a = [c[0], c[1], c[2], c[3]];
            if scale < 0.0 {
                f32::from_le_bytes(a)
            } else {
                f32::from_be_bytes(a)
            }
        })
        .collect();
    let row = w as usize * channels;
    let mut data = Vec::with_capacity(n);
    for j in (0..h as usize).rev() {
        data.extend_from_slice(&vals[j * row..(j + 1) * row]);
    }
    Ok((w, h, channels, data))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pfm_round_trip_bottom_to_top() {
        let data = vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let bytes = encode_pfm(3, 2, 1, &data);
        // The first stored row is the bottom row (4, 5, 6).
        let header = b"Pf\n3 2\n-1.0\n".len();
        assert_eq!(&bytes[header..header + 4], &4.0f32.to_le_bytes());
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("a.pfm");
        write_atomic(&p, &bytes).expect("write");
        let (w, h, c, back) = read_pfm(&p).expect("read");
        assert_eq!((w, h, c), (3, 2, 1));
        assert_eq!(back, data);
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .expect("list")
            .map(|e| e.expect("entry").file_name().into_string().expect("utf8"))
            .collect();
        v.sort();
        v
    }

    /// A failed file removes the temporary files already written; nothing is renamed.
    #[test]
    fn output_set_writes_all_or_nothing() {
        let dir = tempfile::tempdir().expect("tempdir");
        let d = dir.path();
        std::fs::write(d.join("a.png"), "old").expect("write");
        {
            let mut set = OutputSet::new();
            set.add(&d.join("a.png"), b"new").expect("add a");
            set.add(&d.join("b.pfm"), b"new").expect("add b");
            assert_eq!(names(d).len(), 3, "two temporary files beside a.png");
            assert!(set.add(&d.join("missing/c.json"), b"new").is_err());
        }
        assert_eq!(names(d), ["a.png"]);
        assert_eq!(std::fs::read(d.join("a.png")).expect("read"), b"old");
        let mut set = OutputSet::new();
        set.add(&d.join("a.png"), b"new").expect("add a");
        set.add(&d.join("b.pfm"), b"new").expect("add b");
        set.commit().expect("commit");
        assert_eq!(names(d), ["a.png", "b.pfm"]);
        assert_eq!(std::fs::read(d.join("a.png")).expect("read"), b"new");
    }

    #[test]
    fn unwritable_paths_are_refused() {
        let dir = tempfile::tempdir().expect("tempdir");
        let d = dir.path();
        std::fs::write(d.join("file"), "x").expect("write");
        std::fs::create_dir(d.join("sub")).expect("mkdir");
        let slash = PathBuf::from(format!("{}/", d.join("a.pfm").display()));
        for (p, what) in [
            (slash, "expected a file name"),
            (d.join("file/a.pfm"), "is not a directory"),
            (d.join("nope/a.pfm"), "does not exist"),
            (d.join("sub"), "is a directory"),
        ] {
            let e = check_writable(&p).expect_err("refused").to_string();
            assert!(e.contains(what), "{}: {e}", p.display());
        }
        check_writable(&d.join("ok.png")).expect("writable");
        assert!(check_outputs([d.join("x.exr").as_path(), d.join("x.exr").as_path()]).is_err());
        assert_eq!(names(d), ["file", "sub"], "the probes are gone");
    }

    #[test]
    fn srgb_endpoints() {
        assert_eq!(srgb8(0.0), 0);
        assert_eq!(srgb8(1.0), 255);
        assert_eq!(srgb8(f32::NAN), 0);
    }
}
