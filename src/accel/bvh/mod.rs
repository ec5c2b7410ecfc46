//! Bounding volume hierarchies: one canonical binary tree ([`Binary`]) that every
//! builder produces, and one flattener that turns it into the GPU layout ([`Bvh`]).
//!
//! Builders see only primitive bounds and centroids ([`PrimRefs`]); triangles and
//! spheres are both primitives.
//!
//! - `bvh-sah` ([`binned`]): top-down binned SAH after Wald (2007).
//! - `lbvh` ([`lbvh`]): Morton codes and the radix tree of Karras (2012).
//! - `trbvh` ([`treelet`]): LBVH, then treelet restructuring after Karras & Aila
//!   (2013), then collapse of subtrees into leaves where the SAH prefers it.
//!
//! `bvh4` ([`wide`]) collapses the `bvh-sah` tree into 4-wide nodes; `cwbvh` ([`cwbvh`])
//! into 8-wide nodes with quantised child boxes.
//!
//! GPU layout: 64 bytes per inner node, holding both children's boxes so one fetch
//! decides which children a ray enters and in which order. Leaves are not nodes but
//! child references into the primitive-index array:
//!
//! ```text
//! uvec4 0: left box min xyz (f32 bits),  w = left child reference
//! uvec4 1: left box max xyz,             w = right child reference
//! uvec4 2: right box min xyz,            w = 0
//! uvec4 3: right box max xyz,            w = 0
//! child reference: bit 31 clear        -> inner node index
//!                  bit 31 set          -> leaf: bits 3..31 first index, bits 0..3 count - 1
//!                  0xffffffff          -> no child (empty scene, or a one-leaf root)
//! ```
//!
//! The leaf's fields and a worked example: `BVH_LEAF_COUNT_BITS` in src/gpu/bindings.rs
//! ([`leaf_ref`] encodes, [`leaf_range`] decodes).

use crate::accel::validate::ValidateError;
use crate::accel::LeafTally;
use std::time::Instant;

use glam::Vec3;

use super::prim::{self, Prims};
use super::sah::{self, SahCosts};
use super::{BuildStats, Phase};
use crate::gpu::bindings::{BVH_LEAF_COUNT_BITS, BVH_LEAF_COUNT_MASK, BVH_MAX_LEAF};
use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

pub mod binned;
pub mod cwbvh;
pub mod device;
mod flatten;
pub mod gpu_build;
pub mod lbvh;
pub mod treelet;
pub mod wide;

/// Most primitives in one leaf (`BVH_LEAF_COUNT_BITS` bits of the child reference).
pub const MAX_LEAF: usize = BVH_MAX_LEAF as usize;
/// Deepest tree (inner nodes on a path) the kernel's stack is allowed to hold.
pub const MAX_BVH_DEPTH: u32 = 128;
/// Most primitives a BVH can index (the 28 bits of the child reference between the
/// count and the leaf flag).
pub const MAX_BVH_PRIMS: usize = 1 << (31 - BVH_LEAF_COUNT_BITS);
/// Child reference flag: a leaf.
pub const LEAF_REF: u32 = crate::gpu::bindings::BVH_LEAF_REF;
/// Child reference of a missing child.
pub const EMPTY_REF: u32 = crate::gpu::bindings::BVH_EMPTY_REF;
/// Relative margin of the box test against the best hit so far: a box entered within
/// it of the best t is still visited, so ties at equal t resolve as brute force does
/// (the same margin as the kd-tree's, see `kdtree::T_MARGIN`).
pub const T_MARGIN: f32 = super::kdtree::T_MARGIN;

/// One inner node as the kernel reads it (see the module docs).
pub type GpuBvhNode = [[u32; 4]; 4];

/// Which builder made a tree.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BvhBuilder {
    Sah,
    Lbvh,
    Trbvh,
}

impl BvhBuilder {
    pub fn name(self) -> &'static str {
        match self {
            BvhBuilder::Sah => "bvh-sah",
            BvhBuilder::Lbvh => "lbvh",
            BvhBuilder::Trbvh => "trbvh",
        }
    }
}

