//! The one parser of structure parameters. Every structure's parameters are a
//! [`Params`] type: named presets and documented keys. A spec is a comma-separated list
//! applied left to right on top of the current values: a preset name replaces them
//! all, `KEY=VALUE` sets one (`--kd quality,depth=30`). Errors have one format:
//! `--FLAG ITEM: what was expected`.

use std::str::FromStr;

use super::{bvh, grid, kdtree, octree, rayquery, AccelKind, KINDS};

/// One documented key of a structure's parameters.
pub struct Key<P> {
    pub name: &'static str,
    /// What a value must be, as the error says it ("1..=1048576").
    pub expects: &'static str,
    /// Sets the key from its value text; `None` when the value is not what `expects`
    /// says.
    pub set: fn(&mut P, &str) -> Option<()>,
}

impl<P> std::fmt::Debug for Key<P> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Key").field("name", &self.name).field("expects", &self.expects).finish()
    }
}

/// A named preset: its name and the parameters it stands for.
pub type Preset<P> = (&'static str, fn() -> P);

/// Parameters of a structure's builder.
pub trait Params: Copy + Default + 'static {
    /// The command-line flag, without `--`.
    const FLAG: &'static str;
    /// Named presets; `default` is always among them.
    const PRESETS: &'static [Preset<Self>];
    /// Keys in the order the help text lists them.
    const KEYS: &'static [Key<Self>];

    /// Parses `spec` over the defaults.
    fn parse(spec: &str) -> Result<Self, ParamError> {
        Self::default().parse_onto(spec)
    }

    /// Applies `spec` on top of `self`.
    fn parse_onto(self, spec: &str) -> Result<Self, ParamError> {
        let mut p = self;
        for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            if let Some((_, preset)) = Self::PRESETS.iter().find(|(name, _)| *name == item) {
                p = preset();
                continue;
            }
            let err = |what: String| ParamError { flag: Self::FLAG, item: item.to_string(), what };
            let Some((k, v)) = item.split_once('=') else {
                return Err(err(format!("expected a preset ({}) or KEY=VALUE", Self::preset_names())));
            };
            let key = Self::KEYS
                .iter()
                .find(|key| key.name == k.trim())
                .ok_or_else(|| err(format!("unknown key '{}' (keys: {})", k.trim(), Self::key_names())))?;
            (key.set)(&mut p, v.trim()).ok_or_else(|| err(format!("expected {}", key.expects)))?;
        }
        Ok(p)
    }

    /// The preset names, comma-separated.
    fn preset_names() -> String {
        Self::PRESETS.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
    }

    /// The keys, comma-separated.
    fn key_names() -> String {
        Self::KEYS.iter().map(|k| k.name).collect::<Vec<_>>().join(", ")
    }
}

/// A structure parameter that could not be applied.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("--{flag} {item}: {what}")]
pub struct ParamError {
    pub flag: &'static str,
    pub item: String,
    pub what: String,
}

/// `v` as a number within `lo..=hi` (and finite, for floats).
pub fn number<T: FromStr + PartialOrd + Copy>(v: &str, lo: T, hi: T) -> Option<T> {
    let x: T = v.parse().ok()?;
    // NaN fails both comparisons, so it is rejected too.
    (x >= lo && x <= hi).then_some(x)
}


/// Where a structure is built: on the CPU (every structure), or on the GPU (lbvh,
/// trbvh, bvh4 and bvh8, [`super::bvh::gpu_build`]), where it then stays.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum BuildOn {
    /// On the CPU (every structure).
    #[default]
    Cpu,
    /// On the GPU (lbvh, trbvh, bvh4, bvh8), kept there ([`super::bvh::device::DeviceTree`]).
    Gpu,
}

impl BuildOn {
    /// The `--build` value.
    pub fn name(self) -> &'static str {
        match self {
            BuildOn::Cpu => "cpu",
            BuildOn::Gpu => "gpu",
        }
    }
}

