//! The wide BVHs with full-precision boxes: `bvh4` and `bvh8`, the binary tree of a
//! BVH builder (binned SAH, `bvh-sah`) collapsed so that each node holds up to four or
//! eight children. Fewer, wider nodes mean fewer traversal steps and more boxes per
//! step; which pays depends on the device (docs/lavapipe.md; docs/bvh.md).
//!
//! Collapse: a wide node starts with the two children of a binary node and, while it
//! has fewer than W, replaces its inner child of largest surface area by that child's
//! two children (`open_wide`, shared with `cwbvh`). Leaves and their index ranges are
//! the binary tree's, and the child boxes are the binary tree's boxes, exactly (full
//! precision, so every robustness guarantee of the binary BVH holds unchanged).
//!
//! GPU layout: 7 x W / 4 texels per node (112 bytes for W = 4, 224 for W = 8),
//! structure of arrays over the W children, each row W / 4 texels (children 0..3,
//! then 4..7):
//!
//! ```text
//! row 0: min x of the children (f32 bits)
//! row 1: min y
//! row 2: min z
//! row 3: max x
//! row 4: max y
//! row 5: max z
//! row 6: child references, encoded as the binary BVH's (bit 31: leaf, first
//!        index << BVH_LEAF_COUNT_BITS | count - 1; 0xffffffff: no child, its box
//!        all zeros)
//! ```
//!
//! Traversal (`shaders/accel/bvh4.glsl`, `bvh8.glsl`, mirrored by [`WideBvh`]'s CPU
//! traversal): the W boxes are tested against [tmin, best t (1 + T_MARGIN)], the hit
//! children sorted by entry distance (a sorting network: [`SORT4`], [`SORT8`]), the
//! nearest is visited and the others pushed, farthest first. The order only changes
//! the work: closest hits are exact in any order (ties at equal t go to the lower
//! primitive index).

use std::time::Instant;

use glam::Vec3;

use super::{leaf_range, Bvh, BvhBuilder, EMPTY_REF, LEAF_REF, MAX_BVH_DEPTH, MAX_BVH_PRIMS, T_MARGIN};
use crate::accel::prim::{self, Prims};
use crate::accel::sah;
use crate::accel::validate::ValidateError;
use crate::accel::{BuildStats, GpuImage, KernelFamily, Phase, TraceLoop};
use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

/// The sorting network of the 4-wide traversal's child order (five comparators).
pub const SORT4: [(usize, usize); 5] = [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)];

/// The sorting network of the 8-wide traversals' child order (optimal for 8 keys: 19
/// comparators in 6 layers); the kernels run the same comparators in the same order.
pub const SORT8: [(usize, usize); 19] = [
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (2, 4),
    (3, 5),
    (1, 4),
    (3, 6),
    (1, 2),
    (3, 4),
    (5, 6),
];

/// The 4-wide BVH (`bvh4`).
pub type Bvh4 = WideBvh<4>;
/// The 8-wide BVH (`bvh8`).
pub type Bvh8 = WideBvh<8>;

/// A W-wide BVH (W = 4 or 8) in the GPU layout.
#[derive(Debug, Clone)]
pub struct WideBvh<const W: usize> {
    pub bounds: Aabb,
    /// The nodes' texels, [`WideBvh::TEXELS`] per node (see the module docs).
    pub nodes: Vec<[u32; 4]>,
    pub indices: Vec<u32>,
    /// Nodes on the longest root-to-leaf path.
    pub depth: u32,
    pub prims: usize,
    /// The builder of the binary tree that was collapsed.
    pub source: BvhBuilder,
    pub build_ms: f64,
    pub phases: Vec<Phase>,
}

impl<const W: usize> WideBvh<W> {
    /// Children per node.
    pub const WIDTH: usize = W;
    /// Texels per row of the layout.
    const ROW: usize = W / 4;
    /// Texels per node.
    pub const TEXELS: usize = crate::gpu::bindings::WIDE_NODE_PLANES as usize * W / 4;

