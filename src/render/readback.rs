//! Readback and accumulation: a chunk of `GpuPixel`s from the pixel buffer into the
//! frame (radiance averaged over samples, the AOVs of the pixel-centre camera ray).

use super::Frame;
use crate::accel::gpu_layout::{GpuPixel, PIXEL_HEADER_BYTES};
use crate::error::Result;
use crate::gpu::bindings::OVERFLOW_FLAG;
use crate::gpu::{Buffer, Context};

impl Frame {
    /// An empty frame: black, misses everywhere.
    pub fn new(width: u32, height: u32) -> Frame {
        let n = width as usize * height as usize;
        Frame {
            width,
            height,
            radiance: vec![[0.0; 3]; n],
            depth: vec![f32::INFINITY; n],
            normal: vec![[0.0; 3]; n],
            prim: vec![u32::MAX; n],
            nodes: vec![0; n],
            tests: vec![0; n],
            rays: vec![0; n],
        }
    }
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
