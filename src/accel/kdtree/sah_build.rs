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
//!
//! # Reference budget
//!
//! The SAH alone keeps splitting a node while a plane removes even one primitive from
//! a side, so heavily overlapping input (thousands of coplanar triangles over one
//! point) copies its references into both children level after level, up to the
//! depth limit. The tree may hold [`REF_BUDGET_PER_PRIM`] x N + [`REF_BUDGET_EXTRA`]
//! references. The first build counts the references of the leaves it makes and
//! gives up as soon as they exceed that; ordinary scenes (at most 6 per primitive
//! with `quality`) never do, and keep exactly the tree they had. Otherwise a second
//! build shares the budget out: the root gets all of it, each split passes its node's
//! budget on in proportion to the children's counts, and a node whose split would
//! hold more references than its budget stays a leaf. Both builds are deterministic
//! (the first one's outcome depends only on its finished tree's size).

use std::sync::atomic::{AtomicUsize, Ordering};

use super::{BuildNode, KdParams};
use crate::accel::prim::{self, PrimGeom};
use crate::accel::sah::area;
use crate::accel::{lap, Phase};
use crate::math::Aabb;
use crate::scene::Scene;

const END: u8 = 0;
const PLANAR: u8 = 1;
const START: u8 = 2;

/// References per primitive the whole tree may hold (see the module doc).
pub const REF_BUDGET_PER_PRIM: usize = 16;
/// References the whole tree may hold beyond [`REF_BUDGET_PER_PRIM`] x N.
pub const REF_BUDGET_EXTRA: usize = 64;

/// Children with more primitives than this are built in parallel.
const PARALLEL_MIN: usize = 1024;

/// One event, 8 bytes: a key that orders events by position (32 bits of a float
/// mapped to an order-preserving integer, from which the position is recovered), then
/// kind (2 bits), then primitive (30 bits: the node's local index), a total order
/// independent of thread count. Half the size of a (key, position) pair, which
/// matters because sorting, sweeping, splitting and merging all stream events.
#[derive(Debug, Clone, Copy)]
struct Event {
    key: u64,
}

impl Event {
    fn new(pos: f32, kind: u8, prim: u32) -> Event {
        // Positions are finite; map to a u32 that orders like the float (-0 = +0).
        let b = (pos + 0.0).to_bits();
        let ord = if b >> 31 == 1 { !b } else { b | 0x8000_0000 };
        Event { key: (u64::from(ord) << 32) | (u64::from(kind) << 30) | u64::from(prim) }
    }
    /// The order-preserving image of the position: equal positions, equal values.
    #[inline]
    fn ord(&self) -> u32 {
        (self.key >> 32) as u32
    }
    #[inline]
    fn pos(&self) -> f32 {
        let ord = self.ord();
        f32::from_bits(if ord >> 31 == 1 { ord & 0x7fff_ffff } else { !ord })
    }
    #[inline]
    fn kind(&self) -> u8 {
        ((self.key >> 30) & 3) as u8
    }
    #[inline]
    fn prim(&self) -> u32 {
        (self.key & 0x3fff_ffff) as u32
    }
    #[inline]
    fn with_prim(&self, prim: u32) -> Event {
        Event { key: (self.key & !0x3fff_ffff) | u64::from(prim) }
    }
}

fn key(e: &Event) -> u64 {
    e.key
}

struct Ctx<'a> {
    /// References in the leaves made so far (first build) and the most allowed.
    refs: AtomicUsize,
    budget: usize,
    geoms: Vec<PrimGeom>,
    params: &'a KdParams,
    max_depth: u32,
}

#[derive(Clone)]
struct NodeData {
    bbox: Aabb,
    /// Global primitive ids, ascending.
    prims: Vec<u32>,
    events: [Vec<Event>; 3],
}

fn push_axis_events(list: &mut Vec<Event>, b: &Aabb, axis: usize, prim: u32) {
    if b.min[axis] == b.max[axis] {
        list.push(Event::new(b.min[axis], PLANAR, prim));
    } else {
        list.push(Event::new(b.min[axis], START, prim));
        list.push(Event::new(b.max[axis], END, prim));
    }
}

