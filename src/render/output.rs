//! Writers for images (PNG 8-bit sRGB, EXR linear float), AOVs (PFM, EXR; [`aov_channels`]
//! turns a frame into them) and the statistics JSON (with its [`Provenance`]). Every
//! file is written whole to a temporary file beside the target, then renamed, so a
//! failed run never leaves a truncated file or clobbers an existing one.

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
        ("png", "image") => Ok(Format::Png),
        ("exr", _) => Ok(Format::Exr),
        ("pfm", "aov") => Ok(Format::Pfm),
        (_, "image") => Err(Error::invalid(path, "the image output must end in .png or .exr")),
        _ => Err(Error::invalid(path, "an AOV output must end in .pfm or .exr")),
    }
}

/// Writes `bytes` to `path` atomically (temporary file + rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::io(path, e));
    }
    Ok(())
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
                .ok_or_else(|| Error::Usage("image buffer size mismatch".into()))?
                .write_to(&mut out, image::ImageFormat::Png)
        }
        Format::Exr => {
            let data: Vec<f32> = rgb.iter().flatten().copied().collect();
            image::Rgb32FImage::from_raw(width, height, data)
                .ok_or_else(|| Error::Usage("image buffer size mismatch".into()))?
                .write_to(&mut out, image::ImageFormat::OpenExr)
        }
        Format::Pfm => return Ok(encode_pfm(width, height, 3, &rgb.iter().flatten().copied().collect::<Vec<_>>())),
    };
    res.map_err(|e| Error::Usage(format!("encoding failed: {e}")))?;
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

/// Writes the image `rgb` to `path` (PNG or EXR by extension).
pub fn write_image(path: &Path, width: u32, height: u32, rgb: &[[f32; 3]]) -> Result<()> {
    let f = format_of(path, "image")?;
    write_atomic(path, &encode_image(f, width, height, rgb)?)
}

/// Writes a 1- or 3-channel AOV to `path` (PFM or EXR by extension; an EXR of a
/// 1-channel AOV repeats the value in R, G and B).
pub fn write_aov(path: &Path, width: u32, height: u32, channels: usize, data: &[f32]) -> Result<()> {
    let bytes = match format_of(path, "aov")? {
        Format::Pfm => encode_pfm(width, height, channels, data),
        _ => {
            let rgb: Vec<[f32; 3]> = if channels == 3 {
                data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
            } else {
                data.iter().map(|&v| [v, v, v]).collect()
            };
            encode_image(Format::Exr, width, height, &rgb)?
        }
    };
    write_atomic(path, &bytes)
}

/// The AOVs `render --aov` writes, by name.
pub const AOV_NAMES: [&str; 4] = ["depth", "normal", "prim", "cost"];

/// Parses `--aov` values (NAME=PATH pairs, comma-separated or repeated): each name one
/// of [`AOV_NAMES`] and given once, each path a .pfm or .exr.
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
        format_of(&path, "aov")?;
        out.push((name.to_string(), path));
    }
    Ok(out)
}

/// The AOV `name` of `frame` as (channels, row-major values): depth (1), normal (3),
/// prim (1; -1 where the ray missed), cost (3: nodes visited, primitives tested, 0).
pub fn aov_channels(frame: &Frame, name: &str) -> Result<(usize, Vec<f32>)> {
    Ok(match name {
        "depth" => (1, frame.depth.clone()),
        "normal" => (3, frame.normal.iter().flatten().copied().collect()),
        "prim" => (1, frame.prim.iter().map(|&p| if p == u32::MAX { -1.0 } else { p as f32 }).collect()),
        "cost" => (3, frame.nodes.iter().zip(&frame.tests).flat_map(|(&n, &t)| [n as f32, t as f32, 0.0]).collect()),
        _ => return Err(Error::Usage(format!("unknown AOV '{name}' (known: {})", AOV_NAMES.join(", ")))),
    })
}

/// Writes each (name, path) of `aovs` from `frame` (`width` x `height`).
pub fn write_aovs(aovs: &[(String, PathBuf)], frame: &Frame, width: u32, height: u32) -> Result<()> {
    for (name, path) in aovs {
        let (channels, data) = aov_channels(frame, name)?;
        write_aov(path, width, height, channels, &data)?;
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

/// Writes the statistics JSON (`stats` and `provenance`) to `path`.
pub fn write_stats(path: &Path, stats: &RenderStats, provenance: Provenance) -> Result<()> {
    let json = serde_json::to_vec_pretty(&StatsFile { stats, provenance })
        .map_err(|e| Error::Usage(format!("stats JSON: {e}")))?;
    write_atomic(path, &json)
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

    #[test]
    fn srgb_endpoints() {
        assert_eq!(srgb8(0.0), 0);
        assert_eq!(srgb8(1.0), 255);
        assert_eq!(srgb8(f32::NAN), 0);
    }
}
