//! What a scene may be made of, and the one way loaders read a file.
//!
//! Every input is checked for what it is before it is opened (a regular file, not a FIFO,
//! device, directory or socket; symlinks are followed) and read through a size-limited
//! reader, so a file that grows after the check, or a symlink to `/dev/zero`, is still
//! read only up to its limit. Element counts are checked before the memory for them is
//! allocated. docs/limits.md lists every limit and the message the user sees.

use std::io::Read;
use std::path::Path;

use crate::error::{Error, Result};

/// Largest mesh file (OBJ, PLY, OFF) read, in bytes: 2 GiB.
pub const MAX_MESH_FILE_BYTES: u64 = 2 << 30;
/// Largest TOML scene file or MTL material library read, in bytes: 16 MiB.
pub const MAX_TEXT_FILE_BYTES: u64 = 16 << 20;
/// Most triangles a scene (all its meshes together) may have: 2^25 (33.5 million).
/// `arbor info` peaks at about 300 bytes of host memory per triangle (scene, structure
/// build, GPU images), so this is about 10 GB.
pub const MAX_TRIANGLES: u64 = 1 << 25;
/// Most vertices a scene (all its meshes together) may have: 2^25.
pub const MAX_VERTICES: u64 = 1 << 25;
/// Most materials a scene (TOML `[[material]]` tables and MTL `newmtl`s together) may have.
pub const MAX_MATERIALS: u64 = 1 << 20;
/// Most spheres a TOML scene may have.
pub const MAX_SPHERES: u64 = 1 << 20;
/// Most distinct MTL libraries one OBJ file may name (repeats of a name are read once).
pub const MAX_MTLLIBS: usize = 64;
/// Largest image file read (a texture, an environment map, an image `arbor compare`
/// reads), in bytes: 1 GiB.
pub const MAX_IMAGE_FILE_BYTES: u64 = 1 << 30;
/// Longest side of a texture or environment image, in texels.
pub const MAX_IMAGE_SIDE: u32 = 16384;
/// Most texels one texture may have: 2^26 (256 MiB as RGBA8).
pub const MAX_TEXTURE_TEXELS: u64 = 1 << 26;
/// Most texels an environment map may have: 2^24 (192 MiB as RGB f32).
pub const MAX_ENVIRONMENT_TEXELS: u64 = 1 << 24;
/// Most bytes an image decoder may allocate at once (the decoded image included).
pub const MAX_IMAGE_DECODE_BYTES: u64 = 1 << 30;

/// What kind of file is being read, for its size limit and messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileKind {
    /// An OBJ, PLY or OFF mesh.
    Mesh,
    /// An MTL material library.
    MaterialLibrary,
    /// A TOML scene file.
    SceneFile,
    /// A texture image (PNG, JPEG).
    Texture,
    /// An environment map (Radiance HDR, OpenEXR).
    Environment,
    /// An image (EXR, PFM, PNG, HDR, JPEG).
    Image,
}

impl FileKind {
    /// The largest file of this kind that is read.
    pub fn max_bytes(self) -> u64 {
        match self {
            FileKind::Mesh => MAX_MESH_FILE_BYTES,
            FileKind::MaterialLibrary | FileKind::SceneFile => MAX_TEXT_FILE_BYTES,
            FileKind::Texture | FileKind::Environment | FileKind::Image => MAX_IMAGE_FILE_BYTES,
        }
    }

    fn noun(self) -> &'static str {
        match self {
            FileKind::Mesh => "mesh file",
            FileKind::MaterialLibrary => "material library",
            FileKind::SceneFile => "scene file",
            FileKind::Texture => "texture",
            FileKind::Environment => "environment map",
            FileKind::Image => "image",
        }
    }
}

/// `bytes` as a short human size (`16 MiB`, `2 GiB`, `1234 bytes`).
pub fn human_bytes(bytes: u64) -> String {
    match bytes {
        b if b >= 1 << 30 && b % (1 << 30) == 0 => format!("{} GiB", b >> 30),
        b if b >= 1 << 20 && b % (1 << 20) == 0 => format!("{} MiB", b >> 20),
        b if b >= 1 << 30 => format!("{:.1} GiB", b as f64 / (1u64 << 30) as f64),
        b if b >= 1 << 20 => format!("{:.1} MiB", b as f64 / (1u64 << 20) as f64),
        b => format!("{b} bytes"),
    }
}

/// Why `metadata` does not describe a regular file, in words; None for a regular file.
fn not_regular(meta: &std::fs::Metadata) -> Option<&'static str> {
    let t = meta.file_type();
    if t.is_file() {
        return None;
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return Some("is a named pipe (FIFO)");
        }
        if t.is_char_device() {
            return Some("is a character device");
        }
        if t.is_block_device() {
            return Some("is a block device");
        }
        if t.is_socket() {
            return Some("is a socket");
        }
    }
    if t.is_dir() {
        return Some("is a directory");
    }
    Some("is not a regular file")
}

