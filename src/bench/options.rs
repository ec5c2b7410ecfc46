//! From what the command line asked for ([`Request`]) to what to run ([`Options`]):
//! default scenes and ray kinds, one row per build device and per swept parameter.

use std::path::PathBuf;

use crate::accel::{AccelKind, AccelParams, BuildOn};
use crate::error::{Error, Result};
use crate::math::intersect::IntersectMode;

use super::{Options, RayKind};

/// Most timed rounds `--repeat` takes.
pub const MAX_REPEAT: usize = 1000;

/// What the command line asked for; [`Request::options`] fills in the defaults.
#[derive(Debug, Clone)]
pub struct Request {
    /// Triangle counts of the procedural blobs (default 1000,10000,100000; 1000,10000
    /// with `quick`) unless `scenes` is given.
    pub tris: Vec<usize>,
    /// Extra scene arguments, after the blobs.
    pub scenes: Vec<String>,
    pub accel: Vec<AccelKind>,
    /// Every structure's parameters (`build` is ignored: see `builds`).
    pub params: AccelParams,
    /// Build devices; a structure that builds on the GPU gets one row per device.
    pub builds: Vec<BuildOn>,
    /// Grid densities to sweep: one row per value for each structure whose parameters
    /// take a `lambda`.
    pub lambda: Vec<f32>,
    /// Ray kinds (default primary; primary,diffuse with `quick`).
    pub rays: Vec<RayKind>,
    /// Adds shadow rays (the older `--shadow`).
    pub shadow: bool,
    pub intersect: Vec<IntersectMode>,
    /// Traversal of coherent rays in the BVH kernels.
    pub traversal: crate::render::Traversal,
    /// How dispatches are sized and kept in flight.
    pub pacing: crate::render::dispatch::PacingChoice,
    pub size: (u32, u32),
    /// Timed rounds (1 with `quick`).
    pub repeat: usize,
    pub quick: bool,
    pub out: Option<PathBuf>,
    pub json: Option<PathBuf>,
    /// See [`Options::trace_events`].
    pub trace_events: Option<PathBuf>,
    /// Colour scale of the cost figures.
    pub heatmap_scale: crate::render::output::heatmap::Scale,
}

impl Request {
    /// What to run.
    pub fn options(&self) -> Result<Options> {
        if !(1..=MAX_REPEAT).contains(&self.repeat) {
            return Err(Error::Usage(format!("--repeat {}: must be 1..={MAX_REPEAT}", self.repeat)));
        }
        if let Some(bad) = self.lambda.iter().find(|l| !(l.is_finite() && **l > 0.0 && **l <= 1e4)) {
            return Err(Error::Usage(format!("--lambda {bad}: each value must be in (0, 10000]")));
        }
        let tris = match (self.tris.is_empty() && self.scenes.is_empty(), self.quick) {
            (true, true) => vec![1000, 10_000],
            (true, false) => vec![1000, 10_000, 100_000],
            _ => self.tris.clone(),
        };
        let mut rays = self.rays.clone();
        if rays.is_empty() {
            rays = if self.quick { vec![RayKind::Primary, RayKind::Diffuse] } else { vec![RayKind::Primary] };
        }
        if self.shadow && !rays.contains(&RayKind::Shadow) {
            rays.push(RayKind::Shadow);
        }
        Ok(Options {
            scenes: tris.iter().map(|n| format!("builtin:blob:{n}")).chain(self.scenes.iter().cloned()).collect(),
            variants: self.variants(),
            rays,
            intersect: self.intersect.clone(),
            traversal: self.traversal,
            pacing: self.pacing,
            size: self.size,
            repeat: if self.quick { 1 } else { self.repeat },
            out: self.out.clone(),
            json: self.json.clone(),
            trace_events: self.trace_events.clone(),
            heatmap_scale: self.heatmap_scale,
            with_driver: self.accel == AccelKind::ALL,
        })
    }

