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

/// Moves a hit point off its surface along the geometric normal `n` so that a ray
/// spawned from it does not hit the same surface again: Wächter & Binder, "A Fast
/// and Robust Method for Avoiding Self-Intersection", Ray Tracing Gems (2019), ch. 6.
/// Far from the origin the point moves by a fixed number of ulps (integer offset of
/// the float bits); near it, by a small absolute amount.
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let of_i = [(INT_SCALE * n.x) as i32, (INT_SCALE * n.y) as i32, (INT_SCALE * n.z) as i32];
    let pa = p.to_array();
    let na = n.to_array();
    let mut out = [0.0f32; 3];
    for k in 0..3 {
        let bits = pa[k].to_bits() as i32;
        let moved = if pa[k] < 0.0 { bits.wrapping_sub(of_i[k]) } else { bits.wrapping_add(of_i[k]) };
        let p_i = f32::from_bits(moved as u32);
        out[k] = if pa[k].abs() < ORIGIN { pa[k] + FLOAT_SCALE * na[k] } else { p_i };
    }
    Vec3::from_array(out)
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
    fn offset_moves_off_surface_at_every_scale() {
        for scale in [1e-6f32, 1.0, 1e6] {
            let p = Vec3::new(0.3, -0.7, 0.2) * scale;
            let n = Vec3::new(0.0, 1.0, 0.0);
            let q = offset_ray_origin(p, n);
            assert!(q.y > p.y, "scale {scale}: {q:?} not above {p:?}");
            // Near the origin the move is 1/65536 absolute; elsewhere 256 ulps.
            let bound = if p.y.abs() < 1.0 / 32.0 { 1.0 / 65536.0 } else { 256.0 * p.y.abs() * f32::EPSILON };
            assert!((q.y - p.y).abs() <= bound * 1.0001, "scale {scale}: moved {}", q.y - p.y);
        }
    }
}
