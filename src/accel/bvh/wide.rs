//! The 4-wide BVH (`bvh4`): the binary tree of a BVH builder (binned SAH, `bvh-sah`)
//! collapsed so that each node holds up to four children. Fewer, wider nodes mean
//! fewer traversal steps; on lavapipe each step pays the whole loop body for all 8
//! lanes (docs/lavapipe.md), so halving the steps matters more than the extra boxes.
//!
//! Collapse: a wide node starts with the two children of a binary node and, while it
//! has fewer than four, replaces its inner child of largest surface area by that
//! child's two children. Leaves and their index ranges are the binary tree's, and the
//! child boxes are the binary tree's boxes, exactly (full precision, so every
//! robustness guarantee of the binary BVH holds unchanged).
//!
//! GPU layout: 112 bytes (7 texels) per node, structure of arrays over the 4 children:
//!
//! ```text
//! uvec4 0: min x of children 0..3 (f32 bits)
//! uvec4 1: min y
//! uvec4 2: min z
//! uvec4 3: max x
//! uvec4 4: max y
//! uvec4 5: max z
//! uvec4 6: child references 0..3, encoded as the binary BVH's (bit 31: leaf, first
//!          index << 3 | count - 1; 0xffffffff: no child, its box all zeros)
//! ```
//!
//! Traversal (`shaders/accel/bvh4.glsl`, mirrored by [`Bvh4`]'s CPU traversal): the
//! four boxes are tested against [tmin, best t (1 + T_MARGIN)], the hit children are
//! sorted by entry distance (a five-comparator network), the nearest is visited and
//! the others pushed, farthest first. The order only changes the work: closest hits
//! are exact in any order (ties at equal t go to the lower primitive index).

use std::time::Instant;

use glam::Vec3;

use super::{leaf_range, Bvh, BvhBuilder, EMPTY_REF, LEAF_REF, MAX_BVH_DEPTH, MAX_BVH_PRIMS, T_MARGIN};
use crate::accel::prim::{self, Prims};
use crate::accel::sah;
use crate::accel::validate::ValidateError;
use crate::accel::{BuildStats, GpuImage, Phase, TraceLoop};
use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

/// Children per node.
pub const WIDTH: usize = 4;

/// One node as the kernel reads it (see the module docs).
pub type GpuBvh4Node = [[u32; 4]; 7];

/// A 4-wide BVH in the GPU layout.
#[derive(Debug, Clone)]
pub struct Bvh4 {
    pub bounds: Aabb,
    pub nodes: Vec<GpuBvh4Node>,
    pub indices: Vec<u32>,
    /// Nodes on the longest root-to-leaf path.
    pub depth: u32,
    pub prims: usize,
    /// The builder of the binary tree that was collapsed.
    pub source: BvhBuilder,
    pub build_ms: f64,
    pub phases: Vec<Phase>,
}

impl Bvh4 {
    /// Builds the binary tree with `source` and collapses it.
    pub fn build(scene: &Scene, source: BvhBuilder) -> Bvh4 {
        let start = Instant::now();
        let bin = Bvh::build(scene, source);
        let mut phases = bin.phases.clone();
        let t = Instant::now();
        let mut wide = Self::collapse(&bin);
        phases.push(Phase { name: "collapse to 4-wide".into(), ms: t.elapsed().as_secs_f64() * 1e3, detail: None });
        wide.phases = phases;
        wide.build_ms = start.elapsed().as_secs_f64() * 1e3;
        wide
    }

    /// Collapses a binary BVH (any builder's) into 4-wide nodes.
    pub fn collapse(bin: &Bvh) -> Bvh4 {
        let mut w = Bvh4 {
            bounds: bin.bounds,
            nodes: Vec::with_capacity(bin.nodes.len() / 2 + 1),
            indices: bin.indices.clone(),
            depth: 0,
            prims: bin.prims,
            source: bin.builder,
            build_ms: 0.0,
            phases: Vec::new(),
        };
        // (binary inner node, wide slot to fill, depth of the wide node)
        let mut work = vec![(0usize, 0usize, 1u32)];
        w.nodes.push([[0; 4]; 7]);
        while let Some((b, slot, d)) = work.pop() {
            w.depth = w.depth.max(d);
            let kids = open_wide(bin, b, WIDTH);
            let mut node: GpuBvh4Node = [[0; 4]; 7];
            node[6] = [EMPTY_REF; 4];
            for (k, (r, bx)) in kids.iter().enumerate() {
                node[0][k] = bx.min.x.to_bits();
                node[1][k] = bx.min.y.to_bits();
                node[2][k] = bx.min.z.to_bits();
                node[3][k] = bx.max.x.to_bits();
                node[4][k] = bx.max.y.to_bits();
                node[5][k] = bx.max.z.to_bits();
                node[6][k] = if r & LEAF_REF != 0 {
                    *r
                } else {
                    let child = w.nodes.len();
                    w.nodes.push([[0; 4]; 7]);
                    work.push((*r as usize, child, d + 1));
                    child as u32
                };
            }
            w.nodes[slot] = node;
        }
        w
    }

