//! The render loop, one way through for every kernel: [`prepare`] chooses and
//! specialises the kernel, uploads the scene and structure and bounds the loops; [`run`]
//! traces the work in chunks of pixels (or rays) held on the device, each chunk in
//! sample waves (all its pixels reach the same sample count after each wave), each
//! wave in dispatches sized by [`pacing`] and kept in flight on one [`DispatchRing`].
//! The loop owns a chunk from end to end: the upload of its input, the dispatches and
//! their resume passes, the readback, the overflow count and the totals. An integrator
//! says only what a chunk's input is, what follows each wave and what to do with the
//! pixels read back, in a [`WavePolicy`] (renders: [`readback::FrameWaves`]; ray
//! batches their own).
//!
//! The host waits only where it needs a result: when the ring is full (the oldest
//! dispatch lands: its GPU time sizes the next ones, its counters say whether traces
//! stopped, progress moves), at a checkpoint, and at the end of a chunk (readback).
//! A dispatch that stopped traces (docs/kernels.md, "Resumed traces") has its resume
//! passes run when it lands; the trace dispatches in flight behind it leave the
//! pixels it stopped alone and count them as stopped too (`pixel_behind` in
//! `shaders/common/resume_trace.glsl`), so their own resume passes, run in order, bring
//! those pixels up to date sample by sample: the image does not depend on how many
//! dispatches were in flight, nor on how they were sized.

pub mod kernel;
pub mod pacing;
pub mod prepare;
pub mod readback;
pub mod resume;
pub mod tables;
pub mod upload;

use std::collections::VecDeque;
use std::ops::Range;
use std::time::Instant;

use self::pacing::Sizer;
use self::resume::{ResumeTotals, Resumer};
use crate::accel::gpu_layout::{DispatchChunk, GpuDispatch, GpuPixel, GpuRay, PIXEL_HEADER_BYTES};
use crate::error::{Error, Result};
use crate::gpu::bindings::{OVERFLOW_FLAG, PASS_TRACE, WORKGROUP_SIZE};
use crate::gpu::{Buffer, Context, DispatchRing, HeaderDispatch, Kernel};

pub use self::pacing::{dispatch_shape, Pacing, PacingChoice};

/// Byte of the dispatch header the ring copies back after every dispatch
/// (`GpuDispatch::chunk`, whose `counter` is the samples the trace kernel stopped).
const HEADER_COUNTERS: u64 = std::mem::offset_of!(GpuDispatch, chunk) as u64;

/// The image's pixels (or a batch's rays) and samples, and how much of it the device
/// holds at once.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Waves {
    pub total_pixels: u64,
    /// Pixels held on the device at once.
    pub chunk_pixels: u64,
    /// Samples of each pixel, from `first_sample`.
    pub spp: u32,
    /// The first sample index.
    pub first_sample: u32,
    /// The window's left column, top row and width: pixel indices count inside it.
    pub window: [u32; 3],
    /// Resumed: the pixels start from uploaded sums, never from zero.
    pub resumed: bool,
}

impl Waves {
    /// The pixels and samples of `settings`' window and sample range, `chunk_pixels`
    /// pixels at a time.
    pub fn new(settings: &super::RenderSettings, chunk_pixels: u64) -> Waves {
        let win = settings.window();
        Waves {
            total_pixels: win.pixels(),
            chunk_pixels,
            spp: settings.spp,
            first_sample: settings.first_sample,
            window: [win.x0, win.y0, win.width()],
            resumed: settings.resume.is_some(),
        }
    }

    /// The header of a dispatch of the chunk from pixel `chunk` over `pixels` and
    /// `samples`, each trace within `tree_steps` steps.
    fn header(&self, chunk: u64, pixels: Range<u64>, samples: Range<u32>, tree_steps: u32) -> GpuDispatch {
        let [x0, y0, w] = self.window;
        GpuDispatch {
            first: pixels.start as u32,
            count: (pixels.end - pixels.start) as u32,
            sample_begin: samples.start,
            sample_end: samples.end,
            chunk: DispatchChunk { base: chunk as u32, resumed: u32::from(self.resumed), pass: PASS_TRACE, counter: 0 },
            window_left: x0,
            window_top: y0,
            window_width: w,
            zero_sample: self.first_sample,
            trace_steps: tree_steps,
            unused: 0,
            map_size: 0,
            map_buckets: 0,
        }
    }
}

