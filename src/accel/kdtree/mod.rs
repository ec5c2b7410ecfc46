//! Axis-aligned BSP tree (kd-tree): the SAH builder of Wald & Havran (2006), the
//! lecture's simple builder (`bsp-course`) as a baseline, one compact node layout,
//! and the CPU traversal used as the test oracle.
//!
//! # Node layout (8 bytes, `[u32; 2]`, also read by shaders/accel/kdtree.glsl)
//!
//! ```text
//! word 0: inner: split position (f32 bits)      leaf: number of primitives
//! word 1: bits 0..2  axis 0 = x, 1 = y, 2 = z, 3 = leaf
//!         bits 2..32 inner: index of the above (right) child; the below (left)
//!                    child is always the next node (index + 1)
//!                    leaf: first entry in the primitive-index array
//! ```
//!
//! Worked example: an inner node splitting y at 0.5 whose above child is node 7 is
//! `[0x3f000000, (7 << 2) | 1] = [0x3f000000, 0x1d]`; a leaf with 3 primitives
//! starting at index-array entry 40 is `[3, (40 << 2) | 3] = [3, 0xa3]`.

pub mod course;
mod sah_build;

pub use sah_build::{REF_BUDGET_EXTRA, REF_BUDGET_PER_PRIM};

use crate::accel::validate::ValidateError;
use crate::accel::{AccelKind, LeafTally};
use std::time::Instant;

use glam::Vec3;

use super::params::{number, Key, Preset};
use super::prim;
use super::prim::{intersect_prim, Prims};
use super::sah::{self, SahCosts};
use super::BuildStats;
use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

/// 16-byte texel fetches of one node visit in shaders/accel/kdtree.glsl: an 8-byte
/// node is half a texel (`node_pair`), one fetch.
pub const NODE_TEXELS: u32 = 1;

/// Deepest tree the GPU kernel accepts (its stack has one entry per level).
pub const MAX_KD_DEPTH: u32 = 64;

/// Parameters of the SAH kd-tree builder.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct KdParams {
    /// SAH cost constants.
    pub costs: SahCosts,
    /// Clip straddling triangles to the child boxes ("perfect splits"); when off,
    /// their bounding boxes are clipped instead.
    pub perfect_splits: bool,
    /// Nodes with at most this many primitives become leaves without evaluating splits.
    pub leaf_size: usize,
    /// Maximum depth; None = round(8 + 1.3 log2 N), capped at [`MAX_KD_DEPTH`].
    pub max_depth: Option<u32>,
}

impl Default for KdParams {
    /// The balanced preset: perfect splits, Kt = 1, Ki = 1.5, empty bonus 0.8, and
    /// nodes of up to 8 primitives kept as leaves. Measured on lavapipe (75k
    /// triangles) it traces as fast as `quality()` within the noise, builds about twice
    /// as fast and takes a third of the memory (28 against 96 bytes per triangle).
    fn default() -> Self {
        KdParams { costs: SahCosts::default(), perfect_splits: true, leaf_size: 8, max_depth: None }
    }
}

impl KdParams {
    /// Lowest SAH cost: every node with more than one primitive tries to split.
    pub fn quality() -> Self {
        KdParams { leaf_size: 1, ..Self::default() }
    }

    /// Faster build: split candidates from bounding boxes only (no clipping).
    pub fn fast() -> Self {
        KdParams { perfect_splits: false, ..Self::default() }
    }

    /// The depth limit for `n` primitives.
    pub fn depth_limit(&self, n: usize) -> u32 {
        let auto = (8.0 + 1.3 * (n.max(1) as f64).log2()).round() as u32;
        self.max_depth.unwrap_or(auto).min(MAX_KD_DEPTH)
    }
}

