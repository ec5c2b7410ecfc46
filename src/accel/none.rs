//! Brute force with a scene-box early-out: the baseline. The "structure" is only the
//! scene's bounding box; CPU traversal here is the oracle every structure's tests use.

use std::time::Instant;

use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

use super::BuildStats;

/// The scene box, the only state brute force needs.
#[derive(Debug, Clone)]
pub struct BruteForce {
    pub bounds: Aabb,
    build_ms: f64,
}

impl BruteForce {
    /// "Builds" by computing the scene box.
    pub fn build(scene: &Scene) -> BruteForce {
        let start = Instant::now();
        let bounds = scene.bounds();
        BruteForce { bounds, build_ms: start.elapsed().as_secs_f64() * 1e3 }
    }

    /// The box is non-empty and finite.
    pub fn validate(&self) -> Result<(), String> {
        if self.bounds.is_empty() || !self.bounds.min.is_finite() || !self.bounds.max.is_finite() {
            return Err(format!("scene box {:?} is empty or not finite", self.bounds));
        }
        Ok(())
    }

    pub fn stats(&self) -> BuildStats {
        BuildStats { kind: "none".into(), build_ms: self.build_ms, bytes: 0, nodes: 0, max_depth: 0 }
    }

    /// Nearest hit in (tmin, tmax), ties broken by the lower primitive index, exactly
    /// like the GPU loop (which tests in index order and keeps strictly closer hits).
    pub fn intersect(&self, scene: &Scene, ray: &Ray) -> Option<Hit> {
        let inv = Aabb::inv_dir(ray.dir);
        self.bounds.ray_box(ray.origin, inv, ray.tmin, ray.tmax)?;
        let mut best: Option<Hit> = None;
        let mut r = *ray;
        for (i, t) in scene.triangles.iter().enumerate() {
            let [a, b, c] = t.map(|k| scene.positions[k as usize]);
            if let Some((t, u, v)) = crate::math::intersect::ray_triangle(&r, a, b, c) {
                r.tmax = t;
                best = Some(Hit { t, prim: i as u32, u, v });
            }
        }
        let nt = scene.triangles.len() as u32;
        for (i, s) in scene.spheres.iter().enumerate() {
            if let Some(t) = crate::math::intersect::ray_sphere(&r, s.center, s.radius) {
                r.tmax = t;
                best = Some(Hit { t, prim: nt + i as u32, u: 0.0, v: 0.0 });
            }
        }
        best
    }

    /// Whether anything lies in (tmin, tmax).
    pub fn occluded(&self, scene: &Scene, ray: &Ray) -> bool {
        let inv = Aabb::inv_dir(ray.dir);
        if self.bounds.ray_box(ray.origin, inv, ray.tmin, ray.tmax).is_none() {
            return false;
        }
        scene.triangles.iter().any(|t| {
            let [a, b, c] = t.map(|k| scene.positions[k as usize]);
            crate::math::intersect::ray_triangle(ray, a, b, c).is_some()
        }) || scene.spheres.iter().any(|s| crate::math::intersect::ray_sphere(ray, s.center, s.radius).is_some())
    }
}