/// What the dispatches cost and how busy they kept the device.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DispatchTotals {
    /// Sum of the dispatches' GPU time, resume passes included; `None` without
    /// timestamps.
    pub gpu_ms: Option<f64>,
    /// Trace dispatches (resume passes not counted).
    pub dispatches: u32,
    /// Traces resumed after running out of steps, and the passes that did it.
    pub resumes: ResumeTotals,
    /// Pixels (or rays) whose trace ran out of steps in a family that cannot resume
    /// one, counted when their chunk was read back the last time.
    pub overflow: u64,
    /// Whether the loop stopped before its end (its policy said [`Next::Stop`]).
    pub stopped: bool,
    /// GPU milliseconds of each trace dispatch, in order (empty without timestamps).
    pub lengths_ms: Vec<f64>,
    /// Host wall time of the loop, first submission to last landing.
    pub loop_ms: f64,
    /// Most dispatches that were in flight at once.
    pub in_flight: u32,
    /// The target length dispatches were sized toward.
    pub target_ms: f64,
}

/// A dispatch in flight: its header and its pixel-samples.
#[derive(Debug, Clone, Copy)]
struct Pending {
    header: GpuDispatch,
    units: u64,
}

/// The dispatches in flight of one loop, and what they have cost so far.
struct Flight<'r, 'a> {
    ctx: &'a Context,
    kernel: &'r Kernel,
    resumer: &'r mut Resumer<'a>,
    pixel_buf: &'r Buffer,
    ray_buf: Option<&'r Buffer>,
    ring: DispatchRing<'a>,
    pending: VecDeque<Pending>,
    sizer: &'r mut Sizer,
    progress: &'r mut dyn FnMut(u64, u64),
    done: u64,
    total: u64,
    last_landed: Option<Instant>,
    totals: DispatchTotals,
    tree_steps: u32,
}

impl std::fmt::Debug for Flight<'_, '_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Flight").field("in_flight", &self.pending.len()).field("done", &self.done).finish()
    }
}

impl Flight<'_, '_> {
    /// Lands dispatches until another may be submitted: the ring has room, and the
    /// first dispatch (a probe: the next ones are sized from its time) has landed.
    fn make_room(&mut self) -> Result<()> {
        while !self.ring.has_room() || (self.sizer.unmeasured() && !self.pending.is_empty()) {
            self.land()?;
        }
        Ok(())
    }

    /// Submits the dispatch of `header` (`units` pixel-samples); [`Flight::make_room`]
    /// came first.
    fn submit(&mut self, header: GpuDispatch, units: u64) -> Result<()> {
        let (first, n, s, s_end) = (header.first, header.count, header.sample_begin, header.sample_end);
        let label = format!("trace pixels {first}+{n} samples {s}..{s_end}");
        let groups = n.div_ceil(WORKGROUP_SIZE);
        self.ring.submit(&HeaderDispatch {
            kernel: self.kernel,
            groups: [groups, 1, 1],
            buffer: self.pixel_buf,
            header_at: 0,
            header: bytemuck::bytes_of(&header),
            copy_back_at: HEADER_COUNTERS,
            label: &label,
        })?;
        self.pending.push_back(Pending { header, units });
        self.totals.in_flight = self.totals.in_flight.max(self.ring.in_flight() as u32);
        self.totals.dispatches += 1;
        Ok(())
    }

    /// Lands the oldest dispatch: its time, its stopped samples' resume passes, progress.
    fn land(&mut self) -> Result<()> {
        let Some(landed) = self.ring.land_oldest()? else { return Ok(()) };
        let Some(p) = self.pending.pop_front() else { return Ok(()) };
        let now = Instant::now();
        // Without timestamps, the host time since it could have started.
        let busy_from = self.last_landed.map_or(landed.submitted, |t| t.max(landed.submitted));
        self.last_landed = Some(now);
        let ms = landed.gpu_ms.unwrap_or_else(|| now.duration_since(busy_from).as_secs_f64() * 1e3);
        self.sizer.measured(p.units, ms);
        self.totals.gpu_ms = add_ms(self.totals.gpu_ms, landed.gpu_ms);
        if let Some(ms) = landed.gpu_ms {
            self.totals.lengths_ms.push(ms);
        }
        let stopped = bytemuck::cast::<[u32; 4], DispatchChunk>(landed.words).counter;
        self.resumer.settle(self.pixel_buf, p.header, stopped, &mut self.totals.gpu_ms)?;
        self.totals.resumes = self.resumer.totals;
        self.done += p.units;
        (self.progress)(self.done.min(self.total), self.total);
        Ok(())
    }

    /// Waits until every dispatch submitted so far has landed (and its stopped
    /// samples are resumed): the pixels then hold what they were given.
    fn settle(&mut self) -> Result<()> {
        while !self.pending.is_empty() {
            self.land()?;
        }
        Ok(())
    }

