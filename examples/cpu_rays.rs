//! Throughput of arbor's CPU traversal (each structure's `Traverse`, the scalar Rust
//! code the tests use as their oracle) on all cores: the same rays as `arbor bench
//! --rays primary,diffuse` and the Embree peer (`scripts/peers/embree_rays.cpp`), so
//! that the structures' own cost can be told apart from the driver's
//! (docs/lavapipe.md). A measurement tool, not a renderer.
//!
//! ```text
//! cargo run --release --example cpu_rays -- MESH_OR_SCENE... [--accel kdtree,bvh-sah]
//!     [--size 1024x1024] [--threads N] [--repeat 5]
//! ```
//!
//! Per structure it prints the median wall time of the camera rays (one per pixel
//! centre), of one cosine-distributed bounce from every camera hit (traced after the
//! camera rays, timed alone), and the rates.

use arbor::accel::{Accel, AccelKind};
use arbor::math::float::{offset_ray_origin, triangle_point};
use arbor::math::Ray;
use glam::Vec3;
use rayon::prelude::*;
use std::time::Instant;

struct Args {
    scenes: Vec<String>,
    accel: Vec<AccelKind>,
    size: (u32, u32),
    threads: usize,
    repeat: usize,
}

fn parse() -> Result<Args, String> {
    let mut a = Args {
        scenes: Vec::new(),
        accel: vec![AccelKind::Kdtree, AccelKind::BvhSah],
        size: (1024, 1024),
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        repeat: 5,
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut value = |name: &str| it.next().ok_or_else(|| format!("{name} needs a value"));
        match arg.as_str() {
            "--accel" => a.accel = value("--accel")?.split(',').map(str::parse).collect::<Result<_, _>>()?,
            "--size" => {
                let v = value("--size")?;
                let (w, h) = v.split_once('x').ok_or_else(|| format!("--size {v}: expected WxH"))?;
                a.size = (w.parse().map_err(|_| "--size: bad width")?, h.parse().map_err(|_| "--size: bad height")?);
                if a.size.0 == 0 || a.size.1 == 0 {
                    return Err("--size: width and height must be positive".into());
                }
            }
            "--threads" => a.threads = value("--threads")?.parse().map_err(|_| "--threads: expected a count")?,
            "--repeat" => a.repeat = value("--repeat")?.parse().map_err(|_| "--repeat: expected a count")?,
            "-h" | "--help" => {
                println!("usage: cpu_rays MESH_OR_SCENE... [--accel K,..] [--size WxH] [--threads N] [--repeat N]");
                std::process::exit(0);
            }
            s if s.starts_with('-') => return Err(format!("unknown option {s}")),
            s => a.scenes.push(s.to_string()),
        }
    }
    if a.scenes.is_empty() {
        return Err("no scene given (a mesh file, a scene TOML or builtin:NAME)".into());
    }
    a.threads = a.threads.max(1);
    a.repeat = a.repeat.max(1);
    Ok(a)
}

/// PCG hash (Jarzynski & Olano 2020), as the kernels key their random streams.
fn pcg_hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747796405).wrapping_add(2891336453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277803737);
    (word >> 22) ^ word
}

fn next(state: &mut u32) -> f32 {
    *state = pcg_hash(*state);
    (*state >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// A cosine-distributed direction about the unit normal `n`.
fn cosine_direction(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    let (t, b) = n.any_orthonormal_pair();
    let r = u1.sqrt();
    let phi = std::f32::consts::TAU * u2;
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt()).normalize()
}

fn median(mut v: Vec<f64>) -> (f64, f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[0], v[v.len() - 1])
}

fn main() {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("cpu_rays: {e}");
            std::process::exit(2);
        }
    };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(args.threads).build().expect("thread pool");
    let (w, h) = args.size;
    // Every scene loads before anything is printed: a bad one fails first.
    let mut scenes = Vec::new();
    for source in &args.scenes {
        match arbor::scene::Scene::load(source) {
            Ok(s) => scenes.push((source, s)),
            Err(e) => {
                eprintln!("cpu_rays: {e}");
                std::process::exit(1);
            }
        }
    }
    println!("scene,triangles,accel,threads,camera_ms,camera_min,camera_max,camera_mrays,bounce_rays,bounce_ms,bounce_mrays,both_mrays,hit_fraction,bounce_hit_fraction");
    for (source, scene) in &scenes {
        let basis = scene.camera.basis(w, h);
        let nt = scene.triangles.len() as u32;
        for &kind in &args.accel {
            let accel = Accel::build(kind, scene);
            let s = accel.surface();
            let camera = |j: u32| -> Vec<Option<Ray>> {
                (0..w)
                    .map(|i| {
                        let ray = Ray {
                            origin: basis.eye,
                            dir: basis.ray_dir(i, j, 0.5, 0.5, w, h),
                            tmin: 0.0,
                            tmax: f32::INFINITY,
                        };
                        let hit = s.intersect(scene, &ray)?;
                        // The bounce: from the hit point, offset by its error bound, on
                        // the side the ray came from (triangles; spheres bounce from p).
                        let (p, err, gn) = if hit.prim < nt {
                            let [a, b, c] = scene.triangles[hit.prim as usize].map(|k| scene.positions[k as usize]);
                            let (p, err) = triangle_point(a, b, c, hit.u, hit.v);
                            (p, err, (b - a).cross(c - a).normalize_or_zero())
                        } else {
                            let sp = scene.spheres[(hit.prim - nt) as usize];
                            let p = ray.origin + ray.dir * hit.t;
                            (p, Vec3::splat(1e-4 * sp.radius), ((p - sp.center) / sp.radius).normalize_or_zero())
                        };
                        let n = if gn.dot(ray.dir) < 0.0 { gn } else { -gn };
                        let mut rng = pcg_hash((j * w + i) ^ pcg_hash(pcg_hash(0)));
                        let d = cosine_direction(n, next(&mut rng), next(&mut rng));
                        Some(Ray { origin: offset_ray_origin(p, err, n, d), dir: d, tmin: 0.0, tmax: f32::INFINITY })
                    })
                    .collect()
            };
            let (mut cam_ms, mut bounce_ms) = (Vec::new(), Vec::new());
            let mut bounces = Vec::new();
            let mut bounce_hits = 0usize;
            for round in 0..=args.repeat {
                let t0 = Instant::now();
                let rows: Vec<Vec<Option<Ray>>> = pool.install(|| (0..h).into_par_iter().map(camera).collect());
                let t1 = t0.elapsed().as_secs_f64() * 1e3;
                bounces = rows.into_iter().flatten().flatten().collect();
                let t0 = Instant::now();
                bounce_hits = pool.install(|| bounces.par_iter().filter(|r| s.intersect(scene, r).is_some()).count());
                let t2 = t0.elapsed().as_secs_f64() * 1e3;
                if round > 0 {
                    cam_ms.push(t1);
                    bounce_ms.push(t2);
                }
            }
            let pixels = f64::from(w) * f64::from(h);
            let (cm, c0, c1) = median(cam_ms);
            let (bm, _, _) = median(bounce_ms);
            let n = bounces.len() as f64;
            println!(
                "{source},{nt},{},{},{cm:.2},{c0:.2},{c1:.2},{:.2},{},{bm:.2},{:.2},{:.2},{:.4},{:.4}",
                kind.name(),
                args.threads,
                pixels / cm / 1e3,
                bounces.len(),
                n / bm / 1e3,
                (pixels + n) / (cm + bm) / 1e3,
                n / pixels,
                bounce_hits as f64 / n.max(1.0)
            );
        }
    }
}
