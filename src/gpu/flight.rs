//! Dispatches kept in flight: a ring of up to `depth` submissions that the host does
//! not wait for one by one. Each submission writes a small header into a buffer
//! (vkCmdUpdateBuffer), dispatches a kernel, and copies 16 bytes of that buffer (the
//! counters the kernel left in the header) into the slot's own part of a host-visible
//! buffer, all between two timestamps of the slot's own queries. The host collects
//! submissions in the order it made them ([`DispatchRing::land_oldest`]): their GPU
//! time and copied words, and their span on the timeline.
//!
//! The header is written in the submission (vkCmdUpdateBuffer), not passed as push
//! constants: lavapipe compiles a shader again, at every dispatch, for the push-constant
//! and uniform values its control flow depends on, and leaves values read from storage
//! alone.
//!
//! Ordering: submissions to one queue start in order, and every submission opens with
//! a global barrier (as [`Context::dispatch`] does), which orders it after everything
//! submitted before it, ring or not. So the header a kernel reads is its own
//! and the pixels it reads are those the dispatches before it left.

use std::collections::VecDeque;
use std::time::Instant;

use ash::vk;

use super::buffer::{record_copy_to_host, Buffer, BufferKind};
use super::context::{Context, Work};
use super::device::vk_err;
use super::kernel::{barrier_all, check_update, record_dispatch, Kernel};
use super::timing::{self, timestamp_ms, Placement};
use crate::error::{Error, Result};

/// Bytes each submission copies back: the trace kernels' `DispatchChunk`
/// (src/accel/gpu_layout.rs asserts the two agree).
pub const COPY_BACK_BYTES: u64 = 16;

/// Most submissions a ring holds.
pub const MAX_DEPTH: u32 = 16;

/// One submission in flight.
struct Slot {
    index: u32,
    cb: vk::CommandBuffer,
    fence: vk::Fence,
    label: String,
    work: Work,
    submitted: Instant,
}

/// What a landed submission reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Landed {
    /// GPU milliseconds between its timestamps; `None` without timestamps.
    pub gpu_ms: Option<f64>,
    /// The 16 bytes copied back, as words.
    pub words: [u32; 4],
    /// When the host submitted it.
    pub submitted: Instant,
}

/// One submission of a ring: `header` written into `buffer` at byte `header_at`,
/// `kernel` over `groups` workgroups, then the [`COPY_BACK_BYTES`] of `buffer` at
/// `copy_back_at` (the counters the kernel left) copied back for [`Landed::words`].
#[derive(Debug, Clone, Copy)]
pub struct HeaderDispatch<'s> {
    /// The kernel dispatched.
    pub kernel: &'s Kernel,
    /// Workgroups in x, y, z.
    pub groups: [u32; 3],
    /// The buffer the header goes into and the counters come back from.
    pub buffer: &'s Buffer,
    /// Byte of `buffer` the header is written at.
    pub header_at: u64,
    /// The header's bytes (at most 65536, a multiple of 4: vkCmdUpdateBuffer's limits).
    pub header: &'s [u8],
    /// Byte of `buffer` whose [`COPY_BACK_BYTES`] come back.
    pub copy_back_at: u64,
    /// The submission's debug name and timeline label.
    pub label: &'s str,
}

/// Up to `depth` dispatches in flight on `ctx`'s queue.
pub struct DispatchRing<'a> {
    ctx: &'a Context,
    depth: u32,
    queries: vk::QueryPool,
    readback: Buffer,
    slots: VecDeque<Slot>,
    free: Vec<u32>,
    /// Where the ring's ticks sit on the CPU clock: with calibrated timestamps, one
    /// anchor for all (read when the first submission landed), so spans keep their
    /// order; aligned at submit, each span starts at its submission or where the one
    /// before it ended, whichever is later.
    placement: Option<Placement>,
    /// The CPU instant the last span ended (aligned at submit).
    last_end: Option<Instant>,
}

impl std::fmt::Debug for DispatchRing<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DispatchRing").field("depth", &self.depth).field("in_flight", &self.slots.len()).finish()
    }
}

