//! Readback and accumulation: a chunk of `GpuPixel`s from the pixel buffer into the
//! frame (radiance averaged over samples, the AOVs of the pixel-centre camera ray).

use super::Frame;
use crate::accel::gpu_layout::{GpuPixel, PIXEL_HEADER_BYTES};
use crate::error::{Error, Result};
use crate::gpu::bindings::OVERFLOW_FLAG;
use crate::gpu::{Buffer, Context};

impl Frame {
    /// An empty frame: black, misses everywhere. An error (not an abort) when the host
    /// cannot allocate it.
    pub fn new(width: u32, height: u32) -> Result<Frame> {
        let n = width as usize * height as usize;
        let too_big = || {
            Error::Usage(format!(
                "--size {width}x{height}: cannot allocate the frame (about {} MiB); use a smaller --size",
                (n as u64 * super::memory::FRAME_BYTES_PER_PIXEL) >> 20
            ))
        };
        Ok(Frame {
            width,
            height,
            radiance: filled(n, [0.0; 3]).ok_or_else(too_big)?,
            depth: filled(n, f32::INFINITY).ok_or_else(too_big)?,
            normal: filled(n, [0.0; 3]).ok_or_else(too_big)?,
            prim: filled(n, u32::MAX).ok_or_else(too_big)?,
            nodes: filled(n, 0).ok_or_else(too_big)?,
            tests: filled(n, 0).ok_or_else(too_big)?,
            rays: filled(n, 0).ok_or_else(too_big)?,
        })
    }
}

/// `n` copies of `v`, or `None` when the allocation fails.
fn filled<T: Clone>(n: usize, v: T) -> Option<Vec<T>> {
    let mut out = Vec::new();
    out.try_reserve_exact(n).ok()?;
    out.resize(n, v);
    Some(out)
}

/// Reads `len` pixels of the chunk in `pixel_buf` into `frame` from pixel `first`,
/// dividing radiance sums by `spp`. Returns how many pixels ran out of traversal steps.
pub fn read_chunk(ctx: &Context, pixel_buf: &Buffer, frame: &mut Frame, first: u64, len: u64, spp: u32) -> Result<u64> {
    let size = std::mem::size_of::<GpuPixel>();
    let bytes = ctx.read_storage(pixel_buf, PIXEL_HEADER_BYTES, len * size as u64)?;
    let mut overflow = 0u64;
    let inv = 1.0 / spp as f32;
    for (k, g) in bytes.chunks_exact(size).map(bytemuck::pod_read_unaligned::<GpuPixel>).enumerate() {
        let idx = first as usize + k;
        frame.radiance[idx] = [g.radiance[0] * inv, g.radiance[1] * inv, g.radiance[2] * inv];
        frame.normal[idx] = [g.normal_depth[0], g.normal_depth[1], g.normal_depth[2]];
        frame.depth[idx] = g.normal_depth[3];
        frame.prim[idx] = g.prim_cost[0];
        frame.nodes[idx] = g.prim_cost[1];
        frame.tests[idx] = g.prim_cost[2];
        frame.rays[idx] = g.prim_cost[3] & !OVERFLOW_FLAG;
        if g.prim_cost[3] & OVERFLOW_FLAG != 0 {
            overflow += 1;
        }
    }
    Ok(overflow)
}