/// `--kd`: presets `default`, `quality`, `fast`; keys `kt`, `ki` (SAH traversal and
/// intersection cost), `bonus` (empty-space factor), `leaf` (most primitives a node
/// keeps without trying to split), `perfect` (true/false), `depth` (auto or a number).
impl super::params::Params for KdParams {
    const FLAG: &'static str = "kd";
    const PRESETS: &'static [Preset<Self>] =
        &[("default", KdParams::default), ("quality", KdParams::quality), ("fast", KdParams::fast)];
    const KEYS: &'static [Key<Self>] = &[
        Key {
            name: "kt",
            expects: "a non-negative number",
            set: |p, v| {
                p.costs.traversal = cost(v)?;
                Some(())
            },
        },
        Key {
            name: "ki",
            expects: "a non-negative number",
            set: |p, v| {
                p.costs.intersect = cost(v)?;
                Some(())
            },
        },
        Key {
            name: "bonus",
            expects: "a non-negative number",
            set: |p, v| {
                p.costs.empty_bonus = cost(v)?;
                Some(())
            },
        },
        Key {
            name: "leaf",
            expects: "0..=1048576",
            set: |p, v| {
                p.leaf_size = number(v, 0, 1 << 20)?;
                Some(())
            },
        },
        Key {
            name: "perfect",
            expects: "true or false",
            set: |p, v| {
                p.perfect_splits = v.parse().ok()?;
                Some(())
            },
        },
        Key {
            name: "depth",
            expects: "auto or 0..=64",
            set: |p, v| {
                p.max_depth = if v == "auto" { None } else { Some(number(v, 0, MAX_KD_DEPTH)?) };
                Some(())
            },
        },
    ];
}

/// An SAH cost constant: finite and non-negative.
fn cost(v: &str) -> Option<f32> {
    number(v, 0.0, f32::MAX)
}

/// The tree as builders produce it, before flattening.
#[derive(Debug)]
pub(crate) enum BuildNode {
    Leaf(Vec<u32>),
    Inner { axis: usize, split: f32, below: Box<BuildNode>, above: Box<BuildNode> },
}

/// `b` shrunk by a relative 1e-5 of its extent and at least 8 ulps of its coordinates,
/// so that a primitive merely touching a face does not count as overlapping.
pub(crate) fn shrink(b: &Aabb) -> Aabb {
    let mag = b.min.abs().max(b.max.abs());
    let pad = (b.extent() * 1e-5).max(mag * 1e-6).max(Vec3::splat(1e-30));
    Aabb { min: b.min + pad, max: b.max - pad }
}

/// Relative margin of traversal's comparisons against cell boundaries: about 80 ulps, so
/// that primitive tests whose own t rounds differently (Moller-Trumbore far from the
/// origin) still see every cell a hit could lie in.
pub const T_MARGIN: f32 = 1e-5;

/// `a` lies before `b` by more than the margin (both are ray distances, b >= 0).
/// Twin of `before` in shaders/accel/kdtree.glsl.
#[inline]
pub fn before(a: f32, b: f32) -> bool {
    a * (1.0 + T_MARGIN) < b
}

/// Which builder made a tree.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KdBuilder {
    Sah,
    Course,
}

/// A built kd-tree in its GPU layout.
#[derive(Debug, Clone)]
pub struct KdTree {
    pub bounds: Aabb,
    /// 8-byte nodes, see the module doc.
    pub nodes: Vec<[u32; 2]>,
    /// Primitive indices referenced by leaves.
    pub indices: Vec<u32>,
    /// Depth of the deepest leaf (root = 0).
    pub depth: u32,
    pub prims: usize,
    build_ms: f64,
    /// Build phases: events, event sort, SAH splits, flatten (the course builder: its
    /// build, then flatten).
    phases: Vec<super::Phase>,
    builder: KdBuilder,
}

const LEAF: u32 = 3;

impl KdTree {
    /// Builds the SAH tree of Wald & Havran (2006).
    pub fn build(scene: &Scene, params: &KdParams) -> KdTree {
        let start = Instant::now();
        let bounds = scene.bounds();
        let mut phases = Vec::new();
        let root = sah_build::build(scene, params, &bounds, &mut phases);
        Self::flatten(root, bounds, scene.prim_count(), (start, phases), KdBuilder::Sah)
    }

