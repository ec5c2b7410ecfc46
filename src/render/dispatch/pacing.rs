//! How long dispatches are and how many run ahead (docs/kernels.md, "Dispatches sized
//! by the device"). Each dispatch is sized in pixel-samples toward a target GPU length,
//! from the time the dispatches before it took (their timestamps); the structure's
//! cost estimate (`--dispatch-budget`), the driver's loop limit and the responsiveness
//! of `--time` and `--checkpoint` are bounds on top. The split never changes the image:
//! each pixel sums its samples in index order.

use crate::gpu::bindings::WORKGROUP_SIZE;
use crate::gpu::Context;

/// Target GPU length of a dispatch on a GPU: long enough that launching it costs
/// nothing, short enough that progress, Ctrl-C and `--time` answer within a fraction
/// of a second.
pub const GPU_TARGET_MS: f64 = 60.0;

/// Target on llvmpipe, where the work budget ([`crate::render::DEFAULT_DISPATCH_BUDGET`])
/// already keeps dispatches short (a median of 43 ms in the default render on 2 cores,
/// kd-tree): the target only
/// shortens dispatches that run much longer than that (a loaded machine, a
/// structure the cost estimate misjudges).
pub const LLVMPIPE_TARGET_MS: f64 = 1000.0;

/// Dispatches in flight by default on a GPU: enough that the device never waits for
/// the host between two of them.
pub const GPU_IN_FLIGHT: u32 = 3;

/// On llvmpipe: one recorded while the other runs.
pub const LLVMPIPE_IN_FLIGHT: u32 = 2;

/// How much larger than the largest dispatch measured so far the next may be: the
/// first dispatches are small probes, and a measurement is trusted only so far.
const GROWTH: u64 = 4;

/// What a user chose of the pacing (`--dispatch-ms`, `--in-flight`,
/// `--dispatch-budget`); `None` takes the device's default ([`Pacing::for_device`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PacingChoice {
    /// Target GPU milliseconds of one dispatch.
    pub target_ms: Option<f64>,
    /// Dispatches in flight at most (1 waits for each).
    pub in_flight: Option<u32>,
    /// Most primitive tests (estimated) one dispatch may run.
    pub budget: Option<u64>,
}

/// How dispatches are sized and how many run ahead.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pacing {
    /// Target GPU milliseconds of one dispatch.
    pub target_ms: f64,
    /// Dispatches in flight at most; 1 waits for each before the next.
    pub in_flight: u32,
    /// Most primitive tests one dispatch may run (estimated from the structure's cost
    /// per ray): a bound for devices with a watchdog; `None`: no bound.
    pub budget: Option<u64>,
}

impl Pacing {
    /// The device's defaults where a value is not given: on llvmpipe the work budget
    /// of [`crate::render::DEFAULT_DISPATCH_BUDGET`], a long target and 2 in flight; on
    /// other devices no budget, [`GPU_TARGET_MS`] and [`GPU_IN_FLIGHT`].
    pub fn for_device(ctx: &Context, choice: &PacingChoice) -> Pacing {
        let cpu = ctx.info().is_llvmpipe;
        Pacing {
            target_ms: choice.target_ms.unwrap_or(if cpu { LLVMPIPE_TARGET_MS } else { GPU_TARGET_MS }),
            in_flight: choice.in_flight.unwrap_or(if cpu { LLVMPIPE_IN_FLIGHT } else { GPU_IN_FLIGHT }).max(1),
            budget: choice.budget.or(cpu.then_some(crate::render::DEFAULT_DISPATCH_BUDGET)).map(|b| b.max(1)),
        }
    }

    /// Rejects values no loop takes.
    pub fn check(choice: &PacingChoice) -> crate::error::Result<()> {
        use crate::error::Error;
        if let Some(ms) = choice.target_ms {
            if !(ms.is_finite() && ms > 0.0 && ms <= 60_000.0) {
                return Err(Error::Usage(format!("--dispatch-ms must be in (0, 60000] milliseconds, got {ms}")));
            }
        }
        if let Some(n) = choice.in_flight {
            let most = crate::gpu::MAX_IN_FLIGHT;
            if n == 0 || n > most {
                return Err(Error::Usage(format!("--in-flight must be 1..={most}, got {n}")));
            }
        }
        if choice.budget == Some(0) {
            return Err(Error::Usage("--dispatch-budget must be at least 1".into()));
        }
        Ok(())
    }
}

/// Splits `pixels` x `spp` into dispatches of about `budget` units of work, each
/// sample of a pixel costing `cost_per_sample`: returns (pixels per dispatch, samples
/// per dispatch).
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

/// Sizes the next dispatch from the ones measured so far.
#[derive(Debug, Clone)]
pub struct Sizer {
    target_ms: f64,
    /// Most pixel-samples a dispatch may hold (the work budget's shape).
    cap_units: u64,
    /// Most samples per pixel a dispatch may run (loop limit, budget, responsiveness).
    cap_samples: u32,
    /// Size before any measurement.
    first_units: u64,
    /// Measured milliseconds per pixel-sample (a running mean, recent ones weighted).
    ms_per_unit: Option<f64>,
    largest_measured: u64,
}

