//! Image error metrics (`arbor compare`, and benchmarks that measure error against a
//! reference): reading EXR, PFM, PNG, Radiance HDR and JPEG as linear RGB, the error
//! figures, and a false-colour image of the per-pixel relative error.
//!
//! Definitions, over every pixel and channel of a test image `a` and a reference `b`
//! (n = 3 W H values):
//!
//! - `mse = sum (a - b)^2 / n` on linear values as read;
//! - `rel_mse = sum (a - b)^2 / (b^2 + 0.01) / n` (the pbrt / Mitsuba convention);
//! - `psnr = 10 log10(1 / mse01)` dB, where `mse01` is the MSE of the values clamped
//!   to [0, 1] (a peak of 1); infinite when the clamped images are equal;
//! - `max_abs = max |a - b|`.

use std::path::Path;

use crate::error::{Error, Result};
use crate::scene::limits::{self, FileKind};

/// The constant in the denominator of the relative squared error.
pub const REL_EPSILON: f64 = 1e-2;

/// The error of a test image against a reference (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorStats {
    pub mse: f64,
    pub rel_mse: f64,
    /// dB; `f64::INFINITY` when the images, clamped to [0, 1], are equal.
    pub psnr: f64,
    pub max_abs: f64,
}

impl ErrorStats {
    /// The figures as a JSON object (`psnr` is the string `"inf"` when infinite).
    pub fn to_json(&self, width: u32, height: u32) -> serde_json::Value {
        let psnr = if self.psnr.is_finite() { serde_json::json!(self.psnr) } else { serde_json::json!("inf") };
        serde_json::json!({
            "width": width,
            "height": height,
            "mse": self.mse,
            "rel_mse": self.rel_mse,
            "psnr": psnr,
            "max_abs": self.max_abs,
        })
    }
}

/// The relative squared error of one value against its reference.
fn rel_sq(a: f32, b: f32) -> f64 {
    let (a, b) = (f64::from(a), f64::from(b));
    (a - b) * (a - b) / (b * b + REL_EPSILON)
}

/// The error of `test` against `reference`, pixel by pixel. The caller checks that both
/// images have the same size; only the common prefix is compared.
pub fn compare(test: &[[f32; 3]], reference: &[[f32; 3]]) -> ErrorStats {
    debug_assert_eq!(test.len(), reference.len());
    let (mut sq, mut rel, mut sq01, mut max_abs) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut n = 0usize;
    for (pa, pb) in test.iter().zip(reference) {
        for (&a, &b) in pa.iter().zip(pb) {
            let d = f64::from(a) - f64::from(b);
            sq += d * d;
            rel += rel_sq(a, b);
            let d01 = f64::from(a.clamp(0.0, 1.0)) - f64::from(b.clamp(0.0, 1.0));
            sq01 += d01 * d01;
            max_abs = max_abs.max(d.abs());
            n += 1;
        }
    }
    let n = n.max(1) as f64;
    let mse01 = sq01 / n;
    let psnr = if mse01 > 0.0 { 10.0 * (1.0 / mse01).log10() } else { f64::INFINITY };
    ErrorStats { mse: sq / n, rel_mse: rel / n, psnr, max_abs }
}

/// The false-colour stops of [`error_image`]: (log10 of the relative error, sRGB colour).
pub const COLORMAP: [(f32, [u8; 3]); 5] =
    [(-4.0, [0, 0, 0]), (-3.0, [32, 64, 255]), (-2.0, [0, 200, 64]), (-1.0, [255, 230, 0]), (0.0, [255, 0, 0])];

/// The colour of a relative error: black at or below 1e-4, then blue (1e-3), green
/// (1e-2), yellow (0.1), red at or above 1, interpolated linearly in log10 between stops.
pub fn error_color(rel: f64) -> [u8; 3] {
    let l = if rel > 0.0 { rel.log10() as f32 } else { f32::NEG_INFINITY };
    let (first, last) = (COLORMAP[0], COLORMAP[COLORMAP.len() - 1]);
    if l.is_nan() || l <= first.0 {
        return first.1;
    }
    if l >= last.0 {
        return last.1;
    }
    for pair in COLORMAP.windows(2) {
        let ((l0, c0), (l1, c1)) = (pair[0], pair[1]);
        if l <= l1 {
            let t = (l - l0) / (l1 - l0);
            return std::array::from_fn(|k| {
                (f32::from(c0[k]) + t * (f32::from(c1[k]) - f32::from(c0[k]))).round() as u8
            });
        }
    }
    last.1
}