/// What builders see of the primitives: bounds and centroids, indexed like the
/// scene's primitives (triangles first, then spheres).
#[derive(Debug, Clone)]
pub struct PrimRefs {
    pub bounds: Vec<Aabb>,
    pub centroids: Vec<Vec3>,
}

impl PrimRefs {
    pub fn new(scene: &Scene) -> PrimRefs {
        use rayon::prelude::*;
        let n = scene.prim_count() as u32;
        let (mut bounds, mut centroids) = (Vec::new(), Vec::new());
        (0..n)
            .into_par_iter()
            .map(|i| {
                let b = prim::bounds(&prim::geom(scene, i));
                (b, (b.min + b.max) * 0.5)
            })
            .unzip_into_vecs(&mut bounds, &mut centroids);
        PrimRefs { bounds, centroids }
    }

    /// The union of every primitive's box: the scene's box ([`Scene::bounds`], the
    /// same bits, one sign of zero), from the boxes already made instead of the
    /// triangles' vertices again (5.2–5.4 against 8.0–8.4 ms at a million triangles).
    pub fn scene_box(&self) -> Aabb {
        use rayon::prelude::*;
        let b =
            self.bounds.par_iter().fold(|| Aabb::EMPTY, |a, b| a.union(b)).reduce(|| Aabb::EMPTY, |a, b| a.union(&b));
        Aabb { min: b.min + Vec3::ZERO, max: b.max + Vec3::ZERO }
    }

    pub fn len(&self) -> usize {
        self.bounds.len()
    }

    pub fn is_empty(&self) -> bool {
        self.bounds.is_empty()
    }

    /// Union of the bounds of `prims`.
    pub fn union(&self, prims: &[u32]) -> Aabb {
        prims.iter().fold(Aabb::EMPTY, |b, &p| b.union(&self.bounds[p as usize]))
    }
}

/// Flag of [`BNode::left`] marking a leaf.
pub const LEAF_FLAG: u32 = crate::gpu::bindings::BUILD_LEAF_FLAG;

/// A node of the canonical binary BVH. Inner: `left`, `right` are node indices.
/// Leaf: `left` = `LEAF_FLAG | first`, `right` = count, a range of [`Binary::prims`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BNode {
    pub bounds: Aabb,
    pub left: u32,
    pub right: u32,
}

impl BNode {
    pub fn leaf(bounds: Aabb, first: u32, count: u32) -> BNode {
        BNode { bounds, left: LEAF_FLAG | first, right: count }
    }
    pub fn is_leaf(&self) -> bool {
        self.left & LEAF_FLAG != 0
    }
    /// The primitive range of a leaf.
    pub fn range(&self) -> std::ops::Range<usize> {
        let first = (self.left & !LEAF_FLAG) as usize;
        first..first + self.right as usize
    }
}

/// The canonical binary BVH: nodes in any order, a root, and the primitive order
/// leaves index into.
#[derive(Debug, Clone)]
pub struct Binary {
    pub nodes: Vec<BNode>,
    pub root: u32,
    pub prims: Vec<u32>,
}

impl Binary {
    /// The tree of no primitives: one empty leaf.
    pub fn empty() -> Binary {
        Binary { nodes: vec![BNode::leaf(Aabb::EMPTY, 0, 0)], root: 0, prims: Vec::new() }
    }

    /// SAH cost relative to the root's area, with leaves as built (`collapse` false)
    /// or with every subtree of at most [`MAX_LEAF`] primitives turned into a leaf
    /// where that is cheaper (`collapse` true).
    pub fn sah_cost(&self, costs: &SahCosts, collapse: bool) -> f64 {
        let root_area = f64::from(sah::area(&self.nodes[self.root as usize].bounds));
        if root_area <= 0.0 {
            return f64::from(costs.intersect) * self.prims.len() as f64;
        }
        let (c, _) = self.cost_rec(self.root, costs, collapse);
        c / root_area
    }

