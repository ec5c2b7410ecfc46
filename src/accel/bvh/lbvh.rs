//! Linear BVH: Morton codes of centroids sorted, then the binary radix tree of Karras
//! ("Maximizing parallelism in the construction of BVHs, octrees, and k-d trees",
//! HPG 2012), then boxes bottom-up.
//!
//! - Codes: 30 bits, 10 per axis, of the centroid quantised in the centroid box.
//! - Duplicate codes: each key is the code in the high 32 bits and the primitive index
//!   in the low 32 bits, so keys are unique and equal codes are ordered by index
//!   (Karras 2012, section 4); the tree below a run of equal codes splits the run by
//!   index. The depth is therefore at most 62 + 1 whatever the input.
//! - Sort: one most-significant-digit radix pass on the top 10 bits of the code
//!   (counting and scatter), then the 1024 buckets sorted in parallel with rayon.
//! - Hierarchy: every inner node finds its range and split independently from the
//!   sorted keys alone (parallel over nodes). Inner node i is node i of the result,
//!   leaf j (the j-th key) is node n - 1 + j.
//! - Boxes: one post-order pass ([`build_fitted`]); the flattener fits its own, so a
//!   plain LBVH skips it, and treelet restructuring fits them in its own parallel
//!   pass over the tree.

use std::time::Instant;

use rayon::prelude::*;

use super::{lap, BNode, Binary, PrimRefs};
use crate::accel::Phase;
use crate::math::Aabb;

/// Spreads the low 10 bits of `v` to every third bit.
fn expand_bits(v: u32) -> u32 {
    let mut x = v & 0x3ff;
    x = (x | (x << 16)) & 0x0300_00ff;
    x = (x | (x << 8)) & 0x0300_f00f;
    x = (x | (x << 4)) & 0x030c_30c3;
    x = (x | (x << 2)) & 0x0924_9249;
    x
}

/// Quantisation of centroids to 10 bits per axis in a box, bit for bit as the GPU
/// build's (shaders/build_morton.comp): per axis the scale 1024 / extent, correctly
/// rounded (IEEE division here; the GPU corrects Vulkan's less exact quotient), then
/// (p - min) * scale truncated to 0..=1023. An axis of zero extent quantises to 0.
#[derive(Debug, Clone, Copy)]
pub struct MortonGrid {
    min: glam::Vec3,
    scale: [f32; 3],
}

impl MortonGrid {
    pub fn new(b: &Aabb) -> MortonGrid {
        let e = b.extent();
        let s = |k: usize| if e[k] > 0.0 { 1024.0 / e[k] } else { 0.0 };
        MortonGrid { min: b.min, scale: [s(0), s(1), s(2)] }
    }

    /// 30-bit code of `p` (x in the highest bit of each triple).
    pub fn code(&self, p: glam::Vec3) -> u32 {
        let q = |k: usize| -> u32 {
            if self.scale[k] == 0.0 {
                return 0;
            }
            let x = (p[k] - self.min[k]) * self.scale[k];
            if x.is_nan() || x <= 0.0 {
                0
            } else if x >= 1023.0 {
                1023
            } else {
                x as u32
            }
        };
        (expand_bits(q(0)) << 2) | (expand_bits(q(1)) << 1) | expand_bits(q(2))
    }
}

/// 30-bit Morton code of `p` quantised in `b` ([`MortonGrid`]).
pub fn morton30(p: glam::Vec3, b: &Aabb) -> u32 {
    MortonGrid::new(b).code(p)
}

/// Sorted keys: (code << 32 | primitive index).
pub fn sorted_keys(refs: &PrimRefs) -> Vec<u64> {
    let cb = refs.centroids.par_iter().fold(
        || Aabb::EMPTY,
        |mut b, c| {
            b.grow(*c);
            b
        },
    );
    let cb = cb.reduce(|| Aabb::EMPTY, |a, b| a.union(&b));
    let grid = MortonGrid::new(&cb);
    let keys: Vec<u64> =
        refs.centroids.par_iter().enumerate().map(|(i, c)| (u64::from(grid.code(*c)) << 32) | i as u64).collect();
    radix_sort(keys)
}

/// One MSD pass on code bits 20..30, then each bucket sorted in parallel.
fn radix_sort(keys: Vec<u64>) -> Vec<u64> {
    const DIGITS: usize = 1024;
    let digit = |k: u64| ((k >> 52) & 0x3ff) as usize;
    let mut count = vec![0usize; DIGITS + 1];
    for &k in &keys {
        count[digit(k) + 1] += 1;
    }
    for d in 0..DIGITS {
        count[d + 1] += count[d];
    }
    let starts = count.clone();
    let mut out = vec![0u64; keys.len()];
    for &k in &keys {
        let d = digit(k);
        out[count[d]] = k;
        count[d] += 1;
    }
    let mut buckets: Vec<&mut [u64]> = Vec::with_capacity(DIGITS);
    let mut rest: &mut [u64] = &mut out;
    for d in 0..DIGITS {
        let (b, r) = rest.split_at_mut(starts[d + 1] - starts[d]);
        buckets.push(b);
        rest = r;
    }
    buckets.into_par_iter().for_each(|b| b.sort_unstable());
    out
}

