//! SAH kd-tree construction in O(N log N) after Wald & Havran, "On building fast
//! kd-trees for ray tracing, and on doing that in O(N log N)" (IEEE RT 2006).
//!
//! Each node carries, per axis, its primitives' start / planar / end events sorted
//! once at the root by (position, type). Finding the best plane is one sweep per axis;
//! splitting classifies primitives against the plane with one more sweep, keeps the
//! events of one-sided primitives in order, regenerates (clips) only the straddling
//! primitives' events, sorts those few, and merges. Children are built in parallel
//! with rayon; the result does not depend on the thread count (every tie is broken by
//! a total order).

use super::{BuildNode, KdParams};
use crate::accel::prim::{self, PrimGeom};
use crate::accel::sah::area;
use crate::math::Aabb;
use crate::scene::Scene;

const END: u8 = 0;
const PLANAR: u8 = 1;
const START: u8 = 2;

/// Children with more primitives than this are built in parallel.
const PARALLEL_MIN: usize = 1024;

#[derive(Debug, Clone, Copy)]
struct Event {
    pos: f32,
    kind: u8,
    /// Index into the node's primitive list.
    prim: u32,
}

fn key(e: &Event) -> (u32, u8, u32) {
    // Positions are finite; map to a u32 that orders like the float.
    let b = e.pos.to_bits();
    let ord = if b >> 31 == 1 { !b } else { b | 0x8000_0000 };
    (ord, e.kind, e.prim)
}

struct Ctx<'a> {
    geoms: Vec<PrimGeom>,
    params: &'a KdParams,
    max_depth: u32,
}

struct NodeData {
    bbox: Aabb,
    /// Global primitive ids, ascending.
    prims: Vec<u32>,
    events: [Vec<Event>; 3],
}

fn push_events(events: &mut [Vec<Event>; 3], b: &Aabb, prim: u32) {
    for (axis, list) in events.iter_mut().enumerate() {
        if b.min[axis] == b.max[axis] {
            list.push(Event { pos: b.min[axis], kind: PLANAR, prim });
        } else {
            list.push(Event { pos: b.min[axis], kind: START, prim });
            list.push(Event { pos: b.max[axis], kind: END, prim });
        }
    }
}

/// Builds the tree for every primitive of `scene` inside `bounds`.
pub(super) fn build(scene: &Scene, params: &KdParams, bounds: &Aabb) -> BuildNode {
    let n = scene.prim_count();
    let geoms: Vec<PrimGeom> = (0..n as u32).map(|i| prim::geom(scene, i)).collect();
    let ctx = Ctx { geoms, params, max_depth: params.depth_limit(n) };
    let mut prims = Vec::with_capacity(n);
    let mut events: [Vec<Event>; 3] = Default::default();
    for (i, g) in ctx.geoms.iter().enumerate() {
        // Degenerate or out-of-box primitives still get a box so they are never lost.
        let b = prim::clipped_bounds(g, bounds, params.perfect_splits).unwrap_or_else(|| prim::bounds(g));
        let local = prims.len() as u32;
        prims.push(i as u32);
        push_events(&mut events, &b, local);
    }
    {
        use rayon::prelude::*;
        events.par_iter_mut().for_each(|l| l.par_sort_unstable_by_key(key));
    }
    build_node(&ctx, NodeData { bbox: *bounds, prims, events }, 0)
}

struct Plane {
    cost: f32,
    axis: usize,
    pos: f32,
    planar_left: bool,
}

