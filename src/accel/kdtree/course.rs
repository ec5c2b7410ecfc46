//! The lecture's axis-aligned BSP tree, kept as a baseline (`--accel bsp-course`):
//! three candidate planes per axis at 1/4, 2/4 and 3/4 of the node box, cost =
//! left count x left area + right count x right area, at most 4 primitives per leaf,
//! at most 20 levels. Primitives go to every child their bounding box overlaps.
//! Stored compactly in the common node layout (no complete binary tree).

use super::BuildNode;
use crate::accel::prim;
use crate::accel::sah::area;
use crate::math::Aabb;
use crate::scene::Scene;

const MAX_LEVEL: u32 = 20;
const LEAF_PRIMS: usize = 4;

pub(super) fn build(scene: &Scene, bounds: &Aabb) -> BuildNode {
    let boxes: Vec<Aabb> = (0..scene.prim_count() as u32).map(|i| prim::bounds(&prim::geom(scene, i))).collect();
    let all: Vec<u32> = (0..boxes.len() as u32).collect();
    node(&boxes, all, *bounds, 0)
}

fn node(boxes: &[Aabb], prims: Vec<u32>, b: Aabb, level: u32) -> BuildNode {
    if prims.len() <= LEAF_PRIMS || level >= MAX_LEVEL {
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
    let (mut lb, mut rb) = (b, b);
    lb.max[axis] = pos;
    rb.min[axis] = pos;
    let (below, above) = if prims.len() > 1024 {
        rayon::join(|| node(boxes, left, lb, level + 1), || node(boxes, right, rb, level + 1))
    } else {
        (node(boxes, left, lb, level + 1), node(boxes, right, rb, level + 1))
    };
    BuildNode::Inner { axis, split: pos, below: Box::new(below), above: Box::new(above) }
}