impl Context {
    /// A ring of at most `depth` (1..=[`MAX_DEPTH`]) dispatches in flight.
    pub fn dispatch_ring(&self, depth: u32) -> Result<DispatchRing<'_>> {
        if depth == 0 || depth > MAX_DEPTH {
            return Err(Error::Usage(format!("dispatches in flight must be 1..={MAX_DEPTH}, got {depth}")));
        }
        let readback =
            self.create_buffer("dispatch ring readback", COPY_BACK_BYTES * u64::from(depth), BufferKind::Readback)?;
        let dev = &self.shared.device;
        // SAFETY: valid device; the pool is destroyed in Drop after every slot landed.
        let queries = unsafe {
            dev.create_query_pool(
                &vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(2 * depth),
                None,
            )
        }
        .map_err(vk_err("vkCreateQueryPool"))?;
        self.shared.set_name(queries, "dispatch ring timestamps");
        Ok(DispatchRing {
            ctx: self,
            depth,
            queries,
            readback,
            slots: VecDeque::new(),
            free: (0..depth).rev().collect(),
            placement: None,
            last_end: None,
        })
    }
}

impl DispatchRing<'_> {
    /// Most submissions in flight.
    pub fn depth(&self) -> u32 {
        self.depth
    }

    /// Submissions not landed yet.
    pub fn in_flight(&self) -> usize {
        self.slots.len()
    }

    /// Whether another submission fits.
    pub fn has_room(&self) -> bool {
        !self.free.is_empty()
    }

    /// Submits `d`: its header written into its buffer, a barrier, its kernel, a
    /// barrier, then the 16 bytes it names copied back. Fails when the ring is full
    /// (land one first).
    pub fn submit(&mut self, d: &HeaderDispatch<'_>) -> Result<()> {
        let HeaderDispatch {
            kernel,
            groups,
            buffer,
            header_at: offset,
            header: data,
            copy_back_at: copy_offset,
            label,
        } = *d;
        self.ctx.check_dispatch(kernel, &[], groups)?;
        check_update(kernel, buffer, offset, data)?;
        if copy_offset % 4 != 0 || copy_offset.checked_add(COPY_BACK_BYTES).is_none_or(|end| end > buffer.size()) {
            return Err(Error::Vulkan {
                what: format!("copy back after dispatch '{}'", kernel.name()),
                result: format!("byte {copy_offset} of the {}-byte buffer '{}'", buffer.size(), buffer.name()),
            });
        }
        let Some(index) = self.free.pop() else {
            return Err(Error::Failed(format!("{} dispatches already in flight", self.depth)));
        };
        let _span = crate::timeline::span("submit", || label);
        let ctx = self.ctx;
        let dev = &ctx.shared.device;
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(ctx.command_pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool belongs to this device and is used from this thread only.
        let cb = match unsafe { dev.allocate_command_buffers(&alloc) } {
            Ok(v) => v[0],
            Err(e) => {
                self.free.push(index);
                return Err(vk_err("vkAllocateCommandBuffers")(e));
            }
        };
        ctx.shared.set_name(cb, label);
        // SAFETY: valid device.
        let fence = match unsafe { dev.create_fence(&vk::FenceCreateInfo::default(), None) } {
            Ok(f) => f,
            Err(e) => {
                // SAFETY: `cb` was never submitted.
                unsafe { dev.free_command_buffers(ctx.command_pool, &[cb]) };
                self.free.push(index);
                return Err(vk_err("vkCreateFence")(e));
            }
        };
        let q = 2 * index;
        let slot_copy = u64::from(index) * COPY_BACK_BYTES;
        let recorded = (|| -> Result<()> {
            // SAFETY: `cb` is a fresh primary command buffer of this device; every
            // handle recorded is live; the ranges were checked above; the slot's
            // queries and readback bytes belong to no submission in flight (`free`).
            unsafe {
                dev.begin_command_buffer(
                    cb,
                    &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )
                .map_err(vk_err("vkBeginCommandBuffer"))?;
                if ctx.timestamps {
                    dev.cmd_reset_query_pool(cb, self.queries, q, 2);
                }
                barrier_all(dev, cb);
                if ctx.timestamps {
                    // Written once every earlier command has finished (a top-of-pipe
                    // stamp could be taken while the dispatch before this one still
                    // runs): the span is this submission's own time, and the spans of
                    // a ring never overlap.
                    dev.cmd_write_timestamp(cb, vk::PipelineStageFlags::BOTTOM_OF_PIPE, self.queries, q);
                }
                dev.cmd_update_buffer(cb, buffer.raw, offset, data);
                barrier_all(dev, cb);
                record_dispatch(dev, cb, kernel, &[], groups);
                record_copy_to_host(dev, cb, (buffer, copy_offset), (&self.readback, slot_copy), COPY_BACK_BYTES);
                if ctx.timestamps {
                    dev.cmd_write_timestamp(cb, vk::PipelineStageFlags::BOTTOM_OF_PIPE, self.queries, q + 1);
                }
                dev.end_command_buffer(cb).map_err(vk_err("vkEndCommandBuffer"))?;
            }
            Ok(())
        })();
        let submitted = Instant::now();
        let result = recorded.and_then(|()| {
            let cbs = [cb];
            let submit = [vk::SubmitInfo::default().command_buffers(&cbs)];
            // SAFETY: `cb` is recorded; `fence` is unsignalled and unused.
            unsafe { dev.queue_submit(ctx.queue, &submit, fence) }.map_err(vk_err("vkQueueSubmit"))
        });
        if let Err(e) = result {
            // SAFETY: the submission failed, so nothing uses `cb` or `fence`.
            unsafe {
                dev.destroy_fence(fence, None);
                dev.free_command_buffers(ctx.command_pool, &[cb]);
            }
            self.free.push(index);
            return Err(e);
        }
        let work = Work::new("dispatch").arg("kernel", kernel.name()).arg("groups", groups[0]);
        self.slots.push_back(Slot { index, cb, fence, label: label.to_string(), work, submitted });
        Ok(())
    }

    /// Waits for the oldest submission and reports it; `None` when none is in flight.
    pub fn land_oldest(&mut self) -> Result<Option<Landed>> {
        let Some(slot) = self.slots.pop_front() else { return Ok(None) };
        let dev = &self.ctx.shared.device;
        // SAFETY: the fence belongs to this device and guards a submitted batch.
        let waited = unsafe { dev.wait_for_fences(&[slot.fence], true, u64::MAX) }.map_err(vk_err("vkWaitForFences"));
        let landed = waited.and_then(|()| self.read(&slot));
        // SAFETY: the fence was waited on (or waiting failed, and the device is then
        // lost); nothing uses the command buffer or the fence any more.
        unsafe {
            if landed.is_err() {
                let _ = dev.queue_wait_idle(self.ctx.queue);
            }
            dev.destroy_fence(slot.fence, None);
            dev.free_command_buffers(self.ctx.command_pool, &[slot.cb]);
        }
        self.free.push(slot.index);
        self.ctx.check_validation()?;
        landed.map(Some)
    }

    /// The timestamps and copied words of a completed slot; its timeline span.
    fn read(&mut self, slot: &Slot) -> Result<Landed> {
        let at = (u64::from(slot.index) * COPY_BACK_BYTES) as usize;
        let bytes = self.readback.mapped().ok_or_else(|| Error::Vulkan {
            what: "dispatch ring readback".into(),
            result: "not host visible".into(),
        })?;
        let mut words = [0u32; 4];
        for (k, w) in words.iter_mut().enumerate() {
            let b = &bytes[at + 4 * k..at + 4 * k + 4];
            *w = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
        if !self.ctx.timestamps {
            return Ok(Landed { gpu_ms: None, words, submitted: slot.submitted });
        }
        let mut ts = [0u64; 2];
        // SAFETY: both queries were written by the completed submission.
        unsafe {
            self.ctx.shared.device.get_query_pool_results(
                self.queries,
                2 * slot.index,
                &mut ts,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .map_err(vk_err("vkGetQueryPoolResults"))?;
        let gpu_ms = timestamp_ms(ts[0], ts[1], self.ctx.info().timestamp_period_ns)?;
        if !self.placement.is_some_and(|p| p.calibrated()) {
            let from = self.last_end.map_or(slot.submitted, |t| t.max(slot.submitted));
            self.placement = self.ctx.placement(ts[0], from);
        }
        if let Some(place) = &self.placement {
            let args = slot.work.args.clone();
            timing::record(place, (&slot.label, slot.work.cat, args), ts[0], ts[1]);
            self.last_end = Some(place.at(ts[1]));
        }
        Ok(Landed { gpu_ms: Some(gpu_ms), words, submitted: slot.submitted })
    }
}

impl Drop for DispatchRing<'_> {
    fn drop(&mut self) {
        let dev = &self.ctx.shared.device;
        // SAFETY: every slot's fence guards a submitted batch; after the waits nothing
        // in flight uses the command buffers, fences, queries or readback buffer.
        unsafe {
            for slot in self.slots.drain(..) {
                let _ = dev.wait_for_fences(&[slot.fence], true, u64::MAX);
                dev.destroy_fence(slot.fence, None);
                dev.free_command_buffers(self.ctx.command_pool, &[slot.cb]);
            }
            dev.destroy_query_pool(self.queries, None);
        }
    }
}
