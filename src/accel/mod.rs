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
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod bvh;
pub mod calibrate;
pub mod family;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod gpu_layout;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod grid;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod instance;
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod kdtree;
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
#[allow(missing_docs)] // builder internals, documented in docs/ (one page per structure); not the stable API
pub mod validate;

pub use family::{Geometry, KernelFamily};
pub use prim::Prims;
pub use validate::{Site, ValidateError};

use std::fmt;
use std::str::FromStr;

/// Which acceleration structure to build and traverse.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum AccelKind {
    /// Every primitive for every ray, after a scene-box test.
    #[default]
    None,
    /// SAH kd-tree (Wald & Havran 2006), perfect splits.
    Kdtree,
    /// The lecture's BSP tree: 3 candidate planes per axis, <= 4 per leaf, <= 20 levels.
    BspCourse,
    /// BVH, top-down binned SAH (Wald 2007).
    BvhSah,
    /// Linear BVH (Karras 2012).
    Lbvh,
    /// LBVH with treelet restructuring (Karras & Aila 2013).
    Trbvh,
    /// The binned SAH BVH collapsed into 4-wide nodes.
    Bvh4,
    /// The binned SAH BVH collapsed into 8-wide nodes.
    Bvh8,
    /// The binned SAH BVH collapsed into 8-wide nodes with quantised child boxes
    /// (Ylitie, Karras & Laine 2017).
    Cwbvh,
    /// Uniform grid, about lambda x N cells (Amanatides & Woo 1987).
    Grid,
    /// Octree, subdivided about node centres (Revelles et al. 2000 traversal).
    Octree,
    /// The driver's acceleration structure (VK_KHR_acceleration_structure), traced
    /// with VK_KHR_ray_query; needs a device that has both.
    RayQuery,
}

impl AccelKind {
    /// arbor's own structures, in CLI order: every kind but [`AccelKind::RayQuery`],
    /// which exists only on devices with ray queries (see [`AccelKind::EVERY`]).
    pub const ALL: &'static [AccelKind] = Self::EVERY.split_at(Self::EVERY.len() - 1).0;

