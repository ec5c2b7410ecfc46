//! Acceleration structures. Each lives in its own module with the same surface
//! (`build`, `validate`, `stats`, `to_gpu`, CPU `intersect`/`occluded`); the GPU
//! kernel variant for a structure is `trace_<kind>_<geometry>`.
//!
//! This foundation ships [`AccelKind::None`]: brute force over every primitive with
//! a scene-box early-out, the baseline every structure is measured against.

#![forbid(unsafe_code)]

pub mod gpu_layout;
pub mod none;

use std::fmt;
use std::str::FromStr;

/// Which acceleration structure to build and traverse.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum AccelKind {
    /// Every primitive for every ray, after a scene-box test.
    #[default]
    None,
}

impl AccelKind {
    /// Every kind, in CLI order.
    pub const ALL: &'static [AccelKind] = &[AccelKind::None];

    /// The CLI / kernel name.
    pub fn name(self) -> &'static str {
        match self {
            AccelKind::None => "none",
        }
    }
}

impl fmt::Display for AccelKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for AccelKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "none" | "brute-force" => Ok(AccelKind::None),
            _ => Err(format!(
                "unknown structure '{s}'; available: {}",
                AccelKind::ALL.iter().map(|k| k.name()).collect::<Vec<_>>().join(", ")
            )),
        }
    }
}

/// What building a structure cost and produced.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct BuildStats {
    pub kind: String,
    /// CPU wall-clock build time.
    pub build_ms: f64,
    /// Bytes of the structure as uploaded (nodes + indices).
    pub bytes: u64,
    pub nodes: u64,
    pub max_depth: u32,
}
