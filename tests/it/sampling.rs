//! The path integrator's samplers, run on the device through `sample_probe.comp`
//! (the kernel's own GLSL): per material, the pdf a sample reports is the pdf its
//! evaluation reports, the pdf integrates to 1 over the sphere (less what a lobe
//! loses below the horizon), the mean sample weight is the reflectance that the
//! evaluation integrates to, reflectance is at most 1, and exactly 1 for the mirror
//! and lossless glass; glass reflects with the Fresnel probability. Seeded.

use crate::common;

use arbor::gpu::bindings::*;
use arbor::gpu::{spirv, BindingDesc, BindingKind, BufferKind, Context};
use arbor::render::dispatch::upload::GpuScene;
use arbor::scene::{Material, MaterialKind, SceneBuilder, Sphere};
use glam::Vec3;

/// Runs `mode` of the probe on `input` (two vec4 per record) with `shading` rows and
/// `params`; returns three vec4 per record.
pub(crate) fn probe(
    ctx: &Context,
    mode: u32,
    input: &[[f32; 4]],
    shading: &[[f32; 4]],
    params: &arbor::accel::gpu_layout::GpuParams,
    env: (u32, u32),
) -> Vec<[f32; 4]> {
    let records = input.len() / 2;
    let bindings = [
        BindingDesc { binding: BINDING_PARAMS, kind: BindingKind::Uniform, name: "params" },
        BindingDesc { binding: BINDING_SHADING, kind: BindingKind::Texel, name: "shading" },
        BindingDesc { binding: BINDING_ACCEL_NODES, kind: BindingKind::Storage, name: "probe_in" },
        BindingDesc { binding: BINDING_ACCEL_INDICES, kind: BindingKind::Storage, name: "probe_out" },
    ];
    let spv = spirv::get("sample_probe").expect("probe kernel compiled");
    let spec = [(SPEC_ENV_WIDTH, env.0.max(1)), (SPEC_ENV_HEIGHT, env.1.max(1))];
    let mut k = ctx.create_kernel("sample_probe", spv, &bindings, &spec, 32).expect("kernel");
    let u = ctx.upload_uniform("params", bytemuck::bytes_of(params)).expect("uniform");
    let sh = ctx.upload_storage("shading", bytemuck::cast_slice(shading)).expect("shading");
    let inb = ctx.upload_storage("probe_in", bytemuck::cast_slice(input)).expect("in");
    let bytes = (records * 3 * 16) as u64;
    let out = ctx.create_buffer("probe_out", bytes, BufferKind::Storage).expect("out");
    ctx.bind(&mut k, BINDING_PARAMS, &u).expect("bind");
    ctx.bind(&mut k, BINDING_SHADING, &sh).expect("bind");
    ctx.bind(&mut k, BINDING_ACCEL_NODES, &inb).expect("bind");
    ctx.bind(&mut k, BINDING_ACCEL_INDICES, &out).expect("bind");
    let push: [u32; 8] = [mode, records as u32, 0, 0, 0, 0, 0, 0];
    ctx.dispatch(&k, bytemuck::cast_slice(&push), [(records as u32).div_ceil(64), 1, 1], "sample probe")
        .expect("dispatch");
    ctx.check_validation().expect("no validation errors");
    let back = ctx.read_storage(&out, 0, bytes).expect("read");
    bytemuck::cast_slice::<u8, [f32; 4]>(&back).to_vec()
}

