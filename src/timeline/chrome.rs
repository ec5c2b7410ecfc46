//! Chrome trace-event JSON (the "JSON Object Format" that Perfetto and
//! chrome://tracing open): one process, two threads (`CPU`, tid 1; `GPU queue`,
//! tid 2), every span a complete event (`"ph": "X"`, `ts` and `dur` in microseconds
//! with nanosecond decimals), and the run's facts under `otherData`.
//!
//! ```text
//! {"traceEvents": [
//!    {"ph": "M", "name": "process_name", "pid": 1, "args": {"name": "arbor render"}},
//!    {"ph": "M", "name": "thread_name", "pid": 1, "tid": 2, "args": {"name": "GPU queue"}},
//!    {"ph": "X", "name": "trace pixels 0+76800 samples 0..1", "cat": "dispatch",
//!     "ts": 412.306, "dur": 1843.118, "pid": 1, "tid": 2, "args": {"kernel": "trace_bvh"}}, ...],
//!  "displayTimeUnit": "ms",
//!  "otherData": {"gpu_clock": "calibrated", "calibration_error_ns": 2210, ...}}
//! ```

use serde_json::{json, Map, Value};

use super::{Event, GpuClock, Trace, Track};
use crate::error::{Error, Result};

/// Thread id of each track.
pub fn tid(track: Track) -> u64 {
    match track {
        Track::Cpu => 1,
        Track::Gpu => 2,
    }
}

/// Nanoseconds as microseconds with three decimals (exact: no float rounding).
fn micros(ns: u64) -> Value {
    let text = format!("{}.{:03}", ns / 1000, ns % 1000);
    // A decimal of this form always parses as a JSON number.
    serde_json::from_str(&text).unwrap_or(Value::Null)
}

impl Trace {
    /// The trace as Chrome trace-event JSON bytes; spans sorted by track, start, and
    /// longest first (so parents precede their children).
    pub fn to_chrome_json(&self) -> Vec<u8> {
        let mut events: Vec<&Event> = self.events.iter().collect();
        events.sort_by_key(|e| (tid(e.track), e.start_ns, std::cmp::Reverse(e.dur_ns)));
        let process = if self.process.is_empty() { "arbor" } else { self.process.as_str() };
        let mut out = vec![
            json!({"ph": "M", "name": "process_name", "pid": 1, "tid": 0, "args": {"name": process}}),
            json!({"ph": "M", "name": "thread_name", "pid": 1, "tid": 1, "args": {"name": "CPU"}}),
            json!({"ph": "M", "name": "thread_sort_index", "pid": 1, "tid": 1, "args": {"sort_index": 1}}),
            json!({"ph": "M", "name": "thread_name", "pid": 1, "tid": 2, "args": {"name": "GPU queue"}}),
            json!({"ph": "M", "name": "thread_sort_index", "pid": 1, "tid": 2, "args": {"sort_index": 2}}),
        ];
        out.extend(events.into_iter().map(|e| {
            json!({
                "ph": "X",
                "name": e.name,
                "cat": e.cat,
                "ts": micros(e.start_ns),
                "dur": micros(e.dur_ns),
                "pid": 1,
                "tid": tid(e.track),
                "args": e.args,
            })
        }));
        let mut other = self.meta.clone();
        let clock = match self.gpu_clock {
            Some(GpuClock::Calibrated) => "calibrated",
            Some(GpuClock::Submit) => "submit",
            None => "none",
        };
        other.insert("gpu_clock".into(), clock.into());
        other.insert(
            "gpu_clock_note".into(),
            match self.gpu_clock {
                Some(GpuClock::Calibrated) => "GPU spans placed on the CPU clock with VK_EXT_calibrated_timestamps, read after each submission; calibration_error_ns bounds the placement error",
                Some(GpuClock::Submit) => "GPU spans aligned at submit: each starts when the CPU submitted it (no calibrated timestamps); durations are exact, starts are early by the queue's latency",
                None => "no GPU spans",
            }
            .into(),
        );
        other.insert("calibration_error_ns".into(), self.calibration_error_ns.into());
        other.insert("time_unit".into(), "ts and dur in microseconds, with nanosecond decimals".into());
        let doc = json!({"traceEvents": out, "displayTimeUnit": "ms", "otherData": other});
        let mut bytes = serde_json::to_vec_pretty(&doc).unwrap_or_default();
        bytes.push(b'\n');
        bytes
    }
}

