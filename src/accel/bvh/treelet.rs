//! Treelet restructuring after Karras & Aila, "Fast parallel construction of
//! high-quality bounding volume hierarchies" (HPG 2013).
//!
//! A treelet is formed at an inner node by starting from its two children and
//! repeatedly expanding the treelet leaf with the largest surface area (only inner
//! nodes can be expanded) until it has [`TREELET_LEAVES`] leaves. Its optimal topology
//! is found by dynamic programming over the subsets of its leaves: for every subset S,
//! the cheapest of splitting it into two subsets (C_T·A(S) + c(P) + c(S∖P)) and, when
//! S holds at most [`MAX_LEAF`] primitives, of making it one leaf (C_I·A(S)·N(S)). The
//! treelet's inner nodes are reused for the new topology; subtrees below its leaves are
//! kept intact.
//!
//! Nodes are processed bottom-up, so a treelet is optimised after every treelet below
//! it, and only at nodes whose subtree holds at least γ primitives. As in the paper,
//! several rounds run with γ doubling each round ([`gamma`]). A round is a post-order
//! walk that prunes subtrees below γ primitives; the two subtrees of a large node are
//! walked by parallel tasks, since their treelets are disjoint. The result does not
//! depend on thread count or order: each treelet's solution reads only its own subtree
//! (restructuring permutes nodes only within a treelet, so every node's subtree keeps
//! its set of nodes), and the GPU kernel, which goes bottom-up by levels, gets the
//! same tree. A treelet that was optimised without change, and under which nothing
//! has changed since, is skipped in later rounds: its optimum would be the same.
//!
//! A restructuring is applied only when it lowers the treelet root's cost, so the SAH
//! cost (with collapse) never increases. Afterwards [`Restructure::collapse_flags`]
//! marks the subtrees that are cheaper as one leaf.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering::Relaxed};

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use super::{BNode, Binary, LEAF_FLAG, MAX_LEAF};
use crate::accel::sah::{area, SahCosts};
use crate::math::Aabb;

/// Most leaves per treelet (the paper's choice, and the default).
pub const TREELET_LEAVES: usize = 7;
/// A treelet is rewritten only when its optimised cost is below this fraction of its
/// cost (so rounding noise never rewrites a tree); the GPU build gets the same bits.
pub const KEEP_FACTOR: f32 = 1.0 - 1e-6;
/// Rounds of restructuring by default.
pub const ROUNDS: u32 = 3;

/// Minimum primitives below a treelet root in `round` (0-based) for the default
/// treelet size: 7, 14, 28.
pub fn gamma(round: u32) -> u32 {
    (TREELET_LEAVES as u32) << round
}

/// Treelet restructuring parameters: the user's trade between build time and SAH.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TreeletParams {
    /// Leaves per treelet, 3..=7: the dynamic programming costs about 3^leaves.
    pub leaves: usize,
    /// Rounds, each with twice the minimum subtree size of the last (leaves, 2 leaves, ...).
    pub rounds: u32,
}

impl Default for TreeletParams {
    /// The paper's 7 leaves and 3 rounds.
    fn default() -> Self {
        TreeletParams { leaves: TREELET_LEAVES, rounds: ROUNDS }
    }
}

impl TreeletParams {
    /// Faster: 5-leaf treelets. Measured at 100k triangles (median of 9 builds,
    /// lavapipe machine): 1.6x faster than the default for a 1% higher SAH cost.
    pub fn fast() -> Self {
        TreeletParams { leaves: 5, ..Self::default() }
    }

    /// Minimum primitives below a treelet root in `round` (0-based).
    pub fn gamma(&self, round: u32) -> u32 {
        (self.leaves as u32) << round
    }