/// A small counter-based generator (splitmix64), seeded.
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    pub(crate) fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// The materials under test, in the shading rows of a scene (index 0 is the default).
fn materials() -> (Vec<(&'static str, u32)>, Vec<[f32; 4]>) {
    let mut b = SceneBuilder::new("materials");
    let list = vec![
        ("lambert", b.material(Material::lambert("lambert", Vec3::splat(0.8)))),
        ("white lambert", b.material(Material::lambert("white", Vec3::ONE))),
        (
            "phong",
            b.material(Material {
                kind: MaterialKind::Phong,
                specular: Vec3::splat(0.5),
                shininess: 20.0,
                ..Material::lambert("phong", Vec3::splat(0.4))
            }),
        ),
        (
            "sharp phong",
            b.material(Material {
                kind: MaterialKind::Phong,
                specular: Vec3::splat(0.9),
                shininess: 200.0,
                ..Material::lambert("sharp", Vec3::splat(0.05))
            }),
        ),
        ("mirror", b.material(Material { kind: MaterialKind::Mirror, ..Material::lambert("mirror", Vec3::ONE) })),
        (
            "glass",
            b.material(Material { kind: MaterialKind::Glass, ior: 1.5, ..Material::lambert("glass", Vec3::ONE) }),
        ),
    ];
    b.scene.spheres.push(Sphere { center: Vec3::ZERO, radius: 1.0, material: 0 });
    let scene = b.finish().expect("scene");
    (list, GpuScene::new(&scene).shading)
}

pub(crate) fn dir(theta_deg: f32) -> Vec3 {
    let t = theta_deg.to_radians();
    Vec3::new(t.sin(), 0.0, t.cos())
}

fn fresnel(cos_i: f64, eta: f64) -> f64 {
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    0.5 * (rs * rs + rp * rp)
}

#[test]
fn bsdf_sampling_and_evaluation_agree() {
    let Some(ctx) = common::gpu() else { return };
    let (list, shading) = materials();
    let params = arbor::accel::gpu_layout::GpuParams::default();
    let n = 8192;
    let mut rng = Rng(7);
    for &(name, id) in &list {
        for theta in [0.0f32, 30.0, 60.0, 85.0] {
            let wo = dir(theta);
            // Samples.
            let mut input = Vec::with_capacity(2 * n);
            for _ in 0..n {
                input.push([wo.x, wo.y, wo.z, id as f32]);
                input.push([rng.next(), rng.next(), rng.next(), 1.0]);
            }
            let out = probe(&ctx, 0, &input, &shading, &params, (0, 0));
            let (mut mean_weight, mut reflected) = (0.0f64, 0.0f64);
            for r in out.chunks_exact(3) {
                let (wi, pdf, weight, epdf, flags) = (r[0], r[0][3], r[1], r[1][3], r[2][3] as u32);
                let ok = flags & 1 != 0;
                let delta = flags & 2 != 0;
                if !ok {
                    continue;
                }
                assert!(weight.iter().take(3).all(|w| w.is_finite() && *w >= 0.0), "{name}: weight {weight:?}");
                if delta {
                    if flags & 4 == 0 {
                        reflected += 1.0;
                        let want = 2.0 * wo.z * Vec3::Z - wo;
                        assert!((Vec3::new(wi[0], wi[1], wi[2]) - want).length() < 1e-4, "{name}: mirror direction");
                    }
                    // Lossless: the weight times the radiance scale eta^2 of a
                    // refraction is 1 (reflection: 1).
                    let scale = if flags & 4 != 0 { 1.5f64 * 1.5 } else { 1.0 };
                    mean_weight += f64::from(weight[0]) * scale;
                    continue;
                }
                assert!(
                    (pdf - epdf).abs() <= 1e-3 * pdf.max(epdf),
                    "{name} at {theta} degrees: sampled pdf {pdf} but evaluation reports {epdf}"
                );
                mean_weight += f64::from(weight[0]);
            }
            mean_weight /= n as f64;
            // The reflectance by quadrature of f cos over the hemisphere, and the
            // integral of the pdf over it (midpoint rule in theta and phi, fine enough
            // for the sharpest lobe: 0.003 rad against its width of about 0.07).
            let (steps_t, steps_p) = (512usize, 512usize);
            let mut q = Vec::with_capacity(2 * steps_t * steps_p);
            let mut weights = Vec::with_capacity(steps_t * steps_p);
            let dt = std::f64::consts::FRAC_PI_2 / steps_t as f64;
            let dp = 2.0 * std::f64::consts::PI / steps_p as f64;
            for a in 0..steps_t {
                let t = (a as f64 + 0.5) * dt;
                let (st, ct) = t.sin_cos();
                for b in 0..steps_p {
                    let ph = (b as f64 + 0.5) * dp;
                    q.push([wo.x, wo.y, wo.z, id as f32]);
                    q.push([(st * ph.cos()) as f32, (st * ph.sin()) as f32, ct as f32, 0.0]);
                    weights.push((ct, st * dt * dp));
                }
            }
            let out = probe(&ctx, 1, &q, &shading, &params, (0, 0));
            let (mut refl, mut pdf_int) = (0.0f64, 0.0f64);
            for (r, &(ct, dw)) in out.chunks_exact(3).zip(&weights) {
                refl += f64::from(r[0][0]) * ct * dw;
                pdf_int += f64::from(r[0][3]) * dw;
            }
            match name {
                "mirror" => assert!((mean_weight - 1.0).abs() < 1e-6, "mirror reflectance {mean_weight}"),
                "glass" => {
                    assert!((mean_weight - 1.0).abs() < 1e-4, "lossless glass reflectance {mean_weight}");
                    let f = fresnel(f64::from(wo.z), 1.5);
                    let frac = reflected / n as f64;
                    let sd = (f * (1.0 - f) / n as f64).sqrt();
                    assert!((frac - f).abs() <= 5.0 * sd + 1e-3, "glass at {theta}: reflects {frac}, Fresnel {f}");
                }
                _ => {
                    assert!(refl <= 1.0 + 1e-3, "{name} at {theta}: reflectance {refl} > 1");
                    assert!(pdf_int <= 1.0 + 2e-3, "{name} at {theta}: pdf integrates to {pdf_int}");
                    if name.contains("lambert") {
                        assert!((pdf_int - 1.0).abs() < 2e-3, "{name}: pdf integrates to {pdf_int}");
                    }
                    // What sampling estimates is what evaluation integrates to.
                    let tol = 0.02 + 0.02 * refl;
                    assert!(
                        (mean_weight - refl).abs() <= tol,
                        "{name} at {theta}: mean sample weight {mean_weight} vs integrated reflectance {refl}"
                    );
                    if name == "white lambert" {
                        assert!((refl - 1.0).abs() < 2e-3, "white Lambert reflectance {refl}");
                    }
                }
            }
        }
    }
}

/// Glass seen from inside: total internal reflection beyond the critical angle.
#[test]
fn glass_reflects_totally_beyond_the_critical_angle() {
    let Some(ctx) = common::gpu() else { return };
    let (list, shading) = materials();
    let id = list.iter().find(|(n, _)| *n == "glass").expect("glass").1;
    let params = arbor::accel::gpu_layout::GpuParams::default();
    let mut rng = Rng(3);
    // Critical angle asin(1 / 1.5) = 41.8 degrees.
    for (theta, total) in [(30.0f32, false), (50.0, true), (80.0, true)] {
        let wo = dir(theta);
        let mut input = Vec::new();
        for _ in 0..512 {
            input.push([wo.x, wo.y, wo.z, id as f32]);
            input.push([rng.next(), rng.next(), rng.next(), 0.0]);
        }
        let out = probe(&ctx, 0, &input, &shading, &params, (0, 0));
        let transmitted = out.chunks_exact(3).filter(|r| r[2][3] as u32 & 4 != 0).count();
        if total {
            assert_eq!(transmitted, 0, "{theta} degrees from inside must reflect totally");
        } else {
            assert!(transmitted > 400, "{theta} degrees from inside mostly transmits ({transmitted})");
        }
    }
}

/// The environment sampler on the device: the histogram of sampled cells matches the
/// map's luminance x sin(theta) (chi-square at p = 0.001), every sample's pdf is the
/// pdf `env_pdf` reports for its direction, and the radiance is the cell's texel.
#[test]
fn environment_samples_follow_the_map() {
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (32usize, 16usize);
    let mut texels = vec![[0.0f32; 3]; w * h];
    for y in 0..h {
        for x in 0..w {
            let g = 0.2 + x as f32 / w as f32;
            texels[y * w + x] = [g, 0.5 * g, 0.1];
        }
    }
    for (x, y) in [(20, 5), (21, 5), (20, 6)] {
        texels[y * w + x] = [40.0, 30.0, 20.0];
    }
    for x in 0..w {
        texels[9 * w + x] = [0.0; 3]; // a black row
    }
    let mut b = SceneBuilder::new("env");
    b.scene.spheres.push(Sphere { center: Vec3::ZERO, radius: 1.0, material: 0 });
    b.scene.environment = Some(arbor::scene::Environment {
        name: "test map".into(),
        width: w as u32,
        height: h as u32,
        texels: texels.clone(),
        rotation: 30.0,
        intensity: 2.0,
    });
    let scene = b.finish().expect("scene");
    let mut shading = GpuScene::new(&scene).shading;
    let ex = arbor::render::dispatch::tables::extras(&scene, shading.len() as u32, true).expect("extras");
    shading.extend_from_slice(&ex.rows);
    let mut params = arbor::accel::gpu_layout::GpuParams {
        env_intensity: 2.0,
        env_rotation: 30f32.to_radians(),
        ..Default::default()
    };
    ex.set_tables(&mut params);
    let n = 200_000usize;
    let mut rng = Rng(5);
    let mut input = Vec::with_capacity(2 * n);
    for _ in 0..n {
        input.push([rng.next(), rng.next(), 0.0, 0.0]);
        input.push([0.0; 4]);
    }
    let out = probe(&ctx, 2, &input, &shading, &params, (w as u32, h as u32));
    let seen = arbor::render::dispatch::tables::env_texels_as_seen(&texels);
    let lum = |c: [f32; 3]| f64::from(0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]);
    let weight: Vec<f64> =
        (0..w * h).map(|i| lum(seen[i]) * (std::f64::consts::PI * ((i / w) as f64 + 0.5) / h as f64).sin()).collect();
    let total: f64 = weight.iter().sum();
    let mut counts = vec![0f64; w * h];
    for r in out.chunks_exact(3) {
        let cell = r[1][3] as usize;
        let (x, y) = (cell % w, cell / w);
        assert!(cell < w * h, "cell {cell}");
        counts[cell] += 1.0;
        let (pdf, epdf) = (r[0][3], r[1][0]);
        assert!(pdf > 0.0, "a sample of zero density");
        assert!(lum(seen[cell]) > 0.0, "a sample in the black cell ({x}, {y})");
        // A direction on a cell's edge may look up the neighbour: compare where the
        // direction falls in the sampled cell. Near the poles, sin(theta) recomputed
        // from the direction (acos of y) differs from the sampled one by a fraction
        // of a percent.
        let sin_theta = (1.0 - r[0][1] * r[0][1]).max(0.0).sqrt();
        if (r[1][1] as usize, r[1][2] as usize) == (x, y) && sin_theta > 0.01 {
            assert!((pdf - epdf).abs() <= 1e-2 * pdf, "cell ({x}, {y}): sampled pdf {pdf}, env_pdf {epdf}");
        }
        let texel = seen[y * w + x];
        for c in 0..3 {
            assert!((r[2][c] - 2.0 * texel[c]).abs() <= 1e-3 * (1.0 + texel[c]), "radiance of cell ({x}, {y})");
        }
    }
    assert!(counts.iter().zip(&weight).all(|(&c, &f)| f > 0.0 || c == 0.0), "a black cell was sampled");
    let c = ChiSquare::of(counts.iter().copied().zip(weight.iter().map(|f| f / total * n as f64)));
    // p = 0.001: z = 3.090.
    let (df, critical) = (c.df(), c.critical(3.090));
    assert!(c.chi2 < critical, "chi-square {:.1} over {df} degrees of freedom (critical {critical:.1})", c.chi2);
}

