//! SPPM's photon maps beside the ray structures (`arbor bench`; docs/caustics.md): over
//! the visible points a scene's camera rays find at the benchmark's size (radii of three
//! pixel footprints, as `--integrator sppm` starts with), each map's build milliseconds
//! (the grid's pipelines made beforehand, as a render makes them once) and photon
//! lookups per second, a photon jittered near every point. The hash grid is
//! built on the device, the kd-tree on the host, as the integrator builds them; both
//! look photons up on the device (upload and readback included) and must find the same
//! points.

use std::time::Instant;

use glam::Vec3;

use crate::accel::{Accel, AccelKind, Prims, Traverse};
use crate::error::{Error, Result};
use crate::gpu::bindings::{PHOTON_HDR_WORDS, SPPM_FOOTPRINT_PIXELS};
use crate::gpu::{BufferKind, Context};
use crate::math::Ray;
use crate::photon::device::GridBuild;
use crate::photon::{build_grid, tree_lookup_counts, upload_points, PointTree};
use crate::scene::Scene;

/// Most visible points the benchmark takes (a 640 x 480 image's).
const MOST_POINTS: u64 = 307_200;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The visible points of `scene`'s camera rays at `width` x `height` (every pixel, or a
/// regular subset of at most MOST_POINTS), with their radii.
fn visible_points(scene: &Scene, width: u32, height: u32) -> (Vec<Vec3>, Vec<f32>) {
    let accel = Accel::build(AccelKind::CPU_REFERENCE, scene);
    let prims = Prims::new(scene);
    let basis = scene.camera.basis(width, height);
    let pixels = u64::from(width) * u64::from(height);
    let stride = pixels.div_ceil(MOST_POINTS).max(1) as usize;
    let per_pixel = 2.0 * basis.tan_half / height as f32;
    let (mut positions, mut radii) = (Vec::new(), Vec::new());
    for k in (0..pixels as usize).step_by(stride) {
        let (i, j) = ((k % width as usize) as u32, (k / width as usize) as u32);
        let dir = basis.ray_dir(i, j, 0.5, 0.5, width, height);
        let ray = Ray { origin: basis.eye, dir, tmin: 0.0, tmax: f32::INFINITY };
        if let Some(h) = accel.intersect_with(&prims, &ray) {
            let r = SPPM_FOOTPRINT_PIXELS as f32 * per_pixel * h.t;
            if r.is_finite() && r > 0.0 {
                positions.push(basis.eye + dir * h.t);
                radii.push(r);
            }
        }
    }
    (positions, radii)
}

/// One photon near each point: within its radius, jittered by a fixed sequence.
fn photons_near(positions: &[Vec3], radii: &[f32]) -> Vec<Vec3> {
    let mut state = 0x853c_49e6_748f_ea9bu64;
    let mut next = || {
        state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        ((state >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    };
    positions.iter().zip(radii).map(|(&p, &r)| p + Vec3::new(next(), next(), next()) * r).collect()
}

/// The line `arbor bench` prints for `scene` (`short` its name) at `size`, each figure
/// a median of `repeat` runs.
pub fn photon_line(ctx: &Context, scene: &Scene, short: &str, size: (u32, u32), repeat: usize) -> Result<String> {
    let (positions, radii) = visible_points(scene, size.0, size.1);
    if positions.is_empty() {
        return Ok(format!("photon maps, {short}: no camera ray hits the scene at this size"));
    }
    let photons = photons_near(&positions, &radii);
    let points = upload_points(ctx, &positions, &radii)?;
    let n = positions.len() as u32;
    let (mut grid_ms, mut grid_rate, mut tree_ms, mut tree_rate) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut found = (0u64, 0u64);
    // The grid's builds, timed apart from creating its pipelines (once a render).
    let header = ctx.create_buffer("photon grid header", u64::from(PHOTON_HDR_WORDS) * 4, BufferKind::Storage)?;
    let starts = ctx.create_buffer("photon grid starts", (u64::from(n) + 1) * 4, BufferKind::Storage)?;
    let mut build = GridBuild::new(ctx, &header, &points, &starts, n)?;
    build.run(ctx, &header, n)?;
    let grid = build_grid(ctx, &points, n)?;
    for _ in 0..repeat.max(1) {
        let t = Instant::now();
        build.run(ctx, &header, n)?;
        grid_ms.push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        let g = grid.lookup_counts(ctx, &points, &photons)?;
        grid_rate.push(photons.len() as f64 / t.elapsed().as_secs_f64() / 1e6);
        let t = Instant::now();
        let tree = PointTree::build(&positions, &radii).map_err(Error::Failed)?;
        tree_ms.push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        let k = tree_lookup_counts(ctx, &tree, &points, &photons)?;
        tree_rate.push(photons.len() as f64 / t.elapsed().as_secs_f64() / 1e6);
        found = (g.iter().map(|f| u64::from(f[0])).sum(), k.iter().map(|f| u64::from(f[0])).sum());
        if g != k {
            return Err(Error::Failed(format!(
                "photon maps, {short}: the hash grid and the kd-tree found different points"
            )));
        }
    }
    Ok(format!(
        "photon maps, {short}: {n} visible points, {} photons ({:.1} points found a photon): hashgrid build {:.1} ms (device), {:.2} Mlookups/s; kdtree build {:.1} ms (host), {:.2} Mlookups/s (lookups on the device, upload and readback included)",
        photons.len(),
        found.0 as f64 / photons.len() as f64,
        median(grid_ms),
        median(grid_rate),
        median(tree_ms),
        median(tree_rate),
    ))
}
