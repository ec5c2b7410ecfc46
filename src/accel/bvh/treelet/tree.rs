//! The tree being restructured ([`Restructure`]): its nodes ([`Slot`]) with primitive
//! counts and costs, shared by the threads of a round; fitting them bottom-up; the
//! SAH cost with collapse; and flattening where it is ([`Nodes`]).

use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

use glam::Vec3;
use rayon::prelude::*;

use super::TREELET_LEAVES;
use crate::accel::bvh::{BNode, Binary, Nodes, LEAF_FLAG, MAX_LEAF};
use crate::accel::sah::{area, SahCosts};
use crate::math::Aabb;

// A node is 40 bytes (docs/bvh.md, "trbvh"): the settled mark shares the count's word.
const _: () = assert!(std::mem::size_of::<Slot>() == 40);
/// Levels of the tree split between parallel tasks when fitting it (2^10 subtrees).
const FIT_PAR_LEVELS: u32 = 10;

/// One node of the tree being restructured, shared by the threads of a round.
///
/// Treelets in disjoint subtrees are optimised by parallel tasks (`rayon::join`), and
/// a treelet writes only nodes of its own subtree, which the parent's treelet reads
/// only after the join. So relaxed atomics (plain loads and stores on x86) carry every
/// field, and no `unsafe` is needed.
#[derive(Debug)]
pub(super) struct Slot {
    /// min xyz, max xyz (f32 bits).
    bounds: [AtomicU32; 6],
    pub(super) left: AtomicU32,
    pub(super) right: AtomicU32,
    /// Primitives below, and [`SETTLED`] (a 40-byte node instead of 44: 8 MB less
    /// memory to clear per million primitives).
    count: AtomicU32,
    /// Unnormalised SAH cost of the subtree, with collapse (f32 bits).
    cost: AtomicU32,
}

/// Bit of [`Slot::count`]: the treelet rooted here was optimised without change and
/// no node below has changed since, so optimising it again would change nothing.
/// Counts stay below 2^31 (primitive indices do, see `LEAF_FLAG`).
const SETTLED: u32 = 1 << 31;

impl Slot {
    /// A box as the six values of `bounds`.
    pub(super) fn lanes(b: &Aabb) -> [f32; 6] {
        [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z]
    }
    fn new(n: &BNode) -> Slot {
        Slot {
            bounds: Self::lanes(&n.bounds).map(|v| AtomicU32::new(v.to_bits())),
            left: AtomicU32::new(n.left),
            right: AtomicU32::new(n.right),
            count: AtomicU32::new(0),
            cost: AtomicU32::new(0),
        }
    }
    /// As `new`, with a leaf's cost (C_I·A·N) and count set.
    pub(super) fn with_cost(n: &BNode, costs: &SahCosts) -> Slot {
        let s = Slot::new(n);
        if n.is_leaf() {
            s.set_cost(n.right, costs.intersect * area(&n.bounds) * n.right as f32);
        }
        s
    }
    pub(super) fn bounds(&self) -> Aabb {
        let f = |i: usize| f32::from_bits(self.bounds[i].load(Relaxed));
        Aabb { min: Vec3::new(f(0), f(1), f(2)), max: Vec3::new(f(3), f(4), f(5)) }
    }
    fn node(&self) -> BNode {
        BNode { bounds: self.bounds(), left: self.left.load(Relaxed), right: self.right.load(Relaxed) }
    }
    pub(super) fn is_leaf(&self) -> bool {
        self.left.load(Relaxed) & LEAF_FLAG != 0
    }
    pub(super) fn count(&self) -> u32 {
        self.count.load(Relaxed) & !SETTLED
    }
    pub(super) fn settled(&self) -> bool {
        self.count.load(Relaxed) & SETTLED != 0
    }
    /// Marks the treelet rooted here settled (see [`SETTLED`]); a new count and cost
    /// ([`Slot::set_cost`]) clear the mark.
    pub(super) fn mark_settled(&self) {
        self.count.store(self.count.load(Relaxed) | SETTLED, Relaxed);
    }
    pub(super) fn cost(&self) -> f32 {
        f32::from_bits(self.cost.load(Relaxed))
    }
    /// Sets the count and cost, and clears [`SETTLED`].
    pub(super) fn set_cost(&self, count: u32, cost: f32) {
        self.count.store(count, Relaxed);
        self.cost.store(cost.to_bits(), Relaxed);
    }
    pub(super) fn set_inner(&self, left: u32, right: u32, b: &Aabb) {
        for (a, v) in self.bounds.iter().zip(Self::lanes(b)) {
            a.store(v.to_bits(), Relaxed);
        }
        self.left.store(left, Relaxed);
        self.right.store(right, Relaxed);
    }
}

/// The tree being restructured: its nodes with primitive counts and costs, kept
/// across rounds. Flatten it where it is (it is [`Nodes`]), or copy the result into
/// a [`Binary`] with [`Restructure::write_back`].
#[derive(Debug)]
pub struct Restructure {
    pub(super) costs: SahCosts,
    /// Leaves per treelet (3..=TREELET_LEAVES).
    pub(super) leaves: usize,
    pub(super) slots: Vec<Slot>,
    pub(super) root: u32,
    /// The primitive order leaves index into.
    pub(super) prims: Vec<u32>,
}

impl Restructure {
    /// The tree `bin` (an LBVH or any canonical tree) with every inner node's box
    /// fitted to its children's (whatever `bin` holds there: an LBVH comes unfitted),
    /// primitive count and cost, in one parallel post-order pass.
    pub fn new(bin: &Binary, costs: &SahCosts) -> Restructure {
        Self::with_leaves(bin, costs, TREELET_LEAVES)
    }

