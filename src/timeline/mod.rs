//! A timeline of one run: CPU spans (scene loading, each build phase, uploads, the
//! trace loop, readback, output encoding) and GPU spans (every submission, placed on
//! the CPU clock from its timestamp queries), written as Chrome trace-event JSON
//! ([`Trace::to_chrome_json`]), which Perfetto (ui.perfetto.dev) and chrome://tracing
//! open. docs/profiling.md shows one.
//!
//! Recording is per thread and opt-in: [`start`] installs a recorder on the calling
//! thread, and [`span`], [`phase`] and the GPU context's submissions add to it while
//! it lives. Without a recorder every call here is one thread-local read. Work that
//! rayon spreads over other threads is seen as the span of the thread that waited
//! for it; those threads record nothing.
//!
//! The invariants a reader can rely on, and the tests check:
//! - CPU spans nest: a span closes before the span it opened in (guards are scoped,
//!   and [`phase`] spans end when they are recorded, inside the open span).
//! - GPU spans do not overlap: each submission is waited on before the next, and the
//!   timed steps of one submission ([`crate::gpu::Context::run_steps`]) lie inside it.
//! - A GPU span's duration is its timestamps' difference times `timestampPeriod`,
//!   the same figure the render's `trace_ms` sums; only its placement on the CPU
//!   clock is calibrated ([`GpuClock`]).

#![forbid(unsafe_code)]

pub mod chrome;

use std::cell::RefCell;
use std::time::Instant;

use serde_json::{Map, Value};

use crate::error::{Error, Result};

/// Which track of the timeline an event is on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Track {
    /// The recording thread.
    Cpu,
    /// The device's queue.
    Gpu,
}

/// Every category arbor writes ([`Event::cat`]).
pub const CATEGORIES: [&str; 14] = [
    "run", "load", "device", "build", "kernel", "upload", "trace", "readback", "output", "validate", "submit",
    "dispatch", "transfer", "other",
];

/// One span of the timeline.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Event {
    /// The track it is on.
    pub track: Track,
    /// What it was: a phase, a file, a kernel's pixel range and samples.
    pub name: String,
    /// What kind of work, one of [`CATEGORIES`]: `run` (a part of a command, e.g. one
    /// bench round of one structure), `load`, `device` (opening it),
    /// `build`, `kernel` (creating a pipeline: on lavapipe, compiling it), `upload`,
    /// `trace` (the dispatch loop), `readback`, `output` (encoding and writing files),
    /// `validate`, `submit` (the CPU side of a submission) on the CPU track;
    /// `dispatch` (trace and resume kernels), `build` (GPU builders, BLAS/TLAS) and
    /// `transfer` on the GPU track.
    pub cat: &'static str,
    /// Start, nanoseconds after the recording started.
    pub start_ns: u64,
    /// Duration, nanoseconds.
    pub dur_ns: u64,
    /// Extra fields shown with the span (kernel name, pixel range, bytes, ...).
    pub args: Map<String, Value>,
}

impl Event {
    /// End, nanoseconds after the recording started.
    pub fn end_ns(&self) -> u64 {
        self.start_ns + self.dur_ns
    }
}

/// How GPU spans were placed on the CPU clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum GpuClock {
    /// With `VK_EXT_calibrated_timestamps`: the device clock is read together with the
    /// CPU clock after each submission, so a span sits where the device ran it (to
    /// within the calibration's error, recorded as `calibration_error_ns`).
    Calibrated,
    /// Without it: each span starts when the CPU submitted it. Its duration is exact;
    /// its start is an upper bound on the queue's latency earlier than the truth.
    Submit,
}

/// What a recording is asked to do.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// Place GPU spans at their submission even where calibrated timestamps exist
    /// (to compare the two, and to test the fallback).
    pub align_at_submit: bool,
    /// The process name shown on the timeline (e.g. `arbor render`).
    pub process: String,
}

/// A finished recording.
#[derive(Debug, Clone, Default)]
pub struct Trace {
    /// The process name shown on the timeline.
    pub process: String,
    /// Every span, CPU and GPU, in the order they were recorded.
    pub events: Vec<Event>,
    /// How the GPU spans were placed; `None` if there were none.
    pub gpu_clock: Option<GpuClock>,
    /// Largest error of one calibration (the CPU time the device clock read took,
    /// plus the driver's reported deviation), nanoseconds; 0 unless calibrated.
    pub calibration_error_ns: u64,
    /// Facts about the run shown with the trace (device, timestamp period, command).
    pub meta: Map<String, Value>,
}

