//! Floating-point robustness helpers. Each has a GLSL twin of the same name in
//! `shaders/common/ray.glsl`.

use glam::Vec3;

/// pbrt-v4's gamma(n) = n·ε / (1 − n·ε), with ε = 2⁻²⁴ (half an ulp at 1.0): a bound
/// on the relative error of n floating-point operations (Pharr, Jakob & Humphreys,
/// "Physically Based Rendering", 4th ed., §6.8.1).
pub fn gamma(n: u32) -> f32 {
    let e = f32::EPSILON * 0.5 * n as f32;
    e / (1.0 - e)
}

/// Reciprocal that never returns ±inf or NaN: |x| below 1e-30 is replaced by 1e-30
/// with x's sign (−0 counts as negative), so 0 · rcp stays 0 and slabs stay ordered.
pub fn safe_rcp(x: f32) -> f32 {
    if x.abs() > 1e-30 {
        1.0 / x
    } else if x.is_sign_negative() {
        -1e30
    } else {
        1e30
    }
}

/// Moves a hit point `p`, known to within `err` per component, off its surface so
/// that a ray spawned from it toward `w` can not hit that surface again: pbrt-v4's
/// `OffsetRayOrigin` (Pharr, Jakob & Humphreys, "Physically Based Rendering", 4th
/// ed., §6.8.6). The offset along the geometric normal `n` is the error box projected
/// on it, `d = |n| · err`, toward the side `w` leaves to; the result is then rounded
/// one ulp further away from `p` per component. The offset scales with the
/// coordinates' own error, so it is right for scenes a micrometre or a megametre
/// across, near the origin or far from it: there is no fixed epsilon.
/// Twin: `offset_ray_origin` in ray.glsl, same operations in the same order.
pub fn offset_ray_origin(p: Vec3, err: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.x.abs() * err.x + n.y.abs() * err.y + n.z.abs() * err.z;
    let mut offset = n * d;
    if w.x * n.x + w.y * n.y + w.z * n.z < 0.0 {
        offset = -offset;
    }
    let mut po = p + offset;
    for i in 0..3 {
        if offset[i] > 0.0 {
            po[i] = po[i].next_up();
        } else if offset[i] < 0.0 {
            po[i] = po[i].next_down();
        }
    }
    po
}

/// A point on triangle (p0, p1, p2) at barycentrics (u, v) of p1 and p2, and the
/// bound on its error for spawning rays: pbrt-v4's rounding bound of the point,
/// `gamma(7) (|b0 p0| + |b1 p1| + |b2 p2|)`, plus `gamma(32)` times the triangle's
/// largest extent on every axis. The second term stands for the rounding of the
/// spawned ray's own test against this triangle, which grows with the triangle's size
/// (pbrt rejects such hits with a conservative t > 0 test instead; that test also
/// rejects real hits on slivers, which would break watertightness). It matters where
/// the first term is zero: a point on a plane x, y or z = 0 is exact across it.
/// Twin: `triangle_point` in ray.glsl.
pub fn triangle_point(p0: Vec3, p1: Vec3, p2: Vec3, u: f32, v: f32) -> (Vec3, Vec3) {
    let b0 = 1.0 - u - v;
    let (a, b, c) = (p0 * b0, p1 * u, p2 * v);
    let p = a + b + c;
    let size = (p0.max(p1).max(p2) - p0.min(p1).min(p2)).max_element();
    let err = (a.abs() + b.abs() + c.abs()) * gamma(7) + Vec3::splat(size * gamma(32));
    (p, err)
}

/// The hit point of a ray at `t` on the sphere (centre, radius) as (point, error
/// bound, offset from the centre). The offset is rebuilt from the ray's closest
/// approach to the centre, `l = f + b d` with `f = o - c`, `b = -f·d`, plus or minus
/// `sqrt(r² - |l|²) d` (Haines, Günther & Akenine-Möller's quantities): accurate to
/// the radius's own precision even for a sphere far smaller than the float spacing
/// at its position, where `o + t d - c` would be zero (and its normal NaN). It is then
/// projected onto the sphere (pbrt-v4); the error bound is gamma(5) |offset| plus the
/// rounding of adding the centre back, gamma(1) |p|. Twin: `sphere_point` in ray.glsl.
pub fn sphere_point(origin: Vec3, dir: Vec3, t: f32, center: Vec3, radius: f32) -> (Vec3, Vec3, Vec3) {
    let f = origin - center;
    let b = -(f.x * dir.x + f.y * dir.y + f.z * dir.z);
    let l = f + dir * b;
    let disc = (radius * radius - (l.x * l.x + l.y * l.y + l.z * l.z)).max(0.0);
    let s = disc.sqrt();
    let mut pc = if t < b { l - dir * s } else { l + dir * s };
    let len = (pc.x * pc.x + pc.y * pc.y + pc.z * pc.z).sqrt();
    if len > 0.0 {
        pc *= radius / len;
    }
    let p = center + pc;
    let err = pc.abs() * gamma(5) + p.abs() * gamma(1);
    (p, err, pc)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn safe_rcp_is_finite_and_signed() {
        assert_eq!(safe_rcp(0.0), 1e30);
        assert_eq!(safe_rcp(-0.0), -1e30);
        assert_eq!(safe_rcp(2.0), 0.5);
        assert!(safe_rcp(f32::MIN_POSITIVE).is_finite());
    }

    #[test]
    fn glsl_gamma_literals_match() {
        let glsl = include_str!("../../shaders/common/ray.glsl");
        for n in [1u32, 5, 7, 32] {
            let key = format!("const float GAMMA_{n} = ");
            let at = glsl.find(&key).unwrap_or_else(|| panic!("ray.glsl lacks {key}")) + key.len();
            let lit = &glsl[at..at + glsl[at..].find(';').expect("literal ends with ;")];
            let v: f32 = lit.parse().expect("a float literal");
            assert_eq!(v.to_bits(), gamma(n).to_bits(), "GAMMA_{n} = {lit} is not gamma({n})");
        }
    }

    #[test]
    fn offset_moves_off_surface_at_every_scale() {
        for scale in [1e-6f32, 1.0, 1e6] {
            for shift in [0.0f32, 1e6] {
                if shift > 0.0 && scale < 1.0 {
                    continue; // a micrometre triangle at 1e6 collapses to one point
                }
                let (p0, p1, p2) = (
                    Vec3::new(0.0, 0.0, 0.0) * scale + Vec3::splat(shift),
                    Vec3::new(1.0, 0.0, 0.1) * scale + Vec3::splat(shift),
                    Vec3::new(0.0, 0.3, 1.0) * scale + Vec3::splat(shift),
                );
                let n = (p1 - p0).cross(p2 - p0).normalize();
                let (p, err) = triangle_point(p0, p1, p2, 0.3, 0.4);
                let up = offset_ray_origin(p, err, n, n);
                let down = offset_ray_origin(p, err, n, -n);
                // Each side of the plane, in f64, by more than the error projected on n.
                let side = |q: Vec3| (q - p0).as_dvec3().dot(n.as_dvec3());
                assert!(side(up) > 0.0 && side(down) < 0.0, "scale {scale} shift {shift}: {up:?} {down:?}");
                // And not absurdly far: within 64 ulps of the coordinates.
                let ulp = p.abs().max_element().max(f32::MIN_POSITIVE) * f32::EPSILON;
                assert!((up - p).abs().max_element() <= 64.0 * ulp, "scale {scale}: moved {:?}", up - p);
            }
        }
    }
}
