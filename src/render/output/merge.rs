//! `arbor merge`: parts ([`crate::render::output::part`]) back into one image. Parts with the same
//! window are sample ranges of it and add up: their sums, squared luminance, sample
//! and ray counts add in sample order, and the AOVs of sample 0's camera ray come from
//! the part that holds sample 0 (the one that traced it). Windows are tiles and are
//! placed by their data window. A merged tile is bit for bit the part it came from;
//! merged sample ranges equal the single render to float summation error.
//!
//! Refused, with one line naming the file: parts of another scene, other settings or
//! another program version (their hash differs), of another image size, tiles that
//! overlap without being the same window, sample ranges that overlap, and, unless
//! partial output is allowed, missing tiles, missing samples and parts that stopped
//! before their range's end.

#![forbid(unsafe_code)]

use std::path::PathBuf;

use crate::error::{Error, Result};
use crate::render::output::part::PartInfo;
use crate::render::{Crop, Frame};

/// One part read from a file.
#[derive(Debug)]
pub struct Part {
    pub path: PathBuf,
    pub info: PartInfo,
    pub frame: Frame,
}

fn refuse(path: &std::path::Path, why: String) -> Error {
    Error::invalid(path, why)
}

fn overlaps(a: &Crop, b: &Crop) -> bool {
    a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1
}

fn show(c: &Crop) -> String {
    format!("{},{},{},{}", c.x0, c.x1, c.y0, c.y1)
}

/// The fewest samples any pixel of the frame holds.
fn fewest(f: &Frame) -> u32 {
    f.samples.iter().copied().min().unwrap_or(0)
}

