//! The table of structure kinds: one row per [`AccelKind`] holding everything the
//! program knows about the kind (its name and aliases on the command line, its kernel
//! family, what one node visit fetches, whether the device builds it, its parameter
//! flag). Every question about a kind reads its row; nothing else matches on kinds
//! except the builders ([`super::Accel::build_own`]).

use std::fmt;
use std::str::FromStr;

use super::family::KernelFamily;
use super::params::Params;
use super::{bvh, grid, kdtree, octree, rayquery};

/// Which acceleration structure to build and traverse. `render` and `info` pick one
/// with `--accel`, whose default is `auto` (the cost model's pick, [`super::auto`]):
/// a kind has no default of its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum AccelKind {
    /// Every primitive for every ray, after a scene-box test.
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

/// One row of the table: a kind and all that is known about it.
#[derive(Debug)]
pub struct KindRow {
    /// The kind (its row is `KINDS[kind as usize]`).
    pub kind: AccelKind,
    /// Its name on the command line, in statistics and in kernel names.
    pub name: &'static str,
    /// Other names `--accel` takes for it.
    pub aliases: &'static [&'static str],
    /// The kernel family that traverses it (`shaders/accel/<family>.glsl`).
    pub family: KernelFamily,
    /// 16-byte texel fetches of one node (or cell) visit in its kernel, from the GPU
    /// node layout its `to_gpu` writes: the count the `nodes` AOV multiplies by.
    /// `None` for brute force (no nodes) and the driver's structure (not visible).
    pub texels_per_node: Option<u32>,
    /// Whether `--build gpu` builds it ([`super::bvh::gpu_build`]).
    pub builds_on_gpu: bool,
    /// The flag of its builder's parameters (`--kd`, `--grid`, ...), if it has any.
    pub param_flag: Option<&'static str>,
}

/// 16-byte texels of a GPU node of `bytes` bytes.
const fn texels(bytes: usize) -> Option<u32> {
    Some((bytes / 16) as u32)
}

/// The table, in the order of the enum (checked below) and of the command line.
pub const KINDS: [KindRow; 12] = [
    KindRow {
        kind: AccelKind::None,
        name: "none",
        aliases: &["brute-force"],
        family: KernelFamily::None,
        texels_per_node: None,
        builds_on_gpu: false,
        param_flag: None,
    },
    KindRow {
        kind: AccelKind::Kdtree,
        name: "kdtree",
        aliases: &["kd"],
        family: KernelFamily::Kdtree,
        texels_per_node: Some(kdtree::NODE_TEXELS),
        builds_on_gpu: false,
        param_flag: Some(kdtree::KdParams::FLAG),
    },
    KindRow {
        kind: AccelKind::BspCourse,
        name: "bsp-course",
        aliases: &[],
        family: KernelFamily::Kdtree,
        texels_per_node: Some(kdtree::NODE_TEXELS),
        builds_on_gpu: false,
        param_flag: None,
    },
    KindRow {
        kind: AccelKind::BvhSah,
        name: "bvh-sah",
        aliases: &["bvh"],
        family: KernelFamily::Bvh,
        texels_per_node: texels(std::mem::size_of::<bvh::GpuBvhNode>()),
        builds_on_gpu: false,
        param_flag: None,
    },
    KindRow {
        kind: AccelKind::Lbvh,
        name: "lbvh",
        aliases: &[],
        family: KernelFamily::Bvh,
        texels_per_node: texels(std::mem::size_of::<bvh::GpuBvhNode>()),
        builds_on_gpu: true,
        param_flag: None,
    },
    KindRow {
        kind: AccelKind::Trbvh,
        name: "trbvh",
        aliases: &[],
        family: KernelFamily::Bvh,
        texels_per_node: texels(std::mem::size_of::<bvh::GpuBvhNode>()),
        builds_on_gpu: true,
        param_flag: Some(bvh::treelet::TreeletParams::FLAG),
    },
    KindRow {
        kind: AccelKind::Bvh4,
        name: "bvh4",
        aliases: &[],
        family: KernelFamily::Bvh4,
        texels_per_node: Some(bvh::wide::Bvh4::TEXELS as u32),
        builds_on_gpu: true,
        param_flag: None,
    },
    KindRow {
        kind: AccelKind::Bvh8,
        name: "bvh8",
        aliases: &[],
        family: KernelFamily::Bvh8,
        texels_per_node: Some(bvh::wide::Bvh8::TEXELS as u32),
        builds_on_gpu: true,
        param_flag: None,
    },
    KindRow {
        kind: AccelKind::Cwbvh,
        name: "cwbvh",
        aliases: &[],
        family: KernelFamily::Cwbvh,
        texels_per_node: texels(std::mem::size_of::<bvh::cwbvh::GpuCwbvhNode>()),
        builds_on_gpu: false,
        param_flag: None,
    },
    KindRow {
        kind: AccelKind::Grid,
        name: "grid",
        aliases: &[],
        family: KernelFamily::Grid,
        texels_per_node: Some(grid::CELL_TEXELS),
        builds_on_gpu: false,
        param_flag: Some(grid::GridParams::FLAG),
    },
    KindRow {
        kind: AccelKind::Octree,
        name: "octree",
        aliases: &[],
        family: KernelFamily::Octree,
        texels_per_node: Some(octree::NODE_TEXELS),
        builds_on_gpu: false,
        param_flag: Some(octree::OctreeParams::FLAG),
    },
    KindRow {
        kind: AccelKind::RayQuery,
        name: "rayquery",
        aliases: &["ray-query"],
        family: KernelFamily::RayQuery,
        texels_per_node: None,
        builds_on_gpu: false,
        param_flag: Some(rayquery::RayQueryParams::FLAG),
    },
];

