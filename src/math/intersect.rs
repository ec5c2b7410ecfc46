//! Ray/triangle and ray/sphere tests. Each has a GLSL twin of the same name in
//! `shaders/common/ray.glsl` with the same operation order (and `precise` there so
//! the compiler fuses nothing), so CPU and GPU agree to rounding of the division.

use glam::Vec3;

/// A ray with a unit (or at least non-zero) direction and a [tmin, tmax] interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
    pub tmin: f32,
    pub tmax: f32,
}

/// The closest hit found so far.
///
/// Order: smaller t wins; at equal t the lower primitive index wins ([`Hit::closer`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    pub t: f32,
    /// Triangles first in scene order, then spheres.
    pub prim: u32,
    /// Barycentric coordinates of v1 and v2 (triangles only).
    pub u: f32,
    pub v: f32,
}

impl Hit {
    /// Whether a candidate (t, prim) beats this hit: closer, or as close with a lower index.
    #[inline]
    pub fn closer(&self, t: f32, prim: u32) -> bool {
        t < self.t || (t == self.t && prim < self.prim)
    }

    /// The "no hit yet" state for a ray whose interval ends at `tmax`.
    pub fn none(tmax: f32) -> Hit {
        Hit { t: tmax, prim: u32::MAX, u: 0.0, v: 0.0 }
    }
}

/// Tests primitive `prim` of `scene` (triangles first, then spheres) against `ray`
/// clipped to the best hit so far, and records it if it wins. Twin of
/// `intersect_triangle` / `intersect_sphere` in trace.comp.
#[inline]
pub fn intersect_prim(scene: &crate::scene::Scene, prim: u32, ray: &Ray, best: &mut Hit) -> bool {
    let nt = scene.triangles.len() as u32;
    let r = Ray { tmax: best.t, ..*ray };
    if prim < nt {
        let [a, b, c] = scene.triangles[prim as usize].map(|k| scene.positions[k as usize]);
        if let Some((t, u, v)) = ray_triangle(&r, a, b, c) {
            if best.closer(t, prim) {
                *best = Hit { t, prim, u, v };
                return true;
            }
        }
    } else {
        let s = &scene.spheres[(prim - nt) as usize];
        if let Some(t) = ray_sphere(&r, s.center, s.radius) {
            if best.closer(t, prim) {
                *best = Hit { t, prim, u: 0.0, v: 0.0 };
                return true;
            }
        }
    }
    false
}

#[inline]
fn dot3(a: Vec3, b: Vec3) -> f32 {
    a.x * b.x + a.y * b.y + a.z * b.z
}

#[inline]
fn cross3(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x)
}

/// Möller & Trumbore, "Fast, Minimum Storage Ray/Triangle Intersection" (JGT 1997),
/// two-sided, no epsilon: a degenerate triangle has det = 0 and is never hit.
/// Returns (t, u, v) with t in (tmin, tmax]; callers break ties at equal t by the
/// lower primitive index, so every structure agrees with brute force.
pub fn ray_triangle(ray: &Ray, v0: Vec3, v1: Vec3, v2: Vec3) -> Option<(f32, f32, f32)> {
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let p = cross3(ray.dir, e2);
    let det = dot3(e1, p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = ray.origin - v0;
    let u = dot3(s, p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = cross3(s, e1);
    let v = dot3(ray.dir, q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = dot3(e2, q) * inv;
    (t > ray.tmin && t <= ray.tmax).then_some((t, u, v))
}

/// Ray/sphere after Haines, Günther & Akenine-Möller, "Precision Improvements for
/// Ray/Sphere Intersection", Ray Tracing Gems (2019), ch. 7: the discriminant is
/// computed from the distance of the centre to the ray line (no cancellation for
/// small spheres far away) and the roots from the numerically stable quadratic
/// form. Assumes a unit direction. Returns the nearest t in (tmin, tmax].
pub fn ray_sphere(ray: &Ray, center: Vec3, radius: f32) -> Option<f32> {
    let f = ray.origin - center;
    let b = -dot3(f, ray.dir);
    let l = f + b * ray.dir;
    let r2 = radius * radius;
    let disc = r2 - dot3(l, l);
    if disc < 0.0 {
        return None;
    }
    let c = dot3(f, f) - r2;
    let q = if b >= 0.0 { b + disc.sqrt() } else { b - disc.sqrt() };
    if q == 0.0 {
        return None;
    }
    let t0 = c / q;
    let t1 = q;
    let (near, far) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
    if near > ray.tmin && near <= ray.tmax {
        Some(near)
    } else if far > ray.tmin && far <= ray.tmax {
        Some(far)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn ray(o: Vec3, d: Vec3) -> Ray {
        Ray { origin: o, dir: d.normalize(), tmin: 0.0, tmax: f32::INFINITY }
    }

    #[test]
    fn triangle_hit_and_miss() {
        let (a, b, c) = (Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
        let h = ray_triangle(&ray(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z), a, b, c).expect("hit");
        assert!((h.0 - 5.0).abs() < 1e-6);
        assert!(ray_triangle(&ray(Vec3::new(3.0, 0.0, 5.0), -Vec3::Z), a, b, c).is_none());
        // Degenerate triangle is never hit.
        assert!(ray_triangle(&ray(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z), a, a, c).is_none());
    }

    #[test]
    fn sphere_small_and_far() {
        let s = ray_sphere(&ray(Vec3::new(0.0, 0.0, 1e5), -Vec3::Z), Vec3::ZERO, 1e-2).expect("hit");
        assert!((s - (1e5 - 1e-2)).abs() < 0.02, "{s}");
        // From inside: far root.
        let t = ray_sphere(&ray(Vec3::ZERO, Vec3::X), Vec3::ZERO, 2.0).expect("hit");
        assert!((t - 2.0).abs() < 1e-6);
    }

    proptest! {
        #[test]
        fn triangle_hit_point_lies_on_plane(ox in -5.0f32..5.0, oy in -5.0f32..5.0, tx in -0.3f32..0.3, ty in -0.3f32..0.3) {
            let (a, b, c) = (Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
            let o = Vec3::new(ox, oy, 4.0);
            let target = Vec3::new(tx, ty, 0.0);
            let r = ray(o, target - o);
            let h = ray_triangle(&r, a, b, c);
            prop_assert!(h.is_some());
            let (t, _, _) = h.unwrap_or_default();
            let p = r.origin + r.dir * t;
            prop_assert!(p.z.abs() < 1e-5);
        }

        #[test]
        fn sphere_hit_lies_on_surface(ox in -50.0f32..50.0, oy in -50.0f32..50.0, r in 0.01f32..10.0) {
            let o = Vec3::new(ox, oy, 100.0);
            let rr = ray(o, -o);
            let t = ray_sphere(&rr, Vec3::ZERO, r);
            prop_assert!(t.is_some());
            let p = rr.origin + rr.dir * t.unwrap_or_default();
            prop_assert!((p.length() - r).abs() < 1e-4 * o.length().max(1.0));
        }
    }
}