    fn cost_rec(&self, n: u32, costs: &SahCosts, collapse: bool) -> (f64, usize) {
        let node = &self.nodes[n as usize];
        let a = f64::from(sah::area(&node.bounds));
        if node.is_leaf() {
            return (f64::from(costs.intersect) * a * f64::from(node.right), node.right as usize);
        }
        let (cl, nl) = self.cost_rec(node.left, costs, collapse);
        let (cr, nr) = self.cost_rec(node.right, costs, collapse);
        let split = f64::from(costs.traversal) * a + cl + cr;
        let count = nl + nr;
        if collapse && count <= MAX_LEAF {
            return (split.min(f64::from(costs.intersect) * a * count as f64), count);
        }
        (split, count)
    }

    /// Every primitive in the subtree of `n`, in depth-first order.
    pub fn gather(&self, n: u32, out: &mut Vec<u32>) {
        let mut stack = vec![n];
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i as usize];
            if node.is_leaf() {
                out.extend_from_slice(&self.prims[node.range()]);
            } else {
                stack.push(node.right);
                stack.push(node.left);
            }
        }
    }
}

/// A canonical binary tree as the flattener reads it: a [`Binary`], or the tree being
/// restructured ([`treelet::Restructure`]), flattened where it is without a copy.
pub trait Nodes: Sync {
    /// The root node.
    fn root(&self) -> u32;
    /// Node `n`.
    fn node(&self, n: u32) -> BNode;
    /// The primitive order leaves index into.
    fn prims(&self) -> &[u32];
    /// Whether inner node `n` is flattened as one leaf of its subtree's primitives
    /// (trbvh's collapse, decided where the flattener reads the node).
    fn collapsed(&self, _n: u32) -> bool {
        false
    }
    /// For an inner node the flattener keeps: the nodes and indices it emits for the
    /// subtree (the node included), where the tree knows them without a walk; the
    /// flattener then writes its parts straight into their final place.
    fn emitted(&self, _n: u32) -> Option<(usize, usize)> {
        None
    }
    /// A hint: starts reading the children of inner node `n`, which the flattener
    /// will descend into, so that their cache misses overlap with other work instead
    /// of each level waiting on the one above.
    fn read_ahead(&self, _n: u32) {}

    /// Every primitive in the subtree of `n`, in depth-first order, for a small
    /// subtree (recursive: its depth is below its primitive count, at most
    /// [`MAX_LEAF`] when collapsing).
    fn gather_small(&self, n: u32, out: &mut Vec<u32>) {
        let node = self.node(n);
        if node.is_leaf() {
            out.extend_from_slice(&self.prims()[node.range()]);
        } else {
            self.gather_small(node.left, out);
            self.gather_small(node.right, out);
        }
    }
}

/// The LBVH as the flattener reads it: a [`Binary`] whose leaves hold one primitive
/// each, in key order (leaf j holds `prims[j]`, as [`lbvh::build`] makes it). A
/// subtree over leaves lo..=hi then emits hi - lo inner nodes and hi - lo + 1
/// indices, found from its leftmost and rightmost leaves without a walk.
#[derive(Debug)]
pub struct LbvhNodes<'a>(pub &'a Binary);

impl Nodes for LbvhNodes<'_> {
    fn root(&self) -> u32 {
        self.0.root
    }
    #[inline]
    fn node(&self, n: u32) -> BNode {
        self.0.nodes[n as usize]
    }
    fn prims(&self) -> &[u32] {
        &self.0.prims
    }
    fn emitted(&self, n: u32) -> Option<(usize, usize)> {
        let edge = |left: bool| {
            let mut x = n;
            for _ in 0..self.0.nodes.len() {
                let b = self.0.nodes[x as usize];
                if b.is_leaf() {
                    return Some(b.range());
                }
                x = if left { b.left } else { b.right };
            }
            None
        };
        let (lo, hi) = (edge(true)?.start, edge(false)?.end);
        let count = hi.checked_sub(lo)?;
        Some((count.checked_sub(1)?, count))
    }
}