// Row k is kind k, so `row` is an index.
const _: () = {
    let mut k = 0;
    while k < KINDS.len() {
        assert!(KINDS[k].kind as usize == k);
        k += 1;
    }
};

/// Every kind `--accel` takes, in table order: arbor's own, then the driver's.
const EVERY: [AccelKind; KINDS.len()] = {
    let mut all = [AccelKind::None; KINDS.len()];
    let mut k = 0;
    while k < KINDS.len() {
        all[k] = KINDS[k].kind;
        k += 1;
    }
    all
};

impl AccelKind {
    /// arbor's own structures, in CLI order: every kind but [`AccelKind::RayQuery`],
    /// which exists only on devices with ray queries (see [`AccelKind::EVERY`]).
    pub const ALL: &'static [AccelKind] = EVERY.split_at(EVERY.len() - 1).0;

    /// Every kind `--accel` takes: arbor's own, then the driver's.
    pub const EVERY: &'static [AccelKind] = &EVERY;

    /// The structure CPU reference images are traced with: exact like every structure,
    /// and the quickest to build with a good tree.
    pub const CPU_REFERENCE: AccelKind = AccelKind::BvhSah;

    /// This kind's row of the table.
    pub const fn row(self) -> &'static KindRow {
        &KINDS[self as usize]
    }

    /// The CLI / kernel name.
    pub fn name(self) -> &'static str {
        self.row().name
    }

    /// See [`KindRow::texels_per_node`].
    pub fn texels_per_node(self) -> Option<u32> {
        self.row().texels_per_node
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

    /// Whether this is brute force, the baseline every structure is measured against.
    pub fn is_brute_force(self) -> bool {
        self == AccelKind::None
    }

    /// Whether `--build gpu` builds this kind.
    pub fn builds_on_gpu(self) -> bool {
        self.row().builds_on_gpu
    }

    /// The flag of this kind's builder parameters, if it has any.
    pub fn param_flag(self) -> Option<&'static str> {
        self.row().param_flag
    }

    /// The kernel family that traverses this kind.
    pub fn kernel(self) -> KernelFamily {
        self.row().family
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
        KINDS.iter().find(|r| r.name == s || r.aliases.contains(&s)).map(|r| r.kind).ok_or_else(|| {
            format!(
                "unknown structure '{s}'; available: {}",
                KINDS.iter().map(|r| r.name).collect::<Vec<_>>().join(", ")
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_and_alias_parses_to_its_kind() {
        // The spellings the command line has always taken.
        let spellings = [
            ("none", AccelKind::None),
            ("brute-force", AccelKind::None),
            ("kdtree", AccelKind::Kdtree),
            ("kd", AccelKind::Kdtree),
            ("bsp-course", AccelKind::BspCourse),
            ("bvh-sah", AccelKind::BvhSah),
            ("bvh", AccelKind::BvhSah),
            ("lbvh", AccelKind::Lbvh),
            ("trbvh", AccelKind::Trbvh),
            ("bvh4", AccelKind::Bvh4),
            ("bvh8", AccelKind::Bvh8),
            ("cwbvh", AccelKind::Cwbvh),
            ("grid", AccelKind::Grid),
            ("octree", AccelKind::Octree),
            ("rayquery", AccelKind::RayQuery),
            ("ray-query", AccelKind::RayQuery),
        ];
        for (s, kind) in spellings {
            assert_eq!(s.parse::<AccelKind>(), Ok(kind), "{s}");
        }
        let names: Vec<_> = AccelKind::EVERY.iter().map(|k| k.to_string()).collect();
        assert_eq!(names.join(" "), "none kdtree bsp-course bvh-sah lbvh trbvh bvh4 bvh8 cwbvh grid octree rayquery");
        let flags: Vec<_> = AccelKind::EVERY.iter().filter_map(|k| k.param_flag().map(|f| (k.name(), f))).collect();
        assert_eq!(
            flags,
            [("kdtree", "kd"), ("trbvh", "trbvh"), ("grid", "grid"), ("octree", "octree"), ("rayquery", "rayquery")]
        );
        let gpu: Vec<_> = AccelKind::EVERY.iter().filter(|k| k.builds_on_gpu()).map(|k| k.name()).collect();
        assert_eq!(gpu, ["lbvh", "trbvh", "bvh4", "bvh8"]);
        assert!("kd-tree".parse::<AccelKind>().unwrap_err().contains("available: none, kdtree"));
    }

    #[test]
    fn node_strides_are_the_kernels() {
        // What the shaders read a node as (shaders/accel/*.glsl).
        let texels: Vec<_> = KINDS.iter().map(|r| (r.name, r.texels_per_node)).collect();
        assert_eq!(
            texels,
            [
                ("none", None),
                ("kdtree", Some(1)),
                ("bsp-course", Some(1)),
                ("bvh-sah", Some(4)),
                ("lbvh", Some(4)),
                ("trbvh", Some(4)),
                ("bvh4", Some(7)),
                ("bvh8", Some(14)),
                ("cwbvh", Some(6)),
                ("grid", Some(2)),
                ("octree", Some(1)),
                ("rayquery", None)
            ]
        );
    }
}
