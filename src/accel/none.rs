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

    /// Build time and phases (what [`Self::stats`] reports of them, without the rest).
    pub fn timing(&self) -> (f64, Vec<super::Phase>) {
        (self.build_ms, Vec::new())
    }

    pub fn stats(&self, scene: &Scene) -> BuildStats {
        let n = scene.prim_count();
        BuildStats {
            kind: "none".into(),
            build_ms: self.build_ms,
            leaves: 1,
            refs_per_prim: 1.0,
            mean_leaf_depth: 0.0,
            sah_cost: f64::from(super::sah::SahCosts::default().leaf(n)),
            ..Default::default()
        }
    }

    /// Nearest hit in (tmin, tmax]; at equal t the lower primitive index wins, exactly
    /// like the GPU loop.
    pub fn intersect(&self, scene: &Scene, ray: &Ray) -> Option<Hit> {
        let inv = Aabb::inv_dir(ray.dir);
        self.bounds.ray_box(ray.origin, inv, ray.tmin, ray.tmax)?;
        let mut best = Hit::none(ray.tmax);
        for p in 0..scene.prim_count() as u32 {
            crate::math::intersect::intersect_prim(scene, p, ray, &mut best);
        }
        (best.prim != u32::MAX).then_some(best)
    }

    /// Whether anything lies in (tmin, tmax).
    pub fn occluded(&self, scene: &Scene, ray: &Ray) -> bool {
        let inv = Aabb::inv_dir(ray.dir);
        if self.bounds.ray_box(ray.origin, inv, ray.tmin, ray.tmax).is_none() {
            return false;
        }
        scene.triangles.iter().any(|t| {
            let [a, b, c] = t.map(|k| scene.positions[k as usize]);
            crate::math::intersect::ray_triangle(ray, a, b, c, scene.intersect).is_some()
        }) || scene.spheres.iter().any(|s| crate::math::intersect::ray_sphere(ray, s.center, s.radius).is_some())
    }
}
