//! The CPU reference: the same camera and intersection code as the kernels, in plain
//! Rust, used by tests as the oracle for depth, primitive and normal AOVs.

use glam::Vec3;
use rayon::prelude::*;

use super::Frame;
use crate::accel::none::BruteForce;
use crate::accel::Traverse;
use crate::math::{Hit, Ray};
use crate::scene::Scene;

/// The shading normal at a hit (interpolated vertex normals when all three are
/// present, else the geometric normal; sphere: radial). Mirrors `surface` in trace.comp,
/// without normal maps (they bend the shading normal of `pbr` materials only).
pub fn shading_normal(scene: &Scene, hit: &Hit, p: Vec3) -> Vec3 {
    let nt = scene.triangles.len() as u32;
    if hit.prim < nt {
        let t = scene.triangles[hit.prim as usize];
        let [a, b, c] = t.map(|i| scene.positions[i as usize]);
        let gn = (b - a).cross(c - a).normalize_or_zero();
        let [na, nb, nc] = t.map(|i| scene.normals[i as usize]);
        if na != Vec3::ZERO && nb != Vec3::ZERO && nc != Vec3::ZERO {
            let n = na * (1.0 - hit.u - hit.v) + nb * hit.u + nc * hit.v;
            if n.length_squared() > 0.0 {
                return n.normalize();
            }
        }
        gn
    } else {
        let s = scene.spheres[(hit.prim - nt) as usize];
        ((p - s.center) / s.radius).normalize_or_zero()
    }
}

/// Traces the pixel-centre camera ray of every pixel of a `width` x `height` image
/// (parallel over rows; the result does not depend on the thread count).
///
/// An instanced scene is traced as its flattened copy (same primitive numbers).
pub fn reference_aovs(scene: &Scene, width: u32, height: u32) -> Frame {
    if scene.has_instances() {
        if let Ok(flat) = scene.flattened() {
            return reference_aovs(&flat, width, height);
        }
    }
    let accel = BruteForce::build(scene);
    let basis = scene.camera.basis(width, height);
    let rows: Vec<Vec<(f32, u32, [f32; 3])>> = (0..height)
        .into_par_iter()
        .map(|j| {
            (0..width)
                .map(|i| {
                    let ray = Ray {
                        origin: basis.eye,
                        dir: basis.ray_dir(i, j, 0.5, 0.5, width, height),
                        tmin: 0.0,
                        tmax: f32::INFINITY,
                    };
                    match accel.intersect(scene, &ray) {
                        Some(h) => {
                            let n = shading_normal(scene, &h, ray.origin + ray.dir * h.t);
                            (h.t, h.prim, n.to_array())
                        }
                        None => (f32::INFINITY, u32::MAX, [0.0; 3]),
                    }
                })
                .collect()
        })
        .collect();
    let n = (width * height) as usize;
    let mut f = Frame {
        width,
        height,
        radiance: vec![[0.0; 3]; n],
        depth: Vec::with_capacity(n),
        normal: Vec::with_capacity(n),
        prim: Vec::with_capacity(n),
        nodes: vec![1; n],
        tests: vec![scene.prim_count() as u32; n],
        rays: vec![1; n],
        albedo: vec![[0.0; 3]; n],
        variance: vec![0.0; n],
        samples: vec![1; n],
        sum: vec![[0.0; 3]; n],
        sum_y2: vec![0.0; n],
    };
    for (t, p, nrm) in rows.into_iter().flatten() {
        f.depth.push(t);
        f.prim.push(p);
        f.normal.push(nrm);
    }
    f
}

/// The primitive hit by the pixel-centre camera ray of every `stride`-th pixel of a
/// `width` x `height` image, in watertight mode, by CPU traversal of `accel` (every
/// structure equals brute force, tested): the reference `arbor bench` compares each
/// row's camera hits with. Returns (pixel index, primitive or u32::MAX).
pub fn reference_prims(
    scene: &Scene,
    accel: &crate::accel::Accel,
    width: u32,
    height: u32,
    stride: usize,
) -> Vec<(usize, u32)> {
    let basis = scene.camera.basis(width, height);
    let pixels: Vec<usize> = (0..(width as usize * height as usize)).step_by(stride.max(1)).collect();
    pixels
        .par_iter()
        .map(|&k| {
            let (i, j) = ((k % width as usize) as u32, (k / width as usize) as u32);
            let ray = Ray {
                origin: basis.eye,
                dir: basis.ray_dir(i, j, 0.5, 0.5, width, height),
                tmin: 0.0,
                tmax: f32::INFINITY,
            };
            (k, accel.intersect(scene, &ray).map_or(u32::MAX, |h| h.prim))
        })
        .collect()
}