impl Trace {
    /// The spans of `track`.
    pub fn on(&self, track: Track) -> impl Iterator<Item = &Event> {
        self.events.iter().filter(move |e| e.track == track)
    }

    /// Milliseconds summed over the GPU spans of category `cat`.
    pub fn gpu_ms(&self, cat: &str) -> f64 {
        self.on(Track::Gpu).filter(|e| e.cat == cat).map(|e| e.dur_ns as f64 * 1e-6).sum()
    }
}

struct Recorder {
    epoch: Instant,
    opts: Options,
    events: Vec<Event>,
    /// Indices into `events` of the CPU spans still open, innermost last.
    open: Vec<usize>,
    gpu_clock: Option<GpuClock>,
    calibration_error_ns: u64,
    meta: Map<String, Value>,
}

impl Recorder {
    fn ns_since_epoch(&self, t: Instant) -> u64 {
        t.saturating_duration_since(self.epoch).as_nanos() as u64
    }
}

thread_local! {
    static CURRENT: RefCell<Option<Recorder>> = const { RefCell::new(None) };
}

fn with<R>(f: impl FnOnce(&mut Recorder) -> R) -> Option<R> {
    CURRENT.with(|c| c.borrow_mut().as_mut().map(f))
}

/// Whether this thread is recording.
pub fn recording() -> bool {
    CURRENT.with(|c| c.borrow().is_some())
}

/// Starts recording on this thread; the recording ends with [`Recording::finish`] (or
/// when the handle is dropped, keeping nothing). Fails if this thread is recording.
pub fn start(opts: Options) -> Result<Recording> {
    CURRENT.with(|c| {
        let mut c = c.borrow_mut();
        if c.is_some() {
            return Err(Error::Failed("a timeline is already being recorded on this thread".into()));
        }
        *c = Some(Recorder {
            epoch: Instant::now(),
            opts,
            events: Vec::new(),
            open: Vec::new(),
            gpu_clock: None,
            calibration_error_ns: 0,
            meta: Map::new(),
        });
        Ok(Recording { _not_send: std::marker::PhantomData })
    })
}

/// The recording on this thread, from [`start`]. Not `Send`: it ends on the thread
/// that started it.
#[derive(Debug)]
pub struct Recording {
    _not_send: std::marker::PhantomData<*const ()>,
}

impl Recording {
    /// Ends the recording and returns its spans ([`take`]); empty if [`take`] already
    /// ended it.
    pub fn finish(self) -> Trace {
        take().unwrap_or_default()
    }
}

/// Ends this thread's recording, wherever it was started, and returns its spans
/// (`None` if it is not recording). Spans still open are closed now. For code that
/// writes the trace with its other outputs without holding the [`Recording`].
pub fn take() -> Option<Trace> {
    let rec = CURRENT.with(|c| c.borrow_mut().take());
    rec.map(|mut rec| {
        let now = rec.ns_since_epoch(Instant::now());
        for i in std::mem::take(&mut rec.open) {
            let e = &mut rec.events[i];
            e.dur_ns = now.saturating_sub(e.start_ns);
        }
        Trace {
            process: rec.opts.process,
            events: rec.events,
            gpu_clock: rec.gpu_clock,
            calibration_error_ns: rec.calibration_error_ns,
            meta: rec.meta,
        }
    })
}

impl Drop for Recording {
    fn drop(&mut self) {
        CURRENT.with(|c| c.borrow_mut().take());
    }
}

/// Adds a fact about the run to the trace's metadata (no-op without a recording).
pub fn meta(key: &str, value: impl Into<Value>) {
    let value = value.into();
    with(|r| r.meta.insert(key.to_string(), value));
}

/// Opens a CPU span named `name` of category `cat`; it closes when the guard drops.
/// Without a recording, `name` is not called.
pub fn span<S: Into<String>>(cat: &'static str, name: impl FnOnce() -> S) -> Span {
    let index = with(|r| {
        let start_ns = r.ns_since_epoch(Instant::now());
        r.events.push(Event { track: Track::Cpu, name: name().into(), cat, start_ns, dur_ns: 0, args: Map::new() });
        r.open.push(r.events.len() - 1);
        r.events.len() - 1
    });
    Span { index }
}

/// An open CPU span; see [`span`].
#[derive(Debug)]
#[must_use = "a span closes when it is dropped"]
pub struct Span {
    index: Option<usize>,
}

