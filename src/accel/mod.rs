//! Acceleration structures. Each lives in its own module with the same surface
//! (`build`, `validate`, `stats`, `to_gpu`, CPU `intersect`/`occluded`); the GPU
//! kernel variant for a structure is `trace_<kind>_<geometry>`.
//!
//! - [`AccelKind::None`]: brute force over every primitive with a scene-box
//!   early-out, the baseline every structure is measured against.
//! - [`AccelKind::Kdtree`]: the SAH kd-tree of Wald & Havran (2006).
//! - [`AccelKind::BspCourse`]: the lecture's simple BSP tree, same layout and kernel.
//! - [`AccelKind::BvhSah`], [`AccelKind::Lbvh`], [`AccelKind::Trbvh`]: BVHs from
//!   three builders, one layout and one kernel (see [`bvh`]).
//! - [`AccelKind::Bvh4`], [`AccelKind::Bvh8`]: the `bvh-sah` tree collapsed into 4- or
//!   8-wide nodes ([`bvh::wide`]), their own layout and kernels.
//! - [`AccelKind::Cwbvh`]: the `bvh-sah` tree collapsed into 8-wide nodes with quantised
//!   boxes ([`bvh::cwbvh`]), its own layout and kernel.
//! - [`AccelKind::Grid`]: uniform grid, 3D-DDA (Amanatides & Woo 1987).
//! - [`AccelKind::Octree`]: octree with child masks, parametric traversal (Revelles 2000).
//! - [`AccelKind::RayQuery`]: the device driver's own structure, traced with
//!   VK_KHR_ray_query ([`rayquery`]): the peer a Vulkan user would pick instead.

#![forbid(unsafe_code)]

pub mod auto;
mod build_params;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod bvh;
pub mod calibrate;
pub mod family;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod gpu_layout;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod grid;
mod image;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod instance;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod kdtree;
pub mod kinds;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod none;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod octree;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod params;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod prim;
pub mod rayquery;
pub mod sah;
mod stats;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod validate;

pub use build_params::{AccelParams, BuildOn};
pub use family::{Geometry, KernelFamily};
pub use image::{resume_words, AccelBuffers, GpuImage, TraceLoop};
pub use kinds::{AccelKind, KindRow, KINDS};
pub use prim::Prims;
pub(crate) use stats::lap;
pub use stats::{BuildStats, LeafTally, Phase};
pub use validate::{Site, ValidateError};

/// CPU traversal, the test oracle of every structure: each implements `traverse` (in
/// the same order and with the same rules as its kernel) and gets the nearest-hit and
/// any-hit queries.
pub trait Traverse {
    /// Front-to-back traversal that records hits in `best` (whose t bounds the ray);
    /// with `any`, stops at the first hit. Returns whether it hit.
    fn traverse(&self, prims: &Prims, ray: &crate::math::Ray, best: &mut crate::math::Hit, any: bool) -> bool;

    /// Nearest hit with the watertight ray/triangle test.
    fn intersect(&self, scene: &crate::scene::Scene, ray: &crate::math::Ray) -> Option<crate::math::Hit> {
        self.intersect_with(&Prims::new(scene), ray)
    }

    /// Nearest hit with the ray/triangle test of `prims`.
    fn intersect_with(&self, prims: &Prims, ray: &crate::math::Ray) -> Option<crate::math::Hit> {
        let mut best = crate::math::Hit::none(ray.tmax);
        self.traverse(prims, ray, &mut best, false);
        (best.prim != u32::MAX).then_some(best)
    }

    /// Whether anything lies in (tmin, tmax], with the watertight test.
    fn occluded(&self, scene: &crate::scene::Scene, ray: &crate::math::Ray) -> bool {
        self.occluded_with(&Prims::new(scene), ray)
    }

    /// Whether anything lies in (tmin, tmax], with the test of `prims`.
    fn occluded_with(&self, prims: &Prims, ray: &crate::math::Ray) -> bool {
        let mut best = crate::math::Hit::none(ray.tmax);
        self.traverse(prims, ray, &mut best, true)
    }
}

