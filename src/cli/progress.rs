//! Progress of long work (included by main.rs only): on a terminal, a bar that appears
//! after the first second; otherwise (a log file, a pipe, a batch job) a plain line on
//! stderr every few seconds, `render: 35% (12.3 s, about 22 s left, 1.234 M samples/s)` (pixel
//! samples). Nothing with
//! `--quiet`.

use std::cell::Cell;
use std::io::IsTerminal;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// How long work runs before the bar appears.
const BAR_AFTER: Duration = Duration::from_secs(1);
/// Time between plain progress lines.
const LINE_EVERY: Duration = Duration::from_secs(5);

/// Shows how far a piece of work has got.
pub(crate) struct Reporter {
    bar: ProgressBar,
    /// What the plain lines start with ("render", "bench").
    label: &'static str,
    start: Instant,
    /// Draw the bar (stderr is a terminal, not quiet).
    interactive: bool,
    /// Print plain lines (stderr is not a terminal, not quiet).
    plain: bool,
    shown: Cell<bool>,
    last_line: Cell<Instant>,
}

impl Reporter {
    /// A reporter for work called `label`; `bar_now` draws the bar from the start.
    pub(crate) fn new(label: &'static str, quiet: bool, bar_now: bool) -> Self {
        let bar = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::hidden());
        if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} [{bar:40}] {percent}% {per_sec} eta {eta}") {
            bar.set_style(style.progress_chars("=> "));
        }
        let terminal = std::io::stderr().is_terminal();
        let start = Instant::now();
        let r = Reporter {
            bar,
            label,
            start,
            interactive: !quiet && terminal,
            plain: !quiet && !terminal,
            shown: Cell::new(false),
            last_line: Cell::new(start),
        };
        if bar_now && r.interactive {
            r.show_bar();
        }
        r
    }

    pub(crate) fn bar(&self) -> &ProgressBar {
        &self.bar
    }

    fn show_bar(&self) {
        self.bar.set_draw_target(ProgressDrawTarget::stderr());
        self.shown.set(true);
    }

    /// `done` of `total` units are finished.
    pub(crate) fn update(&self, done: u64, total: u64) {
        self.bar.set_length(total);
        self.bar.set_position(done);
        self.tick();
    }

    /// Shows the bar once the work has run a second, or prints a plain line when one is due.
    pub(crate) fn tick(&self) {
        let now = Instant::now();
        if self.interactive && !self.shown.get() && now - self.start > BAR_AFTER {
            self.show_bar();
        }
        if self.plain && now - self.last_line.get() >= LINE_EVERY {
            self.last_line.set(now);
            let (done, total) = (self.bar.position(), self.bar.length().unwrap_or(0));
            eprintln!("{}", line(self.label, done, total, (now - self.start).as_secs_f64()));
        }
    }

    pub(crate) fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// `LABEL: P% (T s, about R s left)`, the estimate from the rate so far.
fn line(label: &str, done: u64, total: u64, secs: f64) -> String {
    let frac = if total > 0 { done as f64 / total as f64 } else { 0.0 };
    let left = if done > 0 { format!(", about {:.0} s left", secs * (1.0 - frac) / frac) } else { String::new() };
    // A render counts pixel samples: their rate is worth showing.
    let rate = if secs > 0.0 && label == "render" {
        format!(", {:.3} M samples/s", done as f64 / secs / 1e6)
    } else {
        String::new()
    };
    format!("{label}: {:.0}% ({secs:.1} s{left}{rate})", frac * 100.0)
}

/// The reporter as the benchmark's progress.
pub(crate) struct BenchProgress(pub(crate) Reporter);

impl arbor::bench::Progress for BenchProgress {
    fn set_length(&self, n: u64) {
        self.0.bar.set_length(n);
    }
    fn message(&self, m: String) {
        self.0.bar.set_message(m);
        self.0.tick();
    }
    fn inc(&self, n: u64) {
        self.0.bar.inc(n);
        self.0.tick();
    }
    fn line(&self, l: &str) -> std::io::Result<()> {
        self.0.bar.suspend(|| crate::common::print_out(&format!("{l}\n")))
    }
    fn note(&self, l: &str) {
        self.0.bar.suspend(|| eprintln!("{l}"));
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn plain_line_has_percent_time_and_estimate() {
        assert_eq!(
            super::line("render", 35_000_000, 100_000_000, 12.5),
            "render: 35% (12.5 s, about 23 s left, 2.800 M samples/s)"
        );
        assert_eq!(super::line("bench", 0, 10, 1.0), "bench: 0% (1.0 s)");
    }
}
