//! Host memory a render will need, checked before anything large is allocated: the
//! frame (per pixel: radiance 12 B, depth 4, normal 12, primitive, nodes, tests and
//! rays 16), the largest output while it is encoded, and the structure's build, against
//! what the system has available and the process may map (`ulimit -v`). A request too
//! large is refused with an error that says what to reduce, instead of an abort when an
//! allocation fails. `ARBOR_MEMORY_LIMIT=BYTES` sets what counts as available (tests,
//! and shared machines where a job should stay under a budget).
//!
//! Device memory is bounded elsewhere: the pixel buffer holds at most a chunk of
//! pixels within `maxStorageBufferRange`, and the structure's buffers are checked
//! against the device's limits by `gpu_image`.

use std::path::Path;

use crate::error::{Error, Result};
use crate::render::output::Format;

/// Bytes per pixel of a [`crate::render::Frame`]: radiance (12), depth (4), normal (12),
/// primitive, nodes, tests, rays (4 each), albedo (12), variance and samples (4 each),
/// the radiance sums (12) and the sum of squared luminance (4).
pub const FRAME_BYTES_PER_PIXEL: u64 = 80;

/// Host bytes per primitive assumed for building a structure (references, nodes,
/// the builder's scratch and the GPU image's staging copy); a generous estimate.
pub const BUILD_BYTES_PER_PRIM: u64 = 512;

/// Bytes per pixel an output in `format` with `channels` channels needs while it is
/// encoded (the values it is made from plus the encoded bytes).
pub fn encode_bytes_per_pixel(format: Format, channels: u64) -> u64 {
    match format {
        // 8-bit values, then the compressed stream (at most about as large).
        Format::Png => 3 + 4,
        // A copy of the values, an RGB float copy, then the encoded file.
        Format::Exr => 4 * channels + 12 + 12 + 12,
        // A copy of the values, then the file.
        Format::Pfm => 8 * channels,
    }
}

/// Host bytes a render of `width` x `height` pixels of a scene with `prims`
/// primitives needs beyond what is already allocated: the frame, the largest output
/// while it is encoded (`outputs`: format and channels of each), the structure's build.
pub fn render_bytes(width: u32, height: u32, prims: usize, outputs: &[(Format, u64)]) -> u64 {
    let pixels = u64::from(width) * u64::from(height);
    let encode = outputs.iter().map(|&(f, c)| encode_bytes_per_pixel(f, c)).max().unwrap_or(0);
    pixels
        .saturating_mul(FRAME_BYTES_PER_PIXEL + encode)
        .saturating_add((prims as u64).saturating_mul(BUILD_BYTES_PER_PRIM))
}

/// Bytes this process can still allocate, as far as it can tell: the least of
/// `ARBOR_MEMORY_LIMIT`, the system's `MemAvailable` and the address-space limit
/// (`ulimit -v`) less what is mapped already. `None` when nothing says.
pub fn available() -> Result<Option<u64>> {
    let mut least: Option<u64> = None;
    let mut take = |v: u64| least = Some(least.map_or(v, |l| l.min(v)));
    if let Ok(v) = std::env::var("ARBOR_MEMORY_LIMIT") {
        let bytes = v
            .trim()
            .parse::<u64>()
            .map_err(|_| Error::Failed(format!("ARBOR_MEMORY_LIMIT={v:?} is not a byte count")))?;
        take(bytes);
    }
    if let Some(kib) = proc_field(Path::new("/proc/meminfo"), "MemAvailable:") {
        take(kib.saturating_mul(1024));
    }
    if let Some(limit) = address_space_limit() {
        let mapped = proc_field(Path::new("/proc/self/status"), "VmSize:").unwrap_or(0).saturating_mul(1024);
        take(limit.saturating_sub(mapped));
    }
    Ok(least)
}

/// The first number after `key` on the line starting with it in `file` (kB in
/// /proc/meminfo and /proc/self/status).
fn proc_field(file: &Path, key: &str) -> Option<u64> {
    let text = std::fs::read_to_string(file).ok()?;
    let line = text.lines().find(|l| l.starts_with(key))?;
    line[key.len()..].split_whitespace().next()?.parse().ok()
}

/// The soft "Max address space" of /proc/self/limits in bytes; `None` when unlimited.
fn address_space_limit() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/limits").ok()?;
    let line = text.lines().find(|l| l.starts_with("Max address space"))?;
    line["Max address space".len()..].split_whitespace().next()?.parse().ok()
}

/// GiB with one decimal.
fn gib(bytes: u64) -> String {
    format!("{:.1}", bytes as f64 / (1u64 << 30) as f64)
}

/// Refuses a render of `width` x `height` that would need more memory than is available
/// ([`render_bytes`], [`available`]). `what` names the setting to reduce in the message
/// (e.g. `--size 640x480`).
pub fn check_render(what: &str, width: u32, height: u32, prims: usize, outputs: &[(Format, u64)]) -> Result<()> {
    let need = render_bytes(width, height, prims, outputs);
    match available()? {
        Some(have) if need > have => Err(Error::Failed(format!(
            "{what}: the frame needs about {} GiB but only {} GiB are available; use a smaller --size",
            gib(need),
            gib(have)
        ))),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn largest_size_needs_more_than_eight_gib() {
        let need = render_bytes(16384, 16384, 10, &[(Format::Png, 3)]);
        assert!(need > 8 << 30, "{need}");
        assert_eq!(render_bytes(1, 1, 0, &[]), FRAME_BYTES_PER_PIXEL);
    }

    #[test]
    fn proc_files_parse() {
        // Linux always has these; elsewhere the check simply has nothing to go on.
        if Path::new("/proc/meminfo").exists() {
            assert!(proc_field(Path::new("/proc/meminfo"), "MemAvailable:").is_some());
        }
        let _ = address_space_limit();
    }
}
