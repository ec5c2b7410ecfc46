//! Readback and accumulation: a chunk of `GpuPixel`s from the pixel buffer into the
//! frame (radiance averaged over samples, the AOVs of the pixel-centre camera ray).

use crate::accel::gpu_layout::{GpuPixel, PIXEL_HEADER_BYTES};
use crate::error::{Error, Result};
use crate::gpu::bindings::OVERFLOW_FLAG;
use crate::gpu::{Buffer, Context};
use crate::render::Frame;

impl Frame {
    /// An empty frame: black, misses everywhere. An error (not an abort) when the host
    /// cannot allocate it.
    pub fn new(width: u32, height: u32) -> Result<Frame> {
        let n = width as usize * height as usize;
        let too_big = || {
            Error::Failed(format!(
                "--size {width}x{height}: cannot allocate the frame (about {} MiB); use a smaller --size",
                (n as u64 * crate::render::memory::FRAME_BYTES_PER_PIXEL) >> 20
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
            albedo: filled(n, [0.0; 3]).ok_or_else(too_big)?,
            variance: filled(n, 0.0).ok_or_else(too_big)?,
            samples: filled(n, 0).ok_or_else(too_big)?,
            sum: filled(n, [0.0; 3]).ok_or_else(too_big)?,
            sum_y2: filled(n, 0.0).ok_or_else(too_big)?,
        })
    }

    /// Pixel `k`'s state as the kernel holds it (what [`read_chunk`] read), for
    /// resuming: bit for bit the sums and AOVs, without the overflow flag.
    pub fn gpu_pixel(&self, k: usize) -> GpuPixel {
        let [r, g, b] = self.sum[k];
        let [nx, ny, nz] = self.normal[k];
        let [ar, ag, ab] = self.albedo[k];
        GpuPixel {
            radiance: [r, g, b, self.samples[k] as f32],
            normal_depth: [nx, ny, nz, self.depth[k]],
            prim_cost: [self.prim[k], self.nodes[k], self.tests[k], self.rays[k]],
            albedo_m2: [ar, ag, ab, self.sum_y2[k]],
        }
    }

    /// Sets the mean radiance and the variance of pixel `k` from its sums and sample
    /// count (as [`read_chunk`] does).
    pub fn finish_pixel(&mut self, k: usize) {
        let n = self.samples[k] as f32;
        let inv = if n > 0.0 { 1.0 / n } else { 0.0 };
        let [r, g, b] = self.sum[k];
        self.radiance[k] = [r * inv, g * inv, b * inv];
        let [r, gg, b] = self.radiance[k];
        let mean = 0.2126 * r + 0.7152 * gg + 0.0722 * b;
        // Variance of the mean: (E[y^2] - E[y]^2) / (n - 1), from the sums.
        self.variance[k] = if n > 1.0 { ((self.sum_y2[k] * inv - mean * mean) / (n - 1.0)).max(0.0) } else { 0.0 };
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
/// dividing radiance sums by the pixel's sample count. Returns how many pixels ran
/// out of traversal steps.
pub fn read_chunk(ctx: &Context, pixel_buf: &Buffer, frame: &mut Frame, first: u64, len: u64) -> Result<u64> {
    let _span = crate::timeline::span("readback", || format!("read back pixels {first}+{len}"));
    let size = std::mem::size_of::<GpuPixel>();
    let bytes = ctx.read_storage(pixel_buf, PIXEL_HEADER_BYTES, len * size as u64)?;
    let mut overflow = 0u64;
    for (k, g) in bytes.chunks_exact(size).map(bytemuck::pod_read_unaligned::<GpuPixel>).enumerate() {
        let idx = first as usize + k;
        frame.samples[idx] = g.radiance[3] as u32;
        frame.sum[idx] = [g.radiance[0], g.radiance[1], g.radiance[2]];
        frame.sum_y2[idx] = g.albedo_m2[3];
        frame.finish_pixel(idx);
        frame.albedo[idx] = [g.albedo_m2[0], g.albedo_m2[1], g.albedo_m2[2]];
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