fn push_events(events: &mut [Vec<Event>; 3], b: &Aabb, prim: u32) {
    for (axis, list) in events.iter_mut().enumerate() {
        push_axis_events(list, b, axis, prim);
    }
}

/// Builds the tree for every primitive of `scene` inside `bounds`.
pub(super) fn build(scene: &Scene, params: &KdParams, bounds: &Aabb, phases: &mut Vec<Phase>) -> BuildNode {
    let mut t = std::time::Instant::now();
    let n = scene.prim_count();
    let geoms: Vec<PrimGeom> = (0..n as u32).map(|i| prim::geom(scene, i)).collect();
    let budget = REF_BUDGET_PER_PRIM * n + REF_BUDGET_EXTRA;
    let ctx = Ctx { refs: AtomicUsize::new(0), budget, geoms, params, max_depth: params.depth_limit(n) };
    let mut prims = Vec::with_capacity(n);
    let mut events: [Vec<Event>; 3] = Default::default();
    for (i, g) in ctx.geoms.iter().enumerate() {
        // Degenerate or out-of-box primitives still get a box so they are never lost.
        let b = prim::clipped_bounds(g, bounds, params.perfect_splits).unwrap_or_else(|| prim::bounds(g));
        let local = prims.len() as u32;
        prims.push(i as u32);
        push_events(&mut events, &b, local);
    }
    let count = events.iter().map(Vec::len).sum::<usize>();
    lap(phases, "events", &mut t);
    {
        use rayon::prelude::*;
        events.par_iter_mut().for_each(|l| l.par_sort_unstable_by_key(key));
    }
    lap(phases, "event sort", &mut t);
    if let Some(p) = phases.last_mut() {
        p.detail = Some(format!("{count} events on 3 axes"));
    }
    let root = NodeData { bbox: *bounds, prims, events };
    let tree = build_node(&ctx, root.clone(), 0, None);
    lap(phases, "SAH splits", &mut t);
    if ctx.refs.load(Ordering::Relaxed) <= budget {
        return tree;
    }
    drop(tree);
    let tree = build_node(&ctx, root, 0, Some(budget));
    lap(phases, "SAH splits within the reference budget", &mut t);
    if let Some(p) = phases.last_mut() {
        p.detail = Some(format!("the first pass made over {budget} references"));
    }
    tree
}

struct Plane {
    cost: f32,
    axis: usize,
    pos: f32,
    planar_left: bool,
}

/// Best plane on one axis by one sweep over its sorted events.
fn sweep_axis(ctx: &Ctx, node: &NodeData, axis: usize, parent: f32) -> Option<Plane> {
    let n = node.prims.len();
    let b = &node.bbox;
    let costs = &ctx.params.costs;
    let ev = &node.events[axis];
    let e = b.extent();
    let (e1, e2) = (e[(axis + 1) % 3], e[(axis + 2) % 3]);
    let (cap, perim) = (e1 * e2, e1 + e2);
    let mut best: Option<Plane> = None;
    let (mut nl, mut nr) = (0usize, n);
    let mut i = 0;
    while i < ev.len() {
        let (ord, p) = (ev[i].ord(), ev[i].pos());
        // Events at one position come sorted by kind: ends, planars, starts.
        let (mut pe, mut pp, mut ps) = (0usize, 0usize, 0usize);
        while i < ev.len() && ev[i].ord() == ord {
            match ev[i].kind() {
                END => pe += 1,
                PLANAR => pp += 1,
                _ => ps += 1,
            }
            i += 1;
        }
        nr -= pp + pe;
        if p > b.min[axis] && p < b.max[axis] {
            // Child areas: 2 (cap + length x perimeter of the other two axes).
            let al = 2.0 * (cap + (p - b.min[axis]) * perim);
            let ar = 2.0 * (cap + (b.max[axis] - p) * perim);
            let (cost, planar_left) = if pp == 0 {
                (costs.split(parent, al, nl, ar, nr), true)
            } else {
                let left = costs.split(parent, al, nl + pp, ar, nr);
                let right = costs.split(parent, al, nl, ar, nr + pp);
                if left <= right {
                    (left, true)
                } else {
                    (right, false)
                }
            };
            if best.as_ref().is_none_or(|bp| cost < bp.cost) {
                best = Some(Plane { cost, axis, pos: p, planar_left });
            }
        }
        nl += ps + pp;
    }
    best
}

