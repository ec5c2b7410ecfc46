//! What to build with: where ([`BuildOn`]) and every structure's builder parameters
//! ([`AccelParams`]), each part parsed by its structure's [`Params`].

use std::str::FromStr;

use super::params::{ParamError, Params};
use super::{bvh, grid, kdtree, octree, rayquery, AccelKind, KINDS};

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
            None => {
                Err(ParamError { flag: "accel", item: kind.name().to_string(), what: "takes no parameters".into() })
            }
        }
    }
}