    /// As `new`, with treelets of `leaves` leaves (clamped to 3..=TREELET_LEAVES).
    pub fn with_leaves(bin: &Binary, costs: &SahCosts, leaves: usize) -> Restructure {
        let slots: Vec<Slot> = bin.nodes.par_iter().map(|n| Slot::with_cost(n, costs)).collect();
        let r = Restructure {
            costs: *costs,
            leaves: leaves.clamp(3, TREELET_LEAVES),
            slots,
            root: bin.root,
            prims: bin.prims.clone(),
        };
        r.fit(r.root, 0);
        r
    }

    /// Fits the box, count and cost of every inner node below `x` (children before
    /// parents). Inner counts are not known yet, so the tree is split between
    /// parallel tasks by depth, down to [`FIT_PAR_LEVELS`] (work stealing evens out
    /// uneven subtrees); below that, [`Restructure::fit_serial`].
    fn fit(&self, x: u32, depth: u32) {
        let s = &self.slots[x as usize];
        if s.is_leaf() {
            return;
        }
        if depth >= FIT_PAR_LEVELS {
            return self.fit_serial(x);
        }
        let (l, r) = (s.left.load(Relaxed), s.right.load(Relaxed));
        rayon::join(|| self.fit(l, depth + 1), || self.fit(r, depth + 1));
        self.fit_node(x);
    }

    /// [`Restructure::fit`] in one task: the inner nodes are listed level by level
    /// ([`Restructure::inner_below`]), then fitted in the reverse order, children
    /// before parents.
    fn fit_serial(&self, top: u32) {
        for &x in self.inner_below(vec![top], usize::MAX).iter().rev() {
            self.fit_node(x);
        }
    }

    /// The inner nodes `start`, then those up to `levels` levels below them, level by
    /// level. Each level's nodes are read first in a loop without branches
    /// ([`Restructure::touch`]), so that their cache misses overlap, where a
    /// depth-first walk waits on each node before it knows the next.
    pub(super) fn inner_below(&self, start: Vec<u32>, levels: usize) -> Vec<u32> {
        let mut list = start;
        let mut kids: Vec<u32> = Vec::new();
        let mut level = 0..list.len();
        for _ in 0..levels {
            if level.is_empty() {
                break;
            }
            kids.clear();
            for &x in &list[level.clone()] {
                let s = &self.slots[x as usize];
                kids.push(s.left.load(Relaxed));
                kids.push(s.right.load(Relaxed));
            }
            self.touch(kids.iter().copied());
            let first = list.len();
            list.extend(kids.iter().copied().filter(|&c| !self.slots[c as usize].is_leaf()));
            level = first..list.len();
        }
        list
    }

    /// Sets inner node `x`'s box, count and cost from its children's.
    fn fit_node(&self, x: u32) {
        let s = &self.slots[x as usize];
        let (left, right) = (s.left.load(Relaxed), s.right.load(Relaxed));
        let (l, rt) = (&self.slots[left as usize], &self.slots[right as usize]);
        let b = l.bounds().union(&rt.bounds());
        s.set_inner(left, right, &b);
        let count = l.count() + rt.count();
        s.set_cost(count, self.node_cost(&b, count, l.cost() + rt.cost()));
    }

    pub(super) fn node_cost(&self, b: &Aabb, count: u32, children: f32) -> f32 {
        self.cost_of_area(area(b), count, children)
    }

    /// [`Restructure::node_cost`] of a node of area `a`.
    #[inline]
    fn cost_of_area(&self, a: f32, count: u32, children: f32) -> f32 {
        let split = self.costs.traversal * a + children;
        if count as usize <= MAX_LEAF {
            split.min(self.costs.intersect * a * count as f32)
        } else {
            split
        }
    }

    /// Cost of the whole tree relative to the root's area (with collapse).
    pub fn root_cost(&self) -> f64 {
        let root = &self.slots[self.root as usize];
        let a = f64::from(area(&root.bounds()));
        if a > 0.0 {
            f64::from(root.cost()) / a
        } else {
            0.0
        }
    }

    /// Copies the current topology and boxes into `bin` (the tree this was made from).
    pub fn write_back(&self, bin: &mut Binary) {
        bin.nodes.par_iter_mut().zip(&self.slots).for_each(|(n, s)| *n = s.node());
    }

    /// Reads the nodes `ids` (both ends of each: a node may straddle two cache lines)
    /// in a loop without branches, so that their cache misses overlap.
    pub(super) fn touch(&self, ids: impl Iterator<Item = u32>) {
        let seen = ids.fold(0u32, |a, c| {
            let s = &self.slots[c as usize];
            a ^ s.bounds[0].load(Relaxed) ^ s.cost.load(Relaxed)
        });
        std::hint::black_box(seen);
    }
}

/// The tree being restructured, flattened where it is.
impl Nodes for Restructure {
    fn root(&self) -> u32 {
        self.root
    }
    #[inline]
    fn node(&self, n: u32) -> BNode {
        self.slots[n as usize].node()
    }
    fn prims(&self) -> &[u32] {
        &self.prims
    }
    /// Whether inner node `n`'s subtree is cheaper as one leaf (of at most
    /// [`MAX_LEAF`] primitives).
    fn collapsed(&self, n: u32) -> bool {
        let s = &self.slots[n as usize];
        if s.is_leaf() || s.count() as usize > MAX_LEAF {
            return false;
        }
        let leaf = self.costs.intersect * area(&s.bounds()) * s.count() as f32;
        leaf <= s.cost()
    }
    fn read_ahead(&self, n: u32) {
        let s = &self.slots[n as usize];
        self.touch([s.left.load(Relaxed), s.right.load(Relaxed)].into_iter());
    }
}