    /// Parses a preset (`default`, `fast`) or `leaves=N,rounds=N` over the default.
    pub fn parse(spec: &str) -> Result<TreeletParams, String> {
        let mut p = TreeletParams::default();
        for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            match item {
                "default" => p = TreeletParams::default(),
                "fast" => p = TreeletParams::fast(),
                _ => {
                    let (k, v) = item
                        .split_once('=')
                        .ok_or_else(|| format!("--trbvh {item:?}: expected a preset (default, fast) or KEY=VALUE"))?;
                    let n: u32 = v.parse().map_err(|_| format!("--trbvh {k}={v}: expected a whole number"))?;
                    match k {
                        "leaves" if (3..=TREELET_LEAVES as u32).contains(&n) => p.leaves = n as usize,
                        "leaves" => return Err(format!("--trbvh leaves={v}: expected 3..={TREELET_LEAVES}")),
                        "rounds" if n <= 8 => p.rounds = n,
                        "rounds" => return Err(format!("--trbvh rounds={v}: expected 0..=8")),
                        _ => return Err(format!("--trbvh: unknown key '{k}' (leaves, rounds)")),
                    }
                }
            }
        }
        Ok(p)
    }
}

const SUBSETS: usize = 1 << TREELET_LEAVES;

/// Subtrees with at least this many primitives are visited by parallel tasks; smaller
/// ones by one task, serially.
const PAR_GRAIN: u32 = 2048;
/// Deepest level visited by parallel recursion; deeper subtrees (only in degenerate
/// trees) are visited serially with an explicit stack.
const PAR_DEPTH: u32 = 48;

/// One node of the tree being restructured, shared by the threads of a round.
///
/// Treelets in disjoint subtrees are optimised by parallel tasks (`rayon::join`), and
/// a treelet writes only nodes of its own subtree, which the parent's treelet reads
/// only after the join. So relaxed atomics (plain loads and stores on x86) carry every
/// field, and no `unsafe` is needed.
#[derive(Debug)]
struct Slot {
    /// min xyz, max xyz (f32 bits).
    bounds: [AtomicU32; 6],
    left: AtomicU32,
    right: AtomicU32,
    /// Primitives below.
    count: AtomicU32,
    /// Unnormalised SAH cost of the subtree, with collapse (f32 bits).
    cost: AtomicU32,
    /// The treelet rooted here was optimised without change and no node below has
    /// changed since: optimising it again would change nothing.
    settled: AtomicBool,
}

impl Slot {
    /// A box as the six values of `bounds`.
    fn lanes(b: &Aabb) -> [f32; 6] {
        [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z]
    }
    fn new(n: &BNode) -> Slot {
        Slot {
            bounds: Self::lanes(&n.bounds).map(|v| AtomicU32::new(v.to_bits())),
            left: AtomicU32::new(n.left),
            right: AtomicU32::new(n.right),
            count: AtomicU32::new(0),
            cost: AtomicU32::new(0),
            settled: AtomicBool::new(false),
        }
    }
    fn bounds(&self) -> Aabb {
        let f = |i: usize| f32::from_bits(self.bounds[i].load(Relaxed));
        Aabb { min: Vec3::new(f(0), f(1), f(2)), max: Vec3::new(f(3), f(4), f(5)) }
    }
    fn node(&self) -> BNode {
        BNode { bounds: self.bounds(), left: self.left.load(Relaxed), right: self.right.load(Relaxed) }
    }
    fn is_leaf(&self) -> bool {
        self.left.load(Relaxed) & LEAF_FLAG != 0
    }
    fn count(&self) -> u32 {
        self.count.load(Relaxed)
    }
    fn cost(&self) -> f32 {
        f32::from_bits(self.cost.load(Relaxed))
    }
    fn set_cost(&self, count: u32, cost: f32) {
        self.count.store(count, Relaxed);
        self.cost.store(cost.to_bits(), Relaxed);
    }
    fn set_inner(&self, left: u32, right: u32, b: &Aabb) {
        for (a, v) in self.bounds.iter().zip(Self::lanes(b)) {
            a.store(v.to_bits(), Relaxed);
        }
        self.left.store(left, Relaxed);
        self.right.store(right, Relaxed);
    }
}

