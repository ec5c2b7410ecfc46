//! The dispatch loop: the image in chunks of pixels held on the device, each chunk in
//! dispatches of pixel ranges x sample waves sized to a work budget, with progress
//! after every dispatch and a callback when a chunk is complete. Any integrator's
//! kernel runs through it: the per-dispatch values travel in the pixel buffer's
//! header (`GpuDispatch`), never in push constants (docs/kernels.md).

use super::resume::{ResumeTotals, Resumer};
use super::Frame;
use crate::accel::gpu_layout::{GpuDispatch, GpuPixel, PIXEL_HEADER_BYTES};
use crate::error::Result;
use crate::gpu::bindings::WORKGROUP_SIZE;
use crate::gpu::{Buffer, Context, Kernel};

/// Splits `pixels` x `spp` into dispatches of about `budget` units of work: returns
/// (pixels per dispatch, samples per dispatch).
pub fn dispatch_shape(pixels: u64, spp: u32, cost_per_sample: u64, budget: u64) -> (u64, u32) {
    let per_pixel_all = cost_per_sample.saturating_mul(u64::from(spp)).max(1);
    if pixels.saturating_mul(per_pixel_all) <= budget {
        return (pixels, spp);
    }
    let px = (budget / cost_per_sample.max(1)).max(u64::from(WORKGROUP_SIZE));
    if px >= pixels {
        let samples = (budget / (pixels.max(1) * cost_per_sample.max(1))).clamp(1, u64::from(spp)) as u32;
        return (pixels, samples);
    }
    (px / u64::from(WORKGROUP_SIZE) * u64::from(WORKGROUP_SIZE), 1)
}

/// How an image is cut into dispatches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Waves {
    pub total_pixels: u64,
    /// Pixels held on the device at once.
    pub chunk_pixels: u64,
    /// Pixels per dispatch.
    pub pixels_per_dispatch: u64,
    /// Samples of each pixel, from `first_sample`.
    pub spp: u32,
    /// Samples per dispatch.
    pub samples_per_dispatch: u32,
    /// The first sample index.
    pub first_sample: u32,
    /// The window's left column, top row and width: pixel indices count inside it.
    pub window: [u32; 3],
    /// Resumed: the pixels start from uploaded sums, never from zero.
    pub resumed: bool,
}

impl Waves {
    /// The dispatches of `settings`' window and sample range, `chunk_pixels` pixels at
    /// a time, in dispatches of the given shape.
    pub fn new(
        settings: &super::RenderSettings,
        chunk_pixels: u64,
        pixels_per_dispatch: u64,
        samples_per_dispatch: u32,
    ) -> Waves {
        let win = settings.window();
        Waves {
            total_pixels: win.pixels(),
            chunk_pixels,
            pixels_per_dispatch,
            spp: settings.spp,
            samples_per_dispatch,
            first_sample: settings.first_sample,
            window: [win.x0, win.y0, win.width()],
            resumed: settings.resume.is_some(),
        }
    }

    fn header(&self, (chunk, first, n): (u64, u64, u64), (s, s_end): (u32, u32)) -> GpuDispatch {
        let [x0, y0, w] = self.window;
        GpuDispatch {
            range: [first as u32, n as u32, s, s_end],
            chunk: [chunk as u32, u32::from(self.resumed), 0, 0],
            window: [x0, y0, w, self.first_sample],
        }
    }
}

/// Writes the chunk's starting pixel states from `resume` (a resumed render).
fn upload_chunk(ctx: &Context, pixel_buf: &Buffer, resume: Option<&Frame>, first: u64, len: u64) -> Result<()> {
    let Some(f) = resume else { return Ok(()) };
    let pixels: Vec<GpuPixel> = (first..first + len).map(|k| f.gpu_pixel(k as usize)).collect();
    ctx.write_storage(pixel_buf, PIXEL_HEADER_BYTES, bytemuck::cast_slice(&pixels))
}

/// What the dispatches cost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DispatchTotals {
    /// Sum of the dispatches' GPU time, resume passes included; `None` without
    /// timestamps.
    pub gpu_ms: Option<f64>,
    /// Trace dispatches (resume passes not counted).
    pub dispatches: u32,
    /// Traces resumed after running out of steps, and the passes that did it.
    pub resumes: ResumeTotals,
}

