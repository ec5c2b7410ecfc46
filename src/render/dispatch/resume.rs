//! Resumed traces (docs/kernels.md, "Resumed traces"). On llvmpipe every trace has a
//! step budget; a trace that runs out of it stops its sample, and the trace kernel
//! leaves the pixel with the samples before that one and counts it in the dispatch
//! header. After such a dispatch, the resume kernel (the same variant specialised with
//! `SPEC_RESUME_PASS`, created the first time one is needed, with the pool bound)
//! runs those samples on: a first pass over the dispatch's pixels takes those behind,
//! each following pass the jobs the one before gave out, until none is left. So the
//! pixels of a dispatch hold all its samples when it returns, as without a budget,
//! and sum them in the same order. The pool's layout and the kernel side:
//! `shaders/common/resume.glsl`.
//!
//! The passes are submitted as the trace dispatches are (a [`DispatchRing`]), and the
//! header's counter comes back with each. The ring is the resumer's own, of one: the
//! trace dispatches submitted behind the one that stopped are still in flight on the
//! loop's ring (the queue runs them before these passes), and the host lands them only
//! after these passes, in order. The host waits for each pass: the count it
//! gives out sizes the next one and splits it in two (the jobs that hold a record
//! first), and bounds the passes (`MAX_PASSES`). An indirect dispatch would size one
//! pass without the host, but not split it.

use super::upload;
use super::{add_ms, HEADER_COUNTERS};
use crate::accel::gpu_layout::{DispatchChunk, GpuDispatch};
use crate::accel::GpuImage;
use crate::error::{Error, Result};
use crate::gpu::bindings::*;
use crate::gpu::{Buffer, BufferKind, DispatchRing, HeaderDispatch, Kernel};

/// Bytes of trace records the pool holds at most (two halves), besides its job lists.
/// More pixels stopped in one pass than the records fit run their sample again from
/// the start in the next one.
const RECORD_POOL_BYTES: u64 = 64 << 20;

/// Resume passes after one trace dispatch before a render gives up: every pass takes
/// each saved trace at least one step further (`Resumer::settle`), so only a trace
/// that cannot advance within its budget gets near this.
const MAX_PASSES: u32 = 1 << 16;

/// What resuming cost a render (`RenderStats`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ResumeTotals {
    /// Pixel samples the trace dispatches stopped.
    pub samples: u64,
    /// Resume dispatches.
    pub dispatches: u32,
    /// Jobs they ran (one per stopped sample per pass).
    pub jobs: u64,
    /// Their GPU time; `None` without timestamps.
    pub gpu_ms: Option<f64>,
    /// Host time to create the resume kernel.
    pub kernel_ms: f64,
}

/// How the pool is cut: words per record, records per half, jobs per list.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PoolShape {
    pub record_words: u32,
    pub records: u32,
    pub jobs: u32,
}

impl PoolShape {
    /// For `jobs` invocations a pass at most (a dispatch's pixels), `log` traces a
    /// sample, the image's traversal state, within `max_range` bytes, with at most
    /// `most` records (a test's setting) where given.
    pub fn new(image: &GpuImage, log: u32, jobs: u64, max_range: u64, most: Option<u32>) -> Result<PoolShape> {
        let record_words = RESUME_HEAD_WORDS + RESUME_LOG_WORDS * log + image.resume_words;
        let job_bytes = 2 * 4 * jobs;
        let room = RECORD_POOL_BYTES.min(max_range.saturating_sub(job_bytes));
        let records = jobs.min(room / (2 * 4 * u64::from(record_words)));
        let records = most.map_or(records, |m| records.min(u64::from(m.max(1))));
        if records == 0 || jobs > u64::from(u32::MAX) {
            return Err(Error::Failed(format!(
                "the device's storage buffers ({max_range} bytes) cannot hold the jobs of {jobs} pixels and one trace record of {} bytes; use a smaller --dispatch-budget",
                4 * record_words
            )));
        }
        Ok(PoolShape { record_words, records: records as u32, jobs: jobs as u32 })
    }