impl Nodes for Binary {
    fn root(&self) -> u32 {
        self.root
    }
    #[inline]
    fn node(&self, n: u32) -> BNode {
        self.nodes[n as usize]
    }
    fn prims(&self) -> &[u32] {
        &self.prims
    }
}

/// A BVH in the GPU layout, with everything `arbor info` reports.
#[derive(Debug, Clone)]
pub struct Bvh {
    /// The scene box rays are first clipped to.
    pub bounds: Aabb,
    pub nodes: Vec<GpuBvhNode>,
    pub indices: Vec<u32>,
    /// Inner nodes on the longest root-to-leaf path.
    pub depth: u32,
    pub prims: usize,
    pub builder: BvhBuilder,
    pub build_ms: f64,
    pub phases: Vec<Phase>,
}

fn unpack_box(min: [u32; 4], max: [u32; 4]) -> Aabb {
    let v = |a: [u32; 4]| Vec3::new(f32::from_bits(a[0]), f32::from_bits(a[1]), f32::from_bits(a[2]));
    Aabb { min: v(min), max: v(max) }
}

/// Leaf reference of `count` (1..=MAX_LEAF) primitives from index entry `first`.
pub fn leaf_ref(first: u32, count: u32) -> u32 {
    LEAF_REF | (first << BVH_LEAF_COUNT_BITS) | (count - 1)
}

/// Leaf reference → (first index, count).
pub fn leaf_range(r: u32) -> (usize, usize) {
    (((r & !LEAF_REF) >> BVH_LEAF_COUNT_BITS) as usize, (r & BVH_LEAF_COUNT_MASK) as usize + 1)
}

impl Bvh {
    /// Builds with `builder` (default treelet parameters) and flattens.
    pub fn build(scene: &Scene, builder: BvhBuilder) -> Bvh {
        Self::build_with(scene, builder, &treelet::TreeletParams::default())
    }

    /// Builds with `builder` and flattens; `tp` applies to trbvh's restructuring.
    pub fn build_with(scene: &Scene, builder: BvhBuilder, tp: &treelet::TreeletParams) -> Bvh {
        let start = Instant::now();
        let mut phases = Vec::new();
        let mut t = Instant::now();
        let refs = PrimRefs::new(scene);
        lap(&mut phases, "prim bounds", &mut t);
        let costs = SahCosts::default();
        let bounds = refs.scene_box();
        let mut bvh = match builder {
            BvhBuilder::Sah => {
                let bin = binned::build(&refs, &costs);
                lap(&mut phases, "binned SAH", &mut t);
                Bvh::flatten(&bin, &refs, bounds, builder)
            }
            BvhBuilder::Lbvh => {
                Bvh::flatten(&LbvhNodes(&lbvh::build(&refs, &mut phases, &mut t)), &refs, bounds, builder)
            }
            BvhBuilder::Trbvh => {
                // The LBVH goes straight into the restructuring's nodes, which are
                // flattened where they are.
                let mut work = treelet::Restructure::lbvh(&refs, &costs, tp.leaves, &mut phases, &mut t);
                for round in 0..tp.rounds {
                    let rs = work.round(tp.gamma(round));
                    lap(&mut phases, &format!("restructure round {}", round + 1), &mut t);
                    if let Some(p) = phases.last_mut() {
                        p.detail = Some(format!(
                            "{} treelets optimised, {} rewritten, {} skipped as settled",
                            rs.optimised, rs.rewritten, rs.skipped
                        ));
                    }
                }
                // Subtrees cheaper as one leaf are collapsed as the flattener reads them.
                Bvh::flatten(&work, &refs, bounds, builder)
            }
        };
        lap(&mut phases, "flatten", &mut t);
        bvh.phases = phases;
        bvh.build_ms = start.elapsed().as_secs_f64() * 1e3;
        bvh
    }