/// The tree being restructured: its nodes with primitive counts and costs, kept
/// across rounds. Read the result back with [`Restructure::write_back`].
#[derive(Debug)]
pub struct Restructure {
    costs: SahCosts,
    /// Leaves per treelet (3..=TREELET_LEAVES).
    leaves: usize,
    slots: Vec<Slot>,
    root: u32,
}

/// A new topology for one treelet: (node, left, right, box, cost, count) per inner node.
struct Update {
    len: usize,
    entries: [(u32, u32, u32, Aabb, f32, u32); TREELET_LEAVES - 1],
}

/// Treelet restructuring work in one round.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct RoundStats {
    /// Treelets whose topology was optimised.
    pub optimised: u32,
    /// Of those, treelets rewritten because the optimum was cheaper.
    pub rewritten: u32,
    /// Treelets skipped because nothing in them changed since they were last optimised
    /// without change (the optimum would be the same).
    pub skipped: u32,
}

impl std::ops::Add for RoundStats {
    type Output = RoundStats;
    fn add(self, o: RoundStats) -> RoundStats {
        RoundStats {
            optimised: self.optimised + o.optimised,
            rewritten: self.rewritten + o.rewritten,
            skipped: self.skipped + o.skipped,
        }
    }
}

impl Restructure {
    /// Counts and costs of `bin` (an LBVH or any canonical tree).
    pub fn new(bin: &Binary, costs: &SahCosts) -> Restructure {
        Self::with_leaves(bin, costs, TREELET_LEAVES)
    }

    /// As `new`, with treelets of `leaves` leaves (clamped to 3..=TREELET_LEAVES).
    pub fn with_leaves(bin: &Binary, costs: &SahCosts, leaves: usize) -> Restructure {
        let leaves = leaves.clamp(3, TREELET_LEAVES);
        let slots: Vec<Slot> = bin.nodes.par_iter().map(Slot::new).collect();
        slots.par_iter().filter(|s| s.is_leaf()).for_each(|s| {
            let count = s.right.load(Relaxed);
            s.set_cost(count, costs.intersect * area(&s.bounds()) * count as f32);
        });
        let r = Restructure { costs: *costs, leaves, slots, root: bin.root };
        // Inner nodes bottom-up (children before parents).
        r.post_order(r.root, 0, &|_| true, &|i, _| {
            let s = &r.slots[i as usize];
            let (l, rt) = (&r.slots[s.left.load(Relaxed) as usize], &r.slots[s.right.load(Relaxed) as usize]);
            let count = l.count() + rt.count();
            s.set_cost(count, r.node_cost(&s.bounds(), count, l.cost() + rt.cost()));
            (false, RoundStats::default())
        });
        r
    }