/// Checks that `path` is a regular file of at most `kind.max_bytes()` and returns its
/// length. Follows symlinks. Opens nothing, so it cannot block.
pub fn check_file(path: &Path, kind: FileKind) -> Result<u64> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if let Some(what) = not_regular(&meta) {
        return Err(Error::invalid(path, format!("{what}; a {} must be a regular file", kind.noun())));
    }
    let limit = kind.max_bytes();
    if meta.len() > limit {
        return Err(too_big(path, kind, Some(meta.len())));
    }
    Ok(meta.len())
}

fn too_big(path: &Path, kind: FileKind, len: Option<u64>) -> Error {
    let size = match len {
        Some(n) => format!("is {n} bytes"),
        None => "grew while it was read".to_string(),
    };
    Error::invalid(
        path,
        format!(
            "{} {size}; at most {} ({} bytes) are read (docs/limits.md)",
            kind.noun(),
            human_bytes(kind.max_bytes()),
            kind.max_bytes()
        ),
    )
}

/// Reads the whole regular file at `path`, at most `kind.max_bytes()` of it: the type and
/// size are checked before opening, the open does not block (a FIFO swapped in after the
/// check is refused, not waited on), and the read stops one byte past the limit.
pub fn read_file(path: &Path, kind: FileKind) -> Result<Vec<u8>> {
    let len = check_file(path, kind)?;
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::fs::OpenOptionsExt;
        /// `O_NONBLOCK` on Linux: opening a FIFO returns at once; no effect on regular files.
        const O_NONBLOCK: i32 = 0o4000;
        options.custom_flags(O_NONBLOCK);
    }
    let file = options.open(path).map_err(|e| Error::io(path, e))?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    if let Some(what) = not_regular(&meta) {
        return Err(Error::invalid(path, format!("{what}; a {} must be a regular file", kind.noun())));
    }
    let limit = kind.max_bytes();
    let mut bytes = Vec::with_capacity(usize::try_from(len.min(limit)).unwrap_or(0));
    file.take(limit + 1).read_to_end(&mut bytes).map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(too_big(path, kind, None));
    }
    Ok(bytes)
}

/// What is wrong with an image of `width` x `height` texels when it exceeds
/// [`MAX_IMAGE_SIDE`] or `max_texels`, or is empty; None when it fits.
pub fn image_size_error(width: u32, height: u32, max_texels: u64) -> Option<String> {
    if width == 0 || height == 0 {
        return Some(format!("the image is {width}x{height}; it has no texels"));
    }
    if width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        return Some(format!(
            "the image is {width}x{height}; each side may be at most {MAX_IMAGE_SIDE} (docs/limits.md)"
        ));
    }
    let texels = u64::from(width) * u64::from(height);
    if texels > max_texels {
        return Some(format!(
            "the image is {width}x{height} = {texels} texels; at most {max_texels} are supported (docs/limits.md)"
        ));
    }
    None
}

/// What is wrong when a scene's running totals exceed [`MAX_TRIANGLES`] or
/// [`MAX_VERTICES`] (`"N triangles; at most M are supported"`); None while they fit.
pub fn totals_error(triangles: u64, vertices: u64) -> Option<String> {
    if triangles > MAX_TRIANGLES {
        return Some(format!("{triangles} triangles; at most {MAX_TRIANGLES} are supported"));
    }
    if vertices > MAX_VERTICES {
        return Some(format!("{vertices} vertices; at most {MAX_VERTICES} are supported"));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_read_well() {
        assert_eq!(human_bytes(16 << 20), "16 MiB");
        assert_eq!(human_bytes(2 << 30), "2 GiB");
        assert_eq!(human_bytes(3 << 29), "1536 MiB");
        assert_eq!(human_bytes(12), "12 bytes");
    }

    #[test]
    fn refuses_what_is_not_a_small_regular_file() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_file(dir.path(), FileKind::Mesh).unwrap_err().to_string();
        assert!(e.contains("is a directory"), "{e}");
        let big = dir.path().join("big.toml");
        std::fs::File::create(&big).unwrap().set_len(MAX_TEXT_FILE_BYTES + 1).unwrap();
        let e = read_file(&big, FileKind::SceneFile).unwrap_err().to_string();
        assert!(e.contains("at most 16 MiB (16777216 bytes)"), "{e}");
        let ok = dir.path().join("ok.toml");
        std::fs::write(&ok, "x").unwrap();
        assert_eq!(read_file(&ok, FileKind::SceneFile).unwrap(), b"x");
        #[cfg(unix)]
        {
            let e = read_file(Path::new("/dev/zero"), FileKind::Mesh).unwrap_err().to_string();
            assert!(e.contains("character device"), "{e}");
        }
    }
}