    /// Builds the lecture's tree (`bsp-course`).
    pub fn build_course(scene: &Scene) -> KdTree {
        let start = Instant::now();
        let bounds = scene.bounds();
        let root = course::build(scene, &bounds);
        let phases = vec![super::Phase::since("build", start)];
        Self::flatten(root, bounds, scene.prim_count(), (start, phases), KdBuilder::Course)
    }

    fn flatten(
        root: BuildNode,
        bounds: Aabb,
        prims: usize,
        (start, phases): (Instant, Vec<super::Phase>),
        builder: KdBuilder,
    ) -> KdTree {
        let flat = Instant::now();
        let mut t =
            KdTree { bounds, nodes: Vec::new(), indices: Vec::new(), depth: 0, prims, build_ms: 0.0, phases, builder };
        // Iterative pre-order: below child right after its parent.
        let mut stack: Vec<(BuildNode, Option<usize>, u32)> = vec![(root, None, 0)];
        while let Some((node, parent_slot, depth)) = stack.pop() {
            let me = t.nodes.len();
            if let Some(p) = parent_slot {
                t.nodes[p][1] = ((me as u32) << 2) | (t.nodes[p][1] & 3);
            }
            t.depth = t.depth.max(depth);
            match node {
                BuildNode::Leaf(list) => {
                    t.nodes.push([list.len() as u32, ((t.indices.len() as u32) << 2) | LEAF]);
                    t.indices.extend(list);
                }
                BuildNode::Inner { axis, split, below, above } => {
                    t.nodes.push([split.to_bits(), axis as u32]);
                    // Above is patched in when it is emitted; below must come next.
                    stack.push((*above, Some(me), depth + 1));
                    stack.push((*below, None, depth + 1));
                }
            }
        }
        t.phases.push(super::Phase::since("flatten", flat));
        t.build_ms = start.elapsed().as_secs_f64() * 1e3;
        t
    }

    /// Bytes of nodes and indices as uploaded.
    pub fn bytes(&self) -> u64 {
        (self.nodes.len() * 8 + self.indices.len() * 4) as u64
    }

    /// Walks the tree with explicit node boxes: calls `f(box, node, depth)` for every node.
    fn walk(&self, mut f: impl FnMut(&Aabb, usize, u32)) {
        let mut stack = vec![(0usize, self.bounds, 0u32)];
        while let Some((n, b, d)) = stack.pop() {
            f(&b, n, d);
            let [w0, w1] = self.nodes[n];
            if w1 & 3 != LEAF {
                let axis = (w1 & 3) as usize;
                let split = f32::from_bits(w0);
                let (mut lo, mut hi) = (b, b);
                lo.max[axis] = split;
                hi.min[axis] = split;
                stack.push((n + 1, lo, d + 1));
                stack.push(((w1 >> 2) as usize, hi, d + 1));
            }
        }
    }

    /// Build time and phases (what [`Self::stats`] reports of them, without the rest).
    pub fn timing(&self) -> (f64, Vec<super::Phase>) {
        (self.build_ms, self.phases.clone())
    }

    /// Statistics for `arbor info` and the stats JSON.
    pub fn stats(&self) -> BuildStats {
        let root_area = sah::area(&self.bounds).max(f32::MIN_POSITIVE);
        let costs = SahCosts::default();
        let mut tally = LeafTally::default();
        self.walk(|b, n, d| {
            let [w0, w1] = self.nodes[n];
            let p = f64::from(sah::area(b) / root_area);
            if w1 & 3 == LEAF {
                tally.leaf(d, u64::from(w0), p * f64::from(costs.intersect) * f64::from(w0));
            } else {
                tally.inner(p * f64::from(costs.traversal));
            }
        });
        let kind = match self.builder {
            KdBuilder::Sah => AccelKind::Kdtree,
            KdBuilder::Course => AccelKind::BspCourse,
        };
        BuildStats {
            build_ms: self.build_ms,
            phases: self.phases.clone(),
            ..tally.stats(kind.name(), self.nodes.len() as u64, self.depth, self.bytes(), self.prims)
        }
    }