fn find_plane(ctx: &Ctx, node: &NodeData) -> Option<Plane> {
    let n = node.prims.len();
    let b = &node.bbox;
    let parent = area(b);
    if parent <= 0.0 {
        return None;
    }
    let costs = &ctx.params.costs;
    let mut best: Option<Plane> = None;
    for axis in 0..3 {
        let ev = &node.events[axis];
        let (mut nl, mut nr) = (0usize, n);
        let mut i = 0;
        while i < ev.len() {
            let p = ev[i].pos;
            let (mut pe, mut pp, mut ps) = (0usize, 0usize, 0usize);
            while i < ev.len() && ev[i].pos == p && ev[i].kind == END {
                pe += 1;
                i += 1;
            }
            while i < ev.len() && ev[i].pos == p && ev[i].kind == PLANAR {
                pp += 1;
                i += 1;
            }
            while i < ev.len() && ev[i].pos == p && ev[i].kind == START {
                ps += 1;
                i += 1;
            }
            nr -= pp + pe;
            if p > b.min[axis] && p < b.max[axis] {
                let (mut lb, mut rb) = (*b, *b);
                lb.max[axis] = p;
                rb.min[axis] = p;
                let (al, ar) = (area(&lb), area(&rb));
                let left = costs.split(parent, al, nl + pp, ar, nr);
                let right = costs.split(parent, al, nl, ar, nr + pp);
                let (cost, planar_left) = if left <= right { (left, true) } else { (right, false) };
                if best.as_ref().is_none_or(|bp| cost < bp.cost) {
                    best = Some(Plane { cost, axis, pos: p, planar_left });
                }
            }
            nl += ps + pp;
        }
    }
    best
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Side {
    Both,
    Left,
    Right,
}

fn build_node(ctx: &Ctx, node: NodeData, depth: u32) -> BuildNode {
    let n = node.prims.len();
    if n <= ctx.params.leaf_size || depth >= ctx.max_depth {
        return BuildNode::Leaf(node.prims);
    }
    let Some(plane) = find_plane(ctx, &node) else { return BuildNode::Leaf(node.prims) };
    if plane.cost >= ctx.params.costs.leaf(n) {
        return BuildNode::Leaf(node.prims);
    }
    let (axis, pos) = (plane.axis, plane.pos);

    // Classify with one sweep over the split axis.
    let mut side = vec![Side::Both; n];
    for e in &node.events[axis] {
        let s = &mut side[e.prim as usize];
        match e.kind {
            END if e.pos <= pos => *s = Side::Left,
            START if e.pos >= pos => *s = Side::Right,
            PLANAR => {
                if e.pos < pos || (e.pos == pos && plane.planar_left) {
                    *s = Side::Left;
                } else {
                    *s = Side::Right;
                }
            }
            _ => {}
        }
    }
    let (mut lbox, mut rbox) = (node.bbox, node.bbox);
    lbox.max[axis] = pos;
    rbox.min[axis] = pos;

    // Straddling primitives: clip to each child; one whose part in a child is empty
    // leaves that child.
    let mut clip_l: Vec<Option<Aabb>> = vec![None; n];
    let mut clip_r: Vec<Option<Aabb>> = vec![None; n];
    for i in 0..n {
        if side[i] == Side::Both {
            let g = &ctx.geoms[node.prims[i] as usize];
            let l = prim::clipped_bounds(g, &lbox, ctx.params.perfect_splits);
            let r = prim::clipped_bounds(g, &rbox, ctx.params.perfect_splits);
            match (l, r) {
                (Some(_), Some(_)) => {
                    clip_l[i] = l;
                    clip_r[i] = r;
                }
                (Some(_), None) => {
                    side[i] = Side::Left;
                    clip_l[i] = l;
                }
                (None, Some(_)) => {
                    side[i] = Side::Right;
                    clip_r[i] = r;
                }
                (None, None) => {
                    // Numerically lost: keep it on both sides with box-clipped bounds.
                    let gb = prim::bounds(g);
                    clip_l[i] = Some(prim::intersect_boxes(&gb, &lbox).unwrap_or(lbox));
                    clip_r[i] = Some(prim::intersect_boxes(&gb, &rbox).unwrap_or(rbox));
                }
            }
        }
    }
    // Local index maps (monotone, so child lists stay ascending).
    let mut lmap = vec![u32::MAX; n];
    let mut rmap = vec![u32::MAX; n];
    let (mut lprims, mut rprims) = (Vec::new(), Vec::new());
    for i in 0..n {
        let (to_l, to_r) = match side[i] {
            Side::Left => (true, clip_l[i].is_some()),
            Side::Right => (clip_r[i].is_some(), true),
            Side::Both => (true, true),
        };
        // A one-sided primitive that was clipped keeps only regenerated events.
        let (to_l, to_r) = match side[i] {
            Side::Left => (to_l, false),
            Side::Right => (false, to_r),
            Side::Both => (to_l, to_r),
        };
        if to_l {
            lmap[i] = lprims.len() as u32;
            lprims.push(node.prims[i]);
        }
        if to_r {
            rmap[i] = rprims.len() as u32;
            rprims.push(node.prims[i]);
        }
    }
    // Events: one-sided primitives keep theirs (already sorted); straddlers (and
    // one-sided primitives that were clipped) get new ones, sorted then merged.
    let regenerated = |i: usize| side[i] == Side::Both || clip_l[i].is_some() || clip_r[i].is_some();
    let mut lev: [Vec<Event>; 3] = Default::default();
    let mut rev: [Vec<Event>; 3] = Default::default();
    for a in 0..3 {
        let mut lo = Vec::with_capacity(node.events[a].len() / 2);
        let mut ro = Vec::with_capacity(node.events[a].len() / 2);
        for e in &node.events[a] {
            let i = e.prim as usize;
            if regenerated(i) {
                continue;
            }
            match side[i] {
                Side::Left => lo.push(Event { prim: lmap[i], ..*e }),
                Side::Right => ro.push(Event { prim: rmap[i], ..*e }),
                Side::Both => {}
            }
        }
        lev[a] = lo;
        rev[a] = ro;
    }
    let mut lnew: [Vec<Event>; 3] = Default::default();
    let mut rnew: [Vec<Event>; 3] = Default::default();
    for i in 0..n {
        if !regenerated(i) {
            continue;
        }
        if let (Some(b), true) = (clip_l[i], lmap[i] != u32::MAX) {
            push_events(&mut lnew, &b, lmap[i]);
        }
        if let (Some(b), true) = (clip_r[i], rmap[i] != u32::MAX) {
            push_events(&mut rnew, &b, rmap[i]);
        }
    }
    for a in 0..3 {
        lnew[a].sort_unstable_by_key(key);
        rnew[a].sort_unstable_by_key(key);
        lev[a] = merge(std::mem::take(&mut lev[a]), std::mem::take(&mut lnew[a]));
        rev[a] = merge(std::mem::take(&mut rev[a]), std::mem::take(&mut rnew[a]));
    }
    drop(node.events);
    let left = NodeData { bbox: lbox, prims: lprims, events: lev };
    let right = NodeData { bbox: rbox, prims: rprims, events: rev };
    let (below, above) = if n > PARALLEL_MIN {
        rayon::join(|| build_node(ctx, left, depth + 1), || build_node(ctx, right, depth + 1))
    } else {
        (build_node(ctx, left, depth + 1), build_node(ctx, right, depth + 1))
    };
    BuildNode::Inner { axis, split: pos, below: Box::new(below), above: Box::new(above) }
}

fn merge(a: Vec<Event>, b: Vec<Event>) -> Vec<Event> {
    if b.is_empty() {
        return a;
    }
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        if key(&a[i]) <= key(&b[j]) {
            out.push(a[i]);
            i += 1;
        } else {
            out.push(b[j]);
            j += 1;
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}