    /// Every kind `--accel` takes: arbor's own, then the driver's.
    pub const EVERY: &'static [AccelKind] = &[
        AccelKind::None,
        AccelKind::Kdtree,
        AccelKind::BspCourse,
        AccelKind::BvhSah,
        AccelKind::Lbvh,
        AccelKind::Trbvh,
        AccelKind::Bvh4,
        AccelKind::Bvh8,
        AccelKind::Cwbvh,
        AccelKind::Grid,
        AccelKind::Octree,
        AccelKind::RayQuery,
    ];

    /// The CLI / kernel name.
    pub fn name(self) -> &'static str {
        match self {
            AccelKind::None => "none",
            AccelKind::Kdtree => "kdtree",
            AccelKind::BspCourse => "bsp-course",
            AccelKind::BvhSah => "bvh-sah",
            AccelKind::Lbvh => "lbvh",
            AccelKind::Trbvh => "trbvh",
            AccelKind::Bvh4 => "bvh4",
            AccelKind::Bvh8 => "bvh8",
            AccelKind::Cwbvh => "cwbvh",
            AccelKind::Grid => "grid",
            AccelKind::Octree => "octree",
            AccelKind::RayQuery => "rayquery",
        }
    }

    /// 16-byte texel fetches of one node (or cell) visit in this structure's kernel:
    /// the count `nodes` AOV multiplies by (shaders/accel/*.glsl: a BVH node is 4
    /// texels, a 4-wide node 7, an 8-wide node 14, a quantised one 6; a kd-tree or
    /// octree node one 8-byte pair, a grid cell its two range words). `None` for brute
    /// force (no nodes) and the driver's structure (not visible).
    pub fn texels_per_node(self) -> Option<u32> {
        match self {
            AccelKind::Kdtree | AccelKind::BspCourse | AccelKind::Octree => Some(1),
            AccelKind::BvhSah | AccelKind::Lbvh | AccelKind::Trbvh => Some(4),
            AccelKind::Bvh4 => Some(7),
            AccelKind::Bvh8 => Some(14),
            AccelKind::Cwbvh => Some(6),
            AccelKind::Grid => Some(2),
            AccelKind::None | AccelKind::RayQuery => None,
        }
    }

    /// Texel fetches of one triangle test: its index in the leaf (none for brute
    /// force), the triangle record and three vertices.
    pub fn texels_per_test(self) -> u32 {
        if self.is_brute_force() {
            4
        } else {
            5
        }
    }

    /// Whether the device's driver builds and traverses this structure (ray queries),
    /// so that it exists only on a device that has them.
    pub fn driver_built(self) -> bool {
        self == AccelKind::RayQuery
    }

    /// The structure `render` and `info` build unless told otherwise.
    pub const DEFAULT: AccelKind = AccelKind::Kdtree;

    /// The structure CPU reference images are traced with: exact like every structure,
    /// and the quickest to build with a good tree.
    pub const CPU_REFERENCE: AccelKind = AccelKind::BvhSah;

    /// Whether this is brute force, the baseline every structure is measured against.
    pub fn is_brute_force(self) -> bool {
        self == AccelKind::None
    }

    /// Whether `--build gpu` can build this structure ([`bvh::gpu_build`]).
    pub fn builds_on_gpu(self) -> bool {
        matches!(self, AccelKind::Lbvh | AccelKind::Trbvh | AccelKind::Bvh4 | AccelKind::Bvh8)
    }

    /// The command-line flag (without `--`) whose parameters this structure's builder
    /// reads, if it has any: `kd`, `grid`, `octree` or `trbvh`.
    pub fn param_flag(self) -> Option<&'static str> {
        match self {
            AccelKind::Kdtree => Some("kd"),
            AccelKind::Trbvh => Some("trbvh"),
            AccelKind::Grid => Some("grid"),
            AccelKind::Octree => Some("octree"),
            AccelKind::RayQuery => Some("rayquery"),
            AccelKind::None
            | AccelKind::BspCourse
            | AccelKind::BvhSah
            | AccelKind::Lbvh
            | AccelKind::Bvh4
            | AccelKind::Bvh8
            | AccelKind::Cwbvh => None,
        }
    }

    /// The kernel family (`trace_<kernel>_<geometry>`) that traverses this structure
    /// over a flat scene.
    pub fn kernel(self) -> KernelFamily {
        match self {
            AccelKind::None => KernelFamily::None,
            AccelKind::Kdtree | AccelKind::BspCourse => KernelFamily::Kdtree,
            AccelKind::BvhSah | AccelKind::Lbvh | AccelKind::Trbvh => KernelFamily::Bvh,
            AccelKind::Bvh4 => KernelFamily::Bvh4,
            AccelKind::Bvh8 => KernelFamily::Bvh8,
            AccelKind::Cwbvh => KernelFamily::Cwbvh,
            AccelKind::Grid => KernelFamily::Grid,
            AccelKind::Octree => KernelFamily::Octree,
            AccelKind::RayQuery => KernelFamily::RayQuery,
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
            "kdtree" | "kd" => Ok(AccelKind::Kdtree),
            "bsp-course" => Ok(AccelKind::BspCourse),
            "bvh-sah" | "bvh" => Ok(AccelKind::BvhSah),
            "lbvh" => Ok(AccelKind::Lbvh),
            "trbvh" => Ok(AccelKind::Trbvh),
            "bvh4" => Ok(AccelKind::Bvh4),
            "bvh8" => Ok(AccelKind::Bvh8),
            "cwbvh" => Ok(AccelKind::Cwbvh),
            "grid" => Ok(AccelKind::Grid),
            "octree" => Ok(AccelKind::Octree),
            "rayquery" | "ray-query" => Ok(AccelKind::RayQuery),
            _ => Err(format!(
                "unknown structure '{s}'; available: {}",
                AccelKind::EVERY.iter().map(|k| k.name()).collect::<Vec<_>>().join(", ")
            )),
        }
    }
}

