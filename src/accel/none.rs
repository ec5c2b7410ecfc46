//! Brute force with a scene-box early-out: the baseline. The "structure" is only the
//! scene's bounding box; CPU traversal here is the oracle every structure's tests use.

use std::time::Instant;

use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

use super::prim::{intersect_prim, Prims};
use super::validate::ValidateError;
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
    pub fn validate(&self) -> Result<(), ValidateError> {
        if self.bounds.is_empty() || !self.bounds.min.is_finite() || !self.bounds.max.is_finite() {
            return Err(ValidateError::whole(format!("scene box {:?} is empty or not finite", self.bounds)));
        }
        Ok(())
    }
}

impl super::Structure for BruteForce {
    fn validate(&self, _scene: &Scene) -> Result<(), ValidateError> {
        BruteForce::validate(self)
    }

    fn timing(&self) -> (f64, Vec<super::Phase>) {
        (self.build_ms, Vec::new())
    }

    /// One leaf holding every primitive.
    fn stats(&self, scene: &Scene) -> BuildStats {
        let n = scene.prim_count();
        BuildStats {
            kind: "none".into(),
            build_ms: self.build_ms,
            nodes: 1,
            leaves: 1,
            empty_leaves: u64::from(n == 0),
            refs_per_prim: 1.0,
            prims_per_leaf: n as f64,
            mean_leaf_depth: 0.0,
            sah_cost: f64::from(super::sah::SahCosts::default().leaf(n)),
            ..Default::default()
        }
    }

    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn gpu_image(&self, scene: &Scene) -> Result<super::GpuImage<'_>, ValidateError> {
        Ok(super::GpuImage {
            family: super::KernelFamily::None,
            buffers: None,
            stack_size: 1,
            cost_per_ray: scene.prim_count().max(1) as u64,
            trace_loop: super::TraceLoop::Unrolled {
                lengths: [scene.triangles.len() as u64, scene.spheres.len() as u64],
            },
            ray_structure: None,
            resume_words: 0,
        })
    }
}

/// Every primitive in index order after the scene-box test; at equal t the lower
/// primitive index wins, exactly like the GPU loop.
impl super::Traverse for BruteForce {
    fn traverse(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        let inv = Aabb::inv_dir(ray.dir);
        if self.bounds.ray_box(ray.origin, inv, ray.tmin, ray.tmax).is_none() {
            return false;
        }
        let mut hit = false;
        for p in 0..prims.scene.prim_count() as u32 {
            hit |= intersect_prim(prims, p, ray, best);
            if hit && any {
                return true;
            }
        }
        hit
    }
}
