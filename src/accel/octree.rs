//! Octree: a cube around the scene subdivided about node centres into eight octants
//! (the lecture's "book keeping with 8 child pointers per node", here one pointer and
//! a child mask). Traversal follows the parametric idea of Revelles, Urena & Lastra
//! ("An efficient parametric algorithm for octree traversal", WSCG 2000): every
//! decision compares the ray parameter t with the t at which the ray crosses a node's
//! mid-planes, with negative directions mirrored and zero components handled without
//! division; see `Octree::traverse` for the stackless form used here.
//!
//! # Node layout (8 bytes, `[u32; 2]`, read by shaders/accel/octree.glsl)
//!
//! ```text
//! word 0: bit 31 set: leaf, bits 0..31 = number of primitives
//!         bit 31 clear: inner node, bits 0..8 = child mask (bit k: octant k exists)
//! word 1: leaf: first entry in the index array
//!         inner: index of the first existing child; the existing children follow it
//!                in octant order, so octant k is at first + popcount(mask & (2^k - 1))
//! octant k: bit 0 = upper half in x, bit 1 = upper in y, bit 2 = upper in z
//! ```
//!
//! Worked example: an inner node whose octants 0, 3 and 6 exist, stored from node 12,
//! is `[0b0100_1001, 12] = [0x49, 12]`; octant 6 is node 12 + popcount(0x49 & 0x3f) =
//! 14. A leaf with 5 primitives from index 40 is `[0x8000_0005, 40]`. Absent octants
//! are empty space: nothing is stored for them.
//!
//! # Reference budget
//!
//! Splitting pays by the SAH while it less than about quadruples a node's references,
//! so densely overlapping input (thousands of coplanar triangles over one point) could
//! multiply its references level after level down to the depth limit. The tree may
//! hold [`REF_BUDGET_PER_PRIM`] x N + [`REF_BUDGET_EXTRA`] references. The first build
//! counts its leaves' references and gives up once over; ordinary scenes never are
//! (at most 7 per primitive by default, 18 with `leaf=1`) and keep their tree.
//! Otherwise a second build shares the budget out: each split passes its node's
//! budget on to the octants in proportion to their counts, and a node whose octants
//! would hold more than its budget stays a leaf.
//!
//! The GPU buffer starts with two vec4 (the root cube's min and max, w unused), then
//! the nodes. A node's centre is `0.5 min + 0.5 max` of its box, computed the same way
//! here and in the kernel, so a child's faces are bit for bit its ancestors' centres.

use super::validate::ValidateError;
use super::{AccelKind, LeafTally};
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

use super::kdtree::{before, shrink};
use super::params::{number, Key, Preset};
use super::prim::{self, PrimGeom};
use super::prim::{intersect_prim, Prims};
use super::sah::{self, SahCosts};
use super::BuildStats;
use crate::math::aabb::FLAT_RCP;
use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

/// 16-byte texel fetches of one node visit in shaders/accel/octree.glsl: an 8-byte
/// node is half a texel (`node_pair`), one fetch.
pub const NODE_TEXELS: u32 = 1;

/// Deepest octree the builder makes.
pub const MAX_OCTREE_DEPTH: u32 = 24;
/// References per primitive the whole tree may hold (see the module doc).
pub const REF_BUDGET_PER_PRIM: usize = 32;
/// References the whole tree may hold beyond [`REF_BUDGET_PER_PRIM`] x N.
pub const REF_BUDGET_EXTRA: usize = 64;
/// Leaf flag in word 0.
pub const LEAF: u32 = 0x8000_0000;
/// Words of the header before the nodes in the GPU layout (a `GpuOctreeHeader`).
pub const HEADER_WORDS: usize = std::mem::size_of::<super::gpu_layout::GpuOctreeHeader>() / 4;

/// Parameters of the octree builder.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct OctreeParams {
    /// Nodes with at most this many primitives become leaves; larger ones split while
    /// the SAH says splitting pays.
    pub leaf_size: usize,
    /// Deepest level (root = 0), at most [`MAX_OCTREE_DEPTH`].
    pub max_depth: u32,
}