/// Merges `parts` into the whole image: the header of the result and its frame.
/// With `allow_partial`, missing tiles stay black misses with no samples, and gaps in
/// the samples or unfinished parts are accepted.
pub fn merge(parts: Vec<Part>, allow_partial: bool) -> Result<(PartInfo, Frame)> {
    let Some(first) = parts.first() else {
        return Err(Error::Usage("merge: no parts given".into()));
    };
    let base = first.info.clone();
    let base_path = first.path.clone();
    for p in &parts {
        let i = &p.info;
        if (i.width, i.height) != (base.width, base.height) {
            return Err(refuse(
                &p.path,
                format!(
                    "a part of a {}x{} image, not {}x{} like {}",
                    i.width,
                    i.height,
                    base.width,
                    base.height,
                    base_path.display()
                ),
            ));
        }
        if i.hash != base.hash || i.version != base.version {
            return Err(refuse(
                &p.path,
                format!(
                    "rendered from another scene, other settings or another arbor than {} (hash {} of arbor {}, not {} of {})",
                    base_path.display(),
                    i.hash,
                    i.version,
                    base.hash,
                    base.version
                ),
            ));
        }
        if let Some(t) = parts.iter().find(|t| t.info.spp_total != 0) {
            if i.spp_total != 0 && i.spp_total != t.info.spp_total {
                return Err(refuse(
                    &p.path,
                    format!(
                        "a sample shard of {} samples per pixel, not {} like {}",
                        i.spp_total,
                        t.info.spp_total,
                        t.path.display()
                    ),
                ));
            }
        }
        if !allow_partial && fewest(&p.frame) < i.samples {
            return Err(refuse(
                &p.path,
                format!(
                    "unfinished: holds {} of its {} samples per pixel (resume it with --resume, or pass --allow-partial)",
                    fewest(&p.frame),
                    i.samples
                ),
            ));
        }
    }
    // Windows: each the same as or apart from every other.
    let mut windows: Vec<(Crop, Vec<usize>)> = Vec::new();
    for (k, p) in parts.iter().enumerate() {
        let c = p.info.crop;
        if let Some(w) = windows.iter_mut().find(|(w, _)| *w == c) {
            w.1.push(k);
            continue;
        }
        if let Some((w, ks)) = windows.iter().find(|(w, _)| overlaps(w, &c)) {
            return Err(refuse(
                &p.path,
                format!("its window {} overlaps the window {} of {}", show(&c), show(w), parts[ks[0]].path.display()),
            ));
        }
        windows.push((c, vec![k]));
    }
    let covered: u64 = windows.iter().map(|(c, _)| c.pixels()).sum();
    let all = u64::from(base.width) * u64::from(base.height);
    if covered < all && !allow_partial {
        return Err(Error::Failed(format!(
            "merge: the parts cover {covered} of the {all} pixels of the {}x{} image: tiles are missing (or pass --allow-partial)",
            base.width, base.height
        )));
    }
    // Samples within each window: disjoint ranges, sorted; all windows alike.
    let mut union: Option<(u32, u32, usize)> = None;
    for (_, ks) in windows.iter_mut() {
        ks.sort_by_key(|&k| parts[k].info.first_sample);
        let mut end = None::<(u32, usize)>;
        for &k in ks.iter() {
            let r = parts[k].info.sample_range();
            if let Some((e, prev)) = end {
                if r.start < e {
                    return Err(refuse(
                        &parts[k].path,
                        format!(
                            "its samples {}..{} overlap those of {} (up to {e})",
                            r.start,
                            r.end,
                            parts[prev].path.display()
                        ),
                    ));
                }
                if r.start > e && !allow_partial {
                    return Err(refuse(
                        &parts[k].path,
                        format!(
                            "samples {e}..{} are missing before its {}..{} (or pass --allow-partial)",
                            r.start, r.start, r.end
                        ),
                    ));
                }
            }
            end = Some((r.end, k));
        }
        let lo = parts[ks[0]].info.first_sample;
        let (hi, last) = end.expect("a window has a part");
        if !allow_partial && lo != 0 {
            return Err(refuse(
                &parts[ks[0]].path,
                format!("samples 0..{lo} of its window are missing (or pass --allow-partial)"),
            ));
        }
        match union {
            None => union = Some((lo, hi, last)),
            Some((l, h, other)) if (l, h) != (lo, hi) && !allow_partial => {
                return Err(refuse(
                    &parts[last].path,
                    format!(
                        "its window holds samples {lo}..{hi}, but that of {} holds {l}..{h}",
                        parts[other].path.display()
                    ),
                ))
            }
            Some(_) => {}
        }
    }
    let (lo, hi, _) = union.expect("at least one part");
    let total = parts.iter().map(|p| p.info.spp_total).max().unwrap_or(0);
    if total != 0 && hi - lo != total && !allow_partial {
        return Err(Error::Failed(format!(
            "merge: the parts hold samples {lo}..{hi} of {total} per pixel: sample shards are missing (or pass --allow-partial)"
        )));
    }

    let mut out = Frame::new(base.width, base.height)?;
    for (c, ks) in &windows {
        for y in c.y0..c.y1 {
            for x in c.x0..c.x1 {
                let o = (y * base.width + x) as usize;
                let mut aovs_from = None;
                for &k in ks {
                    let f = &parts[k].frame;
                    let i = ((y - c.y0) * c.width() + (x - c.x0)) as usize;
                    if f.samples[i] == 0 {
                        continue;
                    }
                    if out.samples[o] == 0 {
                        out.sum[o] = f.sum[i];
                        out.sum_y2[o] = f.sum_y2[i];
                    } else {
                        for ch in 0..3 {
                            out.sum[o][ch] += f.sum[i][ch];
                        }
                        out.sum_y2[o] += f.sum_y2[i];
                    }
                    out.samples[o] += f.samples[i];
                    out.rays[o] += f.rays[i];
                    // Sample 0's AOVs: from the part holding the lowest sample.
                    if aovs_from.is_none() {
                        aovs_from = Some(i);
                        out.depth[o] = f.depth[i];
                        out.normal[o] = f.normal[i];
                        out.prim[o] = f.prim[i];
                        out.nodes[o] = f.nodes[i];
                        out.tests[o] = f.tests[i];
                        out.albedo[o] = f.albedo[i];
                    }
                }
                out.finish_pixel(o);
            }
        }
    }
    let shard = format!("merged from {} parts", parts.len());
    let info = PartInfo {
        crop: Crop::full(base.width, base.height),
        first_sample: lo,
        samples: hi - lo,
        spp_total: total,
        shard,
        ..base
    };
    Ok((info, out))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(name: &str, crop: Crop, first: u32, n: u32, value: f32) -> Part {
        let mut f = Frame::new(crop.width(), crop.height()).expect("frame");
        for k in 0..f.sum.len() {
            f.sum[k] = [value * n as f32; 3];
            f.samples[k] = n;
            f.sum_y2[k] = value * value * n as f32;
            f.rays[k] = n;
            if first == 0 {
                f.prim[k] = 7;
                f.depth[k] = 2.0;
            }
            f.finish_pixel(k);
        }
        let info = PartInfo {
            width: 8,
            height: 6,
            crop,
            first_sample: first,
            samples: n,
            spp_total: 0,
            seed: 0,
            integrator: "path".into(),
            hash: "h".into(),
            version: "v".into(),
            scene: "s".into(),
            shard: String::new(),
        };
        Part { path: PathBuf::from(name), info, frame: f }
    }

    fn top() -> Crop {
        Crop { x0: 0, x1: 8, y0: 0, y1: 3 }
    }
    fn bottom() -> Crop {
        Crop { x0: 0, x1: 8, y0: 3, y1: 6 }
    }

    #[test]
    fn tiles_and_sample_ranges_combine() {
        let parts = vec![
            part("a", top(), 0, 2, 1.0),
            part("b", top(), 2, 2, 3.0),
            part("c", bottom(), 2, 2, 5.0),
            part("d", bottom(), 0, 2, 5.0),
        ];
        let (info, f) = merge(parts, false).expect("merge");
        assert_eq!((info.first_sample, info.samples), (0, 4));
        assert_eq!(f.radiance[0], [2.0; 3]);
        assert_eq!(f.radiance[47], [5.0; 3]);
        assert!(f.samples.iter().all(|&n| n == 4));
        assert!(f.prim.iter().all(|&p| p == 7), "AOVs of the part holding sample 0");
    }

    #[test]
    fn bad_sets_are_refused_naming_the_file() {
        let msg = |parts: Vec<Part>| merge(parts, false).expect_err("refused").to_string();
        let mut foreign = part("foreign", bottom(), 0, 2, 1.0);
        foreign.info.hash = "other".into();
        assert!(msg(vec![part("a", top(), 0, 2, 1.0), foreign]).contains("foreign"));
        assert!(msg(vec![part("a", top(), 0, 2, 1.0)]).contains("tiles are missing"));
        let shifted = part("shifted", Crop { x0: 0, x1: 8, y0: 2, y1: 6 }, 0, 2, 1.0);
        assert!(msg(vec![part("a", top(), 0, 2, 1.0), shifted]).contains("shifted"));
        let twice = vec![part("a", top(), 0, 2, 1.0), part("b", bottom(), 0, 2, 1.0), part("again", top(), 1, 2, 1.0)];
        assert!(msg(twice).contains("again"));
        let gap = vec![part("a", top(), 0, 2, 1.0), part("b", bottom(), 0, 2, 1.0), part("late", top(), 3, 1, 1.0)];
        assert!(msg(gap).contains("late"));
        let mut unfinished = part("unfinished", bottom(), 0, 2, 1.0);
        unfinished.frame.samples[3] = 1;
        assert!(msg(vec![part("a", top(), 0, 2, 1.0), unfinished]).contains("unfinished"));
        // Partial output is allowed on request.
        let (_, f) = merge(vec![part("a", top(), 0, 2, 1.0)], true).expect("partial");
        assert_eq!(f.samples[47], 0);
    }
}
