//! The one parser of structure parameters. Every structure's parameters are a
//! [`Params`] type: named presets and documented keys. A spec is a comma-separated list
//! applied left to right on top of the current values: a preset name replaces them
//! all, `KEY=VALUE` sets one (`--kd quality,depth=30`). Errors have one format:
//! `--FLAG ITEM: what was expected`.

use std::str::FromStr;

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