impl Default for OctreeParams {
    fn default() -> Self {
        OctreeParams { leaf_size: 8, max_depth: 20 }
    }
}

/// `--octree`: preset `default`; keys `leaf` (most primitives a node keeps without
/// splitting) and `depth` (deepest level).
impl super::params::Params for OctreeParams {
    const FLAG: &'static str = "octree";
    const PRESETS: &'static [Preset<Self>] = &[("default", OctreeParams::default)];
    const KEYS: &'static [Key<Self>] = &[
        Key {
            name: "leaf",
            expects: "1..=1048576",
            set: |p, v| {
                p.leaf_size = number(v, 1, 1 << 20)?;
                Some(())
            },
        },
        Key {
            name: "depth",
            expects: "0..=24",
            set: |p, v| {
                p.max_depth = number(v, 0, MAX_OCTREE_DEPTH)?;
                Some(())
            },
        },
    ];
}

/// The tree as the builder produces it.
enum BuildNode {
    Leaf(Vec<u32>),
    /// Children by octant, and the subtree's size below this node.
    Inner {
        children: Vec<(u8, BuildNode)>,
        size: Size,
    },
}

/// Stored nodes below a node (not counting it) and index entries in its subtree.
#[derive(Debug, Clone, Copy, Default)]
struct Size {
    nodes: usize,
    refs: usize,
    depth: u32,
}

impl BuildNode {
    fn size(&self) -> Size {
        match self {
            BuildNode::Leaf(l) => Size { nodes: 0, refs: l.len(), depth: 0 },
            BuildNode::Inner { size, .. } => *size,
        }
    }
}

/// A built octree in its GPU layout.
#[derive(Debug, Clone)]
pub struct Octree {
    /// The root cube (contains the scene box).
    pub bounds: Aabb,
    pub nodes: Vec<[u32; 2]>,
    pub indices: Vec<u32>,
    pub depth: u32,
    pub prims: usize,
    pub params: OctreeParams,
    build_ms: f64,
    phases: Vec<super::Phase>,
}

/// The centre a node is split about (see the module doc).
#[inline]
pub fn centre(b: &Aabb) -> Vec3 {
    b.min * 0.5 + b.max * 0.5
}

/// The box of octant `k` of a node with box `b` and centre `c`.
#[inline]
pub fn octant_box(b: &Aabb, c: Vec3, k: usize) -> Aabb {
    let mut r = *b;
    for a in 0..3 {
        if k >> a & 1 == 1 {
            r.min[a] = c[a];
        } else {
            r.max[a] = c[a];
        }
    }
    r
}

/// Whether a node box can be split: its centre lies strictly inside on every axis,
/// and its children stay above 4e-6 of its coordinates (about 64 ulps, four times the
/// padding of [`prim::grow`]), as grid cells do.
fn splittable(b: &Aabb) -> bool {
    let c = centre(b);
    let mag = b.min.abs().max(b.max.abs()).max_element();
    c.cmpgt(b.min).all() && c.cmplt(b.max).all() && b.extent().min_element() * 0.5 > mag * 4e-6
}

/// A cube containing `b`: same minimum, side the longest extent (min + side is
/// raised to b.max where rounding falls short).
pub fn root_cube(b: &Aabb) -> Aabb {
    if b.is_empty() {
        return Aabb::EMPTY;
    }
    let side = b.extent().max_element().max(f32::MIN_POSITIVE);
    Aabb { min: b.min, max: (b.min + Vec3::splat(side)).max(b.max) }
}

