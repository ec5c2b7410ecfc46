//! Ray/triangle and ray/sphere tests. Each has a GLSL twin of the same name in
//! `shaders/common/ray.glsl` with the same operation order (and `precise` there so
//! the compiler fuses nothing), so CPU and GPU agree to rounding of the division.

use glam::Vec3;

/// A ray: an origin, a unit direction, and the interval (tmin, tmax] in which hits count.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3,
    /// Its direction: unit length (ray/sphere tests assume it; ray batches check it).
    pub dir: Vec3,
    /// Hits at t <= tmin do not count.
    pub tmin: f32,
    /// Hits at t > tmax do not count (may be +inf).
    pub tmax: f32,
}

/// The closest hit found so far.
///
/// Order: smaller t wins; at equal t the lower primitive index wins ([`Hit::closer`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the ray from its origin.
    pub t: f32,
    /// Triangles first in scene order, then spheres.
    pub prim: u32,
    /// Barycentric coordinates of v1 and v2 (triangles only).
    pub u: f32,
    /// (see `u`)
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

#[inline]
fn dot3(a: Vec3, b: Vec3) -> f32 {
    a.x * b.x + a.y * b.y + a.z * b.z
}

#[inline]
fn cross3(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x)
}

/// How rays meet triangles: the user's trade between robustness and speed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum IntersectMode {
    /// Woop, Benthin & Wald (2013): no ray passes between triangles sharing an edge.
    #[default]
    Watertight,
    /// Möller & Trumbore (1997): fewer operations, but rays can slip through shared
    /// edges and vertices.
    Fast,
}

impl IntersectMode {
    /// The specialization constant's value (0 watertight, 1 fast).
    pub fn spec(self) -> u32 {
        match self {
            IntersectMode::Watertight => 0,
            IntersectMode::Fast => 1,
        }
    }

    /// The `--intersect` value.
    pub fn name(self) -> &'static str {
        match self {
            IntersectMode::Watertight => "watertight",
            IntersectMode::Fast => "fast",
        }
    }
}

impl std::str::FromStr for IntersectMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "watertight" => Ok(IntersectMode::Watertight),
            "fast" => Ok(IntersectMode::Fast),
            _ => Err(format!("unknown intersection mode '{s}'; available: watertight, fast")),
        }
    }
}

impl std::fmt::Display for IntersectMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Ray/triangle in `mode`; see [`ray_triangle_watertight`] and [`ray_triangle_fast`].
#[inline]
pub fn ray_triangle(ray: &Ray, v0: Vec3, v1: Vec3, v2: Vec3, mode: IntersectMode) -> Option<(f32, f32, f32)> {
    match mode {
        IntersectMode::Watertight => ray_triangle_watertight(ray, v0, v1, v2),
        IntersectMode::Fast => ray_triangle_fast(ray, v0, v1, v2),
    }
}

/// Woop, Benthin & Wald, "Watertight Ray/Triangle Intersection" (JCGT 2013). The
/// vertices are translated to the ray origin and sheared so the ray runs along +z
/// (kz is the largest direction component; kx, ky swap when it is negative, keeping
/// the winding). The three 2D edge functions are then evaluated from the same
/// transformed vertices by every triangle that shares them, so for a shared edge
/// the two triangles compute the same value with opposite signs, and a ray can not
/// slip between them. Ties: an edge function that is exactly zero counts as inside
/// for both signs after [`edge_function`] has re-evaluated it exactly (the paper uses
/// doubles, which Vulkan devices need not have), so a ray exactly through an edge or
/// vertex hits every triangle there and the closest-hit rule (smaller t, then lower
/// index) picks one.
/// Two-sided; det = 0 (degenerate, or the ray in the triangle's plane) never hits.
/// Returns (t, u, v), u and v the weights of v1 and v2. Twin: ray.glsl.
pub fn ray_triangle_watertight(ray: &Ray, v0: Vec3, v1: Vec3, v2: Vec3) -> Option<(f32, f32, f32)> {
    let d = ray.dir;
    let ad = d.abs();
    let kz = if ad.x > ad.y {
        if ad.x > ad.z {
            0
        } else {
            2
        }
    } else if ad.y > ad.z {
        1
    } else {
        2
    };
    let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
    if d[kz] < 0.0 {
        std::mem::swap(&mut kx, &mut ky);
    }
    let sz = 1.0 / d[kz];
    let sx = d[kx] * sz;
    let sy = d[ky] * sz;
    let a = v0 - ray.origin;
    let b = v1 - ray.origin;
    let c = v2 - ray.origin;
    let ax = a[kx] - sx * a[kz];
    let ay = a[ky] - sy * a[kz];
    let bx = b[kx] - sx * b[kz];
    let by = b[ky] - sy * b[kz];
    let cx = c[kx] - sx * c[kz];
    let cy = c[ky] - sy * c[kz];
    let u = edge_function(cx, by, cy, bx);
    let v = edge_function(ax, cy, ay, cx);
    let w = edge_function(bx, ay, by, ax);
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let az = sz * a[kz];
    let bz = sz * b[kz];
    let cz = sz * c[kz];
    let t_scaled = u * az + v * bz + w * cz;
    let inv = 1.0 / det;
    let t = t_scaled * inv;
    (t > ray.tmin && t <= ray.tmax).then_some((t, v * inv, w * inv))
}

