//! `arbor compare` (included by main.rs only): the error of one image against another.

use anyhow::Result;
use arbor::render::output;

use crate::args::CompareArgs;
use crate::common::{print_out, usage};

/// `arbor compare`: both images are read and checked before --diff is written.
pub(crate) fn run(a: &CompareArgs) -> Result<()> {
    use arbor::render::output::compare as cmp;
    if let Some(d) = a.diff.as_ref().filter(|d| !d.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"))) {
        return Err(usage(format!("{}: --diff must end in .png", d.display())));
    }
    let checked = || -> arbor::Result<(u32, u32, cmp::ErrorStats, Option<Vec<u8>>)> {
        if let Some(d) = &a.diff {
            output::check_writable(d)?;
        }
        let (w, h, test, reference) = cmp::read_pair(&a.test, &a.reference)?;
        let png = a.diff.as_ref().map(|_| cmp::error_png(w, h, &test, &reference)).transpose()?;
        Ok((w, h, cmp::compare(&test, &reference), png))
    };
    let (w, h, st, png) = checked()?;
    if let (Some(d), Some(png)) = (&a.diff, png) {
        output::write_atomic(d, &png)?;
    }
    let text = if a.json {
        format!("{}\n", st.to_json(w, h))
    } else {
        format!("mse      {}\nrel_mse  {}\npsnr     {} dB\nmax_abs  {}\n", st.mse, st.rel_mse, st.psnr, st.max_abs)
    };
    Ok(print_out(&text)?)
}