impl Octree {
    /// Builds the octree of `scene`.
    pub fn build(scene: &Scene, params: &OctreeParams) -> Octree {
        let start = Instant::now();
        let mut t = Instant::now();
        let mut phases = Vec::new();
        let n = scene.prim_count();
        let bounds = root_cube(&scene.bounds());
        let geoms: Vec<PrimGeom> = (0..n as u32).map(|p| prim::geom(scene, p)).collect();
        let params = OctreeParams { max_depth: params.max_depth.min(MAX_OCTREE_DEPTH), ..*params };
        let all: Vec<u32> = (0..n as u32).collect();
        let limit = REF_BUDGET_PER_PRIM * n + REF_BUDGET_EXTRA;
        let watch = Watch { refs: AtomicUsize::new(0), limit };
        let mut root = subdivide(&geoms, &watch, all.clone(), bounds, 0, &params, None);
        if watch.refs.load(Ordering::Relaxed) > limit {
            drop(root);
            root = subdivide(&geoms, &watch, all, bounds, 0, &params, Some(limit));
        }
        super::bvh::lap(&mut phases, "subdivide", &mut t);
        let mut o = Octree {
            bounds,
            nodes: Vec::new(),
            indices: Vec::new(),
            depth: 0,
            prims: n,
            params,
            build_ms: 0.0,
            phases: Vec::new(),
        };
        o.flatten(root);
        super::bvh::lap(&mut phases, "flatten", &mut t);
        o.phases = phases;
        o.build_ms = start.elapsed().as_secs_f64() * 1e3;
        o
    }

    /// Depth-first: a node's existing children are one contiguous block, followed by
    /// the first child's descendants, then the second's, and so on. Subtree sizes are
    /// known, so subtrees are written in parallel into disjoint slices.
    fn flatten(&mut self, root: BuildNode) {
        let size = root.size();
        self.depth = size.depth;
        self.nodes = vec![[0, 0]; 1 + size.nodes];
        self.indices = vec![0; size.refs];
        let (head, rest) = self.nodes.split_at_mut(1);
        fill(root, &mut head[0], rest, 1, &mut self.indices, 0);
    }

    /// Bytes as uploaded: header, nodes, indices.
    pub fn bytes(&self) -> u64 {
        ((HEADER_WORDS + 2 * self.nodes.len() + self.indices.len()) * 4) as u64
    }

    /// Calls `f(box, node, depth)` for every stored node, and `absent(box, depth)` for
    /// every octant an inner node leaves out.
    fn walk(&self, mut f: impl FnMut(&Aabb, usize, u32), mut absent: impl FnMut(&Aabb, u32)) {
        let mut stack = vec![(0usize, self.bounds, 0u32)];
        while let Some((n, b, d)) = stack.pop() {
            f(&b, n, d);
            let [w0, w1] = self.nodes[n];
            if w0 & LEAF == 0 {
                let c = centre(&b);
                let mut next = w1 as usize;
                for k in 0..8 {
                    let ob = octant_box(&b, c, k);
                    if w0 >> k & 1 == 1 {
                        stack.push((next, ob, d + 1));
                        next += 1;
                    } else {
                        absent(&ob, d + 1);
                    }
                }
            }
        }
    }

    /// Build time and phases (what [`Self::stats`] reports of them, without the rest).
    pub fn timing(&self) -> (f64, Vec<super::Phase>) {
        (self.build_ms, self.phases.clone())
    }

    /// Statistics for `arbor info` and the stats JSON. Absent octants count as empty
    /// leaves (they are empty cells a ray steps through).
    pub fn stats(&self) -> BuildStats {
        let costs = SahCosts::default();
        let root = f64::from(sah::area(&self.bounds).max(f32::MIN_POSITIVE));
        let (mut stored, mut absent) = (LeafTally::default(), LeafTally::default());
        self.walk(
            |b, n, d| {
                let [w0, _] = self.nodes[n];
                let p = f64::from(sah::area(b)) / root;
                if w0 & LEAF != 0 {
                    let count = w0 & !LEAF;
                    stored.leaf(d, u64::from(count), p * f64::from(costs.intersect) * f64::from(count));
                } else {
                    stored.inner(p * f64::from(costs.traversal));
                }
            },
            // An absent octant is an empty leaf, and costs the descent that finds it.
            |b, d| absent.leaf(d, 0, f64::from(sah::area(b)) / root * f64::from(costs.traversal)),
        );
        // Stored records (inner nodes and leaves) plus the absent octants.
        let nodes = self.nodes.len() as u64 + absent.leaves;
        BuildStats {
            build_ms: self.build_ms,
            phases: self.phases.clone(),
            ..stored.and(absent).stats(AccelKind::Octree.name(), nodes, self.depth, self.bytes(), self.prims)
        }
    }

