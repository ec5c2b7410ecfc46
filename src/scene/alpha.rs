//! Cut-outs and blended panes (glTF's alphaMode MASK and BLEND; docs/materials.md,
//! "Alpha"): whether a ray meets a triangle where it hits it. Twin of
//! shaders/common/alpha.glsl, which every traversal calls from its primitive test (and
//! the CPU reference from `accel::prim::intersect_prim`), so that both answer alike.
//!
//! - The alpha is the material's `opacity` times the alpha of the albedo texture's
//!   texel under the hit (nearest texel, the texture's wrap modes), times the vertex
//!   colours' alpha there (crate::scene::colors).
//! - MASK: the surface is absent where the alpha is below the cutoff.
//! - BLEND: the ray meets it with probability alpha, decided by a hash of the ray's
//!   origin and direction and the primitive: a seed gives one image, and the samples of
//!   a pixel converge to the blended colour (stochastic transparency).
//! - A sphere takes its material's opacity alone ([`meets_sphere`]).
//! - Opaque materials are met everywhere; a scene without alpha compiles the test out
//!   (`SPEC_ALPHA`).

use glam::{Vec2, Vec3};

use super::{AlphaMode, Material, Scene, Texture, Wrap};

impl Scene {
    /// Whether any material is a cut-out or a blended pane.
    pub fn has_alpha(&self) -> bool {
        self.materials.iter().any(Material::has_alpha)
    }

    /// The textures whose alpha the kernels read: the albedo textures of materials with
    /// alpha that hold an alpha below 255 somewhere (the others read as 1).
    pub fn alpha_textures(&self) -> Vec<u32> {
        let mut out: Vec<u32> = self
            .materials
            .iter()
            .filter(|m| m.has_alpha())
            .filter_map(|m| m.texture)
            .filter(|&t| self.textures[t as usize].texels.iter().any(|p| p[3] < 255))
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }
}

/// PCG hash (rng.glsl's `pcg_hash`).
pub fn pcg_hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// The number in [0, 1) a BLEND surface's alpha is compared with: a hash of the ray and
/// the primitive (`blend_hash` in alpha.glsl).
pub fn blend_hash(origin: Vec3, dir: Vec3, prim: u32) -> f32 {
    let mut h = pcg_hash(prim);
    for w in [origin.x, origin.y, origin.z, dir.x, dir.y, dir.z] {
        h = pcg_hash(h ^ w.to_bits());
    }
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// A texture coordinate reduced to one period of its wrap mode (`wrap_coord` in
/// textures.glsl).
fn wrap_coord(u: f32, w: Wrap) -> f32 {
    match w {
        Wrap::Clamp => u.clamp(-1.0, 2.0),
        Wrap::Mirror => u - 2.0 * (0.5 * u).floor(),
        Wrap::Repeat => u - u.floor(),
    }
}

/// Texel index `i` of `n`, wrapped (`wrap_texel` in textures.glsl).
fn wrap_texel(i: i32, n: i32, w: Wrap) -> u32 {
    match w {
        Wrap::Clamp => i.clamp(0, n - 1) as u32,
        Wrap::Mirror => {
            let p = (i % (2 * n) + 2 * n) % (2 * n);
            (if p < n { p } else { 2 * n - 1 - p }) as u32
        }
        Wrap::Repeat => ((i % n + n) % n) as u32,
    }
}

/// The index of the texel under `uv` (row 0 at the top, v = 1).
pub fn texel_under(t: &Texture, uv: Vec2) -> usize {
    let (w, h) = (t.width as i32, t.height as i32);
    let x = wrap_coord(uv.x, t.wrap[0]) * w as f32;
    let y = (1.0 - wrap_coord(uv.y, t.wrap[1])) * h as f32;
    let ix = wrap_texel(x.floor() as i32, w, t.wrap[0]);
    let iy = wrap_texel(y.floor() as i32, h, t.wrap[1]);
    (iy * t.width + ix) as usize
}

/// The texture coordinates at barycentrics (u, v) of triangle `tri` of `geometry`, as
/// the kernels compute them (no fused multiply-add).
fn uv_at(geometry: &Scene, tri: u32, u: f32, v: f32) -> Vec2 {
    let [a, b, c] = geometry.triangles[tri as usize].map(|k| geometry.uvs.get(k as usize).copied().unwrap_or_default());
    let b0 = 1.0 - u - v;
    a * b0 + b * u + c * v
}

/// Whether a ray from `origin` along `dir` meets triangle `tri` of `geometry` (the
/// scene, or an instance's prototype) at barycentrics (u, v); the materials and
/// textures are `shading`'s.
pub fn meets(shading: &Scene, geometry: &Scene, tri: u32, origin: Vec3, dir: Vec3, u: f32, v: f32) -> bool {
    let m = &shading.materials[geometry.tri_material[tri as usize] as usize];
    if m.alpha_mode == AlphaMode::Opaque {
        return true;
    }
    let mut alpha = m.opacity;
    // A texture whose alpha is 255 everywhere reads as 1, as the kernels' (which skip it).
    if let Some(t) = m.texture.map(|t| &shading.textures[t as usize]) {
        let byte = t.texels[texel_under(t, uv_at(geometry, tri, u, v))][3];
        alpha *= f32::from(byte) / 255.0;
    }
    if shading.has_vertex_colors() {
        alpha *= geometry.color_at(tri, u, v).w;
    }
    match m.alpha_mode {
        AlphaMode::Mask { cutoff } => alpha >= cutoff,
        AlphaMode::Blend => blend_hash(origin, dir, tri) < alpha,
        AlphaMode::Opaque => true,
    }
}

/// Whether a ray meets sphere primitive `prim` of material `material`: its opacity
/// alone decides (a sphere's texture alpha is not read; `sphere_alpha_meets` in
/// alpha.glsl).
pub fn meets_sphere(shading: &Scene, material: u32, prim: u32, origin: Vec3, dir: Vec3) -> bool {
    let m = &shading.materials[material as usize];
    match m.alpha_mode {
        AlphaMode::Opaque => true,
        AlphaMode::Mask { cutoff } => m.opacity >= cutoff,
        AlphaMode::Blend => blend_hash(origin, dir, prim) < m.opacity,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrapped_texels_and_hash_range() {
        let t = Texture { name: "t".into(), width: 4, height: 2, texels: vec![[0; 4]; 8], wrap: [Wrap::Repeat; 2] };
        // Top row is v in (0.5, 1]; column 1 is u in [0.25, 0.5).
        assert_eq!(texel_under(&t, Vec2::new(0.3, 0.9)), 1);
        assert_eq!(texel_under(&t, Vec2::new(1.3, 0.1)), 5);
        // v = -0.1 repeats as 0.9: the top row.
        assert_eq!(texel_under(&t, Vec2::new(-0.7, -0.1)), 1);
        let h: Vec<f32> = (0..1000).map(|k| blend_hash(Vec3::splat(k as f32), Vec3::Y, k)).collect();
        assert!(h.iter().all(|x| (0.0..1.0).contains(x)));
        let mean = h.iter().sum::<f32>() / h.len() as f32;
        assert!((mean - 0.5).abs() < 0.05, "{mean}");
    }
}