    /// Writes a chunk's input where the kernel reads it, once the dispatches of the
    /// chunk before have landed.
    fn upload(&mut self, input: ChunkInput) -> Result<()> {
        match input {
            ChunkInput::None => Ok(()),
            ChunkInput::Pixels(pixels) => {
                self.settle()?;
                self.ctx.write_storage(self.pixel_buf, PIXEL_HEADER_BYTES, bytemuck::cast_slice(&pixels))
            }
            ChunkInput::Rays(rays) => {
                self.settle()?;
                let buf = self.ray_buf.ok_or_else(|| Error::Failed("the kernel has no ray buffer".into()))?;
                self.ctx.write_storage(buf, 0, bytemuck::cast_slice(&rays))
            }
        }
    }

    /// Reads the chunk of `wave` back once its dispatches have landed and gives its
    /// pixels to `policy`; at the chunk's end (`wave.complete`), counts those that ran
    /// out of steps.
    fn read(&mut self, policy: &mut dyn WavePolicy, wave: Wave) -> Result<Next> {
        self.settle()?;
        let pixels = {
            let _span = crate::timeline::span("readback", || format!("read back pixels {}+{}", wave.first, wave.len));
            self.ctx.read_storage_pod::<GpuPixel>(self.pixel_buf, PIXEL_HEADER_BYTES, wave.len as usize)?
        };
        if wave.complete {
            self.totals.overflow += pixels.iter().filter(|p| p.prim_cost[3] & OVERFLOW_FLAG != 0).count() as u64;
        }
        policy.pixels(wave, &pixels)
    }

    /// Counts `units` pixel-samples as done without tracing them (a chunk whose share
    /// of the time budget ran out).
    fn skip(&mut self, units: u64) {
        self.done += units;
    }
}

/// What a chunk starts from, written before its first dispatch.
#[derive(Debug, Clone, PartialEq)]
pub enum ChunkInput {
    /// Nothing: the pixels start from zero.
    None,
    /// The pixels' states (a resumed render's sums).
    Pixels(Vec<GpuPixel>),
    /// The rays of a batch, one a pixel.
    Rays(Vec<GpuRay>),
}

/// What a loop does after a sample wave: go on, read the chunk's pixels so far and
/// then go on (a checkpoint), or stop the whole render (interrupted) or only this
/// chunk (its share of the time budget is spent).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Next {
    Continue,
    ReadBack,
    NextChunk,
    Stop,
}

/// A sample wave just submitted: the chunk's first pixel and length, the samples its
/// pixels will hold, and whether it is the chunk's last (its pixels are final).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Wave {
    pub first: u64,
    pub len: u64,
    pub samples: u32,
    pub complete: bool,
}

/// What an integrator tells the loop: a chunk's input, what comes after each wave, and
/// what to do with the pixels the loop reads back. The loop does the rest.
pub trait WavePolicy {
    /// The input of the chunk of `len` pixels from `first`, before its first dispatch.
    fn input(&mut self, first: u64, len: u64) -> Result<ChunkInput>;

    /// After a wave that is not its chunk's last.
    fn after_wave(&mut self, _wave: Wave) -> Result<Next> {
        Ok(Next::Continue)
    }

    /// The chunk's pixels, once every dispatch so far has landed: at its end
    /// (`wave.complete`: then [`Next::Stop`] stops the loop and anything else goes on;
    /// after a chunk that ended early, whatever is returned is ignored), or when
    /// [`WavePolicy::after_wave`] asked for them ([`Next::ReadBack`] then goes on).
    fn pixels(&mut self, wave: Wave, pixels: &[GpuPixel]) -> Result<Next>;
}

/// What one loop is given: the kernel and its resumer, the pixel buffer (and a ray
/// buffer for batches), the pixels and samples, the sizer and the ring's depth.
pub struct LoopInput<'r, 'a> {
    pub ctx: &'a Context,
    pub kernel: &'r Kernel,
    pub resumer: &'r mut Resumer<'a>,
    pub pixel_buf: &'r Buffer,
    pub ray_buf: Option<&'r Buffer>,
    pub waves: Waves,
    pub sizer: &'r mut Sizer,
    pub in_flight: u32,
    pub target_ms: f64,
    /// The steps one trace may take (`LoopBounds::steps`, the header's `limits`).
    pub tree_steps: u32,
}

impl std::fmt::Debug for LoopInput<'_, '_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LoopInput").field("waves", &self.waves).field("in_flight", &self.in_flight).finish()
    }
}

