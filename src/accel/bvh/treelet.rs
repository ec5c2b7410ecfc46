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
//! The tree to restructure is the LBVH, built straight into this module's nodes by a
//! climb from the leaves ([`Restructure::lbvh`]), or any canonical tree
//! ([`Restructure::new`]).
//!
//! Nodes are processed bottom-up, so a treelet is optimised after every treelet below
//! it, and only at nodes whose subtree holds at least γ primitives. As in the paper,
//! several rounds run, with γ set per round ([`TreeletParams::gamma`]; by default 7, 7,
//! 28, where the paper doubles it: 7, 14, 28). A round is a post-order
//! walk that prunes subtrees below γ primitives; the two subtrees of a large node are
//! walked by parallel tasks, since their treelets are disjoint. Within one task's
//! subtree the treelet roots are listed level by level, and a root is optimised once
//! the roots below it are done: sixteen disjoint treelets at once, one per SIMD lane
//! (AVX-512 where the processor has it, else AVX2 or SSE), by a generated straight-line
//! programme (`dp_gen.rs`). The result does not
//! depend on thread count or order: each treelet's solution reads only its own subtree
//! (restructuring permutes nodes only within a treelet, so every node's subtree keeps
//! its set of nodes), and the GPU kernel, which goes bottom-up by levels, gets the
//! same tree. A treelet that was optimised without change, and under which nothing
//! has changed since, is skipped in later rounds: its optimum would be the same.
//!
//! A restructuring is applied only when it lowers the treelet root's cost, so the SAH
//! cost (with collapse) never increases. The flattener then collapses the subtrees that
//! are cheaper as one leaf (`Nodes::collapsed`).

use std::sync::atomic::{
    AtomicU32,
    Ordering::{AcqRel, Relaxed},
};
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use super::{lap, lbvh, BNode, Binary, Nodes, PrimRefs, LEAF_FLAG, MAX_LEAF};
use crate::accel::sah::{area, SahCosts};
use crate::accel::Phase;
use crate::math::Aabb;

/// Most leaves per treelet (the paper's choice, and the default).
pub const TREELET_LEAVES: usize = 7;
/// A treelet is rewritten only when its optimised cost is below this fraction of its
/// cost (so rounding noise never rewrites a tree); the GPU build gets the same bits.
pub const KEEP_FACTOR: f32 = 1.0 - 1e-6;
/// Rounds of restructuring by default.
pub const ROUNDS: u32 = 3;
/// Most rounds.
pub const MAX_ROUNDS: usize = 8;
/// γ of each round by default, as multiples of the treelet size: two rounds at the
/// treelet size, then one at 4 times it (7, 7, 28 for 7 leaves); later rounds repeat
/// the pattern. Measured at 1M triangles (README, "trbvh"), the paper's doubling (7,
/// 14, 28) spends its second round where little improves: two rounds at 7 alone gave a
/// lower SAH cost than 7, 14, 28, and 7, 7, 28 is within 3% of the binned SAH builder.
const SCHEDULE: [u32; MAX_ROUNDS] = [1, 1, 4, 1, 1, 4, 1, 1];
/// The paper's schedule: γ doubles each round (a round beyond the third starts again;
/// doubling on to 8 and 16 times finds almost nothing to improve).
const DOUBLING: [u32; MAX_ROUNDS] = [1, 2, 4, 1, 2, 4, 1, 2];

/// Minimum primitives below a treelet root in `round` (0-based) for the default
/// parameters.
pub fn gamma(round: u32) -> u32 {
    TreeletParams::default().gamma(round)
}

/// Treelet restructuring parameters: the user's trade between build time and SAH.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TreeletParams {
    /// Leaves per treelet, 3..=7: the dynamic programming costs about 3^leaves.
    pub leaves: usize,
    /// Rounds, 0..=MAX_ROUNDS.
    pub rounds: u32,
    /// Minimum primitives below a treelet root in each round, as a multiple of
    /// `leaves` (see [`TreeletParams::gamma`]).
    pub gamma: [u32; MAX_ROUNDS],
}

impl Default for TreeletParams {
    /// The paper's 7 leaves and 3 rounds, with γ at 7, 7 and 28 (not the paper's 7, 14, 28).
    fn default() -> Self {
        TreeletParams { leaves: TREELET_LEAVES, rounds: ROUNDS, gamma: SCHEDULE }
    }
}

impl TreeletParams {
    /// Faster: 5-leaf treelets (README, "trbvh", for the figures).
    pub fn fast() -> Self {
        TreeletParams { leaves: 5, ..Self::default() }
    }

    /// The paper's schedule: γ at 7, 14 and 28.
    pub fn paper() -> Self {
        TreeletParams { gamma: DOUBLING, ..Self::default() }
    }

    /// Better trees for a longer build: every round at γ = the treelet size. Small
    /// subtrees gain most, and they gain again once the treelets above have regrouped
    /// the nodes below them (README, "trbvh", for the figures).
    pub fn quality() -> Self {
        TreeletParams { gamma: [1; MAX_ROUNDS], ..Self::default() }
    }

