//! The lecture's axis-aligned BSP tree, kept as a baseline (`--accel bsp-course`):
//! three candidate planes per axis at 1/4, 2/4 and 3/4 of the node box, cost =
//! left count x left area + right count x right area, at most 4 primitives per leaf,
//! at most 20 levels. Primitives go to every child their bounding box overlaps.
//! Stored compactly in the common node layout (no complete binary tree).
//!
//! # Caps on degenerate input
//!
//! Splitting a node whose primitives all straddle the plane copies every reference
//! into both children; with co-located, coplanar or fanned primitives that happens at
//! every level, and 20 levels make up to 2^20 copies of each. A budget stops it and
//! leaves trees of ordinary scenes unchanged (see docs/limits.md, "Builders on degenerate input"):
//!
//! - References are budgeted: the tree may hold [`REF_BUDGET_PER_PRIM`] x N +
//!   [`REF_BUDGET_EXTRA`]. The first build counts its leaves' references and gives up
//!   once over; ordinary scenes never are (the lecture's tree holds 100 per primitive
//!   at 80 triangles, 16 at 10,000: the constant covers small scenes). Otherwise a
//!   second build shares the budget out: each split passes its node's budget on in
//!   proportion to the children's counts, and a node whose split would hold more
//!   references than its budget stays a leaf, as does a node whose every primitive's
//!   box contains the node's box (no plane below could separate anything).

use std::sync::atomic::{AtomicUsize, Ordering};

use super::BuildNode;
use crate::accel::prim;
use crate::accel::sah::area;
use crate::math::Aabb;
use crate::scene::Scene;

/// Deepest level (root = 0).
pub const MAX_LEVEL: u32 = 20;
const LEAF_PRIMS: usize = 4;
/// References per primitive the whole tree may hold (see the module doc).
pub const REF_BUDGET_PER_PRIM: usize = 16;
/// References the whole tree may hold beyond [`REF_BUDGET_PER_PRIM`] x N.
pub const REF_BUDGET_EXTRA: usize = 1 << 18;

pub(super) fn build(scene: &Scene, bounds: &Aabb) -> BuildNode {
    let boxes: Vec<Aabb> = (0..scene.prim_count() as u32).map(|i| prim::bounds(&prim::geom(scene, i))).collect();
    let all: Vec<u32> = (0..boxes.len() as u32).collect();
    let limit = REF_BUDGET_PER_PRIM * boxes.len() + REF_BUDGET_EXTRA;
    let watch = Watch { refs: AtomicUsize::new(0), limit };
    let tree = node(&boxes, &watch, all.clone(), *bounds, 0, None);
    if watch.refs.load(Ordering::Relaxed) <= limit {
        return tree;
    }
    drop(tree);
    node(&boxes, &watch, all, *bounds, 0, Some(limit))
}

/// References in the leaves the first build made so far, and the most allowed.
struct Watch {
    refs: AtomicUsize,
    limit: usize,
}

/// The subtree of `prims` in box `b`. First build (`budget` None): counts leaf
/// references and stops early once over the limit (the tree is then discarded).
/// Second build: holds at most `budget` (>= prims.len()) references.
fn node(boxes: &[Aabb], watch: &Watch, prims: Vec<u32>, b: Aabb, level: u32, budget: Option<usize>) -> BuildNode {
    if budget.is_none() && watch.refs.load(Ordering::Relaxed) > watch.limit {
        return BuildNode::Leaf(Vec::new());
    }
    let tree = split(boxes, watch, prims, b, level, budget);
    if let (None, BuildNode::Leaf(list)) = (budget, &tree) {
        watch.refs.fetch_add(list.len(), Ordering::Relaxed);
    }
    tree
}

fn split(boxes: &[Aabb], watch: &Watch, prims: Vec<u32>, b: Aabb, level: u32, budget: Option<usize>) -> BuildNode {
    if prims.len() <= LEAF_PRIMS || level >= MAX_LEVEL {
        return BuildNode::Leaf(prims);
    }
    let covers = |p: &u32| {
        let pb = &boxes[*p as usize];
        pb.min.cmple(b.min).all() && pb.max.cmpge(b.max).all()
    };
    if budget.is_some() && prims.iter().all(covers) {
        return BuildNode::Leaf(prims);
    }
    let mut best: Option<(f32, usize, f32)> = None;
    for axis in 0..3 {
        for q in [0.25f32, 0.5, 0.75] {
            let pos = b.min[axis] + (b.max[axis] - b.min[axis]) * q;
            let (mut lb, mut rb) = (b, b);
            lb.max[axis] = pos;
            rb.min[axis] = pos;
            let nl = prims.iter().filter(|&&p| boxes[p as usize].min[axis] <= pos).count();
            let nr = prims.iter().filter(|&&p| boxes[p as usize].max[axis] >= pos).count();
            let cost = nl as f32 * area(&lb) + nr as f32 * area(&rb);
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, pos));
            }
        }
    }
    let Some((_, axis, pos)) = best else { return BuildNode::Leaf(prims) };
    if !(pos > b.min[axis] && pos < b.max[axis]) {
        return BuildNode::Leaf(prims);
    }
    let left: Vec<u32> = prims.iter().copied().filter(|&p| boxes[p as usize].min[axis] <= pos).collect();
    let right: Vec<u32> = prims.iter().copied().filter(|&p| boxes[p as usize].max[axis] >= pos).collect();
    let (nl, nr) = (left.len(), right.len());
    if budget.is_some_and(|b| nl + nr > b) {
        return BuildNode::Leaf(prims);
    }
    // Proportional shares: each child's share covers its own count because nl + nr <= budget.
    let lbudget = budget.map(|b| ((b as u128 * nl as u128) / (nl + nr).max(1) as u128) as usize);
    let rbudget = budget.zip(lbudget).map(|(b, l)| b - l);
    let (mut lb, mut rb) = (b, b);
    lb.max[axis] = pos;
    rb.min[axis] = pos;
    let (below, above) = if prims.len() > 1024 {
        rayon::join(
            || node(boxes, watch, left, lb, level + 1, lbudget),
            || node(boxes, watch, right, rb, level + 1, rbudget),
        )
    } else {
        (node(boxes, watch, left, lb, level + 1, lbudget), node(boxes, watch, right, rb, level + 1, rbudget))
    };
    BuildNode::Inner { axis, split: pos, below: Box::new(below), above: Box::new(above) }
}