/// The per-pixel relative error (mean over the channels of `(a - b)^2 / (b^2 + 0.01)`,
/// so its mean over the image is `rel_mse`) in false colour ([`error_color`]), row 0
/// at the top.
pub fn error_image(test: &[[f32; 3]], reference: &[[f32; 3]]) -> Vec<[u8; 3]> {
    test.iter()
        .zip(reference)
        .map(|(pa, pb)| error_color((0..3).map(|k| rel_sq(pa[k], pb[k])).sum::<f64>() / 3.0))
        .collect()
}

/// [`error_image`] encoded as PNG bytes (the colours are sRGB as they are).
pub fn error_png(width: u32, height: u32, test: &[[f32; 3]], reference: &[[f32; 3]]) -> Result<Vec<u8>> {
    let data: Vec<u8> = error_image(test, reference).into_iter().flatten().collect();
    let img = image::RgbImage::from_raw(width, height, data)
        .ok_or_else(|| Error::Failed("error image buffer size mismatch".into()))?;
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).map_err(|e| Error::Failed(format!("encoding PNG failed: {e}")))?;
    Ok(out.into_inner())
}

pub use crate::scene::colors::srgb_to_linear;

/// Reads an image as linear RGB, row 0 at the top: `(width, height, pixels)`. The
/// extension picks the format: .exr, .pfm, .hdr (linear as stored), .png, .jpg/.jpeg
/// (sRGB-decoded; 16-bit PNG too). Alpha is dropped, grey is repeated in R, G and B.
/// Non-finite values are an error naming the pixel.
pub fn read_linear(path: &Path) -> Result<(u32, u32, Vec<[f32; 3]>)> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase()).unwrap_or_default();
    let format = match ext.as_str() {
        "exr" => Some(image::ImageFormat::OpenExr),
        "hdr" => Some(image::ImageFormat::Hdr),
        "png" => Some(image::ImageFormat::Png),
        "jpg" | "jpeg" => Some(image::ImageFormat::Jpeg),
        "pfm" => None,
        _ => return Err(Error::invalid(path, "unknown image format; expected .exr, .pfm, .png, .hdr, .jpg or .jpeg")),
    };
    let bytes = limits::read_file(path, FileKind::Image)?;
    let (w, h, pixels) = match format {
        None => decode_pfm(path, &bytes)?,
        Some(f) => decode_image(path, &bytes, f)?,
    };
    if let Some(i) = pixels.iter().position(|p| p.iter().any(|v| !v.is_finite())) {
        let (x, y) = (i % w as usize, i / w as usize);
        return Err(Error::invalid(path, format!("pixel ({x}, {y}) is not finite: {:?}", pixels[i])));
    }
    Ok((w, h, pixels))
}

/// Decodes an EXR, HDR, PNG or JPEG file's bytes.
fn decode_image(path: &Path, bytes: &[u8], format: image::ImageFormat) -> Result<(u32, u32, Vec<[f32; 3]>)> {
    let name = format!("{format:?}").to_uppercase().replace("OPENEXR", "EXR");
    let img = image::ImageReader::with_format(std::io::Cursor::new(bytes), format)
        .decode()
        .map_err(|e| Error::invalid(path, format!("not a readable {name} image: {e}")))?;
    let linear = matches!(img, image::DynamicImage::ImageRgb32F(_) | image::DynamicImage::ImageRgba32F(_));
    let (w, h) = (img.width(), img.height());
    let rgb = img.into_rgb32f();
    let pixels = rgb.pixels().map(|p| if linear { p.0 } else { p.0.map(srgb_to_linear) }).collect();
    Ok((w, h, pixels))
}