    /// The structure's name (`bvh4`, `bvh8`).
    pub fn name() -> &'static str {
        if W == 8 {
            "bvh8"
        } else {
            "bvh4"
        }
    }

    /// Builds the binary tree with `source` and collapses it.
    pub fn build(scene: &Scene, source: BvhBuilder) -> Self {
        let start = Instant::now();
        let bin = Bvh::build(scene, source);
        let mut phases = bin.phases.clone();
        let t = Instant::now();
        let mut wide = Self::collapse(&bin);
        phases.push(Phase::since(format!("collapse to {W}-wide"), t));
        wide.phases = phases;
        wide.build_ms = start.elapsed().as_secs_f64() * 1e3;
        wide
    }

    /// Collapses a binary BVH (any builder's) into W-wide nodes.
    pub fn collapse(bin: &Bvh) -> Self {
        assert!(W == 4 || W == 8, "wide BVHs are 4 or 8 wide");
        let mut w = WideBvh {
            bounds: bin.bounds,
            nodes: Vec::with_capacity((bin.nodes.len() / (W / 2) + 1) * Self::TEXELS),
            indices: bin.indices.clone(),
            depth: 0,
            prims: bin.prims,
            source: bin.builder,
            build_ms: 0.0,
            phases: Vec::new(),
        };
        // Wide nodes in preorder, children in order: the numbering the device's collapse
        // gets by counting wide nodes along the binary tree's preorder (gpu_build.rs).
        // (binary inner node, the parent's slot that points at it, depth of the wide node)
        let mut work = vec![(0usize, None::<(usize, usize)>, 1u32)];
        while let Some((b, parent, d)) = work.pop() {
            let slot = w.node_count();
            w.nodes.resize((slot + 1) * Self::TEXELS, [0; 4]);
            if let Some((p, k)) = parent {
                w.set(p * Self::TEXELS, 6, k, slot as u32);
            }
            w.depth = w.depth.max(d);
            let kids = open_wide(bin, b, W);
            let base = slot * Self::TEXELS;
            for k in 0..W {
                w.set(base, 6, k, EMPTY_REF);
            }
            for (k, (r, bx)) in kids.iter().enumerate() {
                let planes = [bx.min.x, bx.min.y, bx.min.z, bx.max.x, bx.max.y, bx.max.z];
                for (row, v) in planes.iter().enumerate() {
                    w.set(base, row, k, v.to_bits());
                }
                // An inner child's reference is set when it gets its slot.
                w.set(base, 6, k, *r);
            }
            for (k, (r, _)) in kids.iter().enumerate().rev() {
                if r & LEAF_REF == 0 {
                    work.push((*r as usize, Some((slot, k)), d + 1));
                }
            }
        }
        w
    }

    /// Sets word `k` (child k) of row `row` of the node whose texels start at `base`.
    fn set(&mut self, base: usize, row: usize, k: usize, v: u32) {
        self.nodes[base + row * Self::ROW + k / 4][k % 4] = v;
    }

    /// Word `k` of row `row` of node `n`.
    pub fn word(&self, n: usize, row: usize, k: usize) -> u32 {
        self.nodes[n * Self::TEXELS + row * Self::ROW + k / 4][k % 4]
    }

    /// Nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len() / Self::TEXELS
    }

    /// Bytes as uploaded.
    pub fn bytes(&self) -> u64 {
        (self.nodes.len() * 16 + self.indices.len() * 4) as u64
    }

    /// Children of node `n`: (reference, box), empty slots included.
    pub fn children(&self, n: usize) -> [(u32, Aabb); W] {
        std::array::from_fn(|k| {
            let f = |row: usize| f32::from_bits(self.word(n, row, k));
            (self.word(n, 6, k), Aabb { min: Vec3::new(f(0), f(1), f(2)), max: Vec3::new(f(3), f(4), f(5)) })
        })
    }

    /// Statistics, with the SAH cost computed as for every other structure (an empty
    /// slot is an empty leaf).
    pub fn stats(&self) -> BuildStats {
        super::tree_stats(Self::name(), self.node_count(), |n| self.children(n), self.bytes(), self.depth, self.prims)
            .with_timing(self.build_ms, &self.phases)
    }

    /// Checks the binary BVH's invariants ([`Bvh::validate`]), and that an empty slot
    /// has an all-zero box.
    pub fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        if self.nodes.is_empty() || self.nodes.len() % Self::TEXELS != 0 {
            return Err(ValidateError::whole(format!("{} texels do not make whole nodes", self.nodes.len())));
        }
        for n in 0..self.node_count() {
            if self.children(n).iter().any(|(r, b)| *r == EMPTY_REF && (b.min != Vec3::ZERO || b.max != Vec3::ZERO)) {
                return Err(ValidateError::node(n, "an empty slot has a box"));
            }
        }
        super::validate_tree(scene, self.node_count(), &self.indices, self.depth, |n| self.children(n))
    }
}

/// The wide kernels' traversal on the CPU (bvh4, bvh8, cwbvh; see the module docs):
/// node `n`'s children are `children(n)`, ordered by `network`.
#[allow(clippy::too_many_arguments)]
pub(super) fn traverse_wide<const W: usize>(
    bounds: &Aabb,
    depth: u32,
    indices: &[u32],
    children: impl Fn(usize) -> [(u32, Aabb); W],
    network: &[(usize, usize)],
    prims: &Prims,
    ray: &Ray,
    best: &mut Hit,
    any: bool,
) -> bool {
    let inv = Aabb::inv_dir(ray.dir);
    if bounds.ray_box(ray.origin, inv, ray.tmin, ray.tmax).is_none() {
        return false;
    }
    let mut stack: Vec<u32> = Vec::with_capacity((W - 1) * depth as usize + 1);
    let mut cur = 0u32;
    let mut found = false;
    loop {
        while cur & LEAF_REF == 0 {
            let limit = best.t * (1.0 + T_MARGIN);
            let mut keys = [f32::INFINITY; W];
            let mut refs = [EMPTY_REF; W];
            for (k, (r, b)) in children(cur as usize).iter().enumerate() {
                refs[k] = *r;
                if *r != EMPTY_REF {
                    if let Some((t0, _)) = b.ray_box(ray.origin, inv, ray.tmin, limit) {
                        keys[k] = t0;
                    }
                }
            }
            let n = keys.iter().filter(|k| **k < f32::INFINITY).count();
            // The kernel's sorting network, comparator for comparator.
            for &(i, j) in network {
                if keys[j] < keys[i] {
                    keys.swap(i, j);
                    refs.swap(i, j);
                }
            }
            if n > 0 {
                stack.extend(refs[1..n].iter().rev());
                cur = refs[0];
            } else {
                match stack.pop() {
                    Some(c) => cur = c,
                    None => return found,
                }
            }
        }
        let (first, count) = leaf_range(cur);
        for &p in &indices[first..first + count] {
            if prim::intersect_prim(prims, p, ray, best) {
                found = true;
                if any {
                    return true;
                }
            }
        }
        match stack.pop() {
            Some(c) => cur = c,
            None => return found,
        }
    }
}

