//! The compressed 8-wide BVH (`cwbvh`): the binary tree of a BVH builder (binned SAH,
//! `bvh-sah`) collapsed so that each node holds up to eight children, whose boxes are
//! stored as 8-bit offsets on a per-node grid (after Ylitie, Karras & Laine 2017,
//! "Efficient incoherent ray traversal on GPUs through compressed wide BVHs").
//!
//! Collapse: as `bvh4` ([`super::wide`]), with eight in place of four: a wide node
//! starts with the two children of a binary node and, while it has fewer than eight,
//! replaces its inner child of largest surface area by that child's two children.
//! Leaves and their index ranges are the binary tree's.
//!
//! Quantisation, per node and axis: the grid starts at the node's box minimum `p` and
//! steps by a power of two `s = 2^(e - 127)`, the smallest for which `p + 255 s`
//! reaches the node's box maximum. A child box is stored as the grid cells `qlo`,
//! `qhi` (0..=255) whose decoded planes `p + q s` (one f32 rounding: `q s` is exact)
//! lie outside the exact box: `qlo` rounds down and `qhi` up, each then stepped until
//! the decoded plane, computed as the kernel computes it, is at or beyond the exact
//! one. A decoded box therefore always contains the child's exact box, so every ray
//! that meets the primitives of a subtree enters its box, and the watertight and
//! robustness guarantees of the binary BVH hold: quantisation only adds box hits.
//! Decoded boxes of different levels need not nest (each level rounds on its own
//! grid); [`Cwbvh::validate`] checks each against the exact box it stands for.
//!
//! GPU layout: 96 bytes (6 texels) per node:
//!
//! ```text
//! uvec4 0: x, y, z: the grid origin p (f32 bits); w: the exponent bytes
//!          e_x | e_y << 8 | e_z << 16 (s = f32 with exponent field e, mantissa 0)
//! uvec4 1: qlo x of children 0..3, 4..7; qlo y of children 0..3, 4..7
//! uvec4 2: qlo z 0..3, 4..7;             qhi x 0..3, 4..7
//! uvec4 3: qhi y 0..3, 4..7;             qhi z 0..3, 4..7
//!          (child k in byte k mod 4 of its word, least significant first)
//! uvec4 4: child references 0..3, encoded as the binary BVH's (bit 31: leaf, first
//!          index << BVH_LEAF_COUNT_BITS | count - 1; 0xffffffff: no child, its
//!          bytes all zero)
//! uvec4 5: child references 4..7
//! ```
//!
//! Full-precision 8-wide nodes would take 224 bytes; the binary BVH's 64 bytes hold
//! two children. Traversal (`shaders/accel/cwbvh.glsl`, mirrored by [`Cwbvh`]'s CPU
//! traversal): the eight decoded boxes are tested against [tmin, best t
//! (1 + T_MARGIN)], the hit children sorted by entry distance with a 19-comparator
//! network ([`SORT8`]), the nearest visited and the others pushed, farthest first.

use std::time::Instant;

use glam::Vec3;

use super::wide::{check_limits, open_wide, traverse_wide};
use super::{Bvh, BvhBuilder, EMPTY_REF, LEAF_REF};
use crate::accel::prim::Prims;
use crate::accel::validate::ValidateError;
use crate::accel::{BuildStats, GpuImage, KernelFamily, Phase, TraceLoop};
use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

/// Children per node.
pub const WIDTH: usize = 8;

/// One node as the kernel reads it (see the module docs).
pub type GpuCwbvhNode = [[u32; 4]; 6];

pub use super::wide::SORT8;

/// A compressed 8-wide BVH in the GPU layout.
#[derive(Debug, Clone)]
pub struct Cwbvh {
    pub bounds: Aabb,
    pub nodes: Vec<GpuCwbvhNode>,
    /// The exact child boxes the quantised ones stand for (host only, for
    /// [`Cwbvh::validate`]); empty slots hold [`Aabb::EMPTY`].
    pub exact: Vec<[Aabb; WIDTH]>,
    pub indices: Vec<u32>,
    /// Nodes on the longest root-to-leaf path.
    pub depth: u32,
    pub prims: usize,
    /// The builder of the binary tree that was collapsed.
    pub source: BvhBuilder,
    pub build_ms: f64,
    pub phases: Vec<Phase>,
}

