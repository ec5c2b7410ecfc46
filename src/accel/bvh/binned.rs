//! Top-down binned SAH build (Wald, "On fast construction of SAH-based bounding volume
//! hierarchies", IEEE RT 2007): at each node the centroids are binned into 32 bins per
//! axis, and the split between bins with the lowest SAH cost wins. A node becomes a
//! leaf when it holds at most [`MAX_LEAF`] primitives and intersecting them is no
//! dearer than the best split.
//!
//! Deterministic for any thread count: bins are merged with min, max and addition
//! (exact and order-free), partitioning is in place and sequential within a node, and
//! the two children are built independently (in parallel above `PAR_MIN`).

use rayon::prelude::*;

use super::{BNode, Binary, PrimRefs, MAX_LEAF};
use crate::accel::sah::{area, SahCosts};
use crate::math::Aabb;

const BINS: usize = 32;
/// Nodes with more primitives than this build their children in parallel.
const PAR_MIN: usize = 4096;
/// Nodes with more primitives than this bin in parallel chunks.
const PAR_BIN_MIN: usize = 65536;
/// Deeper nodes become leaves (oversized ones are split by the flattener).
const MAX_DEPTH: u32 = 64;

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

const EMPTY_BIN: Bin = Bin { bounds: Aabb::EMPTY, count: 0 };

type Bins = [[Bin; BINS]; 3];

/// The binning of one node: bin of a centroid coordinate on `axis`.
#[derive(Clone, Copy)]
struct Binner {
    min: [f32; 3],
    scale: [f32; 3],
}

impl Binner {
    fn new(cb: &Aabb) -> Binner {
        let e = cb.extent();
        let s = |x: f32| if x > 0.0 { BINS as f32 * (1.0 - 1e-6) / x } else { 0.0 };
        Binner { min: cb.min.to_array(), scale: [s(e.x), s(e.y), s(e.z)] }
    }
    #[inline]
    fn bin(&self, c: f32, axis: usize) -> usize {
        (((c - self.min[axis]) * self.scale[axis]) as usize).min(BINS - 1)
    }
}

enum Tmp {
    Leaf { bounds: Aabb, first: usize, count: usize },
    Inner { bounds: Aabb, left: Box<Tmp>, right: Box<Tmp> },
}

/// Builds the binned SAH tree over every primitive of `refs`.
pub fn build(refs: &PrimRefs, costs: &SahCosts) -> Binary {
    let n = refs.len();
    if n == 0 {
        return Binary::empty();
    }
    let mut idx: Vec<u32> = (0..n as u32).collect();
    let bounds = refs.bounds.par_iter().cloned().reduce(|| Aabb::EMPTY, |a, b| a.union(&b));
    let tmp = build_rec(refs, costs, &mut idx, 0, bounds, 0);
    let mut nodes = Vec::with_capacity(2 * n / 3 + 1);
    emit(&tmp, &mut nodes);
    Binary { nodes, root: 0, prims: idx }
}

fn emit(t: &Tmp, nodes: &mut Vec<BNode>) -> u32 {
    let me = nodes.len();
    match t {
        Tmp::Leaf { bounds, first, count } => nodes.push(BNode::leaf(*bounds, *first as u32, *count as u32)),
        Tmp::Inner { bounds, left, right } => {
            nodes.push(BNode { bounds: *bounds, left: 0, right: 0 });
            let l = emit(left, nodes);
            let r = emit(right, nodes);
            nodes[me].left = l;
            nodes[me].right = r;
        }
    }
    me as u32
}

fn centroid_bounds(refs: &PrimRefs, idx: &[u32]) -> Aabb {
    let fold = |s: &[u32]| {
        s.iter().fold(Aabb::EMPTY, |mut b, &p| {
            b.grow(refs.centroids[p as usize]);
            b
        })
    };
    if idx.len() > PAR_BIN_MIN {
        idx.par_chunks(PAR_BIN_MIN / 4).map(fold).reduce(|| Aabb::EMPTY, |a, b| a.union(&b))
    } else {
        fold(idx)
    }
}