/// Decodes a PFM file: "PF" (RGB) or "Pf" (grey), width, height and scale as ASCII
/// tokens separated by whitespace, one whitespace byte, then W x H x channels f32s,
/// little-endian when the scale is negative and big-endian when positive, rows from the
/// bottom to the top. The scale's magnitude is ignored. The data must have exactly the
/// expected length.
pub fn decode_pfm(path: &Path, bytes: &[u8]) -> Result<(u32, u32, Vec<[f32; 3]>)> {
    let bad = |msg: String| Error::invalid(path, format!("bad PFM file: {msg}"));
    let mut pos = 0usize;
    let mut token = |what: &str| -> Result<String> {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() && pos - start <= 32 {
            pos += 1;
        }
        if pos == start || pos >= bytes.len() || !bytes[pos].is_ascii_whitespace() {
            return Err(bad(format!("expected the {what} followed by whitespace in the header")));
        }
        Ok(String::from_utf8_lossy(&bytes[start..pos]).into_owned())
    };
    let magic = token("type (PF or Pf)")?;
    let channels = match magic.as_str() {
        "PF" => 3usize,
        "Pf" => 1,
        m => return Err(bad(format!("type is '{m}'; expected PF (colour) or Pf (grey)"))),
    };
    let mut side = |what: &str| -> Result<u32> {
        let t = token(what)?;
        match t.parse::<u32>() {
            Ok(v) if v > 0 => Ok(v),
            _ => Err(bad(format!("{what} '{t}' is not a positive integer"))),
        }
    };
    let w = side("width")?;
    let h = side("height")?;
    let t = token("scale")?;
    let scale: f32 = t.parse().map_err(|_| bad(format!("scale '{t}' is not a number")))?;
    if !scale.is_finite() || scale == 0.0 {
        return Err(bad(format!("scale '{t}' must be a non-zero finite number (negative: little-endian)")));
    }
    // `token` stopped on the one whitespace byte that ends the header.
    let data = &bytes[pos + 1..];
    let expected = u128::from(w) * u128::from(h) * channels as u128 * 4;
    if data.len() as u128 != expected {
        return Err(bad(format!(
            "{w}x{h} with {channels} channel(s) needs {expected} bytes of pixel data, found {}",
            data.len()
        )));
    }
    let little = scale < 0.0;
    let values: Vec<f32> = data
        .chunks_exact(4)
        .map(|c| {
            let b = [c[0], c[1], c[2], c[3]];
            if little {
                f32::from_le_bytes(b)
            } else {
                f32::from_be_bytes(b)
            }
        })
        .collect();
    let row = w as usize * channels;
    let mut pixels = Vec::with_capacity(w as usize * h as usize);
    for y in (0..h as usize).rev() {
        for px in values[y * row..(y + 1) * row].chunks_exact(channels) {
            pixels.push(if channels == 3 { [px[0], px[1], px[2]] } else { [px[0]; 3] });
        }
    }
    Ok((w, h, pixels))
}

