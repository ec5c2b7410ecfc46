//! The restructuring rounds ([`Restructure::round`]): a parallel post-order walk over
//! the treelet roots with at least γ primitives below them, batching disjoint treelets
//! of one task's subtree into the SIMD lanes; forming each treelet and rewriting it
//! when its optimum is cheaper.

use std::sync::atomic::Ordering::Relaxed;

use super::lanes::{treelet_lanes, LaneTables, LANES};
use super::tree::Restructure;
use super::{KEEP_FACTOR, TREELET_LEAVES};
use crate::accel::sah::area;
use crate::math::Aabb;

/// Subtrees with at least this many primitives are visited by parallel tasks; smaller
/// ones by one task, serially.
const PAR_GRAIN: u32 = 2048;
/// Levels below the treelet roots' non-root children that a round reads ahead of
/// treelet formation ([`Restructure::inner_below`]).
const TOUCH_LEVELS: usize = 2;
/// Deepest level visited by parallel recursion; deeper subtrees (only in degenerate
/// trees) are visited serially with an explicit stack.
const PAR_DEPTH: u32 = 48;

/// A formed treelet: its `k` leaves and `k - 1` inner nodes (root first).
#[derive(Debug, Clone, Copy, Default)]
struct Formed {
    k: usize,
    leaves: [u32; TREELET_LEAVES],
    internals: [u32; TREELET_LEAVES - 1],
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
    /// Post-order visit of the inner nodes below `x` that `enter` accepts (a node not
    /// accepted is skipped with its subtree): `visit(node, changed below)` returns
    /// whether its subtree changed, and statistics. Subtrees of at least [`PAR_GRAIN`]
    /// primitives are split between parallel tasks.
    /// `serial(node)` does the same for one subtree below [`PAR_GRAIN`] primitives.
    fn post_order<E, V, S>(&self, x: u32, depth: u32, enter: &E, visit: &V, serial: &S) -> (bool, RoundStats)
    where
        E: Fn(u32) -> bool + Sync,
        V: Fn(u32, bool) -> (bool, RoundStats) + Sync,
        S: Fn(u32) -> (bool, RoundStats) + Sync,
    {
        let s = &self.slots[x as usize];
        if s.is_leaf() || !enter(x) {
            return (false, RoundStats::default());
        }
        if s.count() < PAR_GRAIN || depth >= PAR_DEPTH {
            return serial(x);
        }
        let (l, r) = (s.left.load(Relaxed), s.right.load(Relaxed));
        let ((a, sa), (b, sb)) = rayon::join(
            || self.post_order(l, depth + 1, enter, visit, serial),
            || self.post_order(r, depth + 1, enter, visit, serial),
        );
        let (c, sc) = visit(x, a || b);
        (c, sa + sb + sc)
    }

    /// One round: optimises the treelet of every inner node with at least `gamma`
    /// primitives below it, bottom-up.
    pub fn round(&mut self, gamma: u32) -> RoundStats {
        let this = &*self;
        let enter = |x: u32| this.slots[x as usize].count() >= gamma;
        let (_, stats) =
            this.post_order(this.root, 0, &enter, &|x, below| this.settle(x, below), &|x| this.round_serial(x, gamma));
        stats
    }