    /// Bytes of the pool.
    pub fn bytes(&self) -> u64 {
        2 * 4 * (u64::from(self.jobs) + u64::from(self.records) * u64::from(self.record_words))
    }
}

/// The resume kernel, the pool its records live in, and the ring of one its passes
/// are submitted on.
struct Passes<'a> {
    kernel: Kernel,
    _pool: Buffer,
    ring: DispatchRing<'a>,
}

/// What the resume passes take of a prepared trace kernel
/// ([`super::prepare::Prepared::resume_source`]): its variant, specialization, buffers,
/// image and bounds, and the figures that shape the pool.
#[derive(Clone, Copy)]
pub struct ResumeSource<'a> {
    pub ctx: &'a crate::gpu::Context,
    pub scene: &'a crate::scene::Scene,
    pub image: &'a crate::accel::GpuImage<'a>,
    pub variant: &'a super::kernel::Variant,
    pub spec: &'a [(u32, u32)],
    pub bound: &'a super::upload::Bound,
    pub bounds: super::kernel::LoopBounds,
    /// Traces one sample may run.
    pub traces: u64,
    /// Pixels the pixel buffer holds.
    pub chunk_pixels: u64,
    /// For tests: at most this many resume records a pass.
    pub resume_records: Option<u32>,
}

impl std::fmt::Debug for ResumeSource<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ResumeSource").field("kernel", &self.variant.name).field("traces", &self.traces).finish()
    }
}

/// Runs the resume passes of a render's trace dispatches.
pub struct Resumer<'a> {
    /// The trace kernel: its variant, specialization, buffers, image and bounds.
    prep: ResumeSource<'a>,
    shape: PoolShape,
    /// Trace results a record logs.
    log: u32,
    /// The resume kernel, its pool and the ring its passes go through, once needed.
    kernel: Option<Passes<'a>>,
    pub totals: ResumeTotals,
}

impl std::fmt::Debug for Resumer<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Resumer").field("shape", &self.shape).field("totals", &self.totals).finish_non_exhaustive()
    }
}

impl<'a> Resumer<'a> {
    /// For the trace kernel of `prep`: its traces a sample, steps a trace, and
    /// dispatches of a chunk's pixels at most.
    pub fn new(prep: ResumeSource<'a>) -> Result<Resumer<'a>> {
        let log = u32::try_from(prep.traces).unwrap_or(u32::MAX);
        let image = prep.image;
        let shape = if image.resume_words > 0 {
            PoolShape::new(image, log, prep.chunk_pixels, prep.ctx.max_storage_range(), prep.resume_records)?
        } else {
            PoolShape { record_words: 0, records: 0, jobs: 0 }
        };
        Ok(Resumer { prep, shape, log, kernel: None, totals: ResumeTotals { gpu_ms: Some(0.0), ..Default::default() } })
    }

    fn passes(&mut self) -> Result<&mut Passes<'a>> {
        if self.kernel.is_none() {
            let start = std::time::Instant::now();
            let s = self.shape;
            let (ctx, variant) = (self.prep.ctx, self.prep.variant);
            let pool = ctx.create_buffer("resume pool", s.bytes(), BufferKind::Storage)?;
            let mut spec = self.prep.spec.to_vec();
            spec.extend([
                (SPEC_RESUME_PASS, 1),
                (SPEC_RESUME_LOG, self.log),
                (SPEC_RESUME_RECORDS, s.records),
                (SPEC_RESUME_JOBS, s.jobs),
            ]);
            let name = format!("{}.resume", variant.name);
            let mut kernel = ctx.create_kernel(&name, variant.spirv, &variant.bindings, &spec, 0)?;
            upload::bind_again(
                ctx,
                &mut kernel,
                &variant.bindings,
                self.prep.bound,
                self.prep.image.ray_structure,
                (BINDING_RESUME, &pool),
            )?;
            let ring = ctx.dispatch_ring(1)?;
            self.totals.kernel_ms += start.elapsed().as_secs_f64() * 1e3;
            self.kernel = Some(Passes { kernel, _pool: pool, ring });
        }
        self.kernel.as_mut().ok_or_else(|| Error::Failed("no resume kernel".into()))
    }