    /// Bytes as uploaded.
    pub fn bytes(&self) -> u64 {
        (self.nodes.len() * std::mem::size_of::<GpuBvh4Node>() + self.indices.len() * 4) as u64
    }

    /// Children of node `n`: (reference, box), empty slots included.
    pub fn children(&self, n: usize) -> [(u32, Aabb); WIDTH] {
        let c = &self.nodes[n];
        std::array::from_fn(|k| {
            let f = |row: usize| f32::from_bits(c[row][k]);
            (c[6][k], Aabb { min: Vec3::new(f(0), f(1), f(2)), max: Vec3::new(f(3), f(4), f(5)) })
        })
    }

    /// Statistics, with the SAH cost computed as for every other structure (an empty
    /// slot is an empty leaf).
    pub fn stats(&self) -> BuildStats {
        super::tree_stats("bvh4", self.nodes.len(), |n| self.children(n), self.bytes(), self.depth, self.prims)
            .with_timing(self.build_ms, &self.phases)
    }

    /// Checks the binary BVH's invariants ([`Bvh::validate`]), and that an empty slot
    /// has an all-zero box.
    pub fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        for n in 0..self.nodes.len() {
            if self.children(n).iter().any(|(r, b)| *r == EMPTY_REF && (b.min != Vec3::ZERO || b.max != Vec3::ZERO)) {
                return Err(ValidateError::node(n, "an empty slot has a box"));
            }
        }
        super::validate_tree(scene, self.nodes.len(), &self.indices, self.depth, |n| self.children(n))
    }

    /// The kernel's traversal on the CPU (see the module docs).
    fn traverse_impl(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        let inv = Aabb::inv_dir(ray.dir);
        if self.bounds.ray_box(ray.origin, inv, ray.tmin, ray.tmax).is_none() {
            return false;
        }
        let mut stack: Vec<u32> = Vec::with_capacity(3 * self.depth as usize + 1);
        let mut cur = 0u32;
        let mut found = false;
        loop {
            while cur & LEAF_REF == 0 {
                let limit = best.t * (1.0 + T_MARGIN);
                let kids = self.children(cur as usize);
                let mut keys = [f32::INFINITY; WIDTH];
                let mut refs = [EMPTY_REF; WIDTH];
                for (k, (r, b)) in kids.iter().enumerate() {
                    refs[k] = *r;
                    if *r != EMPTY_REF {
                        if let Some((t0, _)) = b.ray_box(ray.origin, inv, ray.tmin, limit) {
                            keys[k] = t0;
                        }
                    }
                }
                let n = keys.iter().filter(|k| **k < f32::INFINITY).count();
                // The kernel's sorting network, comparator for comparator.
                for (i, j) in [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)] {
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
            for &p in &self.indices[first..first + count] {
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

impl crate::accel::Traverse for Bvh4 {
    fn traverse(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        self.traverse_impl(prims, ray, best, any)
    }
}

impl crate::accel::Structure for Bvh4 {
    fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        Bvh4::validate(self, scene)
    }
    fn stats(&self, _scene: &Scene) -> BuildStats {
        Bvh4::stats(self)
    }
    fn timing(&self) -> (f64, Vec<Phase>) {
        (self.build_ms, self.phases.clone())
    }
    fn bounds(&self) -> Aabb {
        self.bounds
    }
    fn gpu_image(&self, _scene: &Scene) -> Result<GpuImage<'_>, ValidateError> {
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
        Ok(GpuImage {
            family: "bvh4",
            buffers: Some((std::borrow::Cow::Borrowed(bytemuck::cast_slice(&self.nodes)), &self.indices)),
            // Each node visited pushes at most 3 children.
            stack_size: 3 * self.depth + 1,
            cost_per_ray: 4 * (u64::from(self.depth) + 8),
            trace_loop: TraceLoop::StepBudget,
        })
    }
}