    /// A round over the subtree of `top` (one task): its treelet roots are listed level
    /// by level (each level's nodes are read independently of each other, so their
    /// cache misses overlap, where a depth-first walk waits on one at a time), and
    /// optimised [`LANES`] treelets of the same size at once ([`treelet_lanes`]) as they
    /// become ready: a root is ready once every root below it is done. The roots of
    /// one batch are therefore disjoint, and each treelet is optimised after every
    /// treelet below it, so the tree is the post-order walk's. Ready roots wait in a
    /// queue (first in, first out; the deepest listed first), so a batch runs short
    /// only when fewer than [`LANES`] roots are ready, near the top.
    fn round_serial(&self, top: u32, gamma: u32) -> (bool, RoundStats) {
        const NONE: u32 = u32::MAX;
        let enter = |x: u32| {
            let s = &self.slots[x as usize];
            !s.is_leaf() && s.count() >= gamma
        };
        if !enter(top) {
            return (false, RoundStats::default());
        }
        // Treelet roots level by level: (node, index of its parent root or NONE); the
        // inner nodes below them that are not roots, the fringe.
        // Each level's children are first read in a loop without branches, so that
        // their cache misses overlap; then sorted into roots and fringe.
        let mut roots: Vec<(u32, u32)> = vec![(top, NONE)];
        let mut fringe: Vec<u32> = Vec::new();
        let mut kids: Vec<(u32, u32)> = Vec::new();
        let mut level = 0..1;
        while !level.is_empty() {
            kids.clear();
            for i in level.clone() {
                let s = &self.slots[roots[i].0 as usize];
                kids.push((s.left.load(Relaxed), i as u32));
                kids.push((s.right.load(Relaxed), i as u32));
            }
            self.touch(kids.iter().map(|k| k.0));
            let first = roots.len();
            for &(c, p) in &kids {
                if enter(c) {
                    roots.push((c, p));
                } else if !self.slots[c as usize].is_leaf() {
                    fringe.push(c);
                }
            }
            level = first..roots.len();
        }
        // Read ahead of treelet formation, which waits on each node before it can
        // choose the next.
        self.inner_below(fringe, TOUCH_LEVELS);
        // Per root: how many of its child roots are not done, and whether one of them
        // changed its subtree.
        let mut waiting = vec![0u8; roots.len()];
        for &(_, p) in &roots[1..] {
            waiting[p as usize] += 1;
        }
        let mut below = vec![false; roots.len()];
        let mut ready: std::collections::VecDeque<u32> =
            (0..roots.len() as u32).rev().filter(|&i| waiting[i as usize] == 0).collect();
        let mut stats = RoundStats::default();
        let mut top_changed = false;
        let mut batch: Vec<(u32, bool)> = Vec::with_capacity(LANES);
        let mut index: Vec<u32> = Vec::with_capacity(LANES);
        // Marks root `i` done with `changed` (whether its subtree changed).
        let mut done = |i: u32, changed: bool, below: &mut [bool], ready: &mut std::collections::VecDeque<u32>| {
            let p = roots[i as usize].1;
            if p == NONE {
                top_changed = changed;
                return;
            }
            below[p as usize] |= changed;
            waiting[p as usize] -= 1;
            if waiting[p as usize] == 0 {
                ready.push_back(p);
            }
        };
        while !ready.is_empty() {
            while batch.len() < LANES {
                let Some(i) = ready.pop_front() else { break };
                let x = roots[i as usize].0;
                let b = below[i as usize];
                if !b && self.slots[x as usize].settled() {
                    stats.skipped += 1;
                    done(i, false, &mut below, &mut ready);
                    continue;
                }
                batch.push((x, b));
                index.push(i);
            }
            if batch.is_empty() {
                continue;
            }
            let (c, sc) = LaneTables::with(|t| self.settle_lanes(&batch, t));
            stats = stats + sc;
            for (lane, &i) in index.iter().enumerate() {
                done(i, c[lane], &mut below, &mut ready);
            }
            batch.clear();
            index.clear();
        }
        (top_changed, stats)
    }

    /// Optimises the treelets at the roots in `batch` (disjoint subtrees, at most
    /// [`LANES`]; with each whether its subtree already changed below its root), at
    /// once for treelets of the same size. Returns whether each subtree changed.
    fn settle_lanes(&self, batch: &[(u32, bool)], t: &mut LaneTables) -> ([bool; LANES], RoundStats) {
        let mut formed = [Formed::default(); LANES];
        for (lane, &(root, _)) in batch.iter().enumerate() {
            formed[lane] = self.form(root, lane, t);
        }
        let mut sizes = [false; TREELET_LEAVES + 1];
        for f in &formed[..batch.len()] {
            sizes[f.k] = true;
        }
        let mut changed = [false; LANES];
        let mut stats = RoundStats::default();
        for k in (3..=TREELET_LEAVES).filter(|&k| sizes[k]) {
            // Lanes of other sizes compute junk from stale entries; nothing reads it.
            treelet_lanes(k, batch.len(), t, self.costs.traversal, self.costs.intersect);
            for (lane, &(root, below)) in batch.iter().enumerate() {
                if formed[lane].k == k {
                    let (c, sc) = self.rewrite(root, &formed[lane], t, lane, below);
                    changed[lane] = c;
                    stats = stats + sc;
                }
            }
        }
        // Treelets too small to restructure (fewer than 3 leaves).
        for (lane, &(root, below)) in batch.iter().enumerate() {
            if formed[lane].k < 3 {
                let (c, sc) = self.rewrite(root, &formed[lane], t, lane, below);
                changed[lane] = c;
                stats = stats + sc;
            }
        }
        (changed, stats)
    }

