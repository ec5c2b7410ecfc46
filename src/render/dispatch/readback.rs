//! Accumulation: the `GpuPixel`s the loop read back into the frame (radiance
//! averaged over samples, the AOVs of the pixel's first camera ray), and the wave
//! policy every render shares ([`FrameWaves`]).

use std::time::Instant;

use super::{ChunkInput, Next, Wave, WavePolicy};
use crate::accel::gpu_layout::GpuPixel;
use crate::error::{Error, Result};
use crate::gpu::bindings::OVERFLOW_FLAG;
use crate::render::{CheckpointWriter, Frame};

impl Frame {
    /// An empty frame: black, misses everywhere. An error (not an abort) when the host
    /// cannot allocate it.
    pub fn new(width: u32, height: u32) -> Result<Frame> {
        let n = width as usize * height as usize;
        let too_big = || {
            Error::Failed(format!(
                "--size {width}x{height}: cannot allocate the frame (about {} MiB); use a smaller --size",
                (n as u64 * crate::render::output::memory::FRAME_BYTES_PER_PIXEL) >> 20
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

    /// Pixel `k`'s state as the kernel holds it (what [`Frame::store`] took), for
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
    /// count (as [`Frame::store`] does).
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

    /// Takes the pixels the loop read back, from pixel `first` on, dividing radiance
    /// sums by each pixel's sample count.
    pub fn store(&mut self, first: u64, pixels: &[GpuPixel]) {
        for (k, g) in pixels.iter().enumerate() {
            let idx = first as usize + k;
            self.samples[idx] = g.radiance[3] as u32;
            self.sum[idx] = [g.radiance[0], g.radiance[1], g.radiance[2]];
            self.sum_y2[idx] = g.albedo_m2[3];
            self.finish_pixel(idx);
            self.albedo[idx] = [g.albedo_m2[0], g.albedo_m2[1], g.albedo_m2[2]];
            self.normal[idx] = [g.normal_depth[0], g.normal_depth[1], g.normal_depth[2]];
            self.depth[idx] = g.normal_depth[3];
            self.prim[idx] = g.prim_cost[0];
            self.nodes[idx] = g.prim_cost[1];
            self.tests[idx] = g.prim_cost[2];
            self.rays[idx] = g.prim_cost[3] & !OVERFLOW_FLAG;
        }
    }
}

/// `n` copies of `v`, or `None` when the allocation fails.
fn filled<T: Clone>(n: usize, v: T) -> Option<Vec<T>> {
    let mut out = Vec::new();
    out.try_reserve_exact(n).ok()?;
    out.resize(n, v);
    Some(out)
}

/// The wave policy of a render, which decides alone what follows each wave: each chunk
/// starts from the resumed part's pixels (or zero) and its pixels go into the frame;
/// between waves it stops when interrupted, reads the chunk back for a checkpoint every
/// so often, and moves to the next chunk once this one's share of the time budget is
/// spent. (The Whitted integrator's is never interrupted, writes no checkpoint and has
/// no budget: it always goes on.)
pub struct FrameWaves<'s> {
    pub frame: Frame,
    /// A resumed part's image, whose sums the pixels start from.
    pub resume: Option<&'s Frame>,
    /// Polled after every wave and at the end of every chunk: true stops the render.
    pub interrupted: Box<dyn Fn() -> bool + 's>,
    /// Every so many seconds (checked after each wave), the image so far.
    pub checkpoint: Option<(f64, CheckpointWriter<'s>)>,
    /// The time budget (seconds) and the pixels it is shared among.
    pub budget: Option<(f64, u64)>,
    pub last_checkpoint: Instant,
    pub chunk_started: Instant,
}

impl std::fmt::Debug for FrameWaves<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrameWaves")
            .field("resumed", &self.resume.is_some())
            .field("budget", &self.budget)
            .finish_non_exhaustive()
    }
}

impl FrameWaves<'_> {
    /// The next chunk once this one (of `len` pixels) has spent its share of the budget.
    fn within_budget(&self, len: u64) -> Next {
        match self.budget {
            Some((budget, total))
                if self.chunk_started.elapsed().as_secs_f64() >= budget * len as f64 / total as f64 =>
            {
                Next::NextChunk
            }
            _ => Next::Continue,
        }
    }
}

impl WavePolicy for FrameWaves<'_> {
    fn input(&mut self, first: u64, len: u64) -> Result<ChunkInput> {
        Ok(match self.resume {
            Some(f) => ChunkInput::Pixels((first..first + len).map(|k| f.gpu_pixel(k as usize)).collect()),
            None => ChunkInput::None,
        })
    }

    fn after_wave(&mut self, wave: Wave) -> Result<Next> {
        if (self.interrupted)() {
            return Ok(Next::Stop);
        }
        if let Some((every, _)) = &self.checkpoint {
            if self.last_checkpoint.elapsed().as_secs_f64() >= *every {
                return Ok(Next::ReadBack);
            }
        }
        Ok(self.within_budget(wave.len))
    }

    fn pixels(&mut self, wave: Wave, pixels: &[GpuPixel]) -> Result<Next> {
        self.frame.store(wave.first, pixels);
        if wave.complete {
            self.chunk_started = Instant::now();
            return Ok(if (self.interrupted)() { Next::Stop } else { Next::Continue });
        }
        if let Some((_, write)) = self.checkpoint.as_mut() {
            write(&self.frame)?;
            self.last_checkpoint = Instant::now();
        }
        Ok(self.within_budget(wave.len))
    }
}