impl Sizer {
    /// For chunks of `chunk_pixels` pixels and `spp` samples, a sample costing
    /// `cost_per_sample` units of the work budget, at most `most_samples` samples per
    /// dispatch (`None`: no limit).
    pub fn new(pacing: &Pacing, chunk_pixels: u64, spp: u32, cost_per_sample: u64, most_samples: Option<u32>) -> Sizer {
        let shape = |budget| dispatch_shape(chunk_pixels, spp, cost_per_sample, budget);
        let (cap_px, cap_spp) = pacing.budget.map_or((chunk_pixels, spp), shape);
        let cap_samples = most_samples.map_or(cap_spp, |m| cap_spp.min(m)).max(1);
        let cap_units = if cap_px < chunk_pixels { cap_px } else { cap_px * u64::from(cap_samples) };
        // Start as if the default budget applied (or the smaller one given): a first
        // dispatch whose time tells the rest. The loop waits for it before the next.
        let (probe_px, probe_spp) = shape(crate::render::DEFAULT_DISPATCH_BUDGET);
        let probe = if probe_px < chunk_pixels { probe_px } else { probe_px * u64::from(probe_spp.min(cap_samples)) };
        let first_units = probe.min(cap_units);
        Sizer {
            target_ms: pacing.target_ms,
            cap_units: cap_units.max(1),
            cap_samples,
            first_units: first_units.max(1),
            ms_per_unit: None,
            largest_measured: 0,
        }
    }

    /// Lowers the samples one dispatch may run (short waves for `--time` and
    /// `--checkpoint`).
    pub fn limit_samples(&mut self, most: u32) {
        self.cap_samples = self.cap_samples.min(most.max(1));
    }

    /// Whether no dispatch has been measured yet (the loop then waits for the first).
    pub fn unmeasured(&self) -> bool {
        self.ms_per_unit.is_none()
    }

    /// Pixel-samples the next dispatch should hold.
    pub fn units(&self) -> u64 {
        let by_time = match self.ms_per_unit {
            Some(r) if r > 0.0 => (self.target_ms / r).clamp(1.0, 1e18) as u64,
            _ => self.first_units,
        };
        let ramp = if self.largest_measured > 0 {
            self.largest_measured.saturating_mul(GROWTH).max(self.first_units)
        } else {
            self.first_units
        };
        by_time.min(ramp).min(self.cap_units).max(1)
    }

    /// Samples per pixel of the next wave over `pixels` pixels with `left` samples to go.
    pub fn wave_samples(&self, pixels: u64, left: u32) -> u32 {
        let per_pixel = self.units() / pixels.max(1);
        (per_pixel.clamp(1, u64::from(u32::MAX)) as u32).min(self.cap_samples).min(left).max(1)
    }

    /// Pixels of the next dispatch of a one-sample wave, at most `left`: a whole number
    /// of workgroups where it is not the rest.
    pub fn pixels(&self, left: u64) -> u64 {
        let wg = u64::from(WORKGROUP_SIZE);
        let n = (self.units() / wg * wg).max(wg);
        n.min(left)
    }

    /// A dispatch of `units` pixel-samples took `ms`.
    pub fn measured(&mut self, units: u64, ms: f64) {
        if units == 0 || !(ms.is_finite() && ms > 0.0) {
            return;
        }
        let r = ms / units as f64;
        self.ms_per_unit = Some(match self.ms_per_unit {
            Some(old) => 0.5 * old + 0.5 * r,
            None => r,
        });
        self.largest_measured = self.largest_measured.max(units);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pacing(target_ms: f64, budget: Option<u64>) -> Pacing {
        Pacing { target_ms, in_flight: 2, budget }
    }

    #[test]
    fn a_budget_gives_its_shape_from_the_start() {
        let s = Sizer::new(&pacing(1e9, Some(1_000_000)), 100_000, 16, 100, None);
        // 10,000 pixel-samples a dispatch: less than the chunk, so one sample each.
        assert_eq!(s.units(), 9_984);
        assert_eq!(s.wave_samples(100_000, 16), 1);
        assert_eq!(s.pixels(100_000), 9_984);
    }

    #[test]
    fn dispatches_grow_toward_the_target_at_most_fourfold() {
        let mut s = Sizer::new(&pacing(100.0, None), 1 << 20, 64, 1_000, None);
        let first = s.units();
        assert!(first < 1 << 20, "starts with a probe: {first}");
        // The probe took 1 ms: the target wants 100x, the ramp allows 4x.
        s.measured(first, 1.0);
        assert_eq!(s.units(), 4 * first);
        for _ in 0..10 {
            let u = s.units();
            s.measured(u, u as f64 / first as f64);
        }
        let settled = s.units() as f64;
        assert!((settled / (100.0 * first as f64) - 1.0).abs() < 0.01, "{settled}");
    }

    #[test]
    fn measurements_shrink_long_dispatches_and_samples_fill_whole_pixels() {
        let mut s = Sizer::new(&pacing(10.0, None), 1000, 64, 1, None);
        s.measured(64_000, 640.0);
        // 0.01 ms a pixel-sample: 1000 units, one sample over all pixels.
        assert_eq!(s.units(), 1000);
        assert_eq!(s.wave_samples(1000, 64), 1);
        s.measured(1000, 2.0);
        // Faster now: the mean rate is (0.01 + 0.002) / 2.
        assert_eq!(s.wave_samples(1000, 64), 1);
        s.limit_samples(4);
        for _ in 0..40 {
            s.measured(1000, 1e-6);
        }
        assert_eq!(s.wave_samples(1000, 64), 4);
        assert_eq!(s.wave_samples(1000, 3), 3);
    }

    #[test]
    fn the_loop_limit_bounds_samples() {
        let s = Sizer::new(&pacing(1e9, Some(u64::MAX)), 1000, 64, 1, Some(5));
        assert_eq!(s.wave_samples(1000, 64), 5);
    }
}