    /// One resume dispatch of `header` running `jobs` jobs, its time added to `gpu_ms`;
    /// the header's counter after it (the ring copies it back).
    fn dispatch(&mut self, pixel_buf: &Buffer, h: &GpuDispatch, jobs: u32, gpu_ms: &mut Option<f64>) -> Result<u32> {
        let groups = h.count.div_ceil(WORKGROUP_SIZE);
        let label = match h.chunk.pass {
            PASS_SWEEP => format!("resume: pixels {}+{}", h.first, h.count),
            _ => format!("resume: jobs {}+{}", h.first, h.count),
        };
        let passes = self.passes()?;
        passes.ring.submit(&HeaderDispatch {
            kernel: &passes.kernel,
            groups: [groups, 1, 1],
            buffer: pixel_buf,
            header_at: 0,
            header: bytemuck::bytes_of(h),
            copy_back_at: HEADER_COUNTERS,
            label: &label,
        })?;
        let landed = passes
            .ring
            .land_oldest()?
            .ok_or_else(|| Error::Failed(format!("the resume pass '{label}' did not land")))?;
        *gpu_ms = add_ms(*gpu_ms, landed.gpu_ms);
        self.totals.gpu_ms = add_ms(self.totals.gpu_ms, landed.gpu_ms);
        self.totals.dispatches += 1;
        self.totals.jobs += u64::from(jobs);
        Ok(bytemuck::cast::<[u32; 4], DispatchChunk>(landed.words).counter)
    }

    /// After the trace dispatch of `header` (its GPU time already in `gpu_ms`), which
    /// counted `stopped` samples stopped or behind: runs them to the dispatch's end,
    /// adding the passes' time to `gpu_ms`.
    ///
    /// Each pass after the sweep runs the jobs that hold a record (the first ones of
    /// its list) before the others, in a dispatch of their own: those that stop again
    /// then take the first places of the next list, and so keep a record. So every
    /// pass takes each saved trace at least a step further, and the samples without a
    /// record get the records their owners free.
    pub fn settle(
        &mut self,
        pixel_buf: &Buffer,
        header: GpuDispatch,
        stopped: u32,
        gpu_ms: &mut Option<f64>,
    ) -> Result<()> {
        if self.prep.image.resume_words == 0 || stopped == 0 {
            return Ok(());
        }
        self.totals.samples += u64::from(stopped);
        let mut h = header;
        h.chunk.pass = PASS_SWEEP;
        h.chunk.counter = 0;
        let mut jobs = self.dispatch(pixel_buf, &h, stopped, gpu_ms)?;
        let mut pass = PASS_LIST0;
        let mut passes = 1u32;
        while jobs > 0 {
            if passes == MAX_PASSES {
                return Err(Error::scene(
                    self.prep.scene.name.clone(),
                    format!(
                        "{jobs} pixel samples still had a trace to resume after {passes} resume passes: a trace makes no progress within its budget of {} steps",
                        self.prep.bounds.steps
                    ),
                ));
            }
            let held = jobs.min(self.shape.records);
            h.chunk.pass = pass;
            h.chunk.counter = 0;
            h.first = 0;
            h.count = held;
            let mut next = self.dispatch(pixel_buf, &h, held, gpu_ms)?;
            if jobs > held {
                h.chunk.counter = next;
                h.first = held;
                h.count = jobs - held;
                next = self.dispatch(pixel_buf, &h, jobs - held, gpu_ms)?;
            }
            jobs = next;
            pass = if pass == PASS_LIST0 { PASS_LIST1 } else { PASS_LIST0 };
            passes += 1;
        }
        Ok(())
    }
}
