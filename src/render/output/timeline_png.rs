//! A picture of a timeline ([`crate::timeline::Trace`]): the CPU track above the GPU
//! track, one row per nesting level, each span a box coloured by its category and
//! labelled where it is wide enough, under a time axis in milliseconds, with the
//! categories' legend and the run's facts (device, GPU clock) below. What
//! `--trace-events FILE.png` writes, for readers without Perfetto.

use plotters::prelude::*;

use crate::error::{Error, Result};
use crate::render::output::heatmap::{encode_png, font};
use crate::timeline::{Event, GpuClock, Trace, Track};

const WIDTH: u32 = 1600;
const MARGIN: u32 = 16;
/// Left column holding the track names.
const GUTTER: u32 = 90;
const ROW: u32 = 22;
const AXIS: u32 = 44;
/// Deepest nesting level drawn; deeper spans are counted in the footer.
const MAX_LEVELS: usize = 12;

/// Colour of a category (a fixed qualitative palette, submissions greyed).
fn colour(cat: &str) -> RGBColor {
    match cat {
        "run" => RGBColor(200, 200, 200),
        "load" => RGBColor(78, 121, 167),
        "device" => RGBColor(156, 117, 95),
        "build" => RGBColor(242, 142, 43),
        "kernel" => RGBColor(176, 122, 161),
        "upload" => RGBColor(118, 183, 178),
        "trace" => RGBColor(89, 161, 79),
        "readback" => RGBColor(237, 201, 72),
        "output" => RGBColor(255, 157, 167),
        "validate" => RGBColor(186, 176, 172),
        "submit" => RGBColor(215, 215, 215),
        "dispatch" => RGBColor(225, 87, 89),
        "transfer" => RGBColor(118, 183, 178),
        _ => RGBColor(160, 160, 160),
    }
}

/// Nesting level of each span of `track` (by the order of `Trace::on`): a span sits
/// one level below the innermost span that still holds its start.
fn levels(trace: &Trace, track: Track) -> Vec<(&Event, usize)> {
    let mut spans: Vec<&Event> = trace.on(track).collect();
    spans.sort_by_key(|e| (e.start_ns, std::cmp::Reverse(e.dur_ns)));
    let mut open: Vec<&Event> = Vec::new();
    spans
        .into_iter()
        .map(|e| {
            while open.last().is_some_and(|p| p.end_ns() <= e.start_ns) {
                open.pop();
            }
            let level = open.len();
            open.push(e);
            (e, level)
        })
        .collect()
}

/// A tick step of 1, 2 or 5 times a power of ten giving about `n` ticks over `span`.
fn tick_step(span: f64, n: f64) -> f64 {
    let raw = (span / n).max(1e-9);
    let p = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * p).find(|s| *s >= raw).unwrap_or(10.0 * p)
}

/// Characters of a 12-point label that fit between `x0` and `x1` (about 7 pixels each).
fn label_room(x0: i32, x1: i32) -> usize {
    ((x1 - x0 - 6) / 7).max(0) as usize
}