    /// Checks the invariants: split planes inside their node boxes, links in range,
    /// depth within the kernel's limit, every index valid, and every primitive present
    /// in every leaf whose box its geometry overlaps (tested by clipping it to the leaf
    /// box shrunk by a relative 1e-5, so touching a face does not count).
    pub fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        if self.depth > MAX_KD_DEPTH {
            return Err(ValidateError::whole(format!("depth {} exceeds {MAX_KD_DEPTH}", self.depth)));
        }
        let n = self.nodes.len();
        let mut errors = Vec::new();
        let mut leaves = Vec::new();
        self.walk(|b, i, _| {
            let [w0, w1] = self.nodes[i];
            if w1 & 3 == LEAF {
                let (first, count) = ((w1 >> 2) as usize, w0 as usize);
                if first + count > self.indices.len() {
                    errors.push(ValidateError::node(i, "leaf indexes past the index array"));
                    return;
                }
                leaves.push((i, &self.indices[first..first + count]));
            } else {
                let axis = (w1 & 3) as usize;
                let split = f32::from_bits(w0);
                if !(split >= b.min[axis] && split <= b.max[axis]) {
                    errors.push(ValidateError::node(
                        i,
                        format!("split {split} on axis {axis} outside [{}, {}]", b.min[axis], b.max[axis]),
                    ));
                }
                if (w1 >> 2) as usize >= n || i + 1 >= n {
                    errors.push(ValidateError::node(i, "child out of range"));
                }
            }
        });
        if let Some(e) = errors.first() {
            return Err(e.clone());
        }
        let np = scene.prim_count() as u32;
        for (i, list) in &leaves {
            if let Some(bad) = list.iter().find(|&&p| p >= np) {
                return Err(ValidateError::node(*i, format!("leaf references primitive {bad} of {np}")));
            }
            if list.windows(2).any(|w| w[0] >= w[1]) {
                return Err(ValidateError::node(*i, "leaf primitive list not strictly ascending"));
            }
        }
        // Per primitive: descend into every child its geometry reaches and check it is
        // listed in every leaf whose (slightly shrunk) box it overlaps.
        use rayon::prelude::*;
        let missing = (0..np).into_par_iter().find_map_first(|p| {
            let g = prim::geom(scene, p);
            let mut stack = vec![(0usize, self.bounds)];
            while let Some((n, b)) = stack.pop() {
                let [w0, w1] = self.nodes[n];
                if w1 & 3 == LEAF {
                    let inner = shrink(&b);
                    if inner.is_empty() || prim::clipped_bounds(&g, &inner, true).is_none() {
                        continue;
                    }
                    let first = (w1 >> 2) as usize;
                    if self.indices[first..first + w0 as usize].binary_search(&p).is_err() {
                        return Some(ValidateError::prim(p, format!("overlaps leaf {n} ({b:?}) but is not in it")));
                    }
                    continue;
                }
                let axis = (w1 & 3) as usize;
                let split = f32::from_bits(w0);
                let (mut lo, mut hi) = (b, b);
                lo.max[axis] = split;
                hi.min[axis] = split;
                if prim::clipped_bounds(&g, &lo, true).is_some() {
                    stack.push((n + 1, lo));
                }
                if prim::clipped_bounds(&g, &hi, true).is_some() {
                    stack.push(((w1 >> 2) as usize, hi));
                }
            }
            None
        });
        match missing {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// Front-to-back traversal with a (node, tmin, tmax) stack; stops as soon as every
    /// remaining cell starts after the best hit. Returns whether it hit.
    ///
    /// Cell boundaries come from `(split - o) * inv`, rounded differently from the
    /// primitive tests' t, so every comparison against a boundary keeps a relative
    /// margin of [`T_MARGIN`]: a hit within it of a boundary visits both sides, which
    /// makes ties at shared edges resolve exactly as brute force does.
    fn traverse_impl(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        let inv = Aabb::inv_dir(ray.dir);
        let Some((mut tmin, mut tmax)) = self.bounds.ray_box(ray.origin, inv, ray.tmin, ray.tmax) else {
            return false;
        };
        let o = ray.origin.to_array();
        let d = ray.dir.to_array();
        let iv = inv.to_array();
        // (node, tmax, in_plane): the next cell starts where the last one ended, so its
        // tmin is the current tmax, except after a ray inside a split plane, whose
        // sibling restarts at the ray's entry (see shaders/accel/kdtree.glsl).
        let t_entry = tmin;
        let mut stack: Vec<(usize, f32, bool)> = Vec::with_capacity(self.depth as usize + 1);
        let mut node = 0usize;
        let mut found = false;
        loop {
            let [w0, w1] = self.nodes[node];
            if w1 & 3 == LEAF {
                let first = (w1 >> 2) as usize;
                for &p in &self.indices[first..first + w0 as usize] {
                    if intersect_prim(prims, p, ray, best) {
                        found = true;
                        if any {
                            return true;
                        }
                    }
                }
                // Next cell: pop until one may still hold a hit before the best. (No
                // early return on the current cell's tmax: a ray lying in a split plane
                // pushes a sibling with the same interval.)
                loop {
                    let Some((n, b, in_plane)) = stack.pop() else { return found };
                    let next_min = if in_plane { t_entry } else { tmax };
                    tmax = b;
                    if !(found && before(best.t, next_min)) {
                        (node, tmin) = (n, next_min);
                        break;
                    }
                }
                continue;
            }
            let axis = (w1 & 3) as usize;
            let split = f32::from_bits(w0);
            let above = (w1 >> 2) as usize;
            let below_first = o[axis] < split || (o[axis] == split && d[axis] <= 0.0);
            let (first, second) = if below_first { (node + 1, above) } else { (above, node + 1) };
            if o[axis] == split && d[axis] == 0.0 {
                // The ray runs inside the plane: both sides, same interval.
                stack.push((second, tmax, true));
                node = first;
                continue;
            }
            let tplane = (split - o[axis]) * iv[axis];
            if before(tmax, tplane) || tplane <= 0.0 {
                node = first;
            } else if before(tplane, tmin) {
                node = second;
            } else {
                stack.push((second, tmax, false));
                node = first;
                tmax = tplane;
            }
        }
    }

    /// Node and index arrays as the kernel reads them.
    pub fn to_gpu(&self) -> (&[[u32; 2]], &[u32]) {
        (&self.nodes, &self.indices)
    }
}

impl super::Traverse for KdTree {
    fn traverse(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        self.traverse_impl(prims, ray, best, any)
    }
}

impl super::Structure for KdTree {
    fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        KdTree::validate(self, scene)
    }
    fn stats(&self, _scene: &Scene) -> BuildStats {
        KdTree::stats(self)
    }
    fn timing(&self) -> (f64, Vec<super::Phase>) {
        KdTree::timing(self)
    }
    fn bounds(&self) -> crate::math::Aabb {
        self.bounds
    }
    fn gpu_image(&self, _scene: &Scene) -> Result<super::GpuImage<'_>, ValidateError> {
        if self.depth > MAX_KD_DEPTH {
            return Err(ValidateError::whole(format!(
                "kd-tree depth {} exceeds the kernel's stack of {MAX_KD_DEPTH}",
                self.depth
            )));
        }
        let (nodes, indices) = self.to_gpu();
        Ok(super::GpuImage {
            family: super::KernelFamily::Kdtree,
            buffers: Some(crate::accel::AccelBuffers::Host(
                std::borrow::Cow::Borrowed(bytemuck::cast_slice(nodes)),
                indices,
            )),
            stack_size: self.depth + 1,
            // A few steps per level: about one step per level plus a few tests.
            cost_per_ray: 4 * (u64::from(self.depth) + 8),
            trace_loop: super::TraceLoop::StepBudget,
            ray_structure: None,
            resume_words: super::resume_words(1, self.depth + 1),
        })
    }
}