/// Runs the kernel (and its resume passes) over every pixel and sample of `waves`,
/// sample waves outermost within each chunk, on one ring. `progress(done, total)`
/// counts pixel-samples as dispatches land; `policy` gives each chunk's input, says
/// what follows each wave and takes the pixels read back (at the end of each chunk,
/// also one that ends early). Returns the totals, with the pixels that ran out of
/// steps and whether the loop stopped before its end.
pub fn run(
    input: LoopInput<'_, '_>,
    progress: &mut dyn FnMut(u64, u64),
    policy: &mut dyn WavePolicy,
) -> Result<DispatchTotals> {
    let LoopInput { ctx, kernel, resumer, pixel_buf, ray_buf, waves, sizer, in_flight, target_ms, tree_steps } = input;
    if waves.total_pixels > u64::from(u32::MAX) {
        return Err(Error::Usage(format!(
            "{} pixels or rays in one loop, more than the dispatch header's 32-bit indices hold ({}); trace them in parts",
            waves.total_pixels,
            u32::MAX
        )));
    }
    let span = crate::timeline::span("trace", || "trace");
    span.arg("pixels", waves.total_pixels);
    span.arg("samples", waves.spp);
    span.arg("in_flight", in_flight);
    span.arg("target_ms", target_ms);
    let start = Instant::now();
    let mut flight = Flight {
        ctx,
        kernel,
        resumer,
        pixel_buf,
        ray_buf,
        ring: ctx.dispatch_ring(in_flight)?,
        pending: VecDeque::new(),
        sizer,
        progress,
        done: 0,
        total: waves.total_pixels * u64::from(waves.spp),
        last_landed: None,
        totals: DispatchTotals { gpu_ms: Some(0.0), target_ms, ..Default::default() },
        tree_steps,
    };
    let stopped = run_chunks(&mut flight, &waves, policy)?;
    flight.settle()?;
    let mut totals = std::mem::take(&mut flight.totals);
    totals.loop_ms = start.elapsed().as_secs_f64() * 1e3;
    totals.stopped = stopped;
    span.arg("dispatches", totals.dispatches);
    Ok(totals)
}

fn run_chunks(flight: &mut Flight<'_, '_>, waves: &Waves, policy: &mut dyn WavePolicy) -> Result<bool> {
    let end = waves.first_sample + waves.spp;
    let mut chunk_start = 0u64;
    while chunk_start < waves.total_pixels {
        let len = waves.chunk_pixels.min(waves.total_pixels - chunk_start);
        let input = policy.input(chunk_start, len)?;
        flight.upload(input)?;
        let mut s = waves.first_sample;
        while s < end {
            flight.make_room()?;
            let m = flight.sizer.wave_samples(len, end - s);
            let s_end = s + m;
            let mut p = 0u64;
            while p < len {
                flight.make_room()?;
                let n = if m > 1 { len - p } else { flight.sizer.pixels(len - p) };
                let pixels = chunk_start + p..chunk_start + p + n;
                let header = waves.header(chunk_start, pixels, s..s_end, flight.tree_steps);
                flight.submit(header, n * u64::from(m))?;
                p += n;
            }
            s = s_end;
            let wave = Wave { first: chunk_start, len, samples: s, complete: s == end };
            let next = if wave.complete {
                flight.read(policy, wave)?
            } else {
                match policy.after_wave(wave)? {
                    Next::ReadBack => flight.read(policy, wave)?,
                    next => next,
                }
            };
            match next {
                Next::Continue | Next::ReadBack => {}
                Next::NextChunk => {
                    if s < end {
                        flight.read(policy, Wave { complete: true, ..wave })?;
                        flight.skip(len * u64::from(end - s));
                    }
                    break;
                }
                Next::Stop => {
                    if s < end {
                        flight.read(policy, Wave { complete: true, ..wave })?;
                    }
                    return Ok(chunk_start + len < waves.total_pixels || s < end);
                }
            }
        }
        chunk_start += len;
    }
    Ok(false)
}

/// The sum of two GPU times, or None when either is unknown (no timestamps): the one
/// way dispatches, resume passes and ray batches add up their milliseconds.
pub(crate) fn add_ms(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a + b),
        _ => None,
    }
}

/// Mean, median and longest of dispatch lengths (ms); zeros for none.
pub fn length_summary(lengths: &[f64]) -> (f64, f64, f64) {
    if lengths.is_empty() {
        return (0.0, 0.0, 0.0);
    }
    let mut v = lengths.to_vec();
    v.sort_by(f64::total_cmp);
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let median = if v.len() % 2 == 1 { v[v.len() / 2] } else { 0.5 * (v[v.len() / 2 - 1] + v[v.len() / 2]) };
    (mean, median, v[v.len() - 1])
}