/// The limits of the wide kernels' layouts: depth within the stack, primitives within
/// the reference's 28 bits.
pub(super) fn check_limits(depth: u32, prims: usize) -> Result<(), ValidateError> {
    if depth > MAX_BVH_DEPTH {
        return Err(ValidateError::whole(format!("BVH depth {depth} exceeds the kernel's stack of {MAX_BVH_DEPTH}")));
    }
    if prims > MAX_BVH_PRIMS {
        return Err(ValidateError::whole(format!("{prims} primitives exceed the BVH layout's {MAX_BVH_PRIMS}")));
    }
    Ok(())
}

/// The children of a wide node collapsed from binary inner node `b`: its two children,
/// then, while fewer than `width`, the inner child of largest surface area (the first
/// of equal ones) replaced in place by its own two children. Empty references are
/// left out.
pub(super) fn open_wide(bin: &Bvh, b: usize, width: usize) -> Vec<(u32, Aabb)> {
    let mut kids: Vec<(u32, Aabb)> = bin.children(b).into_iter().filter(|(r, _)| *r != EMPTY_REF).collect();
    while kids.len() < width {
        let open = kids.iter().enumerate().filter(|(_, (r, _))| r & LEAF_REF == 0).fold(
            None::<(usize, f32)>,
            |best, (i, (_, bx))| {
                let a = sah::area(bx);
                match best {
                    Some((_, ba)) if ba >= a => best,
                    _ => Some((i, a)),
                }
            },
        );
        let Some((i, _)) = open else { break };
        let (r, _) = kids.remove(i);
        let grand: Vec<(u32, Aabb)> = bin.children(r as usize).into_iter().filter(|(r, _)| *r != EMPTY_REF).collect();
        for (k, g) in grand.into_iter().enumerate() {
            kids.insert(i + k, g);
        }
    }
    kids
}

impl<const W: usize> crate::accel::Traverse for WideBvh<W> {
    fn traverse(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        let network: &[(usize, usize)] = if W == 8 { &SORT8 } else { &SORT4 };
        traverse_wide(&self.bounds, self.depth, &self.indices, |n| self.children(n), network, prims, ray, best, any)
    }
}

impl<const W: usize> crate::accel::Structure for WideBvh<W> {
    fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        WideBvh::validate(self, scene)
    }
    fn stats(&self, _scene: &Scene) -> BuildStats {
        WideBvh::stats(self)
    }
    fn timing(&self) -> (f64, Vec<Phase>) {
        (self.build_ms, self.phases.clone())
    }
    fn bounds(&self) -> Aabb {
        self.bounds
    }
    fn gpu_image(&self, _scene: &Scene) -> Result<GpuImage<'_>, ValidateError> {
        check_limits(self.depth, self.prims)?;
        // Each node visited pushes at most W - 1 children.
        let stack_size = (W as u32 - 1) * self.depth + 1;
        Ok(GpuImage {
            family: if W == 8 { KernelFamily::Bvh8 } else { KernelFamily::Bvh4 },
            buffers: Some(crate::accel::AccelBuffers::Host(
                std::borrow::Cow::Borrowed(bytemuck::cast_slice(&self.nodes)),
                &self.indices,
            )),
            stack_size,
            cost_per_ray: W as u64 * (u64::from(self.depth) + 8),
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
    fn the_networks_sort_every_input() {
        // The 0-1 principle: a comparator network that sorts all binary inputs sorts
        // every input.
        fn check<const N: usize>(network: &[(usize, usize)]) {
            for bits in 0u32..(1 << N) {
                let mut v: [u32; N] = std::array::from_fn(|k| (bits >> k) & 1);
                for &(i, j) in network {
                    if v[j] < v[i] {
                        v.swap(i, j);
                    }
                }
                assert!(v.windows(2).all(|w| w[0] <= w[1]), "{bits:b} -> {v:?}");
            }
        }
        check::<4>(&SORT4);
        check::<8>(&SORT8);
    }
}