    /// The structures to run, with the parameters of each row and its label: one row
    /// per `lambda` value for a structure that takes one, one per build device for a
    /// structure that builds on the GPU, else one built on the CPU.
    pub fn variants(&self) -> Vec<(AccelKind, AccelParams, String)> {
        let base = AccelParams { build: self.builds.first().copied().unwrap_or_default(), ..self.params };
        let mut out = Vec::new();
        for &kind in &self.accel {
            if let Some(rows) = self.lambda_sweep(kind, &base) {
                out.extend(rows);
            } else if kind.builds_on_gpu() {
                for &on in &self.builds {
                    let label = match on {
                        BuildOn::Cpu => kind.name().to_string(),
                        BuildOn::Gpu => format!("{}@gpu", kind.name()),
                    };
                    out.push((kind, AccelParams { build: on, ..base }, label));
                }
            } else {
                out.push((kind, AccelParams { build: BuildOn::Cpu, ..base }, kind.name().to_string()));
            }
        }
        out
    }

    /// `kind` once per `lambda` value (labelled `KIND:LAMBDA`), when `lambda` values
    /// are given and `kind`'s parameters take one.
    fn lambda_sweep(&self, kind: AccelKind, base: &AccelParams) -> Option<Vec<(AccelKind, AccelParams, String)>> {
        if self.lambda.is_empty() {
            return None;
        }
        self.lambda
            .iter()
            .map(|&lambda| {
                let mut p = *base;
                p.apply(kind, &format!("lambda={lambda}")).ok()?;
                Some((kind, p, format!("{}:{lambda}", kind.name())))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request() -> Request {
        Request {
            tris: Vec::new(),
            scenes: Vec::new(),
            accel: AccelKind::ALL.to_vec(),
            params: AccelParams::default(),
            builds: vec![BuildOn::Cpu, BuildOn::Gpu],
            lambda: vec![1.0, 4.0],
            rays: Vec::new(),
            shadow: false,
            intersect: vec![IntersectMode::Watertight],
            traversal: crate::render::Traversal::Single,
            pacing: Default::default(),
            size: (16, 16),
            repeat: 3,
            quick: true,
            out: None,
            json: None,
            trace_events: None,
            heatmap_scale: crate::render::output::heatmap::Scale::Linear,
        }
    }

    /// The grid is swept over lambda, the GPU builders run on both devices, every other
    /// structure once on the CPU.
    #[test]
    fn variants_sweep_lambda_and_build_devices() {
        let r = request();
        let v = r.variants();
        let swept: Vec<&(AccelKind, AccelParams, String)> = v.iter().filter(|v| v.2.contains(':')).collect();
        assert_eq!(swept.len(), 2, "{:?}", v.iter().map(|v| &v.2).collect::<Vec<_>>());
        assert_eq!(swept[0].2, format!("{}:1", swept[0].0));
        assert_eq!(swept[1].2, format!("{}:4", swept[1].0));
        assert_ne!(swept[0].1, swept[1].1, "lambda reaches the parameters");
        let gpu = AccelKind::ALL.iter().filter(|k| k.builds_on_gpu()).count();
        assert_eq!(v.iter().filter(|v| v.1.build == BuildOn::Gpu).count(), gpu);
        assert_eq!(v.len(), AccelKind::ALL.len() - 1 + 2 + gpu);
        let o = r.options().expect("options");
        assert_eq!(o.repeat, 1);
        assert_eq!(o.scenes, ["builtin:blob:1000", "builtin:blob:10000"]);
        assert_eq!(o.rays, [RayKind::Primary, RayKind::Diffuse]);
    }

    #[test]
    fn lambda_out_of_range_is_refused() {
        let r = Request { lambda: vec![0.0], ..request() };
        assert!(r.options().is_err());
    }

    #[test]
    fn repeat_out_of_range_is_refused() {
        for repeat in [0, MAX_REPEAT + 1, usize::MAX] {
            let e = Request { repeat, ..request() }.options().expect_err("refused");
            assert_eq!(e.to_string(), format!("--repeat {repeat}: must be 1..=1000"));
        }
    }
}