/// One dispatch: pixels `first..first + n` of the chunk at `chunk`, samples
/// `s..s_end`, then the resume passes for the samples it stopped; its GPU time joins
/// `totals`.
fn dispatch_one(
    ctx: &Context,
    (kernel, resumer): (&Kernel, &mut Resumer<'_>),
    pixel_buf: &Buffer,
    waves: &Waves,
    (chunk, first, n): (u64, u64, u64),
    (s, s_end): (u32, u32),
    totals: &mut DispatchTotals,
) -> Result<()> {
    let header = waves.header((chunk, first, n), (s, s_end));
    let groups = n.div_ceil(u64::from(WORKGROUP_SIZE)) as u32;
    let label = format!("trace pixels {first}+{n} samples {s}..{s_end}");
    let ms = ctx.dispatch_after_write(kernel, pixel_buf, 0, bytemuck::bytes_of(&header), [groups, 1, 1], &label)?;
    totals.gpu_ms = match (totals.gpu_ms, ms) {
        (Some(a), Some(b)) => Some(a + b),
        _ => None,
    };
    totals.dispatches += 1;
    resumer.settle(pixel_buf, header, &mut totals.gpu_ms)?;
    totals.resumes = resumer.totals;
    Ok(())
}

/// The timeline span of a dispatch loop over `waves`.
fn trace_span(waves: &Waves) -> crate::timeline::Span {
    let span = crate::timeline::span("trace", || "trace");
    span.arg("pixels", waves.total_pixels);
    span.arg("samples", waves.spp);
    span.arg("pixels_per_dispatch", waves.pixels_per_dispatch);
    span.arg("samples_per_dispatch", waves.samples_per_dispatch);
    span
}

/// Runs `kernel` (and its resume passes) over every pixel and sample of `waves`. After
/// each dispatch, `progress(done, total)` counts pixel-samples; after each chunk,
/// `chunk_done(first_pixel, pixels)` reads it back.
pub fn run(
    ctx: &Context,
    kernel: (&Kernel, &mut Resumer<'_>),
    pixel_buf: &Buffer,
    waves: &Waves,
    resume: Option<&Frame>,
    mut progress: impl FnMut(u64, u64),
    mut chunk_done: impl FnMut(u64, u64) -> Result<()>,
) -> Result<DispatchTotals> {
    let _span = trace_span(waves);
    let total_work = waves.total_pixels * u64::from(waves.spp);
    let end = waves.first_sample + waves.spp;
    let mut done = 0u64;
    let mut totals = DispatchTotals { gpu_ms: Some(0.0), dispatches: 0, resumes: ResumeTotals::default() };
    let mut chunk_start = 0u64;
    while chunk_start < waves.total_pixels {
        let chunk_len = waves.chunk_pixels.min(waves.total_pixels - chunk_start);
        upload_chunk(ctx, pixel_buf, resume, chunk_start, chunk_len)?;
        let mut p = 0u64;
        while p < chunk_len {
            let n = waves.pixels_per_dispatch.min(chunk_len - p);
            let mut s = waves.first_sample;
            while s < end {
                let s_end = (s + waves.samples_per_dispatch).min(end);
                dispatch_one(
                    ctx,
                    (kernel.0, &mut *kernel.1),
                    pixel_buf,
                    waves,
                    (chunk_start, chunk_start + p, n),
                    (s, s_end),
                    &mut totals,
                )?;
                done += n * u64::from(s_end - s);
                progress(done, total_work);
                s = s_end;
            }
            p += n;
        }
        chunk_done(chunk_start, chunk_len)?;
        chunk_start += chunk_len;
    }
    Ok(totals)
}

/// What a progressive run does after a sample wave: go on, or stop the whole render
/// (interrupted) or only this chunk (its share of the time budget is spent).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Next {
    Continue,
    NextChunk,
    Stop,
}

/// Runs `kernel` like [`run`], but sample waves outermost within each chunk, so that
/// after every wave all pixels of the chunk hold the same number of samples. After
/// each wave, `wave_done(first_pixel, pixels, samples, chunk_complete)` decides what
/// comes next (and may read the chunk back); it is called once more with
/// `chunk_complete = true` when a chunk ends early. Returns the totals and whether
/// the render stopped before its end.
pub fn run_progressive(
    ctx: &Context,
    kernel: (&Kernel, &mut Resumer<'_>),
    pixel_buf: &Buffer,
    waves: &Waves,
    resume: Option<&Frame>,
    mut progress: impl FnMut(u64, u64),
    mut wave_done: impl FnMut(u64, u64, u32, bool) -> Result<Next>,
) -> Result<(DispatchTotals, bool)> {
    let _span = trace_span(waves);
    let total_work = waves.total_pixels * u64::from(waves.spp);
    let end = waves.first_sample + waves.spp;
    let mut done = 0u64;
    let mut totals = DispatchTotals { gpu_ms: Some(0.0), dispatches: 0, resumes: ResumeTotals::default() };
    let mut chunk_start = 0u64;
    while chunk_start < waves.total_pixels {
        let chunk_len = waves.chunk_pixels.min(waves.total_pixels - chunk_start);
        upload_chunk(ctx, pixel_buf, resume, chunk_start, chunk_len)?;
        let mut s = waves.first_sample;
        while s < end {
            let s_end = (s + waves.samples_per_dispatch).min(end);
            let mut p = 0u64;
            while p < chunk_len {
                let n = waves.pixels_per_dispatch.min(chunk_len - p);
                dispatch_one(
                    ctx,
                    (kernel.0, &mut *kernel.1),
                    pixel_buf,
                    waves,
                    (chunk_start, chunk_start + p, n),
                    (s, s_end),
                    &mut totals,
                )?;
                done += n * u64::from(s_end - s);
                progress(done, total_work);
                p += n;
            }
            s = s_end;
            match wave_done(chunk_start, chunk_len, s, s == end)? {
                Next::Continue => {}
                Next::NextChunk => {
                    if s < end {
                        wave_done(chunk_start, chunk_len, s, true)?;
                        done += chunk_len * u64::from(end - s);
                    }
                    break;
                }
                Next::Stop => {
                    if s < end {
                        wave_done(chunk_start, chunk_len, s, true)?;
                    }
                    return Ok((totals, chunk_start + chunk_len < waves.total_pixels || s < end));
                }
            }
        }
        chunk_start += chunk_len;
    }
    Ok((totals, false))
}
