//! The LBVH built straight into the restructuring's nodes ([`Restructure::lbvh`]):
//! Morton codes sorted as [`lbvh`] sorts them, then one bottom-up climb from the
//! leaves that links and fits the radix tree of Karras (2012), in the agglomerative
//! order of Apetrei (2014).

use std::sync::atomic::{AtomicU32, Ordering::AcqRel};
use std::time::Instant;

use rayon::prelude::*;

use super::tree::{Restructure, Slot};
use super::TREELET_LEAVES;
use crate::accel::bvh::{lap, lbvh, BNode, PrimRefs};
use crate::accel::sah::SahCosts;
use crate::accel::Phase;
use crate::math::Aabb;

impl Restructure {
    /// The LBVH of `refs` built straight into the restructuring's nodes (no
    /// [`Binary`] in between) and fitted as [`Restructure::new`] does, by one climb
    /// from the leaves (`Restructure::climb`); with treelets of `leaves` leaves.
    /// Records the phases `morton + sort` and `hierarchy + fit`.
    ///
    /// [`Binary`]: crate::accel::bvh::Binary
    pub fn lbvh(
        refs: &PrimRefs,
        costs: &SahCosts,
        leaves: usize,
        phases: &mut Vec<Phase>,
        t: &mut Instant,
    ) -> Restructure {
        if refs.len() < 2 {
            let bin = lbvh::build(refs, phases, t);
            let r = Self::with_leaves(&bin, costs, leaves);
            lap(phases, "hierarchy + fit", t);
            return r;
        }
        let keys = lbvh::sorted_keys(refs);
        lap(phases, "morton + sort", t);
        let prims = lbvh::key_prims(&keys);
        let n = keys.len();
        // Leaves n - 1 + j (key j), with their costs; inner nodes written by the climb.
        let slots = (0..2 * n - 1)
            .into_par_iter()
            .map(|i| {
                let j = i.wrapping_sub(n - 1);
                let node = if i < n - 1 {
                    BNode { bounds: Aabb::EMPTY, left: 0, right: 0 }
                } else {
                    BNode::leaf(refs.bounds[prims[j] as usize], j as u32, 1)
                };
                Slot::with_cost(&node, costs)
            })
            .collect();
        let r = Restructure { costs: *costs, leaves: leaves.clamp(3, TREELET_LEAVES), slots, root: 0, prims };
        let arrived: Vec<AtomicU32> = (0..n - 1).into_par_iter().map(|_| AtomicU32::new(u32::MAX)).collect();
        (0..n).into_par_iter().for_each(|j| r.climb(&keys, &arrived, j));
        lap(phases, "hierarchy + fit", t);
        r
    }

    /// Builds and fits the radix tree over the sorted `keys` from leaf `j` up, in the
    /// agglomerative order of Apetrei ("Fast and simple agglomerative LBVH
    /// construction", 2014), as the GPU build does, with Karras's node numbers (inner
    /// node i is the one whose range ends at i next to its parent's split), so the tree
    /// is [`lbvh::build`]'s. A node of keys lo..=hi hangs from whichever neighbouring
    /// split joins two keys with the longer common prefix. The first of a split's
    /// two children to arrive leaves the far end of its range in the split's word of
    /// `arrived` and stops; the second learns its parent's range, fits the parent from
    /// both children and climbs on. The word's swap orders the first child's writes
    /// before the second's reads (acquire and release). One task per leaf.
    fn climb(&self, keys: &[u64], arrived: &[AtomicU32], j: usize) {
        let n = keys.len();
        // Common prefix of keys i and i + 1.
        let delta = |i: usize| (keys[i] ^ keys[i + 1]).leading_zeros();
        let is_left = |lo: usize, hi: usize| lo == 0 || (hi != n - 1 && delta(hi) > delta(lo - 1));
        let (mut lo, mut hi) = (j, j);
        while !(lo == 0 && hi == n - 1) {
            let left = is_left(lo, hi);
            let split = if left { hi } else { lo - 1 };
            let far = if left { lo } else { hi } as u32;
            let other = arrived[split].swap(far, AcqRel);
            if other == u32::MAX {
                return;
            }
            if left {
                hi = other as usize;
            } else {
                lo = other as usize;
            }
            let l = if lo == split { n - 1 + split } else { split };
            let r = if hi == split + 1 { n + split } else { split + 1 };
            let p = if lo == 0 && hi == n - 1 {
                0
            } else if is_left(lo, hi) {
                hi
            } else {
                lo
            };
            let (ls, rs) = (&self.slots[l], &self.slots[r]);
            let b = ls.bounds().union(&rs.bounds());
            let count = ls.count() + rs.count();
            let slot = &self.slots[p];
            slot.set_inner(l as u32, r as u32, &b);
            slot.set_cost(count, self.node_cost(&b, count, ls.cost() + rs.cost()));
        }
    }
}