/// `a b - c d`. When that rounds to exactly zero, the two rounded products were equal
/// and the true value is the difference of their rounding errors, which Dekker's
/// TwoProduct (Veltkamp splitting; only multiplications and additions, which Vulkan
/// rounds correctly, so no FMA and no doubles) gives exactly: the result then has the
/// sign of the exact value. This is Woop et al.'s double-precision re-evaluation
/// without doubles: a triangle far from the ray whose edge functions cancel in float
/// would otherwise count as hit. Twin: `edge_function` in ray.glsl.
#[inline]
pub fn edge_function(a: f32, b: f32, c: f32, d: f32) -> f32 {
    let p1 = a * b;
    let p2 = c * d;
    let r = p1 - p2;
    if r != 0.0 {
        return r;
    }
    two_product_error(a, b, p1) - two_product_error(c, d, p2)
}

/// Veltkamp's split of `a` into a high and a low half (each fits 12 bits).
#[inline]
fn split(a: f32) -> (f32, f32) {
    let c = 4097.0 * a;
    let hi = c - (c - a);
    (hi, a - hi)
}

/// Dekker's exact error `a b - p` of the rounded product `p = fl(a b)` (barring
/// overflow and underflow).
#[inline]
fn two_product_error(a: f32, b: f32, p: f32) -> f32 {
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    ((ah * bh - p) + ah * bl + al * bh) + al * bl
}

/// Möller & Trumbore, "Fast, Minimum Storage Ray/Triangle Intersection" (JGT 1997),
/// two-sided, no epsilon: a degenerate triangle has det = 0 and is never hit.
/// Returns (t, u, v) with t in (tmin, tmax]; callers break ties at equal t by the
/// lower primitive index, so every structure agrees with brute force.
pub fn ray_triangle_fast(ray: &Ray, v0: Vec3, v1: Vec3, v2: Vec3) -> Option<(f32, f32, f32)> {
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
    // |f|² - r², which cancels for a huge sphere seen from near its surface: square
    // exactly (Dekker) and subtract the high and low parts separately.
    let (hx, hy, hz) = (f.x * f.x, f.y * f.y, f.z * f.z);
    let lo = two_product_error(f.x, f.x, hx) + two_product_error(f.y, f.y, hy) + two_product_error(f.z, f.z, hz);
    let c = ((hx + hy + hz) - r2) + (lo - two_product_error(radius, radius, r2));
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
        let h = ray_triangle_fast(&ray(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z), a, b, c).expect("hit");
        assert!((h.0 - 5.0).abs() < 1e-6);
        assert!(ray_triangle_fast(&ray(Vec3::new(3.0, 0.0, 5.0), -Vec3::Z), a, b, c).is_none());
        // Degenerate triangle is never hit.
        assert!(ray_triangle_fast(&ray(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z), a, a, c).is_none());
    }

    #[test]
    fn edge_function_is_exact_where_float_cancels() {
        // 0.1f * 0.3f and 0.3f * 0.1f round alike; their true difference is 0.
        assert_eq!(edge_function(0.1, 0.3, 0.3, 0.1), 0.0);
        // a b and c d round to the same float but differ: the sign must survive.
        let (a, b) = (1.0f32 + f32::EPSILON, 1.0f32 - f32::EPSILON);
        let exact = f64::from(a) * f64::from(b) - 1.0;
        let got = edge_function(a, b, 1.0, 1.0);
        assert!(got != 0.0 && (f64::from(got) - exact).abs() <= exact.abs() * 1e-6, "{got} vs {exact}");
        // Swapping the products negates the result exactly (shared edges agree).
        assert_eq!(edge_function(1.0, 1.0, a, b), -got);
    }

    #[test]
    fn watertight_misses_a_tiny_triangle_far_from_the_ray() {
        // From tests/it/kdtree.rs's deep tree: edge functions cancel in float.
        let x = 0.5f32.powi(22);
        let s = x * 0.1;
        let y = 2.0 * s;
        let (a, b, c) = (Vec3::new(x, y, 0.0), Vec3::new(x + s, y, 0.0), Vec3::new(x, y + s, s));
        let r = Ray {
            origin: Vec3::new(0.33630168, 0.39839804, 0.04805419),
            dir: Vec3::new(0.34460494, 0.5358966, -0.7707544),
            tmin: 0.0,
            tmax: f32::INFINITY,
        };
        assert_eq!(ray_triangle_watertight(&r, a, b, c), None);
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
            let h = ray_triangle_fast(&r, a, b, c);
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