/// Length of the common prefix of keys i and j; -1 outside the array.
#[inline]
fn delta(keys: &[u64], i: usize, j: i64) -> i32 {
    if j < 0 || j as usize >= keys.len() {
        return -1;
    }
    (keys[i] ^ keys[j as usize]).leading_zeros() as i32
}

/// Children of inner node `i` of the radix tree over `keys` (n >= 2): node indices,
/// leaves offset by n - 1.
fn inner_children(keys: &[u64], i: usize) -> (u32, u32) {
    let n = keys.len();
    let ii = i as i64;
    // Direction of the range: towards the neighbour sharing the longer prefix.
    let d: i64 = if delta(keys, i, ii + 1) - delta(keys, i, ii - 1) >= 0 { 1 } else { -1 };
    let dmin = delta(keys, i, ii - d);
    // Upper bound on the range length, then binary search for the other end.
    let mut lmax: i64 = 2;
    while delta(keys, i, ii + lmax * d) > dmin {
        lmax *= 2;
    }
    let mut l: i64 = 0;
    let mut t = lmax / 2;
    while t >= 1 {
        if delta(keys, i, ii + (l + t) * d) > dmin {
            l += t;
        }
        t /= 2;
    }
    let j = ii + l * d;
    // Split: the last key sharing more than the node's prefix with key i.
    let dnode = delta(keys, i, j);
    let mut s: i64 = 0;
    let mut t = l;
    loop {
        t = (t + 1) / 2;
        if delta(keys, i, ii + (s + t) * d) > dnode {
            s += t;
        }
        if t <= 1 {
            break;
        }
    }
    let gamma = ii + s * d + d.min(0);
    let (lo, hi) = (ii.min(j), ii.max(j));
    let leaf0 = n as i64 - 1;
    let left = if lo == gamma { leaf0 + gamma } else { gamma };
    let right = if hi == gamma + 1 { leaf0 + gamma + 1 } else { gamma + 1 };
    (left as u32, right as u32)
}

/// Builds the LBVH: leaves of one primitive, inner boxes not yet fitted (left
/// empty). Records phases into `phases`.
pub fn build(refs: &PrimRefs, phases: &mut Vec<Phase>, t: &mut Instant) -> Binary {
    let n = refs.len();
    if n == 0 {
        return Binary::empty();
    }
    let keys = sorted_keys(refs);
    lap(phases, "morton + sort", t);
    let prims = key_prims(&keys);
    if n == 1 {
        return Binary { nodes: vec![BNode::leaf(refs.bounds[0], 0, 1)], root: 0, prims };
    }
    let nodes: Vec<BNode> = (0..2 * n - 1)
        .into_par_iter()
        .map(|i| {
            if i < n - 1 {
                let (left, right) = inner_children(&keys, i);
                BNode { bounds: Aabb::EMPTY, left, right }
            } else {
                let j = i - (n - 1);
                BNode::leaf(refs.bounds[prims[j] as usize], j as u32, 1)
            }
        })
        .collect();
    lap(phases, "hierarchy", t);
    Binary { nodes, root: 0, prims }
}

/// The primitive of each sorted key: the order leaves index into.
pub(super) fn key_prims(keys: &[u64]) -> Vec<u32> {
    keys.par_iter().map(|k| *k as u32).collect()
}

/// [`build`] with every inner node's box fitted (what restructuring needs; the
/// flattener computes boxes on its own).
pub fn build_fitted(refs: &PrimRefs, phases: &mut Vec<Phase>, t: &mut Instant) -> Binary {
    let mut bin = build(refs, phases, t);
    let root = bin.root;
    fit_bounds(&mut bin.nodes, root);
    lap(phases, "bounds", t);
    bin
}

/// Sets every inner node's box to the union of its children's (post-order).
pub fn fit_bounds(nodes: &mut [BNode], root: u32) {
    let mut stack: Vec<(u32, bool)> = vec![(root, false)];
    while let Some((i, children_done)) = stack.pop() {
        let node = nodes[i as usize];
        if node.is_leaf() {
            continue;
        }
        if children_done {
            let b = nodes[node.left as usize].bounds.union(&nodes[node.right as usize].bounds);
            nodes[i as usize].bounds = b;
        } else {
            stack.push((i, true));
            stack.push((node.right, false));
            stack.push((node.left, false));
        }
    }
}