/// Pearson's chi-square of (observed, expected) counts over the bins that expect at
/// least 5, the others pooled into one bin when together they expect 5 or more.
pub(crate) struct ChiSquare {
    pub(crate) chi2: f64,
    pub(crate) bins: usize,
    /// The pooled bins' observed and expected counts.
    pub(crate) pooled: (f64, f64),
}

impl ChiSquare {
    pub(crate) fn of(pairs: impl Iterator<Item = (f64, f64)>) -> ChiSquare {
        let mut c = ChiSquare { chi2: 0.0, bins: 0, pooled: (0.0, 0.0) };
        for (o, e) in pairs {
            if e >= 5.0 {
                c.chi2 += (o - e) * (o - e) / e;
                c.bins += 1;
            } else {
                c.pooled.0 += o;
                c.pooled.1 += e;
            }
        }
        let (o, e) = c.pooled;
        if e >= 5.0 {
            c.chi2 += (o - e) * (o - e) / e;
            c.bins += 1;
        }
        c
    }

    pub(crate) fn df(&self) -> f64 {
        self.bins.saturating_sub(1) as f64
    }

    /// The quantile at the normal deviate `z` for [`ChiSquare::df`] degrees of freedom
    /// (Wilson-Hilferty).
    pub(crate) fn critical(&self, z: f64) -> f64 {
        let df = self.df();
        let k = 2.0 / (9.0 * df);
        df * (1.0 - k + z * k.sqrt()).powi(3)
    }
}
