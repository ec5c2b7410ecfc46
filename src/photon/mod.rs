//! Photon lookups for stochastic progressive photon mapping (SPPM; Hachisuka & Jensen
//! 2009, docs/caustics.md): the visible points of an iteration, each with its own
//! radius, and the question a photon asks at its vertex p, "which visible points
//! hold p within their radius?". Two structures answer it:
//!
//! - [`HashGrid`]: a hash grid over the visible points, built by a counting sort of
//!   cells (Hachisuka, Ogaki & Jensen 2010, "Progressive photon mapping on GPUs";
//!   pbrt-v4's SPPM): a point goes into every cell its sphere overlaps; a photon
//!   tests the points of its one cell.
//! - [`PointTree`]: the lecture's kd-tree, balanced on the points (each split at the
//!   median of the widest axis); each node bounds the spheres below it, and a photon
//!   descends only into nodes whose bounds hold it.
//!
//! Both give the same answer as testing every point ([`brute_force`]); the device
//! passes follow these layouts word for word, and these are their test oracles.

#![forbid(unsafe_code)]

pub mod device;
mod hashgrid;
mod kdtree;

pub use device::{build_grid, tree_lookup_counts, upload_points, DeviceGrid};
pub use hashgrid::HashGrid;
pub use kdtree::PointTree;

use glam::Vec3;

/// Whether `p` lies within visible point `i`'s radius: `|p - position[i]|^2 <
/// radius[i]^2`, the one test both structures and the kernels make.
pub fn holds(positions: &[Vec3], radii: &[f32], i: usize, p: Vec3) -> bool {
    (p - positions[i]).length_squared() < radii[i] * radii[i]
}

/// Every visible point that holds `p`, in index order: the oracle.
pub fn brute_force(positions: &[Vec3], radii: &[f32], p: Vec3) -> Vec<u32> {
    (0..positions.len()).filter(|&i| holds(positions, radii, i, p)).map(|i| i as u32).collect()
}

/// Checks that the visible points are usable: as many radii as positions, every
/// coordinate finite, every radius finite and positive, and fewer than 2^32 points.
pub fn check_points(positions: &[Vec3], radii: &[f32]) -> Result<(), String> {
    if positions.len() != radii.len() {
        return Err(format!("{} visible points but {} radii", positions.len(), radii.len()));
    }
    if positions.len() >= u32::MAX as usize {
        return Err(format!("{} visible points; at most {} fit a 32-bit index", positions.len(), u32::MAX - 1));
    }
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(format!("visible point {i} is at {}, not a finite position", positions[i]));
    }
    if let Some(i) = radii.iter().position(|r| !(r.is_finite() && *r > 0.0)) {
        return Err(format!("visible point {i} has radius {}; a radius must be finite and positive", radii[i]));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small counter-based generator (splitmix64), seeded.
    pub(crate) struct Rng(pub(crate) u64);

    impl Rng {
        pub(crate) fn next(&mut self) -> f32 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
        }
        pub(crate) fn vec(&mut self, scale: f32) -> Vec3 {
            Vec3::new(self.next(), self.next(), self.next()) * scale
        }
    }

    /// Visible points of several kinds: scattered, clustered on a plane (a floor),
    /// all at one spot, with radii from tiny to a tenth of the scene.
    pub(crate) fn point_sets() -> Vec<(&'static str, Vec<Vec3>, Vec<f32>)> {
        let mut rng = Rng(7);
        let mut sets = Vec::new();
        let n = 2000;
        let scattered: Vec<Vec3> = (0..n).map(|_| rng.vec(10.0)).collect();
        let radii: Vec<f32> = (0..n).map(|_| 0.01 + rng.next() * rng.next() * 1.0).collect();
        sets.push(("scattered", scattered, radii));
        let floor: Vec<Vec3> = (0..n).map(|_| Vec3::new(rng.next() * 4.0, 0.0, rng.next() * 4.0)).collect();
        let radii: Vec<f32> = (0..n).map(|_| 0.05 + rng.next() * 0.1).collect();
        sets.push(("floor", floor, radii));
        let spot = vec![Vec3::new(1.0, 2.0, 3.0); 300];
        let radii: Vec<f32> = (0..300).map(|k| 0.001 + k as f32 * 1e-3).collect();
        sets.push(("one spot", spot, radii));
        sets.push(("one point", vec![Vec3::ZERO], vec![0.5]));
        sets.push(("none", Vec::new(), Vec::new()));
        sets
    }

    /// Photon positions for a set: near the points (inside and just outside their
    /// radii) and anywhere in and around the box.
    pub(crate) fn queries(positions: &[Vec3], radii: &[f32]) -> Vec<Vec3> {
        let mut rng = Rng(11);
        let mut q = Vec::new();
        for (i, (&p, &r)) in positions.iter().zip(radii).enumerate().take(500) {
            let d = (rng.vec(2.0) - Vec3::ONE).normalize_or(Vec3::X);
            q.push(p + d * r * (0.5 + (i % 3) as f32 * 0.5));
        }
        for _ in 0..1000 {
            q.push(rng.vec(14.0) - Vec3::splat(2.0));
        }
        q
    }

    #[test]
    fn bad_points_are_refused_with_the_first_bad_one() {
        let p = [Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 0.0)];
        assert!(check_points(&p, &[1.0, 1.0]).unwrap_err().contains("visible point 1"));
        assert!(check_points(&p[..1], &[0.0]).unwrap_err().contains("radius 0"));
        assert!(check_points(&p[..1], &[1.0, 2.0]).unwrap_err().contains("1 visible points but 2 radii"));
        assert!(check_points(&p[..1], &[f32::INFINITY]).is_err());
        assert!(check_points(&[], &[]).is_ok());
    }
}
