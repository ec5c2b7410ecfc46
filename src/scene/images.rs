//! Texture and environment images, read with the `image` crate.
//!
//! Every file goes through [`limits::read_file`] (a regular file of at most
//! [`limits::MAX_IMAGE_FILE_BYTES`]); its size in texels is checked from the header,
//! before the pixels are decoded, against [`limits::MAX_IMAGE_SIDE`] and
//! [`limits::MAX_TEXTURE_TEXELS`] / [`limits::MAX_ENVIRONMENT_TEXELS`], and the decoder's
//! allocations are capped at [`limits::MAX_IMAGE_DECODE_BYTES`]. The format is found from
//! the file's first bytes, or from its extension when they say nothing.
//!
//! * Textures: PNG or JPEG (8 or 16 bits, grey or colour, with or without alpha), kept
//!   as sRGB-encoded RGBA8; grey is spread to RGB, a missing alpha is 255.
//! * Environment maps: Radiance `.hdr` or OpenEXR `.exr`, as linear f32 RGB (alpha
//!   dropped); every texel must be finite and >= 0.

use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageDecoder, ImageFormat, ImageReader};

use crate::error::{Error, Result};
use crate::scene::limits::{self, FileKind};
use crate::scene::mesh::{Environment, Texture};

/// Loads a PNG or JPEG texture as sRGB-encoded RGBA8, row 0 at the top.
pub fn load_texture(path: &Path) -> Result<Texture> {
    let _span = crate::timeline::span("load", || format!("load texture {}", path.display()));
    let image = decode(path, FileKind::Texture, &[ImageFormat::Png, ImageFormat::Jpeg], "PNG or JPEG")?;
    let rgba = image.into_rgba8();
    let (width, height) = rgba.dimensions();
    let texels = rgba.as_raw().chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect();
    Ok(Texture { name: path.display().to_string(), width, height, texels, ..Default::default() })
}

/// Loads an equirectangular environment map (Radiance `.hdr` or OpenEXR `.exr`) as
/// linear RGB. `rotation` (degrees about +y) and `intensity` (a multiplier) are stored
/// as given; both must be finite and `intensity` >= 0.
pub fn load_environment(path: &Path, rotation: f32, intensity: f32) -> Result<Environment> {
    let _span = crate::timeline::span("load", || format!("load environment {}", path.display()));
    if !(rotation.is_finite() && intensity.is_finite() && intensity >= 0.0) {
        return Err(Error::invalid(
            path,
            format!("environment rotation {rotation} and intensity {intensity}: both must be finite, intensity >= 0"),
        ));
    }
    let image = decode(
        path,
        FileKind::Environment,
        &[ImageFormat::Hdr, ImageFormat::OpenExr],
        "Radiance .hdr or OpenEXR .exr",
    )?;
    let rgb = image.into_rgb32f();
    let (width, height) = rgb.dimensions();
    let mut texels = Vec::with_capacity(rgb.as_raw().len() / 3);
    for (i, c) in rgb.as_raw().chunks_exact(3).enumerate() {
        let t = [c[0], c[1], c[2]];
        if !t.iter().all(|v| v.is_finite() && *v >= 0.0) {
            let (x, y) = (i % width as usize, i / width as usize);
            return Err(Error::invalid(
                path,
                format!(
                    "environment texel ({x}, {y}) (column, row from the top) is ({}, {}, {}); every texel must be finite and >= 0",
                    t[0], t[1], t[2]
                ),
            ));
        }
        texels.push(t);
    }
    Ok(Environment { name: path.display().to_string(), width, height, texels, rotation, intensity })
}

/// The same error with `context` put before its message; the file it names is kept.
pub(crate) fn with_context(e: Error, context: &str) -> Error {
    match e {
        Error::Io { path, cause } => Error::invalid(path, format!("{context}: {cause}")),
        Error::Invalid { path, msg } => Error::invalid(path, format!("{context}: {msg}")),
        Error::Parse { path, line, msg } => Error::parse(path, line, format!("{context}: {msg}")),
        other => other,
    }
}

/// Reads and decodes the image at `path`, which must be one of `formats`.
fn decode(path: &Path, kind: FileKind, formats: &[ImageFormat], expected: &str) -> Result<DynamicImage> {
    let bytes = limits::read_file(path, kind)?;
    let reader = ImageReader::new(Cursor::new(bytes)).with_guessed_format().map_err(|e| Error::io(path, e))?;
    let format = reader.format().or_else(|| ImageFormat::from_path(path).ok());
    let Some(format) = format.filter(|f| formats.contains(f)) else {
        let what = format.map_or_else(|| "an unknown format".to_string(), |f| format!("{f:?}"));
        return Err(Error::invalid(path, format!("the file is {what}; expected {expected}")));
    };
    let mut reader = reader;
    reader.set_format(format);
    let mut caps = image::Limits::default();
    caps.max_image_width = Some(limits::MAX_IMAGE_SIDE);
    caps.max_image_height = Some(limits::MAX_IMAGE_SIDE);
    caps.max_alloc = Some(limits::MAX_IMAGE_DECODE_BYTES);
    reader.limits(caps);
    let fail = |e: image::ImageError| Error::invalid(path, format!("cannot decode the {format:?} image: {e}"));
    let decoder = reader.into_decoder().map_err(fail)?;
    let (width, height) = decoder.dimensions();
    let max_texels = match kind {
        FileKind::Environment => limits::MAX_ENVIRONMENT_TEXELS,
        _ => limits::MAX_TEXTURE_TEXELS,
    };
    if let Some(msg) = limits::image_size_error(width, height, max_texels) {
        return Err(Error::invalid(path, msg));
    }
    DynamicImage::from_decoder(decoder).map_err(fail)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_png_becomes_rgba() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("g.png");
        image::GrayImage::from_raw(2, 1, vec![10, 200]).unwrap().save(&path).unwrap();
        let t = load_texture(&path).unwrap();
        assert_eq!((t.width, t.height), (2, 1));
        assert_eq!(t.texels, [[10, 10, 10, 255], [200, 200, 200, 255]]);
    }

    #[test]
    fn environment_rejects_a_png_and_bad_settings() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sky.png");
        image::RgbImage::new(2, 1).save(&path).unwrap();
        let e = load_environment(&path, 0.0, 1.0).unwrap_err().to_string();
        assert!(e.contains("sky.png") && e.contains("expected Radiance"), "{e}");
        let e = load_environment(&path, 0.0, -1.0).unwrap_err().to_string();
        assert!(e.contains("intensity"), "{e}");
    }

    #[test]
    fn sizes_are_checked() {
        assert!(limits::image_size_error(16384, 4096, limits::MAX_TEXTURE_TEXELS).is_none());
        assert!(limits::image_size_error(16385, 1, limits::MAX_TEXTURE_TEXELS).is_some());
        assert!(limits::image_size_error(16384, 4096, limits::MAX_ENVIRONMENT_TEXELS).is_some());
        assert!(limits::image_size_error(0, 4, limits::MAX_TEXTURE_TEXELS).is_some());
    }
}
