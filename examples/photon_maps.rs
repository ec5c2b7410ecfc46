//! The two photon lookups of SPPM (src/photon/, docs/caustics.md) side by side: build
//! milliseconds and lookups per second of the hash grid and the lecture's kd-tree over
//! visible points, medians of several runs, on the CPU; then, on the Vulkan device
//! (where there is one), the hash grid's build and both maps' lookups, which must equal
//! the CPU's.
//!
//! ```text
//! cargo run --release --example photon_maps -- [--points N] [--photons N] [--runs N]
//! ```
//!
//! The visible points lie on a floor (y = 0) and on a sphere above it, as a camera
//! sees them in the glass-ball scene; radii vary over a factor of 4 as SPPM's shrink.
//! Photons land near the points. Both maps must find the same points for every photon
//! (the program exits 1 otherwise); the line per map reads
//!
//! ```text
//! hashgrid: build 92.2 ms, 0.83 Mlookups/s, 89.5 tests a lookup, 14.97 points found a lookup
//! kdtree: build 138.1 ms, 0.43 Mlookups/s, 99.8 nodes a lookup, 14.97 points found a lookup
//! hashgrid = kdtree on 1000000 of 1000000 photons
//! hashgrid on the device (llvmpipe (LLVM 15.0.6, 256 bits)): build 293.1 ms (5 passes), 1.08 Mlookups/s (upload and readback included), equal to the CPU's
//! kdtree on the device: 0.62 Mlookups/s (upload and readback included), equal to the CPU's
//! ```

use std::time::Instant;

use arbor::photon::{build_grid, tree_lookup_counts, upload_points, HashGrid, PointTree};
use arbor::{Context, ContextOptions};
use glam::Vec3;

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn arg(name: &str, default: usize) -> Result<usize, String> {
    let args: Vec<String> = std::env::args().collect();
    match args.iter().position(|a| a == name) {
        None => Ok(default),
        Some(k) => args
            .get(k + 1)
            .and_then(|v| v.parse().ok())
            .filter(|&v| v > 0)
            .ok_or_else(|| format!("{name} takes a positive whole number")),
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let parsed = (|| Ok::<_, String>((arg("--points", 307_200)?, arg("--photons", 1_000_000)?, arg("--runs", 3)?)))();
    let (n, photons, runs) = match parsed {
        Ok(v) => v,
        Err(e) => {
            eprintln!("photon_maps: {e}; usage: photon_maps [--points N] [--photons N] [--runs N]");
            std::process::exit(2);
        }
    };
    let mut rng = Rng(1);
    let mut positions = Vec::with_capacity(n);
    let mut radii = Vec::with_capacity(n);
    for k in 0..n {
        let p = if k % 4 == 0 {
            // On a ball of radius 0.5 at height 1.
            let z = 2.0 * rng.next() - 1.0;
            let phi = rng.next() * std::f32::consts::TAU;
            let s = (1.0 - z * z).max(0.0).sqrt();
            Vec3::new(s * phi.cos(), z, s * phi.sin()) * 0.5 + Vec3::Y
        } else {
            Vec3::new(rng.next() * 8.0 - 4.0, 0.0, rng.next() * 8.0 - 4.0)
        };
        positions.push(p);
        radii.push(0.01 * (1.0 + 3.0 * rng.next()));
    }
    let queries: Vec<Vec3> = (0..photons)
        .map(|_| {
            let k = (rng.next() * n as f32) as usize % n;
            positions[k] + Vec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5) * 0.05
        })
        .collect();
    println!("photon_maps: {n} visible points, {photons} photons, medians of {runs} runs");
    let mut found_by = Vec::new();
    type Lookup<'a> = Box<dyn Fn(Vec3, &mut Vec<u32>) -> usize + 'a>;
    for name in ["hashgrid", "kdtree"] {
        let (mut builds, mut rates) = (Vec::new(), Vec::new());
        let (mut tests, mut found) = (0usize, Vec::new());
        for _ in 0..runs {
            let t = Instant::now();
            let lookup: Lookup = match name {
                "hashgrid" => {
                    let g = HashGrid::build(&positions, &radii).expect("points are valid");
                    builds.push(t.elapsed().as_secs_f64() * 1e3);
                    let (p, r) = (&positions, &radii);
                    Box::new(move |q, out| g.lookup(p, r, q, out))
                }
                _ => {
                    let tree = PointTree::build(&positions, &radii).expect("points are valid");
                    builds.push(t.elapsed().as_secs_f64() * 1e3);
                    let (p, r) = (&positions, &radii);
                    Box::new(move |q, out| tree.lookup(p, r, q, out))
                }
            };
            let t = Instant::now();
            let mut out = Vec::new();
            tests = 0;
            found.clear();
            for &q in &queries {
                out.clear();
                tests += lookup(q, &mut out);
                found.push(out.len() as u32);
                found.extend_from_slice(&out);
            }
            rates.push(photons as f64 / t.elapsed().as_secs_f64() / 1e6);
        }
        let hits = found.len() - photons;
        println!(
            "{name}: build {:.1} ms, {:.2} Mlookups/s, {:.1} {} a lookup, {:.2} points found a lookup",
            median(builds),
            median(rates),
            tests as f64 / photons as f64,
            if name == "hashgrid" { "tests" } else { "nodes" },
            hits as f64 / photons as f64
        );
        found_by.push(found);
    }
    if found_by[0] != found_by[1] {
        eprintln!("photon_maps: the hash grid and the kd-tree found different points");
        std::process::exit(1);
    }
    println!("hashgrid = kdtree on {photons} of {photons} photons");
    // Per photon: the points found and the sum of their indices + 1.
    let mut expected = Vec::with_capacity(photons);
    let mut k = 0;
    while k < found_by[0].len() {
        let m = found_by[0][k] as usize;
        let sum = found_by[0][k + 1..k + 1 + m].iter().fold(0u32, |s, &i| s.wrapping_add(i + 1));
        expected.push([m as u32, sum]);
        k += 1 + m;
    }
    device_build(&positions, &radii, runs, &queries, &expected);
}