/// The grid step whose exponent field is `e`.
fn step(e: u32) -> f32 {
    f32::from_bits(e << 23)
}

/// Plane `q` of the grid from `p` by `s`, as the kernel decodes it.
fn decode(p: f32, s: f32, q: u32) -> f32 {
    p + q as f32 * s
}

/// The exponent field (1..=254) of the finest grid from `lo` whose plane 255 reaches `hi`.
fn grid_exponent(lo: f32, hi: f32) -> u32 {
    let ext = f64::from(hi) - f64::from(lo);
    let mut e = if ext > 0.0 { ((ext / 255.0).log2().ceil() as i64 + 127).clamp(1, 254) as u32 } else { 1 };
    // log2 of a rounded quotient may land one below; the decoded plane decides.
    while e < 254 && decode(lo, step(e), 255) < hi {
        e += 1;
    }
    // One finer may still reach (the estimate can also land one above).
    while e > 1 && decode(lo, step(e - 1), 255) >= hi {
        e -= 1;
    }
    e
}

/// The cells (qlo, qhi) of `[lo, hi]` on the grid from `p` by `s`: decoded, at or
/// outside the interval.
fn quantise(p: f32, s: f32, lo: f32, hi: f32) -> (u32, u32) {
    let mut qlo = (((f64::from(lo) - f64::from(p)) / f64::from(s)).floor().clamp(0.0, 255.0)) as u32;
    while qlo > 0 && decode(p, s, qlo) > lo {
        qlo -= 1;
    }
    let mut qhi = (((f64::from(hi) - f64::from(p)) / f64::from(s)).ceil().clamp(0.0, 255.0)) as u32;
    while qhi < 255 && decode(p, s, qhi) < hi {
        qhi += 1;
    }
    (qlo, qhi)
}

/// Byte `k` of the eight packed in words `w[0]` (children 0..3) and `w[1]` (4..7).
fn byte_of(w: [u32; 2], k: usize) -> u32 {
    (w[k / 4] >> (8 * (k % 4))) & 0xff
}

impl Cwbvh {
    /// Builds the binary tree with `source` and collapses it.
    pub fn build(scene: &Scene, source: BvhBuilder) -> Cwbvh {
        let start = Instant::now();
        let bin = Bvh::build(scene, source);
        let mut phases = bin.phases.clone();
        let t = Instant::now();
        let mut wide = Self::collapse(&bin);
        phases.push(Phase::since("collapse to 8-wide, quantise", t));
        wide.phases = phases;
        wide.build_ms = start.elapsed().as_secs_f64() * 1e3;
        wide
    }