    /// Turns a canonical tree into the GPU layout. An inner node `bin` says is
    /// collapsed ([`Nodes::collapsed`]) becomes a leaf of its subtree's primitives.
    /// Depth-first order, left child first (see `flatten` for how the work is split
    /// between threads, and when parts are written in place).
    pub fn flatten(bin: &impl Nodes, refs: &PrimRefs, bounds: Aabb, builder: BvhBuilder) -> Bvh {
        let (nodes, indices, depth) = flatten::flatten(bin, refs);
        Bvh { bounds, nodes, indices, depth, prims: refs.len(), builder, build_ms: 0.0, phases: Vec::new() }
    }

    /// Bytes as uploaded.
    pub fn bytes(&self) -> u64 {
        (self.nodes.len() * std::mem::size_of::<GpuBvhNode>() + self.indices.len() * 4) as u64
    }

    /// Children of inner node `n`: (reference, box) for left and right.
    pub fn children(&self, n: usize) -> [(u32, Aabb); 2] {
        let [a, b, c, d] = self.nodes[n];
        [(a[3], unpack_box(a, b)), (b[3], unpack_box(c, d))]
    }

    /// Build time and phases (what [`Self::stats`] reports of them, without the rest).
    pub fn timing(&self) -> (f64, Vec<Phase>) {
        (self.build_ms, self.phases.clone())
    }

    /// Statistics, with the SAH cost computed like every other structure's.
    pub fn stats(&self) -> BuildStats {
        tree_stats(self.builder.name(), self.nodes.len(), |n| self.children(n), self.bytes(), self.depth, self.prims)
            .with_timing(self.build_ms, &self.phases)
    }

    /// Checks: depth within the kernel's limit; references in range; every inner node
    /// reached exactly once; every child box contains its subtree (the boxes of an
    /// inner child, the bounds of a leaf's primitives); every primitive in exactly
    /// one leaf.
    pub fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        validate_tree(scene, self.nodes.len(), &self.indices, self.depth, |n| self.children(n))
    }

    /// Front-to-back traversal with a stack of child references: at each inner node
    /// both child boxes are tested against [tmin, best t (1 + T_MARGIN)], the nearer
    /// hit child is visited first and the other pushed.
    fn traverse_impl(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        self.walk(ray, best, |leaf, best| {
            let mut found = false;
            for &p in leaf {
                if super::prim::intersect_prim(prims, p, ray, best) {
                    found = true;
                    if any {
                        return (true, true);
                    }
                }
            }
            (found, false)
        })
    }

    /// The traversal of `Bvh::traverse_impl` with what a leaf does left to `leaf`:
    /// it gets the leaf's indices and the best hit so far (whose t bounds the boxes
    /// entered after it) and says (whether it hit, whether to stop). Returns whether
    /// any leaf hit. The top level of instanced scenes walks its entries with it.
    pub fn walk(&self, ray: &Ray, best: &mut Hit, mut leaf: impl FnMut(&[u32], &mut Hit) -> (bool, bool)) -> bool {
        let inv = Aabb::inv_dir(ray.dir);
        if self.bounds.ray_box(ray.origin, inv, ray.tmin, ray.tmax).is_none() {
            return false;
        }
        let mut stack: Vec<u32> = Vec::with_capacity(self.depth as usize + 1);
        let mut cur = 0u32;
        let mut found = false;
        loop {
            while cur & LEAF_REF == 0 {
                let [(lr, lb), (rr, rb)] = self.children(cur as usize);
                let limit = best.t * (1.0 + T_MARGIN);
                let hl = if lr == EMPTY_REF { None } else { lb.ray_box(ray.origin, inv, ray.tmin, limit) };
                let hr = if rr == EMPTY_REF { None } else { rb.ray_box(ray.origin, inv, ray.tmin, limit) };
                match (hl, hr) {
                    (Some((l0, _)), Some((r0, _))) => {
                        let (near, far) = if l0 <= r0 { (lr, rr) } else { (rr, lr) };
                        stack.push(far);
                        cur = near;
                    }
                    (Some(_), None) => cur = lr,
                    (None, Some(_)) => cur = rr,
                    (None, None) => match stack.pop() {
                        Some(c) => cur = c,
                        None => return found,
                    },
                }
            }
            let (first, count) = leaf_range(cur);
            let (hit, stop) = leaf(&self.indices[first..first + count], best);
            found |= hit;
            if stop {
                return found;
            }
            match stack.pop() {
                Some(c) => cur = c,
                None => return found,
            }
        }
    }

    /// Nodes and indices as the kernel reads them.
    pub fn to_gpu(&self) -> (&[GpuBvhNode], &[u32]) {
        (&self.nodes, &self.indices)
    }
}

