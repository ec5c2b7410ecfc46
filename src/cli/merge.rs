//! `arbor merge` (included by main.rs only): the parts of a farm render into one image.

use std::time::Instant;

use anyhow::Result;
use arbor::render::{self, output};

use crate::args::MergeArgs;
use crate::common::ms;

/// `arbor merge`: parts into one image (and AOVs), written together or not at all.
pub(crate) fn run(a: &MergeArgs) -> Result<()> {
    let start = Instant::now();
    let aovs = output::parse_aovs(&a.aov)?;
    let scale = crate::common::aov_scale(a.aov_scale.as_deref(), &aovs)?;
    output::format_of(&a.output, "image")?;
    let paths = std::iter::once(&a.output).chain(aovs.iter().map(|(_, p)| p));
    output::check_outputs(paths.map(|p| p.as_path()))?;
    let mut parts = Vec::new();
    // Parts decode in parallel (each decoder on one thread); the first failure in the
    // order given is reported.
    use rayon::prelude::*;
    let read: Vec<_> =
        a.parts.par_iter().map(|path| render::output::part::read(path).map(|(i, f)| (path, i, f))).collect();
    for r in read {
        let (path, info, frame) = r?;
        parts.push(render::output::merge::Part { path: path.clone(), info, frame });
    }
    let n = parts.len();
    let (info, frame) = render::output::merge::merge(parts, a.allow_partial)?;
    let mut set = output::OutputSet::new();
    output::write_frame(&mut set, &a.output, &info, &frame)?;
    let heat = output::HeatmapInfo { subject: format!("{}, merged from {n} parts", info.scene), scale };
    output::write_aovs(&mut set, &aovs, &frame, frame.width, frame.height, &heat)?;
    set.commit()?;
    if !a.quiet {
        let fewest = frame.samples.iter().copied().min().unwrap_or(0);
        eprintln!(
            "wrote {} ({}x{}, samples {}..{}, fewest per pixel {fewest}) from {n} parts in {:.0} ms",
            a.output.display(),
            info.width,
            info.height,
            info.first_sample,
            info.first_sample + info.samples,
            ms(start)
        );
    }
    Ok(())
}