    /// Collapses a binary BVH (any builder's) into compressed 8-wide nodes.
    pub fn collapse(bin: &Bvh) -> Cwbvh {
        let mut w = Cwbvh {
            bounds: bin.bounds,
            nodes: Vec::with_capacity(bin.nodes.len() / 4 + 1),
            exact: Vec::with_capacity(bin.nodes.len() / 4 + 1),
            indices: bin.indices.clone(),
            depth: 0,
            prims: bin.prims,
            source: bin.builder,
            build_ms: 0.0,
            phases: Vec::new(),
        };
        // (binary inner node, wide slot to fill, depth of the wide node)
        let mut work = vec![(0usize, 0usize, 1u32)];
        w.nodes.push([[0; 4]; 6]);
        w.exact.push([Aabb::EMPTY; WIDTH]);
        while let Some((b, slot, d)) = work.pop() {
            w.depth = w.depth.max(d);
            let kids = open_wide(bin, b, WIDTH);
            let mut node: GpuCwbvhNode = [[0; 4]; 6];
            let mut exact = [Aabb::EMPTY; WIDTH];
            let node_box = kids.iter().fold(Aabb::EMPTY, |a, (_, b)| a.union(b));
            let mut refs = [EMPTY_REF; WIDTH];
            // Packed bytes per row: qlo x, y, z, qhi x, y, z; two words each.
            let mut rows = [[0u32; 2]; 6];
            let mut exps = 0u32;
            for axis in 0..3 {
                let (lo, hi) = (node_box.min[axis], node_box.max[axis]);
                let e = grid_exponent(lo, hi);
                exps |= e << (8 * axis);
                node[0][axis] = lo.to_bits();
                for (k, (_, bx)) in kids.iter().enumerate() {
                    let (qlo, qhi) = quantise(lo, step(e), bx.min[axis], bx.max[axis]);
                    rows[axis][k / 4] |= qlo << (8 * (k % 4));
                    rows[3 + axis][k / 4] |= qhi << (8 * (k % 4));
                }
            }
            node[0][3] = exps;
            for (t, pair) in rows.chunks(2).enumerate() {
                node[1 + t] = [pair[0][0], pair[0][1], pair[1][0], pair[1][1]];
            }
            for (k, (r, bx)) in kids.iter().enumerate() {
                exact[k] = *bx;
                refs[k] = if r & LEAF_REF != 0 {
                    *r
                } else {
                    let child = w.nodes.len();
                    w.nodes.push([[0; 4]; 6]);
                    w.exact.push([Aabb::EMPTY; WIDTH]);
                    work.push((*r as usize, child, d + 1));
                    child as u32
                };
            }
            node[4] = [refs[0], refs[1], refs[2], refs[3]];
            node[5] = [refs[4], refs[5], refs[6], refs[7]];
            w.nodes[slot] = node;
            w.exact[slot] = exact;
        }
        w
    }

    /// Bytes as uploaded.
    pub fn bytes(&self) -> u64 {
        (self.nodes.len() * std::mem::size_of::<GpuCwbvhNode>() + self.indices.len() * 4) as u64
    }

    /// Children of node `n`: (reference, decoded box), empty slots included (their box
    /// decodes to the grid origin).
    pub fn children(&self, n: usize) -> [(u32, Aabb); WIDTH] {
        let c = &self.nodes[n];
        let p = Vec3::new(f32::from_bits(c[0][0]), f32::from_bits(c[0][1]), f32::from_bits(c[0][2]));
        let s = Vec3::new(step(c[0][3] & 0xff), step((c[0][3] >> 8) & 0xff), step((c[0][3] >> 16) & 0xff));
        let row = |r: usize| -> [u32; 2] {
            let t = &c[1 + r / 2];
            if r % 2 == 0 {
                [t[0], t[1]]
            } else {
                [t[2], t[3]]
            }
        };
        std::array::from_fn(|k| {
            let q = |r: usize| byte_of(row(r), k);
            let min = Vec3::new(decode(p.x, s.x, q(0)), decode(p.y, s.y, q(1)), decode(p.z, s.z, q(2)));
            let max = Vec3::new(decode(p.x, s.x, q(3)), decode(p.y, s.y, q(4)), decode(p.z, s.z, q(5)));
            let r = if k < 4 { c[4][k] } else { c[5][k - 4] };
            (r, Aabb { min, max })
        })
    }

    /// Children of node `n` with their exact boxes.
    fn exact_children(&self, n: usize) -> [(u32, Aabb); WIDTH] {
        let c = self.children(n);
        std::array::from_fn(|k| (c[k].0, self.exact[n][k]))
    }

    /// Statistics over the decoded boxes (what traversal tests), the SAH cost computed
    /// as for every other structure (an empty slot is an empty leaf).
    pub fn stats(&self) -> BuildStats {
        super::tree_stats("cwbvh", self.nodes.len(), |n| self.children(n), self.bytes(), self.depth, self.prims)
            .with_timing(self.build_ms, &self.phases)
    }