    /// Checks the invariants: links in range, children contiguous, depth within the
    /// limit, indices valid and ascending per leaf, and every primitive listed in every
    /// leaf whose box (shrunk by a relative 1e-5) it overlaps and present in no absent
    /// octant it overlaps.
    pub fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        if self.depth > MAX_OCTREE_DEPTH {
            return Err(ValidateError::whole(format!("depth {} exceeds {MAX_OCTREE_DEPTH}", self.depth)));
        }
        let n = self.nodes.len();
        let np = scene.prim_count() as u32;
        for (i, &[w0, w1]) in self.nodes.iter().enumerate() {
            if w0 & LEAF != 0 {
                let (first, count) = (w1 as usize, (w0 & !LEAF) as usize);
                let Some(list) = self.indices.get(first..first + count) else {
                    return Err(ValidateError::node(i, "leaf indexes past the index array"));
                };
                if let Some(bad) = list.iter().find(|&&p| p >= np) {
                    return Err(ValidateError::node(i, format!("leaf references primitive {bad} of {np}")));
                }
                if list.windows(2).any(|w| w[0] >= w[1]) {
                    return Err(ValidateError::node(i, "leaf primitive list not strictly ascending"));
                }
            } else {
                let kids = (w0 & 0xff).count_ones() as usize;
                if w0 & !0xff != 0 || kids == 0 || w1 as usize <= i || w1 as usize + kids > n {
                    return Err(ValidateError::node(i, format!("inner node mask {w0:#x} / first child {w1} invalid")));
                }
            }
        }
        let missing = (0..np).into_par_iter().find_map_first(|p| {
            let g = prim::geom(scene, p);
            let mut stack = vec![(0usize, self.bounds)];
            while let Some((node, b)) = stack.pop() {
                let [w0, w1] = self.nodes[node];
                if w0 & LEAF != 0 {
                    let inner = shrink(&b);
                    if inner.is_empty() || !prim::overlaps(&g, &inner) {
                        continue;
                    }
                    let first = w1 as usize;
                    if self.indices[first..first + (w0 & !LEAF) as usize].binary_search(&p).is_err() {
                        return Some(ValidateError::prim(p, format!("overlaps leaf {node} ({b:?}) but is not in it")));
                    }
                    continue;
                }
                let c = centre(&b);
                let mut next = w1 as usize;
                for k in 0..8 {
                    let ob = octant_box(&b, c, k);
                    let present = w0 >> k & 1 == 1;
                    if prim::overlaps(&g, &ob) {
                        if present {
                            stack.push((next, ob));
                        } else {
                            let inner = shrink(&ob);
                            if !inner.is_empty() && prim::overlaps(&g, &inner) {
                                return Some(ValidateError::prim(
                                    p,
                                    format!("overlaps absent octant {k} of node {node}"),
                                ));
                            }
                        }
                    }
                    next += usize::from(present);
                }
            }
            None
        });
        match missing {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// Front-to-back traversal without a stack. Starting from t = entry, descend from
    /// the root to the cell (leaf or absent octant) the ray is in just after t: at each
    /// node, the ray is in the upper half of axis a when it moves up and has crossed the
    /// mid-plane (tm = (c - o) / d <= t) or moves down and has not; a zero direction
    /// component decides by the origin. Test the leaf, then set t to the cell's exit
    /// (the nearest far face). That face is some ancestor's centre, bit for bit, so the
    /// next descent crosses it and reaches the next cell: traversal always advances.
    /// It stops when the best hit lies before the cell's exit or the exit is the root's.
    ///
    /// A cell inside the previous cell's parent is found from that parent; otherwise
    /// the descent starts at the root. That costs node reads but needs no stack: on
    /// llvmpipe, stack arrays live in scratch memory and cost more than the reads.
    fn traverse_impl(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        if self.prims == 0 {
            return false;
        }
        let inv = Aabb::inv_dir(ray.dir);
        let Some((t_enter, _)) = self.bounds.ray_box(ray.origin, inv, ray.tmin, ray.tmax) else {
            return false;
        };
        let o = ray.origin;
        let flat = inv.abs().cmpge(Vec3::splat(FLAT_RCP));
        let up = inv.cmpgt(Vec3::ZERO);
        let exit_of = |b: &Aabb| {
            let mut t = f32::INFINITY;
            for a in 0..3 {
                if !flat.test(a) {
                    let face = if up.test(a) { b.max[a] } else { b.min[a] };
                    t = t.min((face - o[a]) * inv[a]);
                }
            }
            t
        };
        let root_exit = exit_of(&self.bounds);
        let mut t = t_enter;
        let mut found = false;
        // Where the next descent starts: the root, or the last cell's parent when the
        // next cell lies inside it (see below).
        let (mut start, mut start_box) = (0usize, self.bounds);
        for _ in 0..1 << 24 {
            let mut b = start_box;
            let mut node = start;
            let (mut parent, mut parent_box) = (start, start_box);
            let leaf = loop {
                let [w0, w1] = self.nodes[node];
                if w0 & LEAF != 0 {
                    break Some((w1 as usize, (w0 & !LEAF) as usize));
                }
                (parent, parent_box) = (node, b);
                let c = centre(&b);
                let mut k = 0;
                for a in 0..3 {
                    let upper = if flat.test(a) { o[a] >= c[a] } else { up.test(a) == ((c[a] - o[a]) * inv[a] <= t) };
                    if upper {
                        k |= 1 << a;
                        b.min[a] = c[a];
                    } else {
                        b.max[a] = c[a];
                    }
                }
                if w0 >> k & 1 == 0 {
                    break None;
                }
                node = w1 as usize + (w0 & ((1 << k) - 1)).count_ones() as usize;
            };
            if let Some((first, count)) = leaf {
                for &p in &self.indices[first..first + count] {
                    if intersect_prim(prims, p, ray, best) {
                        found = true;
                        if any {
                            return true;
                        }
                    }
                }
            }
            let t_exit = exit_of(&b);
            if before(best.t, t_exit) || t_exit >= root_exit {
                return found;
            }
            // The next cell is inside the last one's parent when the ray leaves the cell
            // strictly before the parent: then no comparison above the parent changes
            // (the parent's box lies on one side of each of those planes), and the next
            // descent may start there. A cell leaving through one of its parent's faces
            // gives the same float for both exits, so it starts again from the root.
            if t_exit < exit_of(&parent_box) {
                (start, start_box) = (parent, parent_box);
            } else {
                (start, start_box) = (0, self.bounds);
            }
            t = t_exit;
        }
        debug_assert!(false, "octree traversal did not finish: {ray:?}");
        found
    }

    /// Header words (root min, root max) followed by the nodes, and the index array.
    pub fn to_gpu(&self) -> (Vec<u32>, &[u32]) {
        let (mn, mx) = (self.bounds.min, self.bounds.max);
        let head = super::gpu_layout::GpuOctreeHeader { min: [mn.x, mn.y, mn.z, 0.0], max: [mx.x, mx.y, mx.z, 0.0] };
        let mut words = Vec::with_capacity(HEADER_WORDS + 2 * self.nodes.len());
        words.extend_from_slice(bytemuck::cast_slice(bytemuck::bytes_of(&head)));
        words.extend(self.nodes.iter().flatten());
        (words, &self.indices)
    }
}

/// Primitives at which subdivision fans out over threads.
const PARALLEL_PRIMS: usize = 4096;

/// References in the leaves the first build made so far, and the most allowed.
struct Watch {
    refs: AtomicUsize,
    limit: usize,
}

/// The subtree of `prims` in box `b`. First build (`budget` None): counts leaf
/// references and stops early once over the limit (the tree is then discarded).
/// Second build: holds at most `budget` (>= prims.len()) references.
fn subdivide(
    geoms: &[PrimGeom],
    watch: &Watch,
    prims: Vec<u32>,
    b: Aabb,
    depth: u32,
    params: &OctreeParams,
    budget: Option<usize>,
) -> BuildNode {
    if budget.is_none() && watch.refs.load(Ordering::Relaxed) > watch.limit {
        return BuildNode::Leaf(Vec::new());
    }
    let tree = split(geoms, watch, prims, b, depth, params, budget);
    if let (None, BuildNode::Leaf(list)) = (budget, &tree) {
        watch.refs.fetch_add(list.len(), Ordering::Relaxed);
    }
    tree
}

fn split(
    geoms: &[PrimGeom],
    watch: &Watch,
    prims: Vec<u32>,
    b: Aabb,
    depth: u32,
    params: &OctreeParams,
    budget: Option<usize>,
) -> BuildNode {
    if prims.len() <= params.leaf_size || depth >= params.max_depth || !splittable(&b) {
        return BuildNode::Leaf(prims);
    }
    let c = centre(&b);
    let grown: Vec<Aabb> = (0..8).map(|k| prim::grow(&octant_box(&b, c, k))).collect();
    // A grown octant's interval on an axis depends only on its side: lower is
    // grown[0] there, upper grown[7].
    let (lo_max, hi_min) = (grown[0].max, grown[7].min);
    let mut lists: Vec<Vec<u32>> = vec![Vec::new(); 8];
    for &p in &prims {
        let g = &geoms[p as usize];
        let pb = prim::bounds(g);
        let lower = pb.min.cmple(lo_max).bitmask();
        let upper = pb.max.cmpge(hi_min).bitmask();
        if (lower ^ upper) == 0b111 {
            // On one side of every mid-plane's margin: one candidate octant, and the
            // box within it unless it sticks out of the node's own grown box.
            let k = upper as usize;
            if pb.min.cmpge(grown[k].min).all() && pb.max.cmple(grown[k].max).all() {
                lists[k].push(p);
                continue;
            }
        }
        for (k, gb) in grown.iter().enumerate() {
            let side_ok = (0..3).all(|a| if k >> a & 1 == 1 { upper >> a & 1 == 1 } else { lower >> a & 1 == 1 });
            if side_ok && prim::overlaps(g, gb) {
                lists[k].push(p);
            }
        }
    }
    // Keep a leaf when splitting does not separate or does not pay:
    // - an octant keeps every primitive while another octant is not empty: the
    //   primitives meet inside the node (a shared vertex or edge, a fan, crossing
    //   triangles) and no depth separates them. (An octant holding everything alone
    //   is fine: the node shrinks toward a small dense mesh, the teapot in a stadium.)
    // - the SAH (sah.rs), taking the octants as leaves, finds splitting dearer:
    //   Kt + Ki sum(area_k / area n_k) >= Ki n. An octant has a quarter of the
    //   node's area, so this refuses splits that about quadruple the references.
    // - primitives reaching only into the node's grown margin fall in no octant.
    let n = prims.len();
    let non_empty = lists.iter().filter(|l| !l.is_empty()).count();
    if non_empty > 1 && lists.iter().any(|l| l.len() == n) {
        return BuildNode::Leaf(prims);
    }
    let costs = SahCosts::default();
    let parent_area = sah::area(&b);
    let mut split = costs.traversal;
    for (k, l) in lists.iter().enumerate() {
        split += costs.intersect * sah::area(&octant_box(&b, c, k)) / parent_area * l.len() as f32;
    }
    if lists.iter().all(Vec::is_empty) || split >= costs.leaf(prims.len()) {
        return BuildNode::Leaf(prims);
    }
    // Over budget (see the module doc): stay a leaf. Otherwise each octant gets its
    // proportional share, which covers its count because the total fits the budget.
    let total: usize = lists.iter().map(Vec::len).sum();
    if budget.is_some_and(|b| total > b) {
        return BuildNode::Leaf(prims);
    }
    drop(prims);
    let share = |len: usize| budget.map(|b| ((b as u128 * len as u128) / total as u128) as usize);
    let work: Vec<(u8, Vec<u32>, Option<usize>)> = lists
        .into_iter()
        .enumerate()
        .filter(|(_, l)| !l.is_empty())
        .map(|(k, l)| {
            let s = share(l.len());
            (k as u8, l, s)
        })
        .collect();
    let build = |(k, l, s): (u8, Vec<u32>, Option<usize>)| {
        (k, subdivide(geoms, watch, l, octant_box(&b, c, k as usize), depth + 1, params, s))
    };
    let children: Vec<(u8, BuildNode)> = if n >= PARALLEL_PRIMS {
        work.into_par_iter().map(build).collect()
    } else {
        work.into_iter().map(build).collect()
    };
    let mut size = Size { nodes: children.len(), ..Size::default() };
    for (_, ch) in &children {
        let s = ch.size();
        size.nodes += s.nodes;
        size.refs += s.refs;
        size.depth = size.depth.max(s.depth + 1);
    }
    BuildNode::Inner { children, size }
}

/// One subtree to write: node, its slot, its descendants' slice and global start, its
/// references' slice and global start.
type FillJob<'a> = (BuildNode, &'a mut [u32; 2], &'a mut [[u32; 2]], usize, &'a mut [u32], usize);

