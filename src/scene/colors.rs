//! Vertex colours (glTF's COLOR_0, PLY's red/green/blue; docs/materials.md, "Vertex
//! colours"): linear RGBA at each vertex, interpolated across a triangle, multiplying
//! the base colour (the albedo) and the alpha. The kernels read them as 16-bit unorm
//! words from a section of the shading buffer (shaders/common/colors.glsl), so the CPU
//! twin here reads the same quantised values.

use glam::Vec4;

use super::Scene;

/// sRGB-encoded [0, 1] to linear.
pub fn srgb_to_linear(s: f32) -> f32 {
    if s <= 0.04045 {
        s / 12.92
    } else {
        ((s + 0.055) / 1.055).powf(2.4)
    }
}

/// Clamps colours to [0, 1], a non-finite channel to 1 (white is no change).
pub fn clamp_colors(colors: &mut [Vec4]) {
    for c in colors {
        *c = Vec4::from_array(c.to_array().map(|x| if x.is_finite() { x.clamp(0.0, 1.0) } else { 1.0 }));
    }
}

/// A colour as the kernels store it: four 16-bit unorm channels, red and green in the
/// first word (red in the low half), blue and alpha in the second (`vertex_color` in
/// colors.glsl decodes each channel by a division, as [`stored_color`] does).
pub fn color_words(c: Vec4) -> [u32; 2] {
    let q = |x: f32| (x.clamp(0.0, 1.0) * 65535.0).round() as u32;
    [q(c.x) | q(c.y) << 16, q(c.z) | q(c.w) << 16]
}

/// The colour the kernels read back from [`color_words`].
pub fn stored_color(c: Vec4) -> Vec4 {
    let [rg, ba] = color_words(c);
    let f = |w: u32| (w & 0xffff) as f32 / 65535.0;
    Vec4::new(f(rg), f(rg >> 16), f(ba), f(ba >> 16))
}

impl Scene {
    /// Whether any vertex (the scene's or a prototype's) has a colour.
    pub fn has_vertex_colors(&self) -> bool {
        !self.colors.is_empty()
            || self.instancing.iter().flat_map(|i| &i.prototypes).any(|p| !p.geometry.colors.is_empty())
    }

    /// The colour at barycentrics (u, v) of triangle `tri` of this geometry (the scene
    /// or a prototype), as the kernels interpolate the stored colours (no fused
    /// multiply-add; a geometry without colours stores white).
    pub fn color_at(&self, tri: u32, u: f32, v: f32) -> Vec4 {
        let [a, b, c] = self.triangles[tri as usize]
            .map(|k| stored_color(self.colors.get(k as usize).copied().unwrap_or(Vec4::ONE)));
        let b0 = 1.0 - u - v;
        a * b0 + b * u + c * v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantised_colours_round_trip_within_half_a_step() {
        for c in [Vec4::ZERO, Vec4::ONE, Vec4::new(0.25, 0.5, 0.75, 0.1), Vec4::new(1.0 / 3.0, 0.999, 1e-6, 0.5)] {
            let back = stored_color(c);
            assert!((back - c).abs().max_element() <= 0.5 / 65535.0 + 1e-7, "{c} -> {back}");
        }
        assert_eq!(color_words(Vec4::ONE), [0xffff_ffff; 2]);
        let mut odd = [Vec4::new(f32::NAN, -1.0, 2.0, f32::INFINITY)];
        clamp_colors(&mut odd);
        assert_eq!(odd[0], Vec4::new(1.0, 0.0, 1.0, 1.0));
    }
}