    /// Checks the binary BVH's invariants ([`Bvh::validate`]) over the exact boxes, that
    /// every decoded box contains its exact box (so, through them, its subtree's
    /// primitives), that exponents are in range, and that empty slots have zero bytes.
    pub fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        if self.exact.len() != self.nodes.len() {
            return Err(ValidateError::whole("exact boxes and nodes differ in number"));
        }
        for n in 0..self.nodes.len() {
            let c = &self.nodes[n];
            for axis in 0..3 {
                let e = (c[0][3] >> (8 * axis)) & 0xff;
                if !(1..=254).contains(&e) {
                    return Err(ValidateError::node(n, format!("grid exponent {e} out of range")));
                }
            }
            for (k, (r, decoded)) in self.children(n).iter().enumerate() {
                if *r == EMPTY_REF {
                    let zero = (0..6).all(|row| {
                        let t = &c[1 + row / 2];
                        byte_of(if row % 2 == 0 { [t[0], t[1]] } else { [t[2], t[3]] }, k) == 0
                    });
                    if !zero {
                        return Err(ValidateError::node(n, format!("empty slot {k} has a box")));
                    }
                    continue;
                }
                let ex = self.exact[n][k];
                if !(decoded.min.cmple(ex.min).all() && decoded.max.cmpge(ex.max).all()) {
                    return Err(ValidateError::node(
                        n,
                        format!("quantised box {decoded:?} of child {k} does not contain its exact box {ex:?}"),
                    ));
                }
            }
        }
        super::validate_tree(scene, self.nodes.len(), &self.indices, self.depth, |n| self.exact_children(n))
    }
}

impl crate::accel::Traverse for Cwbvh {
    fn traverse(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        traverse_wide(&self.bounds, self.depth, &self.indices, |n| self.children(n), &SORT8, prims, ray, best, any)
    }
}

impl crate::accel::Structure for Cwbvh {
    fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        Cwbvh::validate(self, scene)
    }
    fn stats(&self, _scene: &Scene) -> BuildStats {
        Cwbvh::stats(self)
    }
    fn timing(&self) -> (f64, Vec<Phase>) {
        (self.build_ms, self.phases.clone())
    }
    fn bounds(&self) -> Aabb {
        self.bounds
    }
    fn gpu_image(&self, _scene: &Scene) -> Result<GpuImage<'_>, ValidateError> {
        check_limits(self.depth, self.prims)?;
        // Each node visited pushes at most 7 children.
        let stack_size = 7 * self.depth + 1;
        Ok(GpuImage {
            family: KernelFamily::Cwbvh,
            buffers: Some(crate::accel::AccelBuffers::Host(
                std::borrow::Cow::Borrowed(bytemuck::cast_slice(&self.nodes)),
                &self.indices,
            )),
            stack_size,
            cost_per_ray: 8 * (u64::from(self.depth) + 8),
            trace_loop: TraceLoop::StepBudget,
            ray_structure: None,
            resume_words: crate::accel::resume_words(1, stack_size),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantised_intervals_contain_the_exact_ones() {
        let mut seed = 12345u64;
        let mut next = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 33) as f32 / (1u64 << 31) as f32) * 2.0 - 1.0
        };
        for scale in [1e-30f32, 1e-6, 1.0, 3.0, 1e6, 1e30] {
            for _ in 0..2000 {
                let (a, b) = (next() * scale, next() * scale);
                let (lo, hi) = (a.min(b), a.max(b));
                let offset = next() * scale * 100.0;
                let (lo, hi) = (lo + offset, hi + offset);
                let e = grid_exponent(lo, hi);
                assert!((1..=254).contains(&e));
                assert!(decode(lo, step(e), 255) >= hi, "{lo} {hi} e={e}");
                // A child interval inside [lo, hi].
                let (u, v) = (next().abs(), next().abs());
                let (cl, ch) = (lo + (hi - lo) * u.min(v), lo + (hi - lo) * u.max(v));
                let (cl, ch) = (cl.max(lo), ch.min(hi));
                let (ql, qh) = quantise(lo, step(e), cl, ch);
                assert!(ql <= qh && qh <= 255);
                assert!(decode(lo, step(e), ql) <= cl && decode(lo, step(e), qh) >= ch, "{lo} {hi} {cl} {ch}");
            }
        }
        // A flat axis.
        let e = grid_exponent(2.5, 2.5);
        assert_eq!(quantise(2.5, step(e), 2.5, 2.5), (0, 0));
    }
}