/// What building a structure cost and produced. Every field means the same for every
/// structure: a grid cell counts as a leaf, an absent octant or an empty BVH child as an
/// empty leaf, and brute force as one leaf holding everything.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct BuildStats {
    /// The structure's name ([`AccelKind::name`]).
    pub kind: String,
    /// CPU wall-clock build time.
    pub build_ms: f64,
    /// Bytes of the structure as uploaded (nodes + indices).
    pub bytes: u64,
    /// Inner nodes plus leaves (as counted in `leaves`).
    pub nodes: u64,
    /// Deepest leaf; the root is depth 0 for trees, and grids and brute force are 0.
    pub max_depth: u32,
    /// Every leaf, empty ones included.
    pub leaves: u64,
    /// Leaves that hold no primitive (a subset of `leaves`).
    pub empty_leaves: u64,
    /// Mean depth over every leaf, empty ones included.
    pub mean_leaf_depth: f64,
    /// Primitive references in leaves per primitive.
    pub refs_per_prim: f64,
    /// Primitive references per non-empty leaf.
    pub prims_per_leaf: f64,
    /// SAH cost of the tree with the default constants (sah.rs), relative to the root.
    pub sah_cost: f64,
    /// Build phases in order, CPU wall clock.
    pub phases: Vec<Phase>,
    /// Cells per axis (grid only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resolution: Option<[u32; 3]>,
    /// Each level of a two-level structure (instanced scenes only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub levels: Option<instance::LevelStats>,
    /// Set where the structure is the driver's (`rayquery`): what arbor cannot see of
    /// it (node counts, depth and SAH cost are then 0, meaning unknown). The kernel
    /// cannot count its nodes and primitives either, so renders leave those out.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub opaque: Option<String>,
    /// Set where arbor's own tree was built on the device and kept there: what needs
    /// it read back to the host (leaf counts, SAH cost; 0 until then). The kernel
    /// counts nodes visited and primitives tested as for any tree.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub on_device: Option<String>,
}

/// One timed phase of a build.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Phase {
    /// What the phase does (e.g. `sort`, `flatten`).
    pub name: String,
    /// CPU wall-clock time.
    pub ms: f64,
    /// What the phase did, where it says more than its time (e.g. treelets optimised).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detail: Option<String>,
}

impl Phase {
    /// Phase `name` from `since` until now, also a span on this thread's timeline
    /// ([`crate::timeline`]), where it nests inside the build's span.
    pub fn since(name: impl Into<String>, since: std::time::Instant) -> Phase {
        let name = name.into();
        crate::timeline::phase("build", &name, since, Default::default());
        Phase { name, ms: since.elapsed().as_secs_f64() * 1e3, detail: None }
    }

    /// The same phase with `detail`.
    pub fn with_detail(mut self, detail: String) -> Phase {
        self.detail = Some(detail);
        self
    }
}

/// Records the time since `t` as phase `name` ([`Phase::since`]) and restarts `t`.
pub(crate) fn lap(phases: &mut Vec<Phase>, name: &str, t: &mut std::time::Instant) {
    phases.push(Phase::since(name, *t));
    *t = std::time::Instant::now();
}

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

/// How a structure's kernel bounds its loops (llvmpipe, which has no watchdog, needs
/// every loop bounded; see docs/kernels.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TraceLoop {
    /// Loops over primitive lists of these lengths, unrolled as the kernel was compiled
    /// (`BRUTE_UNROLL`, one kernel per factor).
    Unrolled {
        /// The lengths of the (at most two) primitive lists.
        lengths: [u64; 2],
    },
    /// A traversal loop the kernel stops after `TREE_STEPS` steps (the dispatch
    /// header's `limits`): the trace is resumed in a following dispatch where the
    /// family can ([`GpuImage::resume_words`]), else the pixel is flagged.
    StepBudget,
}

impl TraceLoop {
    /// Loop iterations of one trace: with `unroll` for unrolled loops, or `budget`.
    pub fn iterations(self, unroll: u32, budget: u64) -> u64 {
        match self {
            TraceLoop::Unrolled { lengths } => {
                lengths.iter().map(|&n| n.div_ceil(u64::from(unroll.max(1)))).sum::<u64>() + 2
            }
            TraceLoop::StepBudget => budget,
        }
    }
}