/// Writes `node` into `slot`, its descendants into `below` (which starts at global
/// node index `base`) and its primitive references into `refs` (from global `rbase`).
fn fill(node: BuildNode, slot: &mut [u32; 2], below: &mut [[u32; 2]], base: usize, refs: &mut [u32], rbase: usize) {
    match node {
        BuildNode::Leaf(list) => {
            *slot = [LEAF | list.len() as u32, rbase as u32];
            refs.copy_from_slice(&list);
        }
        BuildNode::Inner { children, size } => {
            let k = children.len();
            let mut mask = 0u32;
            for (o, _) in &children {
                mask |= 1 << o;
            }
            *slot = [mask, base as u32];
            let (block, mut rest) = below.split_at_mut(k);
            let mut refs = refs;
            let (mut nb, mut rb) = (base + k, rbase);
            let mut jobs = Vec::with_capacity(k);
            for ((_, child), s) in children.into_iter().zip(block.iter_mut()) {
                let cs = child.size();
                let (mine, r) = std::mem::take(&mut rest).split_at_mut(cs.nodes);
                rest = r;
                let (my_refs, r) = std::mem::take(&mut refs).split_at_mut(cs.refs);
                refs = r;
                jobs.push((child, s, mine, nb, my_refs, rb));
                nb += cs.nodes;
                rb += cs.refs;
            }
            let run = |(child, s, mine, nb, my_refs, rb): FillJob<'_>| fill(child, s, mine, nb, my_refs, rb);
            if size.refs >= PARALLEL_PRIMS {
                jobs.into_par_iter().for_each(run);
            } else {
                jobs.into_iter().for_each(run);
            }
        }
    }
}