/// The timeline of `trace` as PNG bytes.
pub fn png(trace: &Trace) -> Result<Vec<u8>> {
    font()?;
    let err = |e: &dyn std::fmt::Debug| Error::Failed(format!("timeline picture: drawing failed: {e:?}"));
    let cpu = levels(trace, Track::Cpu);
    let gpu = levels(trace, Track::Gpu);
    let rows = |l: &[(&Event, usize)]| l.iter().map(|x| x.1 + 1).max().unwrap_or(1).min(MAX_LEVELS) as u32;
    let (cpu_rows, gpu_rows) = (rows(&cpu), rows(&gpu));
    let hidden = cpu.iter().chain(&gpu).filter(|x| x.1 >= MAX_LEVELS).count();
    let end_ns = trace.events.iter().map(Event::end_ns).max().unwrap_or(0).max(1);
    let top = MARGIN + 28 + AXIS;
    let gpu_top = top + cpu_rows * ROW + 14;
    let legend_y = gpu_top + gpu_rows * ROW + 14;
    let height = legend_y + 3 * ROW + MARGIN;
    let plot_w = WIDTH - GUTTER - 2 * MARGIN;
    let x_of = |ns: u64| (MARGIN + GUTTER) as i32 + ((ns as f64 / end_ns as f64) * f64::from(plot_w)) as i32;
    let mut buf = vec![255u8; WIDTH as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, height)).into_drawing_area();
        let text = |s: f64| ("sans-serif", s).into_font().color(&BLACK);
        let total_ms = end_ns as f64 * 1e-6;
        let device = trace.meta.get("device").and_then(|v| v.as_str()).unwrap_or("no device");
        let title = format!(
            "{}: {total_ms:.1} ms on {device}",
            if trace.process.is_empty() { "arbor" } else { &trace.process }
        );
        root.draw(&Text::new(title, (MARGIN as i32, MARGIN as i32), text(20.0))).map_err(|e| err(&e))?;
        // Time axis: ticks and labels in ms, with faint lines through both tracks.
        let step = tick_step(total_ms, 10.0);
        let axis_y = (MARGIN + 28 + AXIS - 8) as i32;
        let mut t = 0.0;
        while t <= total_ms + 1e-9 {
            let x = x_of((t * 1e6) as u64);
            let line = PathElement::new(vec![(x, axis_y), (x, (legend_y - 8) as i32)], RGBColor(230, 230, 230));
            root.draw(&line).map_err(|e| err(&e))?;
            root.draw(&Text::new(format!("{t} ms"), (x + 2, axis_y - 18), text(13.0))).map_err(|e| err(&e))?;
            t += step;
        }
        for (name, y0, spans) in [("CPU", top, &cpu), ("GPU queue", gpu_top, &gpu)] {
            root.draw(&Text::new(name, (MARGIN as i32, y0 as i32 + 3), text(15.0))).map_err(|e| err(&e))?;
            // Where the next span of the same row starts (a label may run on to there).
            let mut next = vec![end_ns; spans.len()];
            let mut seen = [end_ns; MAX_LEVELS];
            for (k, &(e, level)) in spans.iter().enumerate().rev() {
                if level < MAX_LEVELS {
                    next[k] = seen[level];
                    seen[level] = e.start_ns;
                }
            }
            for (k, &(e, level)) in spans.iter().enumerate().filter(|x| x.1 .1 < MAX_LEVELS) {
                let (x0, x1) = (x_of(e.start_ns), x_of(e.end_ns()).max(x_of(e.start_ns) + 1));
                let y = (y0 + level as u32 * ROW) as i32;
                let fill = Rectangle::new([(x0, y), (x1, y + ROW as i32 - 3)], colour(e.cat).filled());
                root.draw(&fill).map_err(|e| err(&e))?;
                if x1 - x0 > 3 {
                    let c = colour(e.cat);
                    let dark = RGBColor(c.0 / 2, c.1 / 2, c.2 / 2);
                    let edge = Rectangle::new([(x0, y), (x1, y + ROW as i32 - 3)], dark.stroke_width(1));
                    root.draw(&edge).map_err(|e| err(&e))?;
                }
                // The label (about 7 pixels a character): inside the box where it fits,
                // else after it where the row is free up to the next span, else cut.
                let (room, free) = (label_room(x0, x1), label_room(x1, x_of(next[k]).min(x_of(end_ns) + 1)));
                let n = e.name.chars().count();
                if n <= room {
                    root.draw(&Text::new(e.name.clone(), (x0 + 3, y + 3), text(12.0))).map_err(|e| err(&e))?;
                } else if n <= free {
                    let grey = ("sans-serif", 12.0).into_font().color(&RGBColor(90, 90, 90));
                    root.draw(&Text::new(e.name.clone(), (x1 + 3, y + 3), grey)).map_err(|e| err(&e))?;
                } else if room >= 4 {
                    let label: String = e.name.chars().take(room - 1).chain(std::iter::once('…')).collect();
                    root.draw(&Text::new(label, (x0 + 3, y + 3), text(12.0))).map_err(|e| err(&e))?;
                }
            }
        }
        // Legend: the categories present, then the facts.
        let mut cats: Vec<&str> = trace.events.iter().map(|e| e.cat).collect();
        cats.sort_unstable();
        cats.dedup();
        let mut x = (MARGIN + GUTTER) as i32;
        for c in cats {
            let y = legend_y as i32;
            root.draw(&Rectangle::new([(x, y), (x + 14, y + 14)], colour(c).filled())).map_err(|e| err(&e))?;
            root.draw(&Text::new(c, (x + 18, y), text(13.0))).map_err(|e| err(&e))?;
            x += 30 + 8 * c.len() as i32;
        }
        let clock = match trace.gpu_clock {
            Some(GpuClock::Calibrated) => {
                format!(
                    "GPU spans calibrated to the CPU clock (error at most {} µs)",
                    trace.calibration_error_ns / 1000
                )
            }
            Some(GpuClock::Submit) => "GPU spans aligned at submit (no calibrated timestamps)".to_string(),
            None => "no GPU spans".to_string(),
        };
        let more = if hidden > 0 {
            format!("; {hidden} spans deeper than {MAX_LEVELS} levels not drawn")
        } else {
            String::new()
        };
        let facts = format!("{} spans; {clock}{more}", trace.events.len());
        root.draw(&Text::new(facts, ((MARGIN + GUTTER) as i32, (legend_y + ROW + 4) as i32), text(13.0)))
            .map_err(|e| err(&e))?;
        root.present().map_err(|e| err(&e))?;
    }
    encode_png("timeline picture", WIDTH, height, buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ev(track: Track, cat: &'static str, start_ns: u64, dur_ns: u64) -> Event {
        Event { track, name: format!("{cat} span"), cat, start_ns, dur_ns, args: Default::default() }
    }

    #[test]
    fn levels_follow_nesting_and_ticks_are_round() {
        let t = Trace {
            events: vec![
                ev(Track::Cpu, "build", 0, 100),
                ev(Track::Cpu, "build", 10, 20),
                ev(Track::Cpu, "build", 40, 60),
                ev(Track::Cpu, "output", 100, 5),
            ],
            ..Default::default()
        };
        let l: Vec<usize> = levels(&t, Track::Cpu).iter().map(|x| x.1).collect();
        assert_eq!(l, [0, 1, 1, 0]);
        assert_eq!(tick_step(4.3, 10.0), 0.5);
        assert_eq!(tick_step(1234.0, 10.0), 200.0);
    }

    #[test]
    fn the_picture_shows_both_tracks_in_their_colours() {
        let events = vec![ev(Track::Cpu, "build", 0, 600_000), ev(Track::Gpu, "dispatch", 500_000, 500_000)];
        let t = Trace { process: "arbor test".into(), events, ..Default::default() };
        let png = png(&t).expect("png");
        let img = image::load_from_memory(&png).expect("decodes").to_rgb8();
        assert_eq!(img.width(), WIDTH);
        let has = |c: RGBColor| img.pixels().any(|p| p.0 == [c.0, c.1, c.2]);
        assert!(has(colour("build")) && has(colour("dispatch")));
    }
}