/// The cheapest plane over the three axes (ties: lower axis, then lower position).
fn find_plane(ctx: &Ctx, node: &NodeData) -> Option<Plane> {
    let parent = area(&node.bbox);
    if parent <= 0.0 {
        return None;
    }
    let per_axis: Vec<Option<Plane>> = if node.prims.len() > PARALLEL_MIN {
        use rayon::prelude::*;
        (0..3).into_par_iter().map(|a| sweep_axis(ctx, node, a, parent)).collect()
    } else {
        (0..3).map(|a| sweep_axis(ctx, node, a, parent)).collect()
    };
    let mut best: Option<Plane> = None;
    for p in per_axis.into_iter().flatten() {
        if best.as_ref().is_none_or(|b| p.cost < b.cost) {
            best = Some(p);
        }
    }
    best
}

// Side codes of a primitive relative to the chosen plane.
const BOTH: u8 = 0;
const LEFT: u8 = 1;
const RIGHT: u8 = 2;
/// Set when a primitive's events are regenerated from clipped bounds.
const REGEN: u8 = 4;

/// The subtree of `node`. First build (`budget` None): counts leaf references in
/// `ctx.refs` and stops early once over `ctx.budget` (the tree is then discarded).
/// Second build: holds at most `budget` (>= its primitive count) references.
fn build_node(ctx: &Ctx, node: NodeData, depth: u32, budget: Option<usize>) -> BuildNode {
    if budget.is_none() && ctx.refs.load(Ordering::Relaxed) > ctx.budget {
        return BuildNode::Leaf(Vec::new());
    }
    let tree = split_node(ctx, node, depth, budget);
    if let (None, BuildNode::Leaf(list)) = (budget, &tree) {
        ctx.refs.fetch_add(list.len(), Ordering::Relaxed);
    }
    tree
}

