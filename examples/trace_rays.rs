//! arbor as a library: builds two structures over a mesh, traces the same random rays
//! through each on the device (`RayTracer`) and on the CPU reference
//! (`Accel::trace_cpu`), and prints how far the hits agree and the rates.
//!
//! ```text
//! cargo run --release --example trace_rays -- [MESH_OR_SCENE] [--accel kdtree,bvh-sah]
//!     [--rays 1000000] [--seed 1] [--rays-file RAYS.f32] [--device NAME_OR_INDEX]
//! ```
//!
//! `--rays-file` traces the rays of a file instead: rows of six little-endian f32,
//! origin then direction (Open3D's layout, what `scripts/python-bench.py` writes to
//! compare the Python module with this example on the same rays).
//!
//! The scene defaults to `builtin:blob:100000` (a 100k-triangle mesh). Half the rays
//! start outside the scene's box and aim at a point inside it, half start inside with
//! a random direction; every fourth has a finite `tmax`. Per structure it prints one
//! line, then one line comparing the two structures' device hits:
//!
//! ```text
//! kdtree: build 412.3 ms, 80421 nodes, SAH 31.2; gpu 3.10 Mrays/s (322.6 ms, wall 351.0 ms after a setup of 21.0 ms, 4 dispatches, 0 resumed); cpu 5.12 Mrays/s; hits 71.03%; gpu = cpu on 1000000 of 1000000 rays
//! kdtree vs bvh-sah (gpu): same hit on 1000000 of 1000000 rays
//! ```
//!
//! Two hits agree when both miss, or both hit the same primitive at t within 1e-4
//! (relative) with barycentrics within 1e-3. Exit status 1 when fewer than 99.99% of
//! the rays agree anywhere, 2 on a bad argument, 3 on an arbor error.

use arbor::{Accel, AccelKind, Context, ContextOptions, Hit, Ray, RayTracer, Scene, TraceOptions};
use glam::Vec3;
use std::time::Instant;

struct Args {
    scene: String,
    accel: Vec<AccelKind>,
    rays: usize,
    seed: u64,
    rays_file: Option<String>,
    device: Option<String>,
}

fn parse() -> Result<Args, String> {
    let mut a = Args {
        scene: "builtin:blob:100000".into(),
        accel: vec![AccelKind::Kdtree, AccelKind::BvhSah],
        rays: 1_000_000,
        seed: 1,
        rays_file: None,
        device: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        let mut value = |name: &str| it.next().ok_or_else(|| format!("{name} needs a value"));
        match arg.as_str() {
            "--accel" => a.accel = value("--accel")?.split(',').map(str::parse).collect::<Result<_, _>>()?,
            "--rays" => a.rays = value("--rays")?.parse().map_err(|_| "--rays: expected a count")?,
            "--seed" => a.seed = value("--seed")?.parse().map_err(|_| "--seed: expected a number")?,
            "--device" => a.device = Some(value("--device")?),
            "--rays-file" => a.rays_file = Some(value("--rays-file")?),
            "-h" | "--help" => return Err(
                "usage: trace_rays [MESH_OR_SCENE] [--accel K,K] [--rays N] [--seed S] [--rays-file F] [--device D]"
                    .into(),
            ),
            s if s.starts_with('-') => return Err(format!("unknown option {s}")),
            s => a.scene = s.to_string(),
        }
    }
    if a.accel.is_empty() {
        return Err("--accel: give at least one structure".into());
    }
    Ok(a)
}

/// xorshift64*: a small seeded generator, so the rays are the same on every run.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 40) as f32 / (1u64 << 24) as f32
    }
    fn dir(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(self.next(), self.next(), self.next()) * 2.0 - Vec3::ONE;
            if (0.01..=1.0).contains(&v.length_squared()) {
                return v.normalize();
            }
        }
    }
}

fn random_rays(scene: &Scene, n: usize, seed: u64) -> Vec<Ray> {
    let b = scene.bounds();
    let (c, size) = (b.center(), b.extent());
    let radius = size.length().max(1e-6);
    let mut rng = Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    (0..n)
        .map(|k| {
            let inside = b.min + size * Vec3::new(rng.next(), rng.next(), rng.next());
            let (origin, dir) = if k % 2 == 0 {
                let o = c + rng.dir() * radius;
                (o, (inside - o).normalize())
            } else {
                (inside, rng.dir())
            };
            let tmax = if k % 4 == 1 { radius * rng.next() } else { f32::INFINITY };
            Ray { origin, dir, tmin: 0.0, tmax }
        })
        .collect()
}