fn contains(outer: &Aabb, inner: &Aabb) -> bool {
    inner.min.cmpge(outer.min).all() && inner.max.cmple(outer.max).all()
}

/// Visits every child reference of a BVH of either layout, whose node `n` has the
/// children `children(n)` (empty slots included): `f(reference, box, depth of its
/// parent)`.
fn walk_tree<const W: usize>(children: impl Fn(usize) -> [(u32, Aabb); W], mut f: impl FnMut(u32, &Aabb, u32)) {
    let mut stack = vec![(0usize, 1u32)];
    while let Some((n, d)) = stack.pop() {
        for (r, b) in children(n) {
            f(r, &b, d);
            if r & LEAF_REF == 0 {
                stack.push((r as usize, d + 1));
            }
        }
    }
}

/// Statistics of a BVH of either layout (without its build time and phases): an
/// empty child slot counts as an empty leaf, as in every other structure, and each
/// node record is an inner node whose leaves live in its child slots.
fn tree_stats<const W: usize>(
    kind: &str,
    node_count: usize,
    children: impl Fn(usize) -> [(u32, Aabb); W] + Copy,
    bytes: u64,
    depth: u32,
    prims: usize,
) -> BuildStats {
    let costs = SahCosts::default();
    let root = children(0).iter().filter(|(r, _)| *r != EMPTY_REF).fold(Aabb::EMPTY, |a, (_, b)| a.union(b));
    let root_area = f64::from(sah::area(&root));
    let mut tally = LeafTally::default();
    // The root counts as a traversal step too.
    tally.inner(f64::from(costs.traversal) * root_area);
    walk_tree(children, |r, b, d| {
        let a = f64::from(sah::area(b));
        if r == EMPTY_REF {
            tally.leaf(d, 0, 0.0);
        } else if r & LEAF_REF != 0 {
            let (_, count) = leaf_range(r);
            tally.leaf(d, count as u64, f64::from(costs.intersect) * a * count as f64);
        } else {
            tally.inner(f64::from(costs.traversal) * a);
        }
    });
    BuildStats {
        sah_cost: if root_area > 0.0 { tally.cost / root_area } else { 0.0 },
        ..tally.stats(kind, node_count as u64 + tally.leaves, depth, bytes, prims)
    }
}

impl BuildStats {
    /// These statistics with the build's time and phases.
    fn with_timing(self, build_ms: f64, phases: &[Phase]) -> BuildStats {
        BuildStats { build_ms, phases: phases.to_vec(), ..self }
    }
}