    /// Minimum primitives below a treelet root in `round` (0-based).
    pub fn gamma(&self, round: u32) -> u32 {
        self.leaves as u32 * self.gamma[round as usize % MAX_ROUNDS]
    }

    /// Parses a preset (`default`, `fast`, `quality`, `paper`) or `leaves=N`, `rounds=N` and
    /// `gamma=A/B/...` (γ of each round as multiples of the treelet size; it sets the
    /// rounds too) over the default.
    pub fn parse(spec: &str) -> Result<TreeletParams, String> {
        Self::parse_onto(TreeletParams::default(), spec)
    }

    /// Applies `spec` (presets and KEY=VALUE pairs, in order) on top of `base`.
    pub fn parse_onto(base: TreeletParams, spec: &str) -> Result<TreeletParams, String> {
        let mut p = base;
        let keys = "leaves=3..7, rounds=0..8, gamma=A/B/... (multiples of leaves, one per round)";
        for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            match item {
                "default" => p = TreeletParams::default(),
                "fast" => p = TreeletParams::fast(),
                "quality" => p = TreeletParams::quality(),
                "paper" => p = TreeletParams::paper(),
                _ => {
                    let (k, v) = item.split_once('=').ok_or_else(|| {
                        format!("--trbvh {item:?}: expected a preset (default, fast, quality, paper) or {keys}")
                    })?;
                    let number =
                        |v: &str| v.parse::<u32>().map_err(|_| format!("--trbvh {k}={v}: expected a whole number"));
                    match k {
                        "leaves" => match number(v)? {
                            n if (3..=TREELET_LEAVES as u32).contains(&n) => p.leaves = n as usize,
                            _ => return Err(format!("--trbvh leaves={v}: expected 3..={TREELET_LEAVES}")),
                        },
                        "rounds" => match number(v)? {
                            n if n as usize <= MAX_ROUNDS => p.rounds = n,
                            _ => return Err(format!("--trbvh rounds={v}: expected 0..={MAX_ROUNDS}")),
                        },
                        "gamma" => {
                            let list: Vec<u32> = v.split('/').map(number).collect::<Result<_, _>>()?;
                            if list.is_empty()
                                || list.len() > MAX_ROUNDS
                                || list.iter().any(|&g| !(1..=1 << 20).contains(&g))
                            {
                                return Err(format!(
                                    "--trbvh gamma={v}: expected 1 to {MAX_ROUNDS} multiples of leaves, each 1..=1048576, \
                                     separated by '/'"
                                ));
                            }
                            p.gamma[..list.len()].copy_from_slice(&list);
                            p.rounds = list.len() as u32;
                        }
                        _ => return Err(format!("--trbvh: unknown key '{k}' ({keys})")),
                    }
                }
            }
        }
        Ok(p)
    }
}

// A node is 40 bytes (README, "trbvh"): the settled mark shares the count's word.
const _: () = assert!(std::mem::size_of::<Slot>() == 40);
const SUBSETS: usize = 1 << TREELET_LEAVES;

/// Subtrees with at least this many primitives are visited by parallel tasks; smaller
/// ones by one task, serially.
const PAR_GRAIN: u32 = 2048;
/// Levels below the treelet roots' non-root children that a round reads ahead of
/// treelet formation ([`Restructure::inner_below`]).
const TOUCH_LEVELS: usize = 2;
/// Levels of the tree split between parallel tasks when fitting it (2^10 subtrees).
const FIT_PAR_LEVELS: u32 = 10;
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
        }
    }
    /// As `new`, with a leaf's cost (C_I·A·N) and count set.
    fn with_cost(n: &BNode, costs: &SahCosts) -> Slot {
        let s = Slot::new(n);
        if n.is_leaf() {
            s.set_cost(n.right, costs.intersect * area(&n.bounds) * n.right as f32);
        }
        s
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
        self.count.load(Relaxed) & !SETTLED
    }
    fn settled(&self) -> bool {
        self.count.load(Relaxed) & SETTLED != 0
    }
    /// Marks the treelet rooted here settled (see [`SETTLED`]); a new count and cost
    /// ([`Slot::set_cost`]) clear the mark.
    fn mark_settled(&self) {
        self.count.store(self.count.load(Relaxed) | SETTLED, Relaxed);
    }
    fn cost(&self) -> f32 {
        f32::from_bits(self.cost.load(Relaxed))
    }
    /// Sets the count and cost, and clears [`SETTLED`].
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
/// across rounds. Flatten it where it is (it is [`Nodes`]), or copy the result into
/// a [`Binary`] with [`Restructure::write_back`].
#[derive(Debug)]
pub struct Restructure {
    costs: SahCosts,
    /// Leaves per treelet (3..=TREELET_LEAVES).
    leaves: usize,
    slots: Vec<Slot>,
    root: u32,
    /// The primitive order leaves index into.
    prims: Vec<u32>,
}

/// Treelets optimised at once by the generated programme, one per SIMD lane: one
/// AVX-512 register, or two AVX2 registers run one after the other.
const LANES: usize = 16;
/// One value per lane.
type Lanes = [f32; LANES];