/// The hash grid built on the device, timed as the host sees it (upload excluded) and
/// checked against the CPU's build; then the photons looked up on the device, checked
/// against the CPU's lookups.
fn device_build(positions: &[Vec3], radii: &[f32], runs: usize, queries: &[Vec3], expected: &[[u32; 2]]) {
    let ctx = match Context::new(&ContextOptions::default()) {
        Ok(c) => c,
        Err(e) => {
            println!("hashgrid on the device: skipped ({e})");
            return;
        }
    };
    let host = HashGrid::build(positions, radii).expect("points are valid");
    let points = upload_points(&ctx, positions, radii).expect("upload");
    let (mut times, mut rates) = (Vec::new(), Vec::new());
    for _ in 0..runs {
        let t = Instant::now();
        let grid = build_grid(&ctx, &points, positions.len() as u32).expect("device build");
        times.push(t.elapsed().as_secs_f64() * 1e3);
        if grid.read_back(&ctx).expect("read back") != host {
            eprintln!("photon_maps: the device's hash grid differs from the CPU's");
            std::process::exit(1);
        }
        let t = Instant::now();
        let found = grid.lookup_counts(&ctx, &points, queries).expect("device lookups");
        rates.push(queries.len() as f64 / t.elapsed().as_secs_f64() / 1e6);
        if found != expected {
            eprintln!("photon_maps: the device's lookups differ from the CPU's");
            std::process::exit(1);
        }
    }
    println!(
        "hashgrid on the device ({}): build {:.1} ms (5 passes), {:.2} Mlookups/s (upload and readback included), equal to the CPU's",
        ctx.info().name,
        median(times),
        median(rates)
    );
    let tree = PointTree::build(positions, radii).expect("points are valid");
    let mut rates = Vec::new();
    for _ in 0..runs {
        let t = Instant::now();
        let found = tree_lookup_counts(&ctx, &tree, &points, queries).expect("device lookups");
        rates.push(queries.len() as f64 / t.elapsed().as_secs_f64() / 1e6);
        if found != expected {
            eprintln!("photon_maps: the device's kd-tree lookups differ from the CPU's");
            std::process::exit(1);
        }
    }
    println!(
        "kdtree on the device: {:.2} Mlookups/s (upload and readback included), equal to the CPU's",
        median(rates)
    );
}