/// The invariants of a BVH of either layout, whose node `n` has the children
/// `children(n)`: depth within the kernel's limit; references in range; every node
/// reached exactly once; every child box contains its subtree (an inner child's boxes,
/// a leaf's primitives); every primitive in exactly one leaf.
fn validate_tree<const W: usize>(
    scene: &Scene,
    node_count: usize,
    indices: &[u32],
    depth: u32,
    children: impl Fn(usize) -> [(u32, Aabb); W],
) -> Result<(), ValidateError> {
    if depth > MAX_BVH_DEPTH {
        return Err(ValidateError::whole(format!("depth {depth} exceeds {MAX_BVH_DEPTH}")));
    }
    if node_count == 0 {
        return Err(ValidateError::whole("no root node"));
    }
    let np = scene.prim_count();
    let mut seen_node = vec![false; node_count];
    let mut seen_prim = vec![false; np];
    seen_node[0] = true;
    let mut stack = vec![(0usize, 1u32)];
    let mut max_depth = 0;
    while let Some((n, d)) = stack.pop() {
        max_depth = max_depth.max(d);
        for (r, b) in children(n) {
            if r == EMPTY_REF {
                continue;
            }
            if r & LEAF_REF != 0 {
                let (first, count) = leaf_range(r);
                if first + count > indices.len() {
                    return Err(ValidateError::node(n, "leaf indexes past the index array"));
                }
                for &p in &indices[first..first + count] {
                    let p = p as usize;
                    if p >= np {
                        return Err(ValidateError::node(n, format!("leaf references primitive {p} of {np}")));
                    }
                    if std::mem::replace(&mut seen_prim[p], true) {
                        return Err(ValidateError::prim(p, "in more than one leaf"));
                    }
                    let pb = prim::bounds(&prim::geom(scene, p as u32));
                    if !contains(&b, &pb) {
                        return Err(ValidateError::node(
                            n,
                            format!("leaf box {b:?} does not contain primitive {p} {pb:?}"),
                        ));
                    }
                }
                continue;
            }
            let c = r as usize;
            if c >= node_count {
                return Err(ValidateError::node(n, format!("child {c} out of range")));
            }
            if std::mem::replace(&mut seen_node[c], true) {
                return Err(ValidateError::node(c, "reached twice"));
            }
            for (cr, cb) in children(c) {
                if cr != EMPTY_REF && !contains(&b, &cb) {
                    return Err(ValidateError::node(
                        n,
                        format!("child box {b:?} does not contain its child's box {cb:?}"),
                    ));
                }
            }
            stack.push((c, d + 1));
        }
    }
    if max_depth != depth {
        return Err(ValidateError::whole(format!("recorded depth {depth} but the tree is {max_depth} deep")));
    }
    if let Some(n) = seen_node.iter().position(|s| !s) {
        return Err(ValidateError::node(n, "unreachable"));
    }
    if let Some(p) = seen_prim.iter().position(|s| !s) {
        return Err(ValidateError::prim(p, "in no leaf"));
    }
    Ok(())
}

pub(crate) use super::lap;

impl super::Traverse for Bvh {
    fn traverse(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        self.traverse_impl(prims, ray, best, any)
    }
}

impl super::Structure for Bvh {
    fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        Bvh::validate(self, scene)
    }
    fn stats(&self, _scene: &Scene) -> BuildStats {
        Bvh::stats(self)
    }
    fn timing(&self) -> (f64, Vec<Phase>) {
        Bvh::timing(self)
    }
    fn bounds(&self) -> Aabb {
        self.bounds
    }
    fn gpu_image(&self, _scene: &Scene) -> Result<super::GpuImage<'_>, ValidateError> {
        if self.depth > MAX_BVH_DEPTH {
            return Err(ValidateError::whole(format!(
                "BVH depth {} exceeds the kernel's stack of {MAX_BVH_DEPTH}",
                self.depth
            )));
        }
        if self.prims > MAX_BVH_PRIMS {
            return Err(ValidateError::whole(format!(
                "{} primitives exceed the BVH layout's {MAX_BVH_PRIMS}",
                self.prims
            )));
        }
        let (nodes, indices) = self.to_gpu();
        Ok(super::GpuImage {
            family: super::KernelFamily::Bvh,
            buffers: Some(crate::accel::AccelBuffers::Host(
                std::borrow::Cow::Borrowed(bytemuck::cast_slice(nodes)),
                indices,
            )),
            stack_size: self.depth + 1,
            cost_per_ray: 4 * (u64::from(self.depth) + 8),
            trace_loop: super::TraceLoop::StepBudget,
            ray_structure: None,
            resume_words: super::resume_words(1, self.depth + 1),
        })
    }
}