/// The tables of [`LANES`] treelets of the same size, subset-major and lane-minor
/// (`area[s][lane]`; subset bit i = treelet leaf i). On entry the leaves' entries
/// (`1 << i`) are set; the generated programme fills the rest.
#[repr(C, align(64))]
struct LaneTables {
    /// Box of each subset: min x, y, z, max x, y, z.
    bounds: [[Lanes; 6]; SUBSETS],
    /// Surface area of each subset's box.
    area: [Lanes; SUBSETS],
    /// Primitives in each subset.
    count: [[i32; LANES]; SUBSETS],
    /// Optimal cost of each subset (with collapse).
    cost: [Lanes; SUBSETS],
    /// Cheapest partition sum cost(P) + cost(S∖P) of each subset (+inf if none is
    /// below +inf), for [`LaneTables::best_part`].
    split: [Lanes; SUBSETS],
}

thread_local! {
    /// Each thread's tables, kept between rounds and builds: 80 KiB that would
    /// otherwise be allocated and cleared for every task and every large node.
    static TABLES: std::cell::Cell<Option<Box<LaneTables>>> = const { std::cell::Cell::new(None) };
}

impl LaneTables {
    /// Runs `f` with this thread's tables (new ones if a caller on this thread holds
    /// them). Stale entries from earlier treelets are never read: every entry the
    /// programme reads for a lane in use is written first (the leaves by
    /// [`LaneTables::set_leaf`], the other subsets by the programme).
    fn with<R>(f: impl FnOnce(&mut LaneTables) -> R) -> R {
        let mut t = TABLES.take().unwrap_or_else(LaneTables::new);
        let r = f(&mut t);
        TABLES.set(Some(t));
        r
    }

    fn new() -> Box<LaneTables> {
        Box::new(LaneTables {
            bounds: [[[0.0; LANES]; 6]; SUBSETS],
            area: [[0.0; LANES]; SUBSETS],
            count: [[0; LANES]; SUBSETS],
            cost: [[0.0; LANES]; SUBSETS],
            split: [[0.0; LANES]; SUBSETS],
        })
    }

    /// Box of subset `s` in `lane`.
    fn aabb(&self, s: usize, lane: usize) -> Aabb {
        let b = &self.bounds[s];
        Aabb { min: Vec3::new(b[0][lane], b[1][lane], b[2][lane]), max: Vec3::new(b[3][lane], b[4][lane], b[5][lane]) }
    }

    /// The first part P (holding the lowest leaf of `s`; P descending) with the
    /// strictly cheapest cost(P) + cost(S∖P) in `lane`, or the lowest leaf alone if
    /// none is below +inf: the split whose cost the generated programme found. That
    /// is the first P whose sum equals the cheapest sum the programme kept (`split`;
    /// the same addition, and never NaN), so the scan stops there and carries no
    /// comparison chain from one partition to the next.
    fn best_part(&self, s: usize, lane: usize) -> usize {
        let low = s & s.wrapping_neg();
        let rest = s ^ low;
        let best = self.split[s][lane];
        if best == f32::INFINITY {
            return low;
        }
        let mut q = rest.wrapping_sub(1) & rest;
        loop {
            let p = low | q;
            if self.cost[p][lane] + self.cost[s ^ p][lane] == best || q == 0 {
                return p;
            }
            q = (q - 1) & rest;
        }
    }

    /// Sets leaf `i` of the treelet in `lane`.
    fn set_leaf(&mut self, lane: usize, i: usize, b: &Aabb, count: u32, cost: f32) {
        let m = 1 << i;
        for (a, v) in Slot::lanes(b).into_iter().enumerate() {
            self.bounds[m][a][lane] = v;
        }
        self.count[m][lane] = count as i32;
        self.cost[m][lane] = cost;
    }
}

/// The lane-wise steps of the generated programme (`treelet_lanes_k*`), with one
/// implementation per instruction set. Both give the same bits: each step is the same
/// IEEE operations in the same order, with no fused multiply-add.
trait LaneOps: Copy {
    /// The values of one table row ([`LANES`] lanes), kept in registers.
    type V: Copy;
    /// +inf in every lane.
    fn inf(self) -> Self::V;
    /// Subset `s` = `rest` ∪ {`low`}: its box (min and max as x86's MINPS and MAXPS:
    /// the first operand where it is less, resp. greater, else the second), its area
    /// as [`area`] (0 when empty, the same sum order) and its count.
    fn fold(self, t: &mut LaneTables, s: usize, rest: usize, low: usize);
    /// One step of a comparison chain: the sum `x + y` where it is strictly below `b`
    /// (a NaN sum never is). Only costs are kept; [`LaneTables::best_part`] finds the
    /// part of the few subsets a new topology uses.
    fn step(self, b: Self::V, x: &Lanes, y: &Lanes) -> Self::V;
    /// Merges a later chain `b1` into an earlier one `b`: the first strictly cheapest.
    fn merge(self, b: Self::V, b1: Self::V) -> Self::V;
    /// Keeps `b`, the cheapest partition sum of subset `s` (for
    /// [`LaneTables::best_part`]), and sets `s`'s optimal cost as
    /// [`Restructure::cost_of_area`]: C_T·A + b, or one leaf (C_I·A·N) if cheaper and N ≤
    /// MAX_LEAF. As `f32::min`, a NaN on one side gives the other.
    fn node(self, t: &mut LaneTables, s: usize, b: Self::V, traversal: f32, intersect: f32);
}