/// A structure as the trace kernel reads it.
#[derive(Debug, Clone)]
pub struct GpuImage<'a> {
    /// Kernel family: `shaders/accel/<family>.glsl`, kernels `trace_<family>_<geometry>`.
    pub family: KernelFamily,
    /// Node words and index words; `None` binds neither buffer.
    pub buffers: Option<AccelBuffers<'a>>,
    /// Entries of the kernel's traversal stack (`SPEC_STACK_SIZE`).
    pub stack_size: u32,
    /// Estimated work (primitive tests or traversal steps) of one ray, to size dispatches.
    pub cost_per_ray: u64,
    /// How the kernel bounds its loops.
    pub trace_loop: TraceLoop,
    /// The driver's structure the kernel traces with ray queries (`rayquery`), bound
    /// at `BINDING_TLAS`; `None` for every structure of arbor's own.
    pub ray_structure: Option<&'a crate::gpu::RayStructure>,
    /// Words of traversal state the family's kernel saves when a trace runs out of
    /// steps, to resume it in a following dispatch ([`resume_words`]; docs/kernels.md,
    /// "Resumed traces"). 0: the family cannot suspend a trace (brute force, which needs
    /// no step budget; a traversal inside the driver), and a trace that runs out flags
    /// its pixel and fails the render.
    pub resume_words: u32,
}

/// Where a structure's node and index words are: on the host, uploaded for each
/// render, or already on the device that built them (`--build gpu`), bound as they are.
#[derive(Debug, Clone)]
pub enum AccelBuffers<'a> {
    /// Node bytes and index words on the host.
    Host(std::borrow::Cow<'a, [u8]>, &'a [u32]),
    /// Node and index buffers on the device, with the geometry the build uploaded
    /// (by binding, in the render's layout), which the trace binds instead of its own.
    Device {
        /// The node buffer.
        nodes: std::sync::Arc<crate::gpu::Buffer>,
        /// The primitive index buffer.
        indices: std::sync::Arc<crate::gpu::Buffer>,
        /// `(binding, buffer)` for vertices, triangles and spheres.
        geometry: &'a [(u32, std::sync::Arc<crate::gpu::Buffer>)],
    },
}

/// [`GpuImage::resume_words`] of a kernel that traverses `levels` levels (2 with
/// instances) with a stack of `stack_size` entries: per level the fixed words and two
/// stack arrays (shaders/common/resume.glsl).
pub fn resume_words(levels: u32, stack_size: u32) -> u32 {
    levels * (crate::gpu::bindings::RESUME_LEVEL_WORDS + 2 * stack_size)
}

/// Where a structure is built: on the CPU (every structure), or on the GPU (lbvh,
/// trbvh, bvh4 and bvh8, [`bvh::gpu_build`]), where it then stays.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum BuildOn {
    /// On the CPU (every structure).
    #[default]
    Cpu,
    /// On the GPU (lbvh, trbvh, bvh4, bvh8), kept there ([`bvh::device::DeviceTree`]).
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
    /// Every structure's parameter flag (see [`AccelKind::param_flag`]).
    pub const FLAGS: &'static [&'static str] = &["kd", "grid", "octree", "trbvh", "rayquery"];

    /// Applies `spec` (a preset and/or KEY=VALUE pairs) to the parameters that
    /// `--<flag>` sets, on top of their current values.
    pub fn set_flag(&mut self, flag: &str, spec: &str) -> Result<(), params::ParamError> {
        use params::Params;
        match flag {
            "kd" => self.kd = self.kd.parse_onto(spec)?,
            "grid" => self.grid = self.grid.parse_onto(spec)?,
            "octree" => self.octree = self.octree.parse_onto(spec)?,
            "trbvh" => self.treelet = self.treelet.parse_onto(spec)?,
            "rayquery" => self.rayquery = self.rayquery.parse_onto(spec)?,
            _ => {
                return Err(params::ParamError {
                    flag: "accel",
                    item: flag.to_string(),
                    what: "no structure takes this flag".into(),
                })
            }
        }
        Ok(())
    }

    /// Applies `spec` to the parameters of `kind`'s builder; an error if it has none.
    pub fn apply(&mut self, kind: AccelKind, spec: &str) -> Result<(), params::ParamError> {
        match kind.param_flag() {
            Some(flag) => self.set_flag(flag, spec),
            None => Err(params::ParamError {
                flag: "accel",
                item: kind.name().to_string(),
                what: "takes no parameters".into(),
            }),
        }
    }
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