/// The one surface of every structure (brute force included): invariants, statistics,
/// the image the GPU kernel reads, and CPU traversal ([`Traverse`]). Builders are
/// reached through [`Accel::build_with`], each with its documented parameters.
pub trait Structure: Traverse + Send + Sync {
    /// Checks the structure's invariants against the scene it was built for.
    fn validate(&self, scene: &crate::scene::Scene) -> Result<(), ValidateError>;
    /// Statistics with the meanings [`BuildStats`] documents.
    fn stats(&self, scene: &crate::scene::Scene) -> BuildStats;
    /// Build time and phases alone, as `stats` reports them, without walking the
    /// structure for the rest.
    fn timing(&self) -> (f64, Vec<Phase>);
    /// The box rays are first clipped to.
    fn bounds(&self) -> crate::math::Aabb;
    /// What the kernel needs: buffers, stack size, loop bounds, checked against the
    /// kernel's limits (an error names the limit crossed).
    fn gpu_image(&self, scene: &crate::scene::Scene) -> Result<GpuImage<'_>, ValidateError>;
}

/// A built structure of any kind, with the common surface.
#[derive(Debug, Clone)]
pub enum Accel {
    /// Brute force (`none`).
    None(none::BruteForce),
    /// A kd-tree (`kdtree`, `bsp-course`).
    Kd(kdtree::KdTree),
    /// A binary BVH (`bvh-sah`, `lbvh`, `trbvh`).
    Bvh(bvh::Bvh),
    /// A 4-wide BVH.
    Bvh4(bvh::wide::Bvh4),
    /// An 8-wide BVH.
    Bvh8(bvh::wide::Bvh8),
    /// A compressed 8-wide BVH.
    Cwbvh(bvh::cwbvh::Cwbvh),
    /// A uniform grid.
    Grid(grid::Grid),
    /// An octree.
    Octree(octree::Octree),
    /// Any of the above per prototype of an instanced scene, under a top-level BVH.
    TwoLevel(Box<instance::TwoLevel>),
    /// The driver's structure (ray queries), instanced scenes included.
    RayQuery(Box<rayquery::RayQuery>),
    /// A BVH built on the device and kept there (`--build gpu`).
    Device(Box<bvh::device::DeviceTree>),
}

impl Accel {
    /// Builds `kind` for `scene` with default parameters.
    pub fn build(kind: AccelKind, scene: &crate::scene::Scene) -> Accel {
        Self::build_with(kind, scene, &AccelParams::default())
    }

    /// Builds `kind` for `scene` with `params` (each structure reads its own part); for
    /// a scene with instances, a two-level structure of `kind` ([`instance`]).
    /// `rayquery` made this way has no device part: CPU traversal only (use
    /// [`Accel::build_on`] to trace it).
    pub fn build_with(kind: AccelKind, scene: &crate::scene::Scene, params: &AccelParams) -> Accel {
        let span = crate::timeline::span("build", || format!("build {kind}"));
        span.arg("primitives", scene.prim_count());
        if kind == AccelKind::RayQuery {
            return Accel::RayQuery(Box::new(rayquery::RayQuery::cpu_only(scene, params)));
        }
        if scene.has_instances() {
            return Accel::TwoLevel(Box::new(instance::TwoLevel::build(kind, scene, params)));
        }
        Self::build_own(kind, scene, params)
    }