/// The steps as plain loops over the lanes, which LLVM turns into SSE instructions
/// (the x86-64 baseline). Hence `needless_range_loop` is allowed on them.
#[derive(Debug, Clone, Copy)]
struct PlainLanes;

impl LaneOps for PlainLanes {
    type V = Lanes;

    #[inline(always)]
    fn inf(self) -> Lanes {
        [f32::INFINITY; LANES]
    }

    #[inline(always)]
    #[allow(clippy::needless_range_loop)]
    fn fold(self, t: &mut LaneTables, s: usize, rest: usize, low: usize) {
        let (r, o) = (t.bounds[rest], t.bounds[low]);
        let mut b = [[0f32; LANES]; 6];
        for l in 0..LANES {
            for a in 0..3 {
                b[a][l] = if r[a][l] < o[a][l] { r[a][l] } else { o[a][l] };
                b[a + 3][l] = if r[a + 3][l] > o[a + 3][l] { r[a + 3][l] } else { o[a + 3][l] };
            }
        }
        // Separate loops with no short-circuit, so that each is one vector loop.
        for l in 0..LANES {
            let (ex, ey, ez) = (b[3][l] - b[0][l], b[4][l] - b[1][l], b[5][l] - b[2][l]);
            let empty = (b[0][l] > b[3][l]) | (b[1][l] > b[4][l]) | (b[2][l] > b[5][l]);
            let a = 2.0 * (ex * ey + ey * ez + ez * ex);
            t.area[s][l] = if empty { 0.0 } else { a };
        }
        for l in 0..LANES {
            t.count[s][l] = t.count[rest][l].wrapping_add(t.count[low][l]);
        }
        t.bounds[s] = b;
    }

    #[inline(always)]
    fn step(self, mut b: Lanes, x: &Lanes, y: &Lanes) -> Lanes {
        for l in 0..LANES {
            let c = x[l] + y[l];
            b[l] = if c < b[l] { c } else { b[l] };
        }
        b
    }

    #[inline(always)]
    fn merge(self, mut b: Lanes, b1: Lanes) -> Lanes {
        for l in 0..LANES {
            b[l] = if b1[l] < b[l] { b1[l] } else { b[l] };
        }
        b
    }

    #[inline(always)]
    #[allow(clippy::needless_range_loop)]
    fn node(self, t: &mut LaneTables, s: usize, b: Lanes, traversal: f32, intersect: f32) {
        t.split[s] = b;
        for l in 0..LANES {
            let (a, n) = (t.area[s][l], t.count[s][l]);
            let split = traversal * a + b[l];
            // Both sides computed, so that the choice is a select. Counts are below 2^31.
            let leaf = intersect * a * n as f32;
            let leaf = if n <= MAX_LEAF as i32 { leaf } else { f32::NAN };
            t.cost[s][l] = split.min(leaf);
        }
    }
}

/// The steps in AVX2 registers on one half of the lanes (lanes 8h..8h+8 for half
/// h), eight lanes in one register (x86-64-v3; chosen at run time where the processor
/// has it and not AVX-512, see [`treelet_lanes`]). The programme runs once per half
/// that holds a treelet, so each pass runs the instructions of an 8-lane batch, from
/// one copy of the code. Compiled for the whole crate, LLVM turned the plain loops
/// into scalar code under AVX2, so this writes the vector operations out (with
/// `pulp`, whose wrappers are safe to call once its token proves the features).
#[cfg(target_arch = "x86_64")]
#[derive(Debug, Clone, Copy)]
struct AvxLanes {
    v3: pulp::x86::V3,
    /// First lane of the half: 0 or 8.
    first: usize,
}

#[cfg(target_arch = "x86_64")]
impl AvxLanes {
    /// Half `half` (0 or 1) of the lanes.
    #[inline(always)]
    fn new(v3: pulp::x86::V3, half: usize) -> AvxLanes {
        AvxLanes { v3, first: 8 * (half & 1) }
    }
    /// This half of a row.
    #[inline(always)]
    fn part<T>(self, x: &[T; LANES]) -> &[T; 8] {
        x[self.first..self.first + 8].try_into().expect("a row holds two halves")
    }
    #[inline(always)]
    fn part_mut<T>(self, x: &mut [T; LANES]) -> &mut [T; 8] {
        (&mut x[self.first..self.first + 8]).try_into().expect("a row holds two halves")
    }
    #[inline(always)]
    fn load(self, x: &Lanes) -> pulp::f32x8 {
        pulp::cast(*self.part(x))
    }
    #[inline(always)]
    fn load_i(self, x: &[i32; LANES]) -> pulp::i32x8 {
        pulp::cast(*self.part(x))
    }
    #[inline(always)]
    fn store(self, dst: &mut Lanes, v: pulp::f32x8) {
        *self.part_mut(dst) = pulp::cast(v);
    }
}