    /// Optimises the treelet at `x` unless it is settled; returns whether the subtree
    /// of `x` changed (`below`: whether it changed under the treelet's root already).
    fn settle(&self, x: u32, below: bool) -> (bool, RoundStats) {
        let s = &self.slots[x as usize];
        if !below && s.settled() {
            return (false, RoundStats { skipped: 1, ..Default::default() });
        }
        let (changed, stats) = LaneTables::with(|t| self.settle_lanes(&[(x, below)], t));
        (changed[0], stats)
    }

    /// Forms the treelet rooted at `root` (expanding the inner leaf of largest area
    /// until full) and writes its leaves into `lane` of `t`.
    fn form(&self, root: u32, lane: usize, t: &mut LaneTables) -> Formed {
        let slots = &self.slots;
        let r = &slots[root as usize];
        let mut f = Formed::default();
        let mut inner = [false; TREELET_LEAVES];
        let mut boxes = [Aabb::EMPTY; TREELET_LEAVES];
        let mut areas = [0f32; TREELET_LEAVES];
        f.internals[0] = root;
        let mut ni = 1;
        let look = |id: u32| {
            let s = &slots[id as usize];
            let b = s.bounds();
            (b, !s.is_leaf(), area(&b))
        };
        for (slot, id) in [(0, r.left.load(Relaxed)), (1, r.right.load(Relaxed))] {
            f.leaves[slot] = id;
            (boxes[slot], inner[slot], areas[slot]) = look(id);
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
            let e = &slots[f.leaves[slot] as usize];
            f.internals[ni] = f.leaves[slot];
            ni += 1;
            let (l, rt) = (e.left.load(Relaxed), e.right.load(Relaxed));
            for (slot, id) in [(slot, l), (k, rt)] {
                f.leaves[slot] = id;
                (boxes[slot], inner[slot], areas[slot]) = look(id);
            }
            k += 1;
        }
        f.k = k;
        for (i, &l) in f.leaves[..k].iter().enumerate() {
            let s = &slots[l as usize];
            t.set_leaf(lane, i, &boxes[i], s.count(), s.cost());
        }
        f
    }

    /// Writes the treelet's new topology from its optimal costs and parts in `lane` of
    /// `t`, reusing its inner nodes root first, if it is cheaper than now; else marks
    /// the treelet settled. Returns whether the subtree of `root` changed (`below`:
    /// whether it changed under the treelet already).
    fn rewrite(&self, root: u32, f: &Formed, t: &LaneTables, lane: usize, below: bool) -> (bool, RoundStats) {
        let full = (1usize << f.k) - 1;
        let best = if f.k < 3 { f32::NAN } else { t.cost[full][lane] };
        if best.is_nan() || best >= self.slots[root as usize].cost() * KEEP_FACTOR {
            self.slots[root as usize].mark_settled();
            return (below, RoundStats { optimised: 1, ..Default::default() });
        }
        let mut next = 1;
        let mut work = [(0usize, 0u32); TREELET_LEAVES];
        let mut top = 1;
        work[0] = (full, f.internals[0]);
        let node_of = |sub: usize, next: &mut usize| -> u32 {
            if sub.count_ones() == 1 {
                f.leaves[sub.trailing_zeros() as usize]
            } else {
                let id = f.internals[*next];
                *next += 1;
                id
            }
        };
        while top > 0 {
            top -= 1;
            let (s, id) = work[top];
            let p = t.best_part(s, lane);
            let (a, b) = (p, s ^ p);
            let la = node_of(a, &mut next);
            let lb = node_of(b, &mut next);
            let slot = &self.slots[id as usize];
            slot.set_inner(la, lb, &t.aabb(s, lane));
            slot.set_cost(t.count[s][lane] as u32, t.cost[s][lane]);
            if a.count_ones() > 1 {
                work[top] = (a, la);
                top += 1;
            }
            if b.count_ones() > 1 {
                work[top] = (b, lb);
                top += 1;
            }
        }
        debug_assert_eq!(next, f.k - 1);
        (true, RoundStats { optimised: 1, rewritten: 1, skipped: 0 })
    }
}