impl FromStr for BuildOn {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "cpu" => Ok(BuildOn::Cpu),
            "gpu" => Ok(BuildOn::Gpu),
            _ => Err(format!("unknown build device '{s}'; expected cpu or gpu")),
        }
    }
}

/// Builder parameters of every structure that has any.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct AccelParams {
    /// Where to build (the GPU builds lbvh, trbvh, bvh4 and bvh8).
    pub build: BuildOn,
    /// The kd-tree builder's (`--kd`).
    pub kd: kdtree::KdParams,
    /// The grid's resolution (`--grid`).
    pub grid: grid::GridParams,
    /// The octree builder's (`--octree`).
    pub octree: octree::OctreeParams,
    /// trbvh's treelet restructuring.
    pub treelet: bvh::treelet::TreeletParams,
    /// The driver's build (`rayquery`).
    pub rayquery: rayquery::RayQueryParams,
}

impl AccelParams {
    /// Every structure's parameter flag, in table order ([`AccelKind::param_flag`]).
    pub fn flags() -> impl Iterator<Item = &'static str> {
        KINDS.iter().filter_map(|r| r.param_flag)
    }

    /// Applies `spec` (a preset and/or KEY=VALUE pairs) to the parameters that
    /// `--<flag>` sets, on top of their current values.
    pub fn set_flag(&mut self, flag: &str, spec: &str) -> Result<(), ParamError> {
        if flag == kdtree::KdParams::FLAG {
            self.kd = self.kd.parse_onto(spec)?;
        } else if flag == grid::GridParams::FLAG {
            self.grid = self.grid.parse_onto(spec)?;
        } else if flag == octree::OctreeParams::FLAG {
            self.octree = self.octree.parse_onto(spec)?;
        } else if flag == bvh::treelet::TreeletParams::FLAG {
            self.treelet = self.treelet.parse_onto(spec)?;
        } else if flag == rayquery::RayQueryParams::FLAG {
            self.rayquery = self.rayquery.parse_onto(spec)?;
        } else {
            return Err(ParamError {
                flag: "accel",
                item: flag.to_string(),
                what: "no structure takes this flag".into(),
            });
        }
        Ok(())
    }

    /// Applies `spec` to the parameters of `kind`'s builder; an error if it has none.
    pub fn apply(&mut self, kind: AccelKind, spec: &str) -> Result<(), ParamError> {
        match kind.param_flag() {
            Some(flag) => self.set_flag(flag, spec),
            None => Err(ParamError {
                flag: "accel",
                item: kind.name().to_string(),
                what: "takes no parameters".into(),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::grid::GridParams;
    use crate::accel::kdtree::KdParams;
    use crate::accel::octree::OctreeParams;

    #[test]
    fn presets_keys_and_one_error_format() {
        let kd = KdParams::parse("quality,depth=30").expect("parses");
        assert_eq!((kd.leaf_size, kd.max_depth), (1, Some(30)));
        assert_eq!(KdParams::parse("depth=auto,fast").expect("parses"), KdParams::fast());
        let g = GridParams::default().parse_onto("lambda=4").expect("parses");
        assert_eq!(g.parse_onto("cells=100").expect("parses").lambda, 4.0);
        let e = OctreeParams::parse("leaf=0").expect_err("out of range");
        assert_eq!(e.to_string(), "--octree leaf=0: expected 1..=1048576");
        let e = GridParams::parse("size=3").expect_err("unknown key");
        assert_eq!(e.to_string(), "--grid size=3: unknown key 'size' (keys: lambda, cells)");
        let e = KdParams::parse("best").expect_err("unknown preset");
        assert_eq!(e.to_string(), "--kd best: expected a preset (default, quality, fast) or KEY=VALUE");
        for bad in ["lambda=nan", "lambda=inf", "lambda=-1", "cells=0", "lambda="] {
            assert!(GridParams::parse(bad).is_err(), "{bad}");
        }
    }
}