/// Reads a test image and its reference and checks they have the same size (an error
/// naming the test file otherwise): `(width, height, test, reference)`.
#[allow(clippy::type_complexity)]
pub fn read_pair(test: &Path, reference: &Path) -> Result<(u32, u32, Vec<[f32; 3]>, Vec<[f32; 3]>)> {
    let (w, h, a) = read_linear(test)?;
    let (rw, rh, b) = read_linear(reference)?;
    if (w, h) != (rw, rh) {
        return Err(Error::invalid(
            test,
            format!(
                "is {w}x{h} but the reference {} is {rw}x{rh}; images must have the same size",
                reference.display()
            ),
        ));
    }
    Ok((w, h, a, b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::output::encode_pfm;

    fn pfm(bytes: &[u8]) -> Result<(u32, u32, Vec<[f32; 3]>)> {
        decode_pfm(Path::new("x.pfm"), bytes)
    }

    fn err(bytes: &[u8]) -> String {
        match pfm(bytes) {
            Ok(_) => panic!("accepted {:?}", String::from_utf8_lossy(bytes)),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn pfm_reads_what_arbor_writes_and_big_endian_and_grey() {
        let data = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let (w, h, px) = pfm(&encode_pfm(1, 2, 3, &data)).expect("read");
        assert_eq!((w, h), (1, 2));
        assert_eq!(px, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        // Big-endian, grey, header with other whitespace; the bottom row comes first.
        let mut be = b"Pf 2  1\n1.0\n".to_vec();
        be.extend_from_slice(&0.5f32.to_be_bytes());
        be.extend_from_slice(&(-2.0f32).to_be_bytes());
        assert_eq!(pfm(&be).expect("read").2, vec![[0.5; 3], [-2.0; 3]]);
        let mut grey = b"Pf\n1 2\n-1\n".to_vec();
        grey.extend_from_slice(&1.0f32.to_le_bytes());
        grey.extend_from_slice(&7.0f32.to_le_bytes());
        assert_eq!(pfm(&grey).expect("read").2, vec![[7.0; 3], [1.0; 3]]);
    }

    #[test]
    fn pfm_malformed_headers_are_errors_naming_the_file() {
        let four = [0u8; 4];
        let with = |h: &str, n: usize| [h.as_bytes(), &four.repeat(n)].concat();
        for (bytes, want) in [
            (b"P6\n1 1\n255\n".to_vec(), "type is 'P6'"),
            (b"".to_vec(), "expected the type"),
            (b"PF".to_vec(), "expected the type"),
            (b"PF\n1\n".to_vec(), "expected the height"),
            (with("PF\n0 1\n-1\n", 3), "width '0' is not a positive integer"),
            (with("PF\n1 x\n-1\n", 3), "height 'x'"),
            (with("PF\n-1 1\n-1\n", 3), "width '-1'"),
            (with("PF\n1 1\nabc\n", 3), "scale 'abc' is not a number"),
            (with("PF\n1 1\n0.0\n", 3), "non-zero finite"),
            (with("PF\n1 1\nnan\n", 3), "non-zero finite"),
            (with("PF\n1 1\n-1\n", 2), "needs 12 bytes of pixel data, found 8"),
            (with("PF\n1 1\n-1\n", 4), "found 16"),
            (with("PF\n4294967295 4294967295\n-1\n", 3), "found 12"),
            (with(&format!("PF\n{}1 1\n-1\n", "9".repeat(100)), 3), "width"),
        ] {
            let e = err(&bytes);
            assert!(e.starts_with("x.pfm: bad PFM file: ") && e.contains(want), "{e} lacks {want}");
        }
    }

    #[test]
    fn stats_of_a_known_difference() {
        let a = [[0.5, 0.5, 0.5], [1.5, 0.0, 0.0]];
        let b = [[0.25, 0.5, 0.5], [1.0, 0.0, 0.0]];
        let s = compare(&a, &b);
        let close = |x: f64, y: f64| (x - y).abs() <= 1e-12 * y.abs().max(1.0);
        assert!(close(s.mse, 0.3125 / 6.0), "{s:?}");
        assert!(close(s.rel_mse, (0.0625 / 0.0725 + 0.25 / 1.01) / 6.0), "{s:?}");
        assert!(close(s.psnr, 10.0 * 96f64.log10()), "{s:?}");
        assert_eq!(s.max_abs, 0.5);
        let same = compare(&a, &a);
        assert_eq!((same.mse, same.rel_mse, same.max_abs, same.psnr), (0.0, 0.0, 0.0, f64::INFINITY));
        assert_eq!(same.to_json(2, 1)["psnr"], "inf");
    }

    #[test]
    fn colormap_stops() {
        assert_eq!(error_color(0.0), [0, 0, 0]);
        assert_eq!(error_color(1e-5), [0, 0, 0]);
        assert_eq!(error_color(1e-3), [32, 64, 255]);
        assert_eq!(error_color(1e-2), [0, 200, 64]);
        assert_eq!(error_color(0.1), [255, 230, 0]);
        assert_eq!(error_color(5.0), [255, 0, 0]);
        assert_eq!(error_color(f64::NAN), [0, 0, 0]);
    }

    #[test]
    fn srgb_decoding_inverts_the_writer() {
        for i in 0..=255u8 {
            let lin = srgb_to_linear(f32::from(i) / 255.0);
            assert_eq!(crate::render::output::srgb8(lin), i);
        }
    }
}
