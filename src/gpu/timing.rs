//! GPU spans for the timeline ([`crate::timeline`]): each submission's timestamps
//! placed on the CPU clock.
//!
//! With `VK_EXT_calibrated_timestamps` (enabled wherever the device offers its
//! `DEVICE` time domain), after a submission completes the device clock is read once
//! ([`vkGetCalibratedTimestampsEXT`]) between two reads of the CPU clock; the device
//! tick `d` is taken to have happened at the midpoint `h` of those reads, and a
//! timestamp `t` at `h - (d - t) * timestampPeriod`. The error of one placement is at
//! most half the CPU time between the reads plus the deviation the driver reports.
//! Without the extension, a span starts at the CPU instant of its `vkQueueSubmit`
//! (and the trace says so). Durations never depend on the placement: they are the
//! timestamps' difference times the period, as in [`timestamp_ms`].
//!
//! [`vkGetCalibratedTimestampsEXT`]: https://registry.khronos.org/vulkan/specs/1.3-extensions/man/html/vkGetCalibratedTimestampsEXT.html

use std::time::{Duration, Instant};

use ash::vk;
use serde_json::{Map, Value};

use crate::error::{Error, Result};
use crate::timeline::{self, GpuClock};

/// Milliseconds between two timestamp query values, scaled by the device's
/// `timestampPeriod` (nanoseconds per tick); an error if they are out of order.
pub fn timestamp_ms(begin: u64, end: u64, period_ns: f32) -> Result<f64> {
    if end < begin {
        return Err(Error::Failed(format!("GPU timestamps out of order: {begin} then {end}")));
    }
    Ok((end - begin) as f64 * f64::from(period_ns) * 1e-6)
}

/// Whether `pd` can read its device clock together with the host's
/// (`VK_EXT_calibrated_timestamps` with the `DEVICE` time domain).
pub(crate) fn calibration_supported(entry: &ash::Entry, instance: &ash::Instance, pd: vk::PhysicalDevice) -> bool {
    // SAFETY: `pd` comes from `instance`; enumeration has no other requirement.
    let exts = unsafe { instance.enumerate_device_extension_properties(pd) }.unwrap_or_default();
    let name = ash::ext::calibrated_timestamps::NAME;
    if !exts.iter().any(|e| e.extension_name_as_c_str() == Ok(name)) {
        return false;
    }
    let ext = ash::ext::calibrated_timestamps::Instance::new(entry, instance);
    // SAFETY: the device offers the extension, so its physical-device query exists.
    let domains = unsafe { ext.get_physical_device_calibrateable_time_domains(pd) }.unwrap_or_default();
    domains.contains(&vk::TimeDomainKHR::DEVICE)
}

/// Where a submission's ticks sit on the CPU clock: tick `anchor_ticks` at `anchor`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Placement {
    anchor_ticks: u64,
    anchor: Instant,
    period_ns: f64,
    clock: GpuClock,
    error_ns: u64,
}

impl Placement {
    /// Whether the device clock was read with the host's (else: aligned at submit).
    pub(crate) fn calibrated(&self) -> bool {
        self.clock == GpuClock::Calibrated
    }

    /// The CPU instant of device tick `ticks`.
    pub(crate) fn at(&self, ticks: u64) -> Instant {
        let off = |d: u64| Duration::from_nanos((d as f64 * self.period_ns).round() as u64);
        if ticks >= self.anchor_ticks {
            self.anchor + off(ticks - self.anchor_ticks)
        } else {
            self.anchor.checked_sub(off(self.anchor_ticks - ticks)).unwrap_or(self.anchor)
        }
    }

    /// Nanoseconds between two ticks (the duration a span shows).
    fn span_ns(&self, begin: u64, end: u64) -> u64 {
        (end.saturating_sub(begin) as f64 * self.period_ns).round() as u64
    }
}

/// How to place a submission whose first timestamp is `begin_ticks` and which the CPU
/// submitted at `submitted`, on a device whose ticks last `period_ns` and which reads
/// its clock with `calibration` where it can; `None` when this thread is not recording
/// a timeline.
pub(crate) fn placement(
    calibration: Option<&ash::ext::calibrated_timestamps::Device>,
    period_ns: f32,
    begin_ticks: u64,
    submitted: Instant,
) -> Option<Placement> {
    if !timeline::recording() {
        return None;
    }
    let period_ns = f64::from(period_ns);
    let submit =
        Placement { anchor_ticks: begin_ticks, anchor: submitted, period_ns, clock: GpuClock::Submit, error_ns: 0 };
    let Some(ext) = calibration.filter(|_| !timeline::align_at_submit()) else {
        return Some(submit);
    };
    let info = [vk::CalibratedTimestampInfoKHR::default().time_domain(vk::TimeDomainKHR::DEVICE)];
    let before = Instant::now();
    // SAFETY: the extension is enabled on this device and DEVICE is one of its domains.
    let read = unsafe { ext.get_calibrated_timestamps(&info) };
    let after = Instant::now();
    match read {
        Ok((ticks, deviation)) if !ticks.is_empty() => {
            let half = after.duration_since(before) / 2;
            Some(Placement {
                anchor_ticks: ticks[0],
                anchor: before + half,
                period_ns,
                clock: GpuClock::Calibrated,
                error_ns: half.as_nanos() as u64 + deviation,
            })
        }
        _ => Some(submit),
    }
}

/// Records the GPU span of one submission, `label` from tick `begin` to `end`.
pub(crate) fn record(
    place: &Placement,
    (label, cat, args): (&str, &'static str, Map<String, Value>),
    begin: u64,
    end: u64,
) {
    timeline::gpu((label, cat, args), place.at(begin), place.span_ns(begin, end), (place.clock, place.error_ns));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_placed_around_the_anchor_and_spans_scale_by_the_period() {
        let anchor = Instant::now() + Duration::from_secs(1);
        let p = Placement { anchor_ticks: 1_000, anchor, period_ns: 2.5, clock: GpuClock::Calibrated, error_ns: 0 };
        assert_eq!(p.at(1_400), anchor + Duration::from_nanos(1_000));
        assert_eq!(p.at(600), anchor - Duration::from_nanos(1_000));
        assert_eq!(p.span_ns(600, 1_400), 2_000);
        assert_eq!(p.span_ns(1_400, 600), 0);
    }

    #[test]
    fn timestamps_are_scaled_by_the_period_and_ordered() {
        let ms = |a, b, p| super::timestamp_ms(a, b, p).expect("ordered");
        assert!((ms(1_000, 3_000, 1.0) - 0.002).abs() < 1e-12);
        assert!((ms(1_000, 3_000, 40.0) - 0.08).abs() < 1e-12);
        assert_eq!(ms(7, 7, 1.0), 0.0);
        assert!(super::timestamp_ms(3_000, 1_000, 1.0).is_err());
    }
}
