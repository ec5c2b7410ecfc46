//! The treelet dynamic programme over [`LANES`] treelets at once, one per SIMD lane:
//! their tables ([`LaneTables`]), the lane-wise steps (`LaneOps`) in SSE, AVX2 and
//! AVX-512, the straight-line programme build.rs generates over those steps, and the
//! choice of instruction set at run time ([`treelet_lanes`]). Every way gives the same
//! bits (tested against the plain loop).

use glam::Vec3;

use super::tree::Slot;
use super::TREELET_LEAVES;
use crate::accel::bvh::MAX_LEAF;
use crate::math::Aabb;

const SUBSETS: usize = 1 << TREELET_LEAVES;

/// Treelets optimised at once by the generated programme, one per SIMD lane: one
/// AVX-512 register, or two AVX2 registers run one after the other.
pub(super) const LANES: usize = 16;
/// One value per lane.
type Lanes = [f32; LANES];

/// The tables of [`LANES`] treelets of the same size, subset-major and lane-minor
/// (`area[s][lane]`; subset bit i = treelet leaf i). On entry the leaves' entries
/// (`1 << i`) are set; the generated programme fills the rest.
#[repr(C, align(64))]
pub(super) struct LaneTables {
    /// Box of each subset: min x, y, z, max x, y, z.
    bounds: [[Lanes; 6]; SUBSETS],
    /// Surface area of each subset's box.
    area: [Lanes; SUBSETS],
    /// Primitives in each subset.
    pub(super) count: [[i32; LANES]; SUBSETS],
    /// Optimal cost of each subset (with collapse).
    pub(super) cost: [Lanes; SUBSETS],
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
    pub(super) fn with<R>(f: impl FnOnce(&mut LaneTables) -> R) -> R {
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
    pub(super) fn aabb(&self, s: usize, lane: usize) -> Aabb {
        let b = &self.bounds[s];
        Aabb { min: Vec3::new(b[0][lane], b[1][lane], b[2][lane]), max: Vec3::new(b[3][lane], b[4][lane], b[5][lane]) }
    }

    /// The first part P (holding the lowest leaf of `s`; P descending) with the
    /// strictly cheapest cost(P) + cost(S∖P) in `lane`, or the lowest leaf alone if
    /// none is below +inf: the split whose cost the generated programme found. That
    /// is the first P whose sum equals the cheapest sum the programme kept (`split`;
    /// the same addition, and never NaN), so the scan stops there and carries no
    /// comparison chain from one partition to the next.
    pub(super) fn best_part(&self, s: usize, lane: usize) -> usize {
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
    pub(super) fn set_leaf(&mut self, lane: usize, i: usize, b: &Aabb, count: u32, cost: f32) {
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
    ///
    /// [`area`]: crate::accel::sah::area
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
    ///
    /// [`Restructure::cost_of_area`]: super::Restructure::cost_of_area
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
/// instruction do twice the work of AVX2's 8 for the same fetch (docs/bvh.md, "trbvh").
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

// The straight-line programme, generated by build.rs (src/accel/bvh/dp_gen.rs):
// `treelet_lanes_k{k}(ops, tables, traversal, intersect)` for k = 3..=7, in the order
// of `tests::reference`, and `treelet_lanes_with(ops, k, ...)`.
include!(concat!(env!("OUT_DIR"), "/treelet_dp.rs"));

/// Optimises [`LANES`] treelets of `k` leaves at once (the first `used` lanes hold
/// treelets): in AVX-512 registers where the processor has them (x86-64-v4), else in
/// AVX2 registers (x86-64-v3) one half of the lanes at a time, else in SSE registers;
/// the same bits every way (tested).
pub(super) fn treelet_lanes(k: usize, used: usize, t: &mut LaneTables, traversal: f32, intersect: f32) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::sah::{area, SahCosts};

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
}
