//! Axis-aligned boxes and the robust slab test.

use glam::Vec3;

use super::float::{gamma, safe_rcp};

/// Operations whose rounding the box test's far padding covers (see `ray_box`).
pub const BOX_PAD_OPS: u32 = 7;
/// |1/d| at or above this means a zero direction component (see `safe_rcp`).
pub const FLAT_RCP: f32 = 1e30;

/// An axis-aligned box; `Aabb::EMPTY` has min > max.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// The least corner.
    pub min: Vec3,
    /// The greatest corner.
    pub max: Vec3,
}

impl Aabb {
    /// The box holding nothing (min +inf, max -inf): growing it by a point gives that point.
    pub const EMPTY: Aabb = Aabb { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };

    /// Grows the box to contain `p`.
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    /// The smallest box containing both.
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }
    /// True when min > max on some axis.
    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }
    /// The centre.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
    /// max - min per axis.
    pub fn extent(&self) -> Vec3 {
        self.max - self.min
    }

    /// Slab test (Kay & Kajiya) with a NaN-free reciprocal (`safe_rcp`) and the far
    /// distance padded by 1 + 2·gamma(7) (Ize, "Robust BVH Ray Traversal", JCGT 2013)
    /// so that a hit on a face is never culled: a subtraction and a product (half an
    /// ulp each) and the reciprocal, which Vulkan allows 2.5 ulp (5 half-ulps).
    /// A zero direction component (±0, or below 1e-30, where `safe_rcp` saturates)
    /// makes that slab everything when the origin lies within it, faces included,
    /// and nothing otherwise; (b − o)·(1/d) would give 0 for an origin on a face and
    /// cull a ray lying in the face's plane. Returns the entry/exit interval clipped
    /// to [tmin, tmax], or None. Twin: `ray_box` in ray.glsl.
    pub fn ray_box(&self, origin: Vec3, inv_dir: Vec3, tmin: f32, tmax: f32) -> Option<(f32, f32)> {
        let t0 = (self.min - origin) * inv_dir;
        let t1 = (self.max - origin) * inv_dir;
        let mut near = t0.min(t1);
        let mut far = t0.max(t1) * (1.0 + 2.0 * gamma(BOX_PAD_OPS));
        for a in 0..3 {
            if inv_dir[a].abs() >= FLAT_RCP {
                let inside = origin[a] >= self.min[a] && origin[a] <= self.max[a];
                near[a] = if inside { -f32::MAX } else { f32::MAX };
                far[a] = if inside { f32::MAX } else { -f32::MAX };
            }
        }
        let enter = near.max_element().max(tmin);
        let exit = far.min_element().min(tmax);
        (enter <= exit).then_some((enter, exit))
    }

    /// The reciprocal direction `ray_box` expects.
    pub fn inv_dir(dir: Vec3) -> Vec3 {
        Vec3::new(safe_rcp(dir.x), safe_rcp(dir.y), safe_rcp(dir.z))
    }
}
