//! `arbor calibrate` (included by main.rs only): measures the cost model of `--accel
//! auto` on a device and writes it to the cache (`arbor::accel::calibrate`).

use std::time::Instant;

use anyhow::{Context as _, Result};
use arbor::accel::calibrate;

use crate::args::CalibrateArgs;
use crate::common::{context, print_out, trace_device};

/// `arbor calibrate`: checks that the cache can be written, measures, writes the file
/// and prints the constants.
pub(crate) fn run(a: &CalibrateArgs) -> Result<()> {
    let dir = calibrate::cache_dir().context("no cache directory: set ARBOR_CACHE_DIR (or XDG_CACHE_HOME or HOME)")?;
    calibrate::check_writable(&dir)?;
    let ctx = context(&a.device)?;
    trace_device(&ctx);
    eprintln!("calibrate: {}, {}", ctx.info().name, ctx.info().driver);
    let start = Instant::now();
    let costs = arbor::bench::calibrate::measure(&ctx, &mut |line| {
        eprintln!("calibrate: {line} ({:.1} s)", start.elapsed().as_secs_f64());
    })?;
    ctx.check_validation()?;
    let path = calibrate::save(&dir, ctx.info(), &costs)?;
    let text = if a.json {
        let rows: Vec<serde_json::Value> = costs
            .trees
            .iter()
            .map(|t| {
                serde_json::json!({ "kind": t.kind.name(), "build": t.build.name(), "build_ns": t.build_ns, "trace_ns": t.trace_ns })
            })
            .collect();
        let doc = serde_json::json!({ "device": ctx.info().name, "driver": ctx.info().driver, "file": path, "brute_test_ns": costs.brute_test_ns, "trees": rows });
        format!("{}\n", serde_json::to_string_pretty(&doc)?)
    } else {
        let mut t = format!("{:<10} {:<6} {:>12} {:>12}\n", "structure", "build", "build ns/prim", "trace ns/ray");
        for c in &costs.trees {
            t += &format!("{:<10} {:<6} {:>12.1} {:>12.1}\n", c.kind.name(), c.build.name(), c.build_ns, c.trace_ns);
        }
        t += &format!("brute force: {:.2} ns a primitive test\n", costs.brute_test_ns);
        t
    };
    print_out(&text)?;
    eprintln!(
        "calibrate: wrote {} in {:.1} s; `render --accel auto` uses it on this device",
        path.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