    /// Builds `kind` over the scene's own primitives (instances left out).
    pub fn build_own(kind: AccelKind, scene: &crate::scene::Scene, params: &AccelParams) -> Accel {
        match kind {
            AccelKind::None => Accel::None(none::BruteForce::build(scene)),
            AccelKind::Kdtree => Accel::Kd(kdtree::KdTree::build(scene, &params.kd)),
            AccelKind::BspCourse => Accel::Kd(kdtree::KdTree::build_course(scene)),
            AccelKind::BvhSah => Accel::Bvh(bvh::Bvh::build(scene, bvh::BvhBuilder::Sah)),
            AccelKind::Lbvh => Accel::Bvh(bvh::Bvh::build(scene, bvh::BvhBuilder::Lbvh)),
            AccelKind::Trbvh => Accel::Bvh(bvh::Bvh::build_with(scene, bvh::BvhBuilder::Trbvh, &params.treelet)),
            AccelKind::Bvh4 => Accel::Bvh4(bvh::wide::Bvh4::build(scene, bvh::BvhBuilder::Sah)),
            AccelKind::Bvh8 => Accel::Bvh8(bvh::wide::Bvh8::build(scene, bvh::BvhBuilder::Sah)),
            AccelKind::Cwbvh => Accel::Cwbvh(bvh::cwbvh::Cwbvh::build(scene, bvh::BvhBuilder::Sah)),
            AccelKind::Grid => Accel::Grid(grid::Grid::build(scene, &params.grid)),
            AccelKind::Octree => Accel::Octree(octree::Octree::build(scene, &params.octree)),
            AccelKind::RayQuery => Accel::RayQuery(Box::new(rayquery::RayQuery::cpu_only(scene, params))),
        }
    }

    /// Builds `kind` where `params.build` says: on the CPU as [`Accel::build_with`], or
    /// with the GPU builder on `ctx` (lbvh, trbvh, bvh4, bvh8; anything else is a usage error).
    pub fn build_on(
        ctx: &crate::gpu::Context,
        kind: AccelKind,
        scene: &crate::scene::Scene,
        params: &AccelParams,
    ) -> crate::error::Result<Accel> {
        Self::build_on_reusing(ctx, kind, scene, params, &mut None)
    }

    /// [`Accel::build_on`], creating the GPU build pipelines in `pipelines` on first
    /// use and reusing them after (for repeated builds, as `bench` runs them).
    pub fn build_on_reusing(
        ctx: &crate::gpu::Context,
        kind: AccelKind,
        scene: &crate::scene::Scene,
        params: &AccelParams,
        pipelines: &mut Option<bvh::gpu_build::GpuBuilder>,
    ) -> crate::error::Result<Accel> {
        // The CPU builds open their span in build_with; the device's builds here.
        let span = (params.build == BuildOn::Gpu || kind == AccelKind::RayQuery)
            .then(|| crate::timeline::span("build", || format!("build {kind} on the device")));
        if let Some(s) = &span {
            s.arg("primitives", scene.prim_count());
        }
        check_build(kind, scene, params.build)?;
        if kind == AccelKind::RayQuery {
            return Ok(Accel::RayQuery(Box::new(rayquery::RayQuery::build(ctx, scene, params)?)));
        }
        match params.build {
            BuildOn::Cpu => Ok(Self::build_with(kind, scene, params)),
            BuildOn::Gpu => {
                let target = bvh::gpu_build::Target::of(kind)
                    .ok_or_else(|| crate::error::Error::Usage(format!("--build gpu cannot build {kind}")))?;
                let g = match pipelines {
                    Some(g) => g,
                    None => pipelines.insert(bvh::gpu_build::GpuBuilder::new(ctx)?),
                };
                Ok(Accel::Device(Box::new(g.build_target(ctx, scene, target, &params.treelet)?)))
            }
        }
    }

    /// The structure behind its one surface.
    pub fn surface(&self) -> &dyn Structure {
        match self {
            Accel::None(t) => t,
            Accel::Kd(t) => t,
            Accel::Bvh(t) => t,
            Accel::Bvh4(t) => t,
            Accel::Bvh8(t) => t,
            Accel::Cwbvh(t) => t,
            Accel::Grid(t) => t,
            Accel::Octree(t) => t,
            Accel::TwoLevel(t) => t.as_ref(),
            Accel::RayQuery(t) => t.as_ref(),
            Accel::Device(t) => t.as_ref(),
        }
    }