fn split_node(ctx: &Ctx, node: NodeData, depth: u32, budget: Option<usize>) -> BuildNode {
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
    let mut side = vec![BOTH; n];
    for e in &node.events[axis] {
        let s = &mut side[e.prim() as usize];
        let epos = e.pos();
        match e.kind() {
            END if epos <= pos => *s = LEFT,
            START if epos >= pos => *s = RIGHT,
            PLANAR => *s = if epos < pos || (epos == pos && plane.planar_left) { LEFT } else { RIGHT },
            _ => {}
        }
    }
    let (mut lbox, mut rbox) = (node.bbox, node.bbox);
    lbox.max[axis] = pos;
    rbox.min[axis] = pos;

    // Straddling primitives: clip to each child; one whose part in a child is empty
    // leaves that child. All of them get regenerated events.
    let mut straddlers: Vec<(u32, Option<Aabb>, Option<Aabb>)> = Vec::new();
    for (i, s) in side.iter_mut().enumerate() {
        if *s != BOTH {
            continue;
        }
        let g = &ctx.geoms[node.prims[i] as usize];
        let l = prim::clipped_bounds(g, &lbox, ctx.params.perfect_splits);
        let r = prim::clipped_bounds(g, &rbox, ctx.params.perfect_splits);
        let (l, r, new_side) = match (l, r) {
            (Some(_), Some(_)) => (l, r, BOTH),
            (Some(_), None) => (l, None, LEFT),
            (None, Some(_)) => (None, r, RIGHT),
            (None, None) => {
                // Numerically lost: keep it on both sides with box-clipped bounds.
                let gb = prim::bounds(g);
                let l = prim::intersect_boxes(&gb, &lbox).unwrap_or(lbox);
                let r = prim::intersect_boxes(&gb, &rbox).unwrap_or(rbox);
                (Some(l), Some(r), BOTH)
            }
        };
        *s = new_side | REGEN;
        straddlers.push((i as u32, l, r));
    }
    let nl = side.iter().filter(|&&s| s & 3 != RIGHT).count();
    let nr = side.iter().filter(|&&s| s & 3 != LEFT).count();
    if budget.is_some_and(|b| nl + nr > b) {
        // Over budget (see the module doc): the node stays a leaf.
        return BuildNode::Leaf(node.prims);
    }
    // Local index maps (monotone, so child lists stay ascending).
    let mut lmap = vec![u32::MAX; n];
    let mut rmap = vec![u32::MAX; n];
    let (mut lprims, mut rprims) = (Vec::new(), Vec::new());
    for i in 0..n {
        let s = side[i] & 3;
        if s != RIGHT {
            lmap[i] = lprims.len() as u32;
            lprims.push(node.prims[i]);
        }
        if s != LEFT {
            rmap[i] = rprims.len() as u32;
            rprims.push(node.prims[i]);
        }
    }
    // Per axis: one-sided primitives keep their (sorted) events, regenerated ones get
    // new events, sorted, then merged.
    let split_axis = |a: usize| -> (Vec<Event>, Vec<Event>) {
        let old = &node.events[a];
        // Branch-free: write every event to both outputs and advance only the side it
        // belongs to (the side of consecutive events is unpredictable).
        let mut lo = vec![Event { key: 0 }; old.len() + 1];
        let mut ro = vec![Event { key: 0 }; old.len() + 1];
        let (mut nl, mut nr) = (0usize, 0usize);
        for e in old {
            let i = e.prim() as usize;
            let s = side[i];
            lo[nl] = e.with_prim(lmap[i]);
            nl += usize::from(s == LEFT);
            ro[nr] = e.with_prim(rmap[i]);
            nr += usize::from(s == RIGHT);
        }
        lo.truncate(nl);
        ro.truncate(nr);
        let mut ln = Vec::new();
        let mut rn = Vec::new();
        for &(i, l, r) in &straddlers {
            let i = i as usize;
            if let Some(b) = l {
                push_axis_events(&mut ln, &b, a, lmap[i]);
            }
            if let Some(b) = r {
                push_axis_events(&mut rn, &b, a, rmap[i]);
            }
        }
        ln.sort_unstable_by_key(key);
        rn.sort_unstable_by_key(key);
        (merge(lo, ln), merge(ro, rn))
    };
    let per_axis: Vec<(Vec<Event>, Vec<Event>)> = if n > PARALLEL_MIN {
        use rayon::prelude::*;
        (0..3).into_par_iter().map(split_axis).collect()
    } else {
        (0..3).map(split_axis).collect()
    };
    drop(node.events);
    let mut lev: [Vec<Event>; 3] = Default::default();
    let mut rev: [Vec<Event>; 3] = Default::default();
    for (a, (l, r)) in per_axis.into_iter().enumerate() {
        lev[a] = l;
        rev[a] = r;
    }
    // Proportional shares: each covers its child's count because nl + nr <= budget.
    let lbudget = budget.map(|b| ((b as u128 * nl as u128) / (nl + nr).max(1) as u128) as usize);
    let rbudget = budget.zip(lbudget).map(|(b, l)| b - l);
    let left = NodeData { bbox: lbox, prims: lprims, events: lev };
    let right = NodeData { bbox: rbox, prims: rprims, events: rev };
    let (below, above) = if n > PARALLEL_MIN {
        rayon::join(|| build_node(ctx, left, depth + 1, lbudget), || build_node(ctx, right, depth + 1, rbudget))
    } else {
        (build_node(ctx, left, depth + 1, lbudget), build_node(ctx, right, depth + 1, rbudget))
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
        if a[i].key <= b[j].key {
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
