//! The caustic under a glass ball (`builtin:caustic-lamp`: a small emissive sphere above
//! the ball) rendered by `path` and by `sppm` for the same time, each against a
//! converged reference, over the ball's shadow on the floor, where the caustic is; and
//! the photon pass's rays per second beside the path tracer's. Medians of `--runs`
//! renders (seeds 1..), on the first Vulkan device.
//!
//! ```text
//! cargo run --example sppm_caustic -- [--size WxH] [--seconds S] [--reference N] [--runs N]
//! ```
//!
//! The reference is sppm at `--reference` iterations (a consistent estimator: it
//! converges to the light transport both integrators estimate); the program also prints
//! its caustic mean beside a long path render's, which must agree.

use std::time::Instant;

use arbor::accel::AccelKind;
use arbor::render::integrators::sppm::SppmSettings;
use arbor::render::{gpu, Frame, Integrator, RenderSettings, RenderStats};
use arbor::scene::Scene;
use arbor::{Context, ContextOptions};
use glam::Vec3;

fn arg(name: &str) -> Option<String> {
    let args: Vec<String> = std::env::args().collect();
    args.iter().position(|a| a == name).and_then(|k| args.get(k + 1).cloned())
}

fn number(name: &str, default: f64) -> Result<f64, String> {
    match arg(name) {
        None => Ok(default),
        Some(v) => {
            v.parse().ok().filter(|v: &f64| v.is_finite() && *v > 0.0).ok_or(format!("{name} takes a positive number"))
        }
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn lum(c: [f32; 3]) -> f64 {
    f64::from(0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2])
}

/// The pixels whose centre ray meets the floor inside the ball's shadow from the lamp.
fn caustic_pixels(scene: &Scene, w: u32, h: u32) -> Vec<usize> {
    let ball = scene.spheres[0];
    let lamp = scene.spheres.get(1).map_or(Vec3::new(0.0, 3.5, 0.0), |s| s.center);
    let basis = scene.camera.basis(w, h);
    let hits_ball = |o: Vec3, d: Vec3, tmax: f32| {
        let oc = o - ball.center;
        let b = oc.dot(d);
        let c = oc.length_squared() - ball.radius * ball.radius;
        let disc = b * b - c;
        disc > 0.0 && {
            let t = -b - disc.sqrt();
            t > 0.0 && t < tmax
        }
    };
    let mut out = Vec::new();
    for j in 0..h {
        for i in 0..w {
            let d = basis.ray_dir(i, j, 0.5, 0.5, w, h);
            let t = -basis.eye.y / d.y;
            if t.is_nan() || t <= 0.0 || hits_ball(basis.eye, d, t) {
                continue;
            }
            let p = basis.eye + d * t;
            let to = lamp - p;
            if hits_ball(p, to.normalize(), to.length()) {
                out.push((j * w + i) as usize);
            }
        }
    }
    out
}

fn rmse(f: &Frame, reference: &Frame, pixels: &[usize]) -> f64 {
    let sum: f64 = pixels.iter().map(|&k| (lum(f.radiance[k]) - lum(reference.radiance[k])).powi(2)).sum();
    (sum / pixels.len() as f64).sqrt()
}

fn mean(f: &Frame, pixels: &[usize]) -> f64 {
    pixels.iter().map(|&k| lum(f.radiance[k])).sum::<f64>() / pixels.len() as f64
}

fn run() -> Result<(), String> {
    let (w, h) = match arg("--size") {
        None => (160, 120),
        Some(s) => {
            let (a, b) = s.split_once('x').ok_or("--size takes WxH")?;
            (a.parse().map_err(|_| "--size takes WxH")?, b.parse().map_err(|_| "--size takes WxH")?)
        }
    };
    let seconds = number("--seconds", 10.0)?;
    let reference_iterations = number("--reference", 1024.0)? as u32;
    let runs = number("--runs", 3.0)? as u32;
    let ctx = Context::new(&ContextOptions::default()).map_err(|e| e.to_string())?;
    let scene = Scene::load("builtin:caustic-lamp").map_err(|e| e.to_string())?;
    let pixels = caustic_pixels(&scene, w, h);
    if pixels.is_empty() {
        return Err("the ball's shadow covers no pixel at this size".into());
    }
    let base = |integrator: Integrator, spp: u32, seed: u32| {
        let mut s = RenderSettings::for_size(w, h);
        s.integrator = integrator;
        s.spp = spp;
        s.seed = seed;
        s.accel = AccelKind::BvhSah;
        s.sppm = SppmSettings::default();
        s
    };
    let render = |s: &RenderSettings| -> Result<(Frame, RenderStats), String> {
        gpu::render(&ctx, &scene, s, |_, _| {}).map_err(|e| e.to_string())
    };
    println!(
        "device: {}; {w}x{h}; {} caustic pixels; {seconds} s a render; medians of {runs}",
        ctx.info().name,
        pixels.len()
    );
    let started = Instant::now();
    let (reference, _) = render(&base(Integrator::Sppm, reference_iterations, 1000))?;
    println!("reference: sppm {reference_iterations} iterations in {:.1} s", started.elapsed().as_secs_f64());
    let mut errors = [Vec::new(), Vec::new()];
    let mut rates = [Vec::new(), Vec::new()];
    let mut done = [Vec::new(), Vec::new()];
    for seed in 1..=runs {
        for (k, integrator) in [Integrator::Path, Integrator::Sppm].into_iter().enumerate() {
            let mut s = base(integrator, 1 << 20, seed);
            s.time_budget = Some(seconds);
            let (f, st) = render(&s)?;
            errors[k].push(rmse(&f, &reference, &pixels));
            done[k].push(f64::from(st.samples_done));
            let rate = match &st.sppm {
                Some(sp) => sp.photon_ms.filter(|&ms| ms > 0.0).map(|ms| sp.photon_rays as f64 / (ms * 1e3)),
                None => st.mrays_per_s,
            };
            rates[k].push(rate.unwrap_or(f64::NAN));
        }
    }
    let (path_err, sppm_err) = (median(errors[0].clone()), median(errors[1].clone()));
    println!(
        "caustic RMSE at {seconds} s: path {path_err:.4} ({:.0} spp), sppm {sppm_err:.4} ({:.0} iterations): sppm / path = {:.3}",
        median(done[0].clone()),
        median(done[1].clone()),
        sppm_err / path_err
    );
    let (path_rate, photon_rate) = (median(rates[0].clone()), median(rates[1].clone()));
    println!(
        "rays per second: path {path_rate:.3} Mrays/s, sppm's photon pass {photon_rate:.3} Mrays/s: photon / path = {:.3}",
        photon_rate / path_rate
    );
    // The reference against a long path render, over the caustic (path is unbiased).
    let long = (4.0 * seconds).max(1.0);
    let mut s = base(Integrator::Path, 1 << 20, 99);
    s.time_budget = Some(long);
    let (p, st) = render(&s)?;
    println!(
        "caustic mean: reference {:.4}, path at {long} s ({} spp) {:.4}",
        mean(&reference, &pixels),
        st.samples_done,
        mean(&p, &pixels)
    );
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("sppm_caustic: {e}");
        std::process::exit(1);
    }
}