    fn node_cost(&self, b: &Aabb, count: u32, children: f32) -> f32 {
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

    /// Post-order visit of the inner nodes below `x` that `enter` accepts (a node not
    /// accepted is skipped with its subtree): `visit(node, changed below)` returns
    /// whether its subtree changed, and statistics. Subtrees of at least [`PAR_GRAIN`]
    /// primitives are split between parallel tasks.
    fn post_order<E, V>(&self, x: u32, depth: u32, enter: &E, visit: &V) -> (bool, RoundStats)
    where
        E: Fn(u32) -> bool + Sync,
        V: Fn(u32, bool) -> (bool, RoundStats) + Sync,
    {
        let s = &self.slots[x as usize];
        if s.is_leaf() || !enter(x) {
            return (false, RoundStats::default());
        }
        if s.count() < PAR_GRAIN || depth >= PAR_DEPTH {
            return self.post_order_serial(x, enter, visit);
        }
        let (l, r) = (s.left.load(Relaxed), s.right.load(Relaxed));
        let ((a, sa), (b, sb)) =
            rayon::join(|| self.post_order(l, depth + 1, enter, visit), || self.post_order(r, depth + 1, enter, visit));
        let (c, sc) = visit(x, a || b);
        (c, sa + sb + sc)
    }

    fn post_order_serial<E, V>(&self, top: u32, enter: &E, visit: &V) -> (bool, RoundStats)
    where
        E: Fn(u32) -> bool,
        V: Fn(u32, bool) -> (bool, RoundStats),
    {
        let mut stats = RoundStats::default();
        let mut stack: Vec<(u32, bool)> = vec![(top, false)];
        let mut changed: Vec<bool> = Vec::new();
        while let Some((x, post)) = stack.pop() {
            let s = &self.slots[x as usize];
            if post {
                let b = changed.pop().unwrap_or(false);
                let a = changed.pop().unwrap_or(false);
                let (c, sc) = visit(x, a || b);
                stats = stats + sc;
                changed.push(c);
            } else if s.is_leaf() || !enter(x) {
                changed.push(false);
            } else {
                stack.push((x, true));
                stack.push((s.right.load(Relaxed), false));
                stack.push((s.left.load(Relaxed), false));
            }
        }
        (changed.pop().unwrap_or(false), stats)
    }

    /// One round: optimises the treelet of every inner node with at least `gamma`
    /// primitives below it, bottom-up.
    pub fn round(&mut self, gamma: u32) -> RoundStats {
        let this = &*self;
        let enter = |x: u32| this.slots[x as usize].count() >= gamma;
        let (_, stats) = this.post_order(this.root, 0, &enter, &|x, below| this.settle(x, below));
        stats
    }

    /// Optimises the treelet at `x` unless it is settled; returns whether the subtree
    /// of `x` changed (`below`: whether it changed under the treelet's root already).
    fn settle(&self, x: u32, below: bool) -> (bool, RoundStats) {
        let s = &self.slots[x as usize];
        if !below && s.settled.load(Relaxed) {
            return (false, RoundStats { skipped: 1, ..Default::default() });
        }
        match self.optimise(x) {
            Some(u) => {
                for &(node, l, r, b, c, count) in &u.entries[..u.len] {
                    let slot = &self.slots[node as usize];
                    slot.set_inner(l, r, &b);
                    slot.set_cost(count, c);
                    slot.settled.store(false, Relaxed);
                }
                (true, RoundStats { optimised: 1, rewritten: 1, skipped: 0 })
            }
            None => {
                s.settled.store(true, Relaxed);
                (below, RoundStats { optimised: 1, ..Default::default() })
            }
        }
    }

    /// The optimal topology of the treelet rooted at `root`, if it is cheaper.
    fn optimise(&self, root: u32) -> Option<Update> {
        let slots = &self.slots;
        // Form the treelet: expand the inner leaf of largest area until full.
        let r = &slots[root as usize];
        let mut leaves = [0u32; TREELET_LEAVES];
        let mut inner = [false; TREELET_LEAVES];
        let mut areas = [0f32; TREELET_LEAVES];
        let mut boxes = [Box4::EMPTY; SUBSETS];
        let mut internals = [0u32; TREELET_LEAVES - 1];
        internals[0] = root;
        let mut ni = 1;
        let look = |id: u32| {
            let s = &slots[id as usize];
            let b = s.bounds();
            (Box4::from(&b), !s.is_leaf(), area(&b))
        };
        for (slot, id) in [(0, r.left.load(Relaxed)), (1, r.right.load(Relaxed))] {
            leaves[slot] = id;
            (boxes[1 << slot], inner[slot], areas[slot]) = look(id);
        }
        let mut k = 2;
        while k < self.leaves {
            let mut pick: Option<usize> = None;
            for i in 0..k {
                if inner[i] && pick.is_none_or(|p| areas[i] > areas[p]) {
                    pick = Some(i);
                }
            }
            let Some(slot) = pick else { break };
            let e = &slots[leaves[slot] as usize];
            internals[ni] = leaves[slot];
            ni += 1;
            let (l, rt) = (e.left.load(Relaxed), e.right.load(Relaxed));
            for (slot, id) in [(slot, l), (k, rt)] {
                leaves[slot] = id;
                (boxes[1 << slot], inner[slot], areas[slot]) = look(id);
            }
            k += 1;
        }
        if k < 3 {
            return None;
        }
        // Dynamic programming over the subsets of the k leaves.
        let full = (1usize << k) - 1;
        let mut counts = [0u32; SUBSETS];
        let mut copt = [0f32; SUBSETS];
        let mut popt = [0u8; SUBSETS];
        for (i, &l) in leaves[..k].iter().enumerate() {
            let s = &slots[l as usize];
            counts[1 << i] = s.count();
            copt[1 << i] = s.cost();
        }
        let mut areas = [0f32; SUBSETS];
        for s in 1..=full {
            let low = s & s.wrapping_neg();
            if s == low {
                continue;
            }
            boxes[s] = boxes[s ^ low].union(&boxes[low]);
            areas[s] = boxes[s].area();
            counts[s] = counts[s ^ low] + counts[low];
        }
        dp(k, &mut copt, &mut popt, &|s, best| self.cost_of_area(areas[s], counts[s], best));
        if copt[full] >= r.cost() * KEEP_FACTOR || copt[full].is_nan() {
            return None;
        }
        // Rebuild with the treelet's inner nodes, root first.
        let mut update = Update { len: 0, entries: [(0, 0, 0, Aabb::EMPTY, 0.0, 0); TREELET_LEAVES - 1] };
        let mut next = 1;
        let mut work = [(0usize, 0u32); TREELET_LEAVES];
        let mut top = 1;
        work[0] = (full, internals[0]);
        let node_of = |sub: usize, next: &mut usize| -> u32 {
            if sub.count_ones() == 1 {
                leaves[sub.trailing_zeros() as usize]
            } else {
                let id = internals[*next];
                *next += 1;
                id
            }
        };
        while top > 0 {
            top -= 1;
            let (s, id) = work[top];
            let p = popt[s] as usize;
            let (a, b) = (p, s ^ p);
            let la = node_of(a, &mut next);
            let lb = node_of(b, &mut next);
            update.entries[update.len] = (id, la, lb, boxes[s].aabb(), copt[s], counts[s]);
            update.len += 1;
            if a.count_ones() > 1 {
                work[top] = (a, la);
                top += 1;
            }
            if b.count_ones() > 1 {
                work[top] = (b, lb);
                top += 1;
            }
        }
        debug_assert_eq!(next, ni);
        Some(update)
    }

    /// Marks every inner node whose subtree is cheaper as one leaf (at most
    /// [`MAX_LEAF`] primitives).
    pub fn collapse_flags(&self) -> Vec<bool> {
        self.slots
            .par_iter()
            .map(|s| {
                if s.is_leaf() || s.count() as usize > MAX_LEAF {
                    return false;
                }
                let leaf = self.costs.intersect * area(&s.bounds()) * s.count() as f32;
                leaf <= s.cost()
            })
            .collect()
    }
}

/// A box in SIMD lanes for the dynamic programming: the same bits as [`Aabb`]'s union
/// and [`area`] (lane-wise min, max and subtraction are exact, and the area sums in the
/// same order).
#[derive(Debug, Clone, Copy)]
struct Box4 {
    min: Vec3A,
    max: Vec3A,
}

impl Box4 {
    const EMPTY: Box4 = Box4 { min: Vec3A::splat(f32::INFINITY), max: Vec3A::splat(f32::NEG_INFINITY) };