#[cfg(target_arch = "x86_64")]
impl LaneOps for AvxLanes {
    type V = pulp::f32x8;

    #[inline(always)]
    fn inf(self) -> pulp::f32x8 {
        self.v3.splat_f32x8(f32::INFINITY)
    }

    #[inline(always)]
    fn fold(self, t: &mut LaneTables, s: usize, rest: usize, low: usize) {
        let v = self.v3;
        let (r, o) = (&t.bounds[rest], &t.bounds[low]);
        let lo = |a: usize| v.min_f32x8(self.load(&r[a]), self.load(&o[a]));
        let hi = |a: usize| v.max_f32x8(self.load(&r[a]), self.load(&o[a]));
        let b = [lo(0), lo(1), lo(2), hi(3), hi(4), hi(5)];
        let (ex, ey, ez) = (v.sub_f32x8(b[3], b[0]), v.sub_f32x8(b[4], b[1]), v.sub_f32x8(b[5], b[2]));
        let empty =
            v.or_m32x8(v.or_m32x8(v.cmp_gt_f32x8(b[0], b[3]), v.cmp_gt_f32x8(b[1], b[4])), v.cmp_gt_f32x8(b[2], b[5]));
        let sum = v.add_f32x8(v.add_f32x8(v.mul_f32x8(ex, ey), v.mul_f32x8(ey, ez)), v.mul_f32x8(ez, ex));
        let a = v.mul_f32x8(v.splat_f32x8(2.0), sum);
        self.store(&mut t.area[s], v.select_f32x8(empty, v.splat_f32x8(0.0), a));
        let n = v.wrapping_add_i32x8(self.load_i(&t.count[rest]), self.load_i(&t.count[low]));
        *self.part_mut(&mut t.count[s]) = pulp::cast(n);
        for (dst, src) in t.bounds[s].iter_mut().zip(b) {
            self.store(dst, src);
        }
    }

    #[inline(always)]
    fn step(self, b: pulp::f32x8, x: &Lanes, y: &Lanes) -> pulp::f32x8 {
        // MINPS(c, b): c where c < b, else b.
        self.v3.min_f32x8(self.v3.add_f32x8(self.load(x), self.load(y)), b)
    }

    #[inline(always)]
    fn merge(self, b: pulp::f32x8, b1: pulp::f32x8) -> pulp::f32x8 {
        self.v3.min_f32x8(b1, b)
    }

    #[inline(always)]
    fn node(self, t: &mut LaneTables, s: usize, b: pulp::f32x8, traversal: f32, intersect: f32) {
        let v = self.v3;
        self.store(&mut t.split[s], b);
        let a = self.load(&t.area[s]);
        let n = self.load_i(&t.count[s]);
        let split = v.add_f32x8(v.mul_f32x8(v.splat_f32x8(traversal), a), b);
        let leaf = v.mul_f32x8(v.mul_f32x8(v.splat_f32x8(intersect), a), v.convert_i32x8_to_f32x8(n));
        let big = v.cmp_gt_i32x8(n, v.splat_i32x8(MAX_LEAF as i32));
        let leaf = v.select_f32x8(big, v.splat_f32x8(f32::NAN), leaf);
        // f32::min: MINPS(leaf, split) gives split where either is NaN; a NaN split
        // gives leaf.
        let m = v.min_f32x8(leaf, split);
        let split_nan = v.is_nan_f32x8(split);
        self.store(&mut t.cost[s], v.select_f32x8(split_nan, leaf, m));
    }
}

/// The steps in AVX-512 registers, all [`LANES`] lanes in one (x86-64-v4; chosen at
/// run time where the processor has it, see [`treelet_lanes`]). The generated
/// programme is large (about 80 KiB of code for 7 leaves, where the first-level
/// instruction cache holds 32), so fetching it bounds its speed: 16 lanes per
/// instruction do twice the work of AVX2's 8 for the same fetch (README, "trbvh").
#[cfg(target_arch = "x86_64")]
#[derive(Debug, Clone, Copy)]
struct Avx512Lanes(pulp::x86::V4);

#[cfg(target_arch = "x86_64")]
impl Avx512Lanes {
    #[inline(always)]
    fn load(x: &Lanes) -> pulp::f32x16 {
        pulp::cast(*x)
    }
}

#[cfg(target_arch = "x86_64")]
impl LaneOps for Avx512Lanes {
    type V = pulp::f32x16;

    #[inline(always)]
    fn inf(self) -> pulp::f32x16 {
        self.0.splat_f32x16(f32::INFINITY)
    }