    /// Whether the structure lives on the device only (built there and not read back),
    /// so that CPU traversal, `validate` and the full `stats` need [`Accel::read_back`].
    pub fn on_device_only(&self) -> bool {
        matches!(self, Accel::Device(t) if t.host().is_none())
    }

    /// Reads a structure built on the device back to the host, for what needs the
    /// whole tree there (`validate`, node statistics, CPU traversal); its time is a
    /// phase of the build's (`readback for the host`). Nothing for any other structure.
    pub fn read_back(&mut self, ctx: &crate::gpu::Context) -> crate::error::Result<()> {
        match self {
            Accel::Device(t) => t.read_back(ctx),
            _ => Ok(()),
        }
    }

    /// Checks the structure's invariants against the scene.
    pub fn validate(&self, scene: &crate::scene::Scene) -> Result<(), ValidateError> {
        self.surface().validate(scene)
    }

    /// The structure's statistics ([`BuildStats`]).
    pub fn stats(&self, scene: &crate::scene::Scene) -> BuildStats {
        self.surface().stats(scene)
    }

    /// Build time and phases alone, as [`Accel::stats`] reports them.
    pub fn timing(&self) -> (f64, Vec<Phase>) {
        self.surface().timing()
    }

    /// The box rays are first clipped to.
    pub fn bounds(&self) -> crate::math::Aabb {
        self.surface().bounds()
    }

    /// The CPU reference for a batch of rays: each ray's closest hit in order, `None`
    /// where it meets nothing in `(tmin, tmax]`, with the watertight ray/triangle test,
    /// on every core. The same answer as [`crate::render::integrators::rays::RayTracer::trace`]
    /// (same primitive; t and barycentrics to rounding).
    pub fn trace_cpu(&self, scene: &crate::scene::Scene, rays: &[crate::math::Ray]) -> Vec<Option<crate::math::Hit>> {
        self.trace_cpu_with(scene, rays, crate::math::intersect::IntersectMode::Watertight)
    }

    /// [`Accel::trace_cpu`] with the ray/triangle test `mode`.
    pub fn trace_cpu_with(
        &self,
        scene: &crate::scene::Scene,
        rays: &[crate::math::Ray],
        mode: crate::math::intersect::IntersectMode,
    ) -> Vec<Option<crate::math::Hit>> {
        use rayon::prelude::*;
        let prims = Prims::with_mode(scene, mode);
        rays.par_iter().map(|r| self.intersect_with(&prims, r)).collect()
    }

    /// What the trace kernel reads, checked against its limits.
    pub fn gpu_image(&self, scene: &crate::scene::Scene) -> Result<GpuImage<'_>, ValidateError> {
        self.surface().gpu_image(scene)
    }
}

impl Traverse for Accel {
    fn traverse(&self, prims: &Prims, ray: &crate::math::Ray, best: &mut crate::math::Hit, any: bool) -> bool {
        self.surface().traverse(prims, ray, best, any)
    }
}

/// Whether `kind` can be built on `build` for `scene`, checked before a device is
/// opened (a usage error: the command line asked for what cannot be): the device
/// builds lbvh, trbvh, bvh4 and bvh8 of scenes without instances; the driver builds
/// rayquery.
pub fn check_build(kind: AccelKind, scene: &crate::scene::Scene, build: BuildOn) -> crate::error::Result<()> {
    use crate::error::Error::Usage;
    if build != BuildOn::Gpu {
        return Ok(());
    }
    if kind == AccelKind::RayQuery {
        return Err(Usage(
            "--build gpu builds lbvh, trbvh, bvh4 and bvh8; rayquery is built by the device's driver (use --build cpu)"
                .into(),
        ));
    }
    if !kind.builds_on_gpu() {
        return Err(Usage(format!(
            "--build gpu builds lbvh, trbvh, bvh4 and bvh8; {kind} is built on the CPU (use --build cpu)"
        )));
    }
    if scene.has_instances() {
        return Err(Usage("--build gpu does not build instanced scenes; use --build cpu (or --flatten)".into()));
    }
    Ok(())
}