    fn from(b: &Aabb) -> Box4 {
        Box4 { min: b.min.into(), max: b.max.into() }
    }
    fn aabb(&self) -> Aabb {
        Aabb { min: self.min.into(), max: self.max.into() }
    }
    #[inline]
    fn union(&self, o: &Box4) -> Box4 {
        Box4 { min: self.min.min(o.min), max: self.max.max(o.max) }
    }
    #[inline]
    fn area(&self) -> f32 {
        if self.min.cmpgt(self.max).any() {
            return 0.0;
        }
        let e = self.max - self.min;
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }
}

// The straight-line programme, generated by build.rs (src/accel/bvh/dp_gen.rs):
// `dp(k, copt, popt, node)`, in the order of `tests::dp_loop`.
include!(concat!(env!("OUT_DIR"), "/treelet_dp.rs"));

/// The first strictly cheapest of two (cost, P) candidates, `a` coming first in the
/// canonical order. The generated code folds each run of partitions from (+inf, lowest
/// leaf), so `a` is never NaN and a NaN sum never wins.
#[inline(always)]
fn first_min(a: (f32, u8), b: (f32, u8)) -> (f32, u8) {
    if b.0 < a.0 {
        b
    } else {
        a
    }
}

/// Helper for tests: the collapsed SAH cost of a canonical tree.
pub fn collapsed_cost(bin: &Binary, costs: &SahCosts) -> f64 {
    bin.sah_cost(costs, true)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cheapest partition of subset `s` as a loop: (copt[P] + copt[S∖P], P), P
    /// running over the lowest leaf plus every proper subset of the rest, largest
    /// first; the first strictly cheapest wins; (+inf, lowest leaf) if none is below
    /// +inf. The kernel's order (build_treelet.comp, `best_split`).
    fn best_partition_loop(copt: &[f32; SUBSETS], s: usize) -> (f32, u8) {
        let low = s & s.wrapping_neg();
        let rest = s ^ low;
        let mut best = (f32::INFINITY, low as u8);
        let mut q = (rest - 1) & rest;
        loop {
            let p = low | q;
            let c = copt[p] + copt[s ^ p];
            if c < best.0 {
                best = (c, p as u8);
            }
            if q == 0 {
                break;
            }
            q = (q - 1) & rest;
        }
        best
    }

    /// The loop form of [`dp`]: subsets ascending, each after its subsets.
    fn dp_loop<F: Fn(usize, f32) -> f32>(k: usize, c: &mut [f32; SUBSETS], popt: &mut [u8; SUBSETS], node: &F) {
        for s in 1..(1usize << k) {
            if s.count_ones() < 2 {
                continue;
            }
            let (best, p) = best_partition_loop(c, s);
            c[s] = node(s, best);
            popt[s] = p;
        }
    }

    /// The generated programme gives the loop's costs and choices bit for bit, for every
    /// treelet size, on random costs with many ties, zeros, +inf and NaN.
    #[test]
    fn generated_programme_equals_the_loop() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let special = [0.0, 1.0, 2.0, f32::INFINITY, f32::NAN];
        for trial in 0..3000 {
            for k in 3..=TREELET_LEAVES {
                let mut a = [0f32; SUBSETS];
                let mut b = [0f32; SUBSETS];
                let node_add: Vec<f32> = (0..SUBSETS)
                    .map(|_| {
                        let r = next();
                        if trial % 3 == 0 {
                            special[(r % 4) as usize]
                        } else {
                            (r % 1000) as f32 * 0.25
                        }
                    })
                    .collect();
                for i in 0..k {
                    let r = next();
                    let v = if r % 7 == 0 { special[(r >> 8) as usize % special.len()] } else { (r % 16) as f32 };
                    a[1 << i] = v;
                    b[1 << i] = v;
                }
                // A node cost like the real one: its own term plus the children's, with
                // a leaf cap that makes ties common.
                let node = |s: usize, ch: f32| (node_add[s] + ch).min(40.0 + node_add[s] * 0.5);
                let (mut pa, mut pb) = ([0u8; SUBSETS], [0u8; SUBSETS]);
                dp(k, &mut a, &mut pa, &node);
                dp_loop(k, &mut b, &mut pb, &node);
                for s in 1..(1usize << k) {
                    assert_eq!(a[s].to_bits(), b[s].to_bits(), "k {k}, subset {s}, trial {trial}");
                    assert_eq!(pa[s], pb[s], "k {k}, subset {s}, trial {trial}");
                }
            }
        }
    }
}
