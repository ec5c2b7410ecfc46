//! The surface area heuristic, shared by every builder so that costs are comparable
//! across structures (MacDonald & Booth 1990; Wald & Havran 2006 for the empty-space
//! bonus).

use crate::math::Aabb;

/// Cost constants of the SAH.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SahCosts {
    /// Cost of one traversal step (visiting an inner node).
    pub traversal: f32,
    /// Cost of one primitive intersection test.
    pub intersect: f32,
    /// Factor (< 1) applied to a split that leaves one side empty, favouring cutting
    /// off empty space (Wald & Havran use 0.8).
    pub empty_bonus: f32,
}

impl Default for SahCosts {
    fn default() -> Self {
        SahCosts { traversal: 1.0, intersect: 1.5, empty_bonus: 0.8 }
    }
}

/// Surface area of a box (0 for an empty box).
pub fn area(b: &Aabb) -> f32 {
    if b.is_empty() {
        return 0.0;
    }
    let e = b.extent();
    2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
}

impl SahCosts {
    /// Cost of a leaf with `n` primitives (relative to reaching it).
    pub fn leaf(&self, n: usize) -> f32 {
        self.intersect * n as f32
    }

    /// Cost of splitting a node of area `parent` into children of areas `left`,
    /// `right` holding `nl`, `nr` primitives.
    #[inline]
    pub fn split(&self, parent: f32, left: f32, nl: usize, right: f32, nr: usize) -> f32 {
        let pl = left / parent;
        let pr = right / parent;
        let lambda = if nl == 0 || nr == 0 { self.empty_bonus } else { 1.0 };
        lambda * (self.traversal + self.intersect * (pl * nl as f32 + pr * nr as f32))
    }
}