fn bin_prims(refs: &PrimRefs, idx: &[u32], binner: &Binner) -> Bins {
    let fold = |s: &[u32]| {
        let mut bins = [[EMPTY_BIN; BINS]; 3];
        for &p in s {
            let c = refs.centroids[p as usize];
            let b = &refs.bounds[p as usize];
            for (axis, axis_bins) in bins.iter_mut().enumerate() {
                let bin = &mut axis_bins[binner.bin(c[axis], axis)];
                bin.count += 1;
                bin.bounds = bin.bounds.union(b);
            }
        }
        bins
    };
    let merge = |mut a: Bins, b: Bins| {
        for axis in 0..3 {
            for k in 0..BINS {
                a[axis][k].count += b[axis][k].count;
                a[axis][k].bounds = a[axis][k].bounds.union(&b[axis][k].bounds);
            }
        }
        a
    };
    if idx.len() > PAR_BIN_MIN {
        idx.par_chunks(PAR_BIN_MIN / 4).map(fold).reduce(|| [[EMPTY_BIN; BINS]; 3], merge)
    } else {
        fold(idx)
    }
}

struct Split {
    cost: f32,
    axis: usize,
    /// Bins below this go left.
    bin: usize,
    left: Aabb,
    right: Aabb,
}

/// The cheapest split between bins over the three axes (ties: lower axis, lower bin).
fn best_split(bins: &Bins, parent_area: f32, costs: &SahCosts, usable: [bool; 3]) -> Option<Split> {
    let mut best: Option<Split> = None;
    for axis in 0..3 {
        if !usable[axis] {
            continue;
        }
        let b = &bins[axis];
        // Right-to-left running boxes and counts.
        let mut rbox = [Aabb::EMPTY; BINS];
        let mut rcount = [0u32; BINS];
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0u32);
        for k in (1..BINS).rev() {
            acc = acc.union(&b[k].bounds);
            cnt += b[k].count;
            rbox[k] = acc;
            rcount[k] = cnt;
        }
        let (mut lacc, mut lcnt) = (Aabb::EMPTY, 0u32);
        for k in 1..BINS {
            lacc = lacc.union(&b[k - 1].bounds);
            lcnt += b[k - 1].count;
            if lcnt == 0 || rcount[k] == 0 {
                continue;
            }
            let cost = costs.traversal
                + costs.intersect * (area(&lacc) * lcnt as f32 + area(&rbox[k]) * rcount[k] as f32) / parent_area;
            if best.as_ref().is_none_or(|s| cost < s.cost) {
                best = Some(Split { cost, axis, bin: k, left: lacc, right: rbox[k] });
            }
        }
    }
    best
}

fn build_rec(refs: &PrimRefs, costs: &SahCosts, idx: &mut [u32], offset: usize, bounds: Aabb, depth: u32) -> Tmp {
    let n = idx.len();
    let leaf = Tmp::Leaf { bounds, first: offset, count: n };
    if n <= 1 || depth >= MAX_DEPTH {
        return leaf;
    }
    let cb = centroid_bounds(refs, idx);
    let e = cb.extent();
    let usable = [e.x > 0.0, e.y > 0.0, e.z > 0.0];
    let parent_area = area(&bounds);
    let split = if usable.iter().any(|&u| u) && parent_area > 0.0 {
        let binner = Binner::new(&cb);
        let bins = bin_prims(refs, idx, &binner);
        best_split(&bins, parent_area, costs, usable).map(|s| (s, binner))
    } else {
        None
    };
    let (mid, lbox, rbox) = match split {
        Some((s, _)) if n <= MAX_LEAF && s.cost >= costs.intersect * n as f32 => return leaf,
        Some((s, binner)) => {
            let mid = partition(idx, |p| binner.bin(refs.centroids[p as usize][s.axis], s.axis) < s.bin);
            (mid, s.left, s.right)
        }
        None if n <= MAX_LEAF => return leaf,
        None => {
            // Identical centroids (or a flat box): halve the list as it stands.
            let mid = n / 2;
            (mid, refs.union(&idx[..mid]), refs.union(&idx[mid..]))
        }
    };
    let (l, r) = idx.split_at_mut(mid);
    let (left, right) = if n > PAR_MIN {
        rayon::join(
            || build_rec(refs, costs, l, offset, lbox, depth + 1),
            || build_rec(refs, costs, r, offset + mid, rbox, depth + 1),
        )
    } else {
        (build_rec(refs, costs, l, offset, lbox, depth + 1), build_rec(refs, costs, r, offset + mid, rbox, depth + 1))
    };
    Tmp::Inner { bounds, left: Box::new(left), right: Box::new(right) }
}

/// In-place partition: elements satisfying `pred` first; returns their count.
fn partition(v: &mut [u32], pred: impl Fn(u32) -> bool) -> usize {
    let mut i = 0;
    let mut j = v.len();
    while i < j {
        if pred(v[i]) {
            i += 1;
        } else {
            j -= 1;
            v.swap(i, j);
        }
    }
    i
}
