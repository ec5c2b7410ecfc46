//! Shards: part I of N of a render, as a band of rows (tiles) or a contiguous range
//! of samples, with I given or read from the scheduler's environment (Slurm job
//! arrays, Kubernetes Indexed Jobs). Which pixels and samples a shard computes never
//! changes them: every sample's random numbers depend on (pixel, sample, seed) only.

#![forbid(unsafe_code)]

use crate::error::{Error, Result};
use crate::render::Crop;

/// How `--shard` splits the work.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ShardBy {
    /// N bands of whole rows, top to bottom, as even as the height allows.
    #[default]
    Tiles,
    /// N contiguous ranges of the samples per pixel, as even as the count allows.
    Samples,
}

impl ShardBy {
    pub fn name(self) -> &'static str {
        match self {
            ShardBy::Tiles => "tiles",
            ShardBy::Samples => "samples",
        }
    }
}

impl std::str::FromStr for ShardBy {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "tiles" => Ok(ShardBy::Tiles),
            "samples" => Ok(ShardBy::Samples),
            _ => Err(format!("unknown --shard-by '{s}'; expected tiles or samples")),
        }
    }
}

/// The environment variables `--shard auto/N` reads, in order.
pub const INDEX_VARIABLES: [&str; 2] = ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"];

/// Part `index` of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

impl Shard {
    /// Parses `I/N` or `auto/N`; `env` looks a variable up (`std::env::var` outside
    /// tests).
    pub fn parse(s: &str, env: impl Fn(&str) -> Option<String>) -> Result<Shard> {
        let usage = || Error::Usage(format!("--shard '{s}': expected I/N or auto/N, with 0 <= I < N"));
        let (i, n) = s.split_once('/').ok_or_else(usage)?;
        let count: u32 = n.trim().parse().map_err(|_| usage())?;
        if count == 0 {
            return Err(usage());
        }
        let index = if i.trim() == "auto" {
            let (var, value) = INDEX_VARIABLES
                .iter()
                .find_map(|v| env(v).map(|x| (*v, x)))
                .ok_or_else(|| {
                    Error::Usage(format!(
                        "--shard auto/{count}: neither {} nor {} is set (run it as a Slurm array task or a Kubernetes Indexed Job, or give the index)",
                        INDEX_VARIABLES[0], INDEX_VARIABLES[1]
                    ))
                })?;
            value
                .trim()
                .parse::<u32>()
                .map_err(|_| Error::Usage(format!("--shard auto/{count}: {var}='{value}' is not a shard index")))?
        } else {
            i.trim().parse().map_err(|_| usage())?
        };
        if index >= count {
            return Err(Error::Usage(format!("--shard {s}: index {index} is not below the count {count}")));
        }
        Ok(Shard { index, count })
    }

    /// `[start, end)` of part `index` of `total` items split as evenly as possible.
    fn range(&self, total: u32) -> (u32, u32) {
        let at = |k: u32| (u64::from(total) * u64::from(k) / u64::from(self.count)) as u32;
        (at(self.index), at(self.index + 1))
    }

    /// The window and sample range `(crop, first_sample, samples)` of this shard of a
    /// `width` x `height` image of `spp` samples, inside `crop` (the whole image when
    /// `None`).
    pub fn plan(&self, by: ShardBy, crop: Crop, first_sample: u32, spp: u32) -> Result<(Crop, u32, u32)> {
        match by {
            ShardBy::Tiles => {
                let h = crop.height();
                if self.count > h {
                    return Err(Error::Usage(format!(
                        "--shard {}/{} by tiles: the image has only {h} rows to split",
                        self.index, self.count
                    )));
                }
                let (a, b) = self.range(h);
                Ok((Crop { y0: crop.y0 + a, y1: crop.y0 + b, ..crop }, first_sample, spp))
            }
            ShardBy::Samples => {
                if self.count > spp {
                    return Err(Error::Usage(format!(
                        "--shard {}/{} by samples: only {spp} samples per pixel to split (raise --spp)",
                        self.index, self.count
                    )));
                }
                let (a, b) = self.range(spp);
                Ok((crop, first_sample + a, b - a))
            }
        }
    }

    /// `I/N tiles` or `I/N samples`, for the part's header.
    pub fn describe(&self, by: ShardBy) -> String {
        format!("{}/{} {}", self.index, self.count, by.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn no_env(_: &str) -> Option<String> {
        None
    }

    #[test]
    fn explicit_and_auto_indices() {
        assert_eq!(Shard::parse("2/5", no_env).expect("ok"), Shard { index: 2, count: 5 });
        let slurm = |v: &str| (v == "SLURM_ARRAY_TASK_ID").then(|| "3".to_string());
        assert_eq!(Shard::parse("auto/4", slurm).expect("ok").index, 3);
        let k8s = |v: &str| (v == "JOB_COMPLETION_INDEX").then(|| "1".to_string());
        assert_eq!(Shard::parse("auto/4", k8s).expect("ok").index, 1);
        let both = |v: &str| Some(if v == "SLURM_ARRAY_TASK_ID" { "0" } else { "2" }.to_string());
        assert_eq!(Shard::parse("auto/4", both).expect("ok").index, 0, "Slurm's variable comes first");
        for bad in ["4/4", "5/4", "1/0", "x/2", "1", "1/2/3", "-1/2"] {
            assert!(Shard::parse(bad, no_env).is_err(), "{bad}");
        }
        let e = Shard::parse("auto/4", no_env).expect_err("unset").to_string();
        assert!(e.contains("SLURM_ARRAY_TASK_ID") && e.contains("JOB_COMPLETION_INDEX"), "{e}");
        let big = |_: &str| Some("7".to_string());
        assert!(Shard::parse("auto/4", big).expect_err("too big").to_string().contains("not below"));
        let junk = |_: &str| Some("seven".to_string());
        assert!(Shard::parse("auto/4", junk).is_err());
    }

    #[test]
    fn shards_cover_the_image_and_the_samples_once() {
        let full = Crop::full(50, 37);
        for n in [1, 2, 3, 7, 37] {
            let mut rows = [0; 37];
            for i in 0..n {
                let (c, first, spp) = Shard { index: i, count: n }.plan(ShardBy::Tiles, full, 0, 9).expect("plan");
                assert_eq!((c.x0, c.x1, first, spp), (0, 50, 0, 9));
                (c.y0..c.y1).for_each(|y| rows[y as usize] += 1);
            }
            assert!(rows.iter().all(|&r| r == 1), "{n} tiles");
            let mut samples = [0; 20];
            for i in 0..n.min(20) {
                let (c, first, spp) =
                    Shard { index: i, count: n.min(20) }.plan(ShardBy::Samples, full, 0, 20).expect("plan");
                assert_eq!(c, full);
                (first..first + spp).for_each(|s| samples[s as usize] += 1);
            }
            assert!(samples.iter().all(|&s| s == 1), "{n} sample shards");
        }
        assert!(Shard { index: 0, count: 38 }.plan(ShardBy::Tiles, full, 0, 1).is_err());
        assert!(Shard { index: 0, count: 3 }.plan(ShardBy::Samples, full, 0, 2).is_err());
    }
}