    #[inline(always)]
    fn fold(self, t: &mut LaneTables, s: usize, rest: usize, low: usize) {
        let v = self.0;
        let (r, o) = (&t.bounds[rest], &t.bounds[low]);
        let lo = |a: usize| v.min_f32x16(Self::load(&r[a]), Self::load(&o[a]));
        let hi = |a: usize| v.max_f32x16(Self::load(&r[a]), Self::load(&o[a]));
        let b = [lo(0), lo(1), lo(2), hi(3), hi(4), hi(5)];
        let (ex, ey, ez) = (v.sub_f32x16(b[3], b[0]), v.sub_f32x16(b[4], b[1]), v.sub_f32x16(b[5], b[2]));
        // Mask registers: one bit per lane.
        let e0 = v.cmp_gt_f32x16(b[0], b[3]);
        let e1 = v.cmp_gt_f32x16(b[1], b[4]);
        let e2 = v.cmp_gt_f32x16(b[2], b[5]);
        let empty = pulp::b16(e0.0 | e1.0 | e2.0);
        let sum = v.add_f32x16(v.add_f32x16(v.mul_f32x16(ex, ey), v.mul_f32x16(ey, ez)), v.mul_f32x16(ez, ex));
        let a = v.mul_f32x16(v.splat_f32x16(2.0), sum);
        t.area[s] = pulp::cast(v.select_f32x16(empty, v.splat_f32x16(0.0), a));
        let n = v.wrapping_add_i32x16(pulp::cast(t.count[rest]), pulp::cast(t.count[low]));
        t.count[s] = pulp::cast(n);
        for (dst, src) in t.bounds[s].iter_mut().zip(b) {
            *dst = pulp::cast(src);
        }
    }

    #[inline(always)]
    fn step(self, b: pulp::f32x16, x: &Lanes, y: &Lanes) -> pulp::f32x16 {
        self.0.min_f32x16(self.0.add_f32x16(Self::load(x), Self::load(y)), b)
    }

    #[inline(always)]
    fn merge(self, b: pulp::f32x16, b1: pulp::f32x16) -> pulp::f32x16 {
        self.0.min_f32x16(b1, b)
    }

    #[inline(always)]
    fn node(self, t: &mut LaneTables, s: usize, b: pulp::f32x16, traversal: f32, intersect: f32) {
        let v = self.0;
        t.split[s] = pulp::cast(b);
        let a = Self::load(&t.area[s]);
        let n: pulp::i32x16 = pulp::cast(t.count[s]);
        let split = v.add_f32x16(v.mul_f32x16(v.splat_f32x16(traversal), a), b);
        let leaf = v.mul_f32x16(v.mul_f32x16(v.splat_f32x16(intersect), a), v.convert_i32x16_to_f32x16(n));
        let big = v.cmp_gt_i32x16(n, v.splat_i32x16(MAX_LEAF as i32));
        let leaf = v.select_f32x16(big, v.splat_f32x16(f32::NAN), leaf);
        // As AVX2's: VMINPS gives its second operand where either is NaN.
        let m = v.min_f32x16(leaf, split);
        let split_nan = v.is_nan_f32x16(split);
        t.cost[s] = pulp::cast(v.select_f32x16(split_nan, leaf, m));
    }
}

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

    /// The LBVH of `refs` built straight into the restructuring's nodes (no
    /// [`Binary`] in between) and fitted as [`Restructure::new`] does, by one climb
    /// from the leaves (`Restructure::climb`); with treelets of `leaves` leaves.
    /// Records the phases `morton + sort` and `hierarchy + fit`.
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
    fn inner_below(&self, start: Vec<u32>, levels: usize) -> Vec<u32> {
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

    /// Reads the nodes `ids` (both ends of each: a node may straddle two cache lines)
    /// in a loop without branches, so that their cache misses overlap.
    fn touch(&self, ids: impl Iterator<Item = u32>) {
        let seen = ids.fold(0u32, |a, c| {
            let s = &self.slots[c as usize];
            a ^ s.bounds[0].load(Relaxed) ^ s.cost.load(Relaxed)
        });
        std::hint::black_box(seen);
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

// The straight-line programme, generated by build.rs (src/accel/bvh/dp_gen.rs):
// `treelet_lanes_k{k}(ops, tables, traversal, intersect)` for k = 3..=7, in the order
// of `tests::reference`, and `treelet_lanes_with(ops, k, ...)`.
include!(concat!(env!("OUT_DIR"), "/treelet_dp.rs"));

/// Optimises [`LANES`] treelets of `k` leaves at once (the first `used` lanes hold
/// treelets): in AVX-512 registers where the processor has them (x86-64-v4), else in
/// AVX2 registers (x86-64-v3) one half of the lanes at a time, else in SSE registers;
/// the same bits every way (tested).
fn treelet_lanes(k: usize, used: usize, t: &mut LaneTables, traversal: f32, intersect: f32) {
    #[cfg(target_arch = "x86_64")]
    if let Some(v4) = pulp::x86::V4::try_new() {
        return treelet_lanes_avx512(v4, k, t, traversal, intersect);
    }
    #[cfg(target_arch = "x86_64")]
    if let Some(v3) = pulp::x86::V3::try_new() {
        return treelet_lanes_avx(v3, k, used, t, traversal, intersect);
    }
    treelet_lanes_plain(k, t, traversal, intersect);
}

/// [`treelet_lanes`] in SSE registers.
#[inline(never)]
fn treelet_lanes_plain(k: usize, t: &mut LaneTables, traversal: f32, intersect: f32) {
    treelet_lanes_with(PlainLanes, k, t, traversal, intersect);
}

/// [`treelet_lanes`] in AVX2 registers: the generated code compiled with the
/// features `v3` proves.
#[cfg(target_arch = "x86_64")]
#[inline(never)]
fn treelet_lanes_avx(v3: pulp::x86::V3, k: usize, used: usize, t: &mut LaneTables, traversal: f32, intersect: f32) {
    /// The call `vectorize` compiles with the features (a closure's body would not
    /// be inlined into it, and every step would become a call).
    struct Dp<'a>(pulp::x86::V3, usize, usize, &'a mut LaneTables, f32, f32);
    impl pulp::NullaryFnOnce for Dp<'_> {
        type Output = ();
        #[inline(always)]
        fn call(self) {
            let Dp(v3, k, used, t, traversal, intersect) = self;
            for half in 0..used.div_ceil(8).min(2) {
                treelet_lanes_with(AvxLanes::new(v3, half), k, t, traversal, intersect);
            }
        }
    }
    v3.vectorize(Dp(v3, k, used, t, traversal, intersect));
}