/// Reads a trace written by [`Trace::to_chrome_json`] back (its complete events on
/// tids 1 and 2); `what` names the source in errors.
pub fn read(bytes: &[u8], what: &std::path::Path) -> Result<Trace> {
    let bad = |msg: String| Error::invalid(what, msg);
    let doc: Value = serde_json::from_slice(bytes).map_err(|e| bad(format!("not JSON: {e}")))?;
    let list = doc
        .get("traceEvents")
        .and_then(Value::as_array)
        .ok_or_else(|| bad("no traceEvents array (not a Chrome trace-event file)".into()))?;
    let mut trace = Trace::default();
    let ns = |v: Option<&Value>, field: &str, i: usize| -> Result<u64> {
        let us = v.and_then(Value::as_f64).filter(|x| x.is_finite() && *x >= 0.0);
        us.map(|us| (us * 1000.0).round() as u64)
            .ok_or_else(|| bad(format!("traceEvents[{i}]: '{field}' is not a non-negative number")))
    };
    for (i, e) in list.iter().enumerate() {
        match e.get("ph").and_then(Value::as_str) {
            Some("X") => {}
            Some("M") => {
                if e.get("name").and_then(Value::as_str) == Some("process_name") {
                    let name = e.pointer("/args/name").and_then(Value::as_str).unwrap_or_default();
                    trace.process = name.to_string();
                }
                continue;
            }
            _ => continue,
        }
        let track = match e.get("tid").and_then(Value::as_u64) {
            Some(1) => Track::Cpu,
            Some(2) => Track::Gpu,
            _ => continue,
        };
        let name = e.get("name").and_then(Value::as_str).unwrap_or_default().to_string();
        let cat = intern(e.get("cat").and_then(Value::as_str).unwrap_or_default());
        let args = e.get("args").and_then(Value::as_object).cloned().unwrap_or_default();
        let start_ns = ns(e.get("ts"), "ts", i)?;
        let dur_ns = ns(e.get("dur"), "dur", i)?;
        trace.events.push(Event { track, name, cat, start_ns, dur_ns, args });
    }
    if let Some(other) = doc.get("otherData").and_then(Value::as_object) {
        trace.gpu_clock = match other.get("gpu_clock").and_then(Value::as_str) {
            Some("calibrated") => Some(GpuClock::Calibrated),
            Some("submit") => Some(GpuClock::Submit),
            _ => None,
        };
        trace.calibration_error_ns = other.get("calibration_error_ns").and_then(Value::as_u64).unwrap_or(0);
        trace.meta = other.clone();
    }
    Ok(trace)
}

/// The category `cat` as one of [`super::CATEGORIES`]; any other becomes `other`.
fn intern(cat: &str) -> &'static str {
    super::CATEGORIES.iter().find(|k| **k == cat).copied().unwrap_or("other")
}

/// Checks the nesting rules of [`super`] on `trace`: on each track, two spans either
/// nest or do not overlap (to within `slack_ns`). Returns the first offending pair.
pub fn check_nesting(trace: &Trace, slack_ns: u64) -> std::result::Result<(), String> {
    for track in [Track::Cpu, Track::Gpu] {
        let mut spans: Vec<&Event> = trace.on(track).collect();
        spans.sort_by_key(|e| (e.start_ns, std::cmp::Reverse(e.dur_ns)));
        let mut open: Vec<&Event> = Vec::new();
        for e in spans {
            while open.last().is_some_and(|p| p.end_ns() <= e.start_ns + slack_ns) {
                open.pop();
            }
            if let Some(p) = open.last() {
                if e.end_ns() > p.end_ns() + slack_ns {
                    return Err(format!(
                        "{track:?} spans overlap without nesting: '{}' [{}, {}] and '{}' [{}, {}] (ns)",
                        p.name,
                        p.start_ns,
                        p.end_ns(),
                        e.name,
                        e.start_ns,
                        e.end_ns()
                    ));
                }
            }
            open.push(e);
        }
    }
    Ok(())
}

/// A `Map` from `(key, value)` pairs, for span arguments.
pub fn args<const N: usize>(pairs: [(&str, Value); N]) -> Map<String, Value> {
    pairs.into_iter().map(|(k, v)| (k.to_string(), v)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn ev(track: Track, name: &str, start_ns: u64, dur_ns: u64) -> Event {
        Event { track, name: name.into(), cat: "build", start_ns, dur_ns, args: Map::new() }
    }

    #[test]
    fn written_and_read_back_unchanged_with_nanosecond_times() {
        let mut t = Trace { process: "arbor test".into(), ..Default::default() };
        t.events.push(ev(Track::Cpu, "outer", 1_234_567, 9_000_001));
        t.events.push(ev(Track::Gpu, "kernel", 2_000_000, 1_999));
        t.gpu_clock = Some(GpuClock::Calibrated);
        t.calibration_error_ns = 1500;
        let bytes = t.to_chrome_json();
        let back = read(&bytes, Path::new("t.json")).expect("read");
        assert_eq!(back.events, t.events);
        assert_eq!(back.process, "arbor test");
        assert_eq!(back.gpu_clock, Some(GpuClock::Calibrated));
        assert_eq!(back.calibration_error_ns, 1500);
        let doc: Value = serde_json::from_slice(&bytes).expect("json");
        assert_eq!(doc["traceEvents"][5]["ts"].to_string(), "1234.567");
    }

    #[test]
    fn nesting_is_checked_per_track() {
        let mut t = Trace::default();
        t.events.push(ev(Track::Cpu, "a", 0, 100));
        t.events.push(ev(Track::Cpu, "b", 10, 20));
        t.events.push(ev(Track::Cpu, "c", 40, 60));
        t.events.push(ev(Track::Gpu, "g", 50, 100));
        assert!(check_nesting(&t, 0).is_ok());
        t.events.push(ev(Track::Cpu, "d", 90, 20));
        let err = check_nesting(&t, 0).expect_err("d crosses the end of c (and a)");
        assert!(err.contains("'c'") && err.contains("'d'"), "{err}");
        assert!(check_nesting(&t, 10).is_ok());
    }

    #[test]
    fn bad_files_are_errors_naming_the_file() {
        let e = read(b"{}", Path::new("x.json")).expect_err("no events").to_string();
        assert!(e.starts_with("x.json: no traceEvents"), "{e}");
        let e = read(br#"{"traceEvents":[{"ph":"X","tid":1,"ts":-1,"dur":2}]}"#, Path::new("y.json"))
            .expect_err("negative ts")
            .to_string();
        assert!(e.contains("traceEvents[0]: 'ts'"), "{e}");
        assert!(read(b"not json", Path::new("z.json")).is_err());
    }
}