/// Rows of six little-endian f32 (origin, direction of any length but zero), as rays
/// with unit directions.
fn read_rays(path: &str) -> arbor::Result<Vec<Ray>> {
    let bytes = std::fs::read(path).map_err(|cause| arbor::Error::Io { path: path.into(), cause })?;
    if bytes.len() % 24 != 0 {
        return Err(arbor::Error::Usage(format!(
            "{path}: {} bytes is not a whole number of 24-byte rays",
            bytes.len()
        )));
    }
    let floats: Vec<f32> = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    floats
        .chunks_exact(6)
        .enumerate()
        .map(|(row, r)| {
            let dir = Vec3::new(r[3], r[4], r[5]);
            if !(dir.length() > 0.0 && dir.is_finite()) {
                return Err(arbor::Error::Usage(format!("{path}: ray {row} has no direction")));
            }
            Ok(Ray { origin: Vec3::new(r[0], r[1], r[2]), dir: dir.normalize(), tmin: 0.0, tmax: f32::INFINITY })
        })
        .collect()
}

fn agree(a: &Option<Hit>, b: &Option<Hit>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => {
            a.prim == b.prim
                && (a.t - b.t).abs() <= 1e-4 * b.t.abs().max(1e-6)
                && (a.u - b.u).abs() <= 1e-3
                && (a.v - b.v).abs() <= 1e-3
        }
        _ => false,
    }
}

fn agreeing(a: &[Option<Hit>], b: &[Option<Hit>]) -> usize {
    a.iter().zip(b).filter(|(x, y)| agree(x, y)).count()
}

fn run(args: &Args) -> arbor::Result<bool> {
    let scene = Scene::load(&args.scene)?;
    let scene = if scene.has_instances() { scene.flattened()? } else { scene };
    let rays = match &args.rays_file {
        Some(path) => read_rays(path)?,
        None => random_rays(&scene, args.rays, args.seed),
    };
    let ctx = Context::new(&ContextOptions { device: args.device.clone(), ..Default::default() })?;
    println!(
        "trace_rays: scene {} ({} triangles, {} spheres), {} rays, seed {}, device {}",
        scene.name,
        scene.triangles.len(),
        scene.spheres.len(),
        rays.len(),
        args.seed,
        ctx.info().name
    );
    let need = |n: usize| n as f64 >= 0.9999 * rays.len() as f64;
    let mut ok = true;
    let mut gpu_hits: Vec<(AccelKind, Vec<Option<Hit>>)> = Vec::new();
    for &kind in &args.accel {
        let accel = Accel::build_on(&ctx, kind, &scene, &Default::default())?;
        let st = accel.stats(&scene);
        // The kernel is compiled by the first tracer; a second one's setup is the
        // upload alone, what each cast of the Python module pays.
        drop(RayTracer::new(&ctx, &scene, &accel, &TraceOptions::default())?);
        let t0 = Instant::now();
        let tracer = RayTracer::new(&ctx, &scene, &accel, &TraceOptions::default())?;
        let setup_ms = t0.elapsed().as_secs_f64() * 1e3;
        let (hits, batch) = tracer.trace_stats(&rays)?;
        let t0 = Instant::now();
        let cpu = accel.trace_cpu(&scene, &rays);
        let cpu_s = t0.elapsed().as_secs_f64();
        let same = agreeing(&hits, &cpu);
        ok &= need(same);
        let hit_count = hits.iter().filter(|h| h.is_some()).count();
        println!(
            "{}: build {:.1} ms, {} nodes, SAH {:.1}; gpu {:.2} Mrays/s ({:.1} ms, wall {:.1} ms after a setup of {:.1} ms, {} dispatches, {} resumed); cpu {:.2} Mrays/s; hits {:.2}%; gpu = cpu on {} of {} rays",
            kind.name(),
            st.build_ms,
            st.nodes,
            st.sah_cost,
            batch.mrays_per_s(),
            batch.gpu_ms.unwrap_or(batch.wall_ms),
            batch.wall_ms,
            setup_ms,
            batch.dispatches,
            batch.resumed,
            rays.len() as f64 / cpu_s.max(1e-9) / 1e6,
            100.0 * hit_count as f64 / rays.len().max(1) as f64,
            same,
            rays.len()
        );
        gpu_hits.push((kind, hits));
    }
    for pair in gpu_hits.windows(2) {
        let same = agreeing(&pair[0].1, &pair[1].1);
        ok &= need(same);
        println!("{} vs {} (gpu): same hit on {} of {} rays", pair[0].0, pair[1].0, same, rays.len());
    }
    Ok(ok)
}

fn main() {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("trace_rays: {e}");
            std::process::exit(2);
        }
    };
    match run(&args) {
        Ok(true) => {}
        Ok(false) => {
            eprintln!("trace_rays: fewer than 99.99% of the rays agree");
            std::process::exit(1);
        }
        Err(e) => {
            eprintln!("trace_rays: {e}");
            std::process::exit(3);
        }
    }
}