/// [`treelet_lanes`] in AVX-512 registers: the generated code compiled with the
/// features `v4` proves.
#[cfg(target_arch = "x86_64")]
#[inline(never)]
fn treelet_lanes_avx512(v4: pulp::x86::V4, k: usize, t: &mut LaneTables, traversal: f32, intersect: f32) {
    struct Dp<'a>(pulp::x86::V4, usize, &'a mut LaneTables, f32, f32);
    impl pulp::NullaryFnOnce for Dp<'_> {
        type Output = ();
        #[inline(always)]
        fn call(self) {
            let Dp(v4, k, t, traversal, intersect) = self;
            treelet_lanes_with(Avx512Lanes(v4), k, t, traversal, intersect);
        }
    }
    v4.vectorize(Dp(v4, k, t, traversal, intersect));
}

/// Helper for tests: the collapsed SAH cost of a canonical tree.
pub fn collapsed_cost(bin: &Binary, costs: &SahCosts) -> f64 {
    bin.sah_cost(costs, true)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The loop the generated programme unrolls, for one treelet of `k` leaves (box,
    /// count, cost each): subsets ascending, each folded as rest ∪ lowest leaf; its
    /// partitions (P, S∖P) with the lowest leaf in P, P descending, the first strictly
    /// cheapest winning and (+inf, lowest leaf) if none is below +inf; then the node
    /// cost of [`Restructure::cost_of_area`]. Returns (area, count, cost, part) per subset.
    #[allow(clippy::type_complexity)]
    fn reference(
        k: usize,
        leaves: &[(Aabb, u32, f32)],
        costs: &SahCosts,
    ) -> ([f32; SUBSETS], [u32; SUBSETS], [f32; SUBSETS], [usize; SUBSETS]) {
        let mut boxes = [Aabb::EMPTY; SUBSETS];
        let (mut areas, mut counts, mut cost, mut part) =
            ([0f32; SUBSETS], [0u32; SUBSETS], [0f32; SUBSETS], [0; SUBSETS]);
        for (i, &(b, n, c)) in leaves[..k].iter().enumerate() {
            (boxes[1 << i], counts[1 << i], cost[1 << i]) = (b, n, c);
        }
        for s in 1..(1usize << k) {
            let low = s & s.wrapping_neg();
            if s == low {
                continue;
            }
            boxes[s] = boxes[s ^ low].union(&boxes[low]);
            areas[s] = area(&boxes[s]);
            counts[s] = counts[s ^ low] + counts[low];
            let rest = s ^ low;
            let mut best = (f32::INFINITY, low);
            let mut q = (rest - 1) & rest;
            loop {
                let p = low | q;
                let c = cost[p] + cost[s ^ p];
                if c < best.0 {
                    best = (c, p);
                }
                if q == 0 {
                    break;
                }
                q = (q - 1) & rest;
            }
            let split = costs.traversal * areas[s] + best.0;
            let leaf = costs.intersect * areas[s] * counts[s] as f32;
            cost[s] = if counts[s] as usize <= MAX_LEAF { split.min(leaf) } else { split };
            part[s] = best.1;
        }
        (areas, counts, cost, part)
    }

    /// The generated programme gives every lane the loop's areas, counts, costs and
    /// (through `best_part`) splits bit for bit, for every treelet size, on random
    /// treelets with many ties, zeros, +inf and NaN costs, flat, empty and half-inverted
    /// boxes, and counts on both sides of MAX_LEAF.
    #[test]
    fn generated_programme_equals_the_loop() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let costs = SahCosts::default();
        let special = [0.0, 1.0, 2.0, f32::INFINITY, f32::NAN];
        let mut t = LaneTables::new();
        for trial in 0..1500 {
            for k in 3..=TREELET_LEAVES {
                let mut lanes = vec![];
                for lane in 0..LANES {
                    let leaves: Vec<(Aabb, u32, f32)> = (0..k)
                        .map(|_| {
                            let r = next();
                            let v: Vec<f32> = (0..6).map(|i| ((r >> (40 + 3 * i)) % 8) as f32 * 0.5).collect();
                            let min = Vec3::new(v[0], v[1], v[2]);
                            let b = match r % 9 {
                                0 => Aabb::EMPTY,
                                1 => Aabb { min, max: min },
                                // Inverted on one axis only.
                                2 => Aabb { min, max: min - Vec3::AXES[(r >> 60) as usize % 3] },
                                _ => Aabb { min, max: min + Vec3::new(v[3], v[4], v[5]) },
                            };
                            let n = 1 + (r >> 8) as u32 % 4;
                            let c = if trial % 3 == 0 && r % 5 == 0 {
                                special[(r >> 16) as usize % special.len()]
                            } else {
                                ((r >> 20) % 16) as f32
                            };
                            (b, n, c)
                        })
                        .collect();
                    for (i, &(b, n, c)) in leaves.iter().enumerate() {
                        t.set_leaf(lane, i, &b, n, c);
                    }
                    lanes.push(leaves);
                }
                // Every instruction set on the same tables (the same bits): SSE first,
                // then AVX2 and AVX-512 where the processor has them, each over the
                // results of the one before.
                treelet_lanes_plain(k, &mut t, costs.traversal, costs.intersect);
                let plain = (t.area, t.count, t.cost);
                let same = |t: &LaneTables, what: &str| {
                    for s in 1..(1usize << k) {
                        let bits = |r: &[f32; LANES]| r.map(f32::to_bits);
                        assert_eq!(bits(&t.area[s]), bits(&plain.0[s]), "{what} area, k {k}, subset {s}");
                        assert_eq!(t.count[s], plain.1[s], "{what} count, k {k}, subset {s}");
                        assert_eq!(bits(&t.cost[s]), bits(&plain.2[s]), "{what} cost, k {k}, subset {s}");
                    }
                };
                #[cfg(target_arch = "x86_64")]
                if let Some(v3) = pulp::x86::V3::try_new() {
                    treelet_lanes_avx(v3, k, LANES, &mut t, costs.traversal, costs.intersect);
                    same(&t, "AVX2");
                }
                #[cfg(target_arch = "x86_64")]
                if let Some(v4) = pulp::x86::V4::try_new() {
                    treelet_lanes_avx512(v4, k, &mut t, costs.traversal, costs.intersect);
                    same(&t, "AVX-512");
                }
                for (lane, leaves) in lanes.iter().enumerate() {
                    let (areas, counts, cost, part) = reference(k, leaves, &costs);
                    for s in 1..(1usize << k) {
                        if s.count_ones() < 2 {
                            continue;
                        }
                        let at = format!("k {k}, lane {lane}, subset {s}, trial {trial}");
                        assert_eq!(t.area[s][lane].to_bits(), areas[s].to_bits(), "area, {at}");
                        assert_eq!(t.count[s][lane] as u32, counts[s], "count, {at}");
                        assert_eq!(t.cost[s][lane].to_bits(), cost[s].to_bits(), "cost, {at}");
                        assert_eq!(t.best_part(s, lane), part[s], "part, {at}");
                    }
                }
            }
        }
    }

    /// Presets and keys parse; each round's γ follows the schedule; bad values are
    /// refused.
    #[test]
    fn parameters_parse_and_gamma_cycles() {
        let d = TreeletParams::default();
        assert_eq!(TreeletParams::parse("default"), Ok(d));
        assert_eq!((d.leaves, d.rounds), (7, 3));
        let g: Vec<u32> = (0..3).map(|r| d.gamma(r)).collect();
        assert_eq!(g, [7, 7, 28]);
        let g: Vec<u32> = (0..3).map(|r| TreeletParams::paper().gamma(r)).collect();
        assert_eq!(g, [7, 14, 28]);
        assert_eq!(TreeletParams::parse("quality").map(|q| q.gamma(2)), Ok(7));
        assert_eq!(TreeletParams::parse("fast,rounds=5"), Ok(TreeletParams { leaves: 5, rounds: 5, ..d }));
        let g: Vec<u32> = (0..5).map(|r| TreeletParams::fast().gamma(r)).collect();
        assert_eq!(g, [5, 5, 20, 5, 5]);
        let p = TreeletParams::parse("leaves=6,gamma=1/4/2").expect("parses");
        assert_eq!((p.rounds, p.gamma(0), p.gamma(1), p.gamma(2)), (3, 6, 24, 12));
        for bad in ["leaves=8", "rounds=9", "best", "gamma=", "gamma=0", "gamma=1/x", "gamma=1/1/1/1/1/1/1/1/1"] {
            assert!(TreeletParams::parse(bad).is_err(), "{bad}");
        }
    }
}