impl super::Traverse for Octree {
    fn traverse(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        self.traverse_impl(prims, ray, best, any)
    }
}

impl super::Structure for Octree {
    fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        Octree::validate(self, scene)
    }
    fn stats(&self, _scene: &Scene) -> BuildStats {
        Octree::stats(self)
    }
    fn timing(&self) -> (f64, Vec<super::Phase>) {
        Octree::timing(self)
    }
    fn bounds(&self) -> Aabb {
        self.bounds
    }
    fn gpu_image(&self, _scene: &Scene) -> Result<super::GpuImage<'_>, ValidateError> {
        if self.depth > MAX_OCTREE_DEPTH {
            return Err(ValidateError::whole(format!(
                "octree depth {} exceeds the kernel's limit of {MAX_OCTREE_DEPTH}",
                self.depth
            )));
        }
        let (words, indices) = self.to_gpu();
        Ok(super::GpuImage {
            family: super::KernelFamily::Octree,
            buffers: Some(crate::accel::AccelBuffers::Host(
                std::borrow::Cow::Owned(bytemuck::cast_slice(&words).to_vec()),
                indices,
            )),
            stack_size: 1,
            // A descent from the root per cell visited.
            cost_per_ray: 8 * (u64::from(self.depth) + 4),
            trace_loop: super::TraceLoop::StepBudget,
            ray_structure: None,
            resume_words: super::resume_words(1, 1),
        })
    }
}
