//! Crack counting: rays from inside a closed mesh must all hit it, so every miss is a
//! ray that slipped through the surface. Used by `arbor bench` on `builtin:inside:N`
//! and by the robustness tests.

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::{Accel, Prims, Traverse};
use crate::math::intersect::IntersectMode;
use crate::math::Ray;
use crate::scene::Scene;

/// Deterministic xorshift generator in [0, 1).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }

    fn dir(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(self.next() * 2.0 - 1.0, self.next() * 2.0 - 1.0, self.next() * 2.0 - 1.0);
            if v.length_squared() > 0.01 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }
}

/// `n` rays from within `radius` of `centre` (inside the closed mesh): a third in
/// random directions, a third aimed exactly at vertices and a third at edge midpoints,
/// where a non-watertight test lets rays through.
pub fn aimed_rays(scene: &Scene, centre: Vec3, radius: f32, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Rng(seed | 1);
    let (np, nt) = (scene.positions.len(), scene.triangles.len());
    (0..n)
        .map(|k| {
            let origin = centre + rng.dir() * (radius * rng.next());
            let target = match k % 3 {
                _ if np == 0 || nt == 0 => origin + rng.dir(),
                0 => origin + rng.dir(),
                1 => scene.positions[(rng.next() * np as f32) as usize % np],
                _ => {
                    let t = scene.triangles[(rng.next() * nt as f32) as usize % nt];
                    let e = (rng.next() * 3.0) as usize % 3;
                    (scene.positions[t[e] as usize] + scene.positions[t[(e + 1) % 3] as usize]) * 0.5
                }
            };
            let dir = (target - origin).try_normalize().unwrap_or(Vec3::X);
            Ray { origin, dir, tmin: 0.0, tmax: f32::INFINITY }
        })
        .collect()
}

/// Rays that hit nothing (CPU traversal of `accel`, in the scene's intersection mode).
pub fn escapes(scene: &Scene, mode: IntersectMode, accel: &Accel, rays: &[Ray]) -> usize {
    let prims = Prims::with_mode(scene, mode);
    rays.par_iter().filter(|r| accel.intersect_with(&prims, r).is_none()).count()
}