impl Span {
    /// Adds `key: value` to the span's arguments.
    pub fn arg(&self, key: &str, value: impl Into<Value>) {
        if let Some(i) = self.index {
            let value = value.into();
            with(|r| {
                if let Some(e) = r.events.get_mut(i) {
                    e.args.insert(key.to_string(), value);
                }
            });
        }
    }
}

impl Drop for Span {
    fn drop(&mut self) {
        let Some(i) = self.index else { return };
        with(|r| {
            let now = r.ns_since_epoch(Instant::now());
            // Close every span opened after this one too (a guard kept past its parent).
            while let Some(j) = r.open.pop() {
                let e = &mut r.events[j];
                e.dur_ns = now.saturating_sub(e.start_ns);
                if j == i {
                    break;
                }
            }
        });
    }
}

/// Records a finished CPU span from `since` until now (a build phase timed the way
/// [`crate::accel::Phase`] is). It must lie inside the innermost open span, which it
/// does when that span was open at `since`.
pub fn phase(cat: &'static str, name: &str, since: Instant, args: Map<String, Value>) {
    with(|r| {
        let start_ns = r.ns_since_epoch(since);
        let dur_ns = r.ns_since_epoch(Instant::now()).saturating_sub(start_ns);
        r.events.push(Event { track: Track::Cpu, name: name.to_string(), cat, start_ns, dur_ns, args });
    });
}

/// Whether the recording wants GPU spans placed at their submission
/// ([`Options::align_at_submit`]); false without a recording.
pub fn align_at_submit() -> bool {
    with(|r| r.opts.align_at_submit).unwrap_or(false)
}

/// Records a GPU span that began at `start` on the CPU clock and lasted `dur_ns`,
/// placed as `clock` says (with a calibration error of `error_ns`).
pub fn gpu(
    (name, cat, args): (&str, &'static str, Map<String, Value>),
    start: Instant,
    dur_ns: u64,
    (clock, error_ns): (GpuClock, u64),
) {
    with(|r| {
        let start_ns = r.ns_since_epoch(start);
        r.events.push(Event { track: Track::Gpu, name: name.to_string(), cat, start_ns, dur_ns, args });
        // The weaker placement wins: one span aligned at submit makes the file say so.
        r.gpu_clock = match (r.gpu_clock, clock) {
            (Some(GpuClock::Submit), _) | (_, GpuClock::Submit) => Some(GpuClock::Submit),
            _ => Some(GpuClock::Calibrated),
        };
        r.calibration_error_ns = r.calibration_error_ns.max(error_ns);
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spans_nest_and_phases_land_inside_their_parent() {
        let rec = start(Options::default()).expect("start");
        assert!(start(Options::default()).is_err(), "a second recording on one thread is refused");
        {
            let outer = span("build", || "build kdtree");
            outer.arg("triangles", 12);
            let t = Instant::now();
            std::thread::sleep(std::time::Duration::from_millis(2));
            phase("build", "events", t, Map::new());
            let _inner = span("build", || "split");
        }
        let trace = rec.finish();
        assert!(!recording());
        let names: Vec<&str> = trace.events.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["build kdtree", "events", "split"]);
        let (outer, events, inner) = (&trace.events[0], &trace.events[1], &trace.events[2]);
        assert!(events.dur_ns >= 2_000_000);
        for child in [events, inner] {
            assert!(child.start_ns >= outer.start_ns && child.end_ns() <= outer.end_ns(), "{child:?} in {outer:?}");
        }
        assert!(inner.start_ns >= events.end_ns());
        assert_eq!(outer.args["triangles"], 12);
    }

    #[test]
    fn without_a_recording_nothing_is_kept_and_names_are_not_built() {
        let s = span("load", || -> String { panic!("the name must not be built") });
        s.arg("k", 1);
        drop(s);
        phase("build", "x", Instant::now(), Map::new());
        assert!(!recording());
    }

    #[test]
    fn one_span_aligned_at_submit_marks_the_whole_trace() {
        let rec = start(Options::default()).expect("start");
        let now = Instant::now();
        gpu(("a", "dispatch", Map::new()), now, 1_000, (GpuClock::Calibrated, 300));
        gpu(("b", "dispatch", Map::new()), now, 2_500, (GpuClock::Submit, 0));
        let trace = rec.finish();
        assert_eq!(trace.gpu_clock, Some(GpuClock::Submit));
        assert_eq!(trace.calibration_error_ns, 300);
        assert!((trace.gpu_ms("dispatch") - 0.0035).abs() < 1e-12);
    }
}
