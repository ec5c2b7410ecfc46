//! The microfacet materials on the device, through `sample_probe.comp` (the kernels'
//! own GLSL): each rough conductor, dielectric and metallic-roughness material draws directions with the density
//! its evaluation reports (chi-square over the sphere, seeded), its mean sample weight
//! is the reflectance its evaluation integrates to, it reflects no more than it
//! receives, a white conductor loses more energy the rougher it is (single scattering)
//! and none when smooth; roughness 0 is the mirror (of Fresnel reflectance) and the
//! smooth glass, bit for bit.

use crate::common;
use crate::path;
use crate::sampling::{dir, probe, ChiSquare, Rng};

use arbor::accel::gpu_layout::GpuParams;
use arbor::render::dispatch::upload::GpuScene;
use arbor::render::{Integrator, Mis};
use arbor::scene::procedural::quad;
use arbor::scene::{Camera, ComplexIor, Light, Material, MaterialKind, SceneBuilder, Sphere};
use glam::Vec3;

/// Gold's complex index at about 650, 550 and 450 nm.
const GOLD: ComplexIor = ComplexIor { eta: Vec3::new(0.143, 0.374, 1.442), k: Vec3::new(3.983, 2.385, 1.603) };

fn conductor(name: &str, roughness: f32, ior: Option<ComplexIor>, color: Vec3) -> Material {
    Material { kind: MaterialKind::Conductor, roughness, complex_ior: ior, ..Material::lambert(name, color) }
}

fn dielectric(name: &str, roughness: f32) -> Material {
    Material { kind: MaterialKind::Dielectric, roughness, ior: 1.5, ..Material::lambert(name, Vec3::ONE) }
}

/// glTF's metallic-roughness material (F0 0.04, specular weight 1).
fn pbr(name: &str, roughness: f32, metallic: f32, color: Vec3) -> Material {
    Material { kind: MaterialKind::Pbr, roughness, metallic, ..Material::lambert(name, color) }
}

/// Shading rows of `materials` (material i + 1 is `materials[i]`; 0 is the default).
fn shading(materials: Vec<Material>) -> (Vec<u32>, Vec<[f32; 4]>) {
    let mut b = SceneBuilder::new("microfacets");
    let ids = materials.into_iter().map(|m| b.material(m)).collect();
    b.scene.spheres.push(Sphere { center: Vec3::ZERO, radius: 1.0, material: 0 });
    let scene = b.finish().expect("scene");
    (ids, GpuScene::new(&scene).shading)
}

/// The sphere binned in `Z` bins of theta (small ones near the poles, where the lobes
/// of normal incidence lie) by `P` of phi.
const Z: usize = 32;
const P: usize = 48;

fn cell_of(w: [f32; 4]) -> usize {
    let theta = f64::from(w[2]).clamp(-1.0, 1.0).acos();
    let z = (theta / std::f64::consts::PI * Z as f64).floor().clamp(0.0, Z as f64 - 1.0) as usize;
    let phi = f64::from(w[1]).atan2(f64::from(w[0])) + std::f64::consts::PI;
    let p = (phi / (2.0 * std::f64::consts::PI) * P as f64).floor().clamp(0.0, P as f64 - 1.0) as usize;
    z * P + p
}

/// Per bin, the integrals over it of the pdf and of f |cos| (red channel) for `wo`.
struct Integrals {
    pdf: Vec<f64>,
    f_cos: Vec<f64>,
}

impl Integrals {
    /// The integral of f cos over the upper hemisphere and of f |cos| over the lower.
    fn above_below(&self) -> (f64, f64) {
        let (a, b) = self.f_cos.split_at(Z / 2 * P);
        (a.iter().sum(), b.iter().sum())
    }
}

/// [`Integrals`] by the midpoint rule in cos(theta) and phi (solid angle is dz dphi;
/// a lobe at a pole is smooth in z, not in theta): every bin with 4 x 4 points, then
/// with 24 x 24 those that hold a sample or expect half of one (a lobe of roughness
/// 0.3 refracted at normal incidence is a few thousandths of the pole's bin wide).
fn integrate(
    ctx: &arbor::gpu::Context,
    shading: &[[f32; 4]],
    id: u32,
    wo: Vec3,
    front: bool,
    counts: &[f64],
) -> Integrals {
    let all: Vec<usize> = (0..Z * P).collect();
    let mut g = integrate_bins(ctx, shading, id, wo, front, &all, 4);
    let n: f64 = counts.iter().sum();
    let busy: Vec<usize> = all.into_iter().filter(|&b| counts[b] > 0.0 || g.pdf[b] * n >= 0.5).collect();
    let fine = integrate_bins(ctx, shading, id, wo, front, &busy, 24);
    for b in busy {
        g.pdf[b] = fine.pdf[b];
        g.f_cos[b] = fine.f_cos[b];
    }
    g
}

fn integrate_bins(
    ctx: &arbor::gpu::Context,
    shading: &[[f32; 4]],
    id: u32,
    wo: Vec3,
    front: bool,
    bins: &[usize],
    q: usize,
) -> Integrals {
    let (dt, dp) = (std::f64::consts::PI / Z as f64, 2.0 * std::f64::consts::PI / P as f64);
    let mut input = Vec::with_capacity(2 * bins.len() * q * q);
    let mut points = Vec::with_capacity(bins.len() * q * q);
    for &bin in bins {
        let (zb, pb) = (bin / P, bin % P);
        let (z0, z1) = ((zb as f64 * dt).cos(), ((zb + 1) as f64 * dt).cos());
        for a in 0..q {
            // At a pole, where a lobe of normal incidence peaks, the points crowd
            // toward it: z = pole -+ width t^2, dz = 2 width t dt.
            let t = (a as f64 + 0.5) / q as f64;
            let (z, dz) = match zb {
                0 => (1.0 - (1.0 - z1) * t * t, 2.0 * (1.0 - z1) * t / q as f64),
                _ if zb == Z - 1 => (-1.0 + (1.0 + z0) * t * t, 2.0 * (1.0 + z0) * t / q as f64),
                _ => (z0 + (z1 - z0) * t, (z0 - z1) / q as f64),
            };
            for c in 0..q {
                let phi = -std::f64::consts::PI + (pb as f64 + (c as f64 + 0.5) / q as f64) * dp;
                let r = (1.0 - z * z).max(0.0).sqrt();
                input.push([wo.x, wo.y, wo.z, id as f32]);
                input.push([(r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32, if front { 1.0 } else { 0.0 }]);
                let dw = dz * dp / q as f64;
                points.push((bin, z.abs() * dw, dw));
            }
        }
    }
    let out = probe(ctx, 1, &input, shading, &GpuParams::default(), (0, 0));
    let mut g = Integrals { pdf: vec![0.0; Z * P], f_cos: vec![0.0; Z * P] };
    for (r, &(bin, cos_dw, dw)) in out.chunks_exact(3).zip(&points) {
        let (f, pdf) = (f64::from(r[0][0]), f64::from(r[0][3]));
        assert!(f.is_finite() && f >= 0.0 && pdf.is_finite() && pdf >= 0.0, "f {f}, pdf {pdf}");
        g.pdf[bin] += pdf * dw;
        g.f_cos[bin] += f * cos_dw;
    }
    g
}

#[test]
fn rough_conductors_and_dielectrics_sample_the_pdf_they_evaluate() {
    let Some(ctx) = common::gpu() else { return };
    let roughness = [0.3f32, 0.5, 0.8];
    let mut materials = Vec::new();
    for &r in &roughness {
        materials.push(conductor(&format!("copper {r}"), r, None, Vec3::new(0.95, 0.64, 0.54)));
        materials.push(conductor(&format!("gold {r}"), r, Some(GOLD), Vec3::ONE));
        materials.push(conductor(&format!("white {r}"), r, None, Vec3::ONE));
        materials.push(dielectric(&format!("rough glass {r}"), r));
        materials.push(pbr(&format!("plastic {r}"), r, 0.0, Vec3::new(0.8, 0.5, 0.3)));
        materials.push(pbr(&format!("half metal {r}"), r, 0.5, Vec3::new(0.95, 0.64, 0.54)));
    }
    let names: Vec<String> = materials.iter().map(|m| m.name.clone()).collect();
    let (ids, shading) = shading(materials);
    let n = 40_000usize;
    let mut rng = Rng(11);
    let mut white_loss: Vec<(f32, f32, f64)> = Vec::new();
    for (name, &id) in names.iter().zip(&ids) {
        let glass = name.starts_with("rough glass");
        let sides: &[bool] = if glass { &[true, false] } else { &[true] };
        for &front in sides {
            for theta in [0.0f32, 40.0, 80.0] {
                let what = format!("{name}, {} at {theta} degrees", if front { "outside" } else { "inside" });
                let wo = dir(theta);
                let mut input = Vec::with_capacity(2 * n);
                for _ in 0..n {
                    input.push([wo.x, wo.y, wo.z, id as f32]);
                    input.push([rng.next(), rng.next(), rng.next(), if front { 1.0 } else { 0.0 }]);
                }
                let out = probe(&ctx, 0, &input, &shading, &GpuParams::default(), (0, 0));
                let mut counts = vec![0f64; Z * P];
                let (mut lost, mut sum, mut sum2) = (0f64, 0f64, 0f64);
                for r in out.chunks_exact(3) {
                    let (wi, pdf, weight, epdf, flags) = (r[0], r[0][3], r[1], r[1][3], r[2][3] as u32);
                    if flags & 1 == 0 {
                        lost += 1.0;
                        continue;
                    }
                    assert_eq!(flags & 2, 0, "{what}: a rough material sampled a delta lobe");
                    assert_eq!(flags & 4 != 0, wi[2] < 0.0, "{what}: transmission flag and side disagree");
                    assert!(glass || wi[2] > 0.0, "{what}: a conductor transmitted");
                    assert!((pdf - epdf).abs() <= 1e-4 * pdf.max(epdf) && pdf > 0.0, "{what}: pdf {pdf} vs {epdf}");
                    assert!(weight.iter().take(3).all(|w| w.is_finite() && *w >= 0.0), "{what}: weight {weight:?}");
                    counts[cell_of(wi)] += 1.0;
                    let w = f64::from(weight[0]);
                    sum += w;
                    sum2 += w * w;
                }
                let g = integrate(&ctx, &shading, id, wo, front, &counts);
                // Chi-square: bins with an expected count of at least 5, the rest and the
                // lost samples (the pdf's deficit) pooled or alone.
                let total_pdf: f64 = g.pdf.iter().sum();
                assert!(total_pdf <= 1.0 + 2e-3, "{what}: the pdf integrates to {total_pdf}");
                let lost_e = (1.0 - total_pdf).max(0.0) * n as f64;
                let c = ChiSquare::of(
                    counts.iter().copied().chain([lost]).zip(g.pdf.iter().map(|p| p * n as f64).chain([lost_e])),
                );
                let (pool_o, pool_e) = c.pooled;
                if pool_e < 5.0 {
                    assert!(pool_o <= 20.0 + 4.0 * pool_e, "{what}: {pool_o} samples where {pool_e:.2} were expected");
                }
                assert!(c.bins >= 3, "{what}: only {} bins", c.bins);
                // p = 1e-4: z = 3.719.
                let (chi2, df, critical) = (c.chi2, c.df(), c.critical(3.719));
                if chi2 >= critical {
                    let mut worst: Vec<(f64, usize)> = (0..Z * P)
                        .map(|b| (counts[b] - g.pdf[b] * n as f64, b))
                        .map(|(d, b)| (d * d / (g.pdf[b] * n as f64).max(1e-9), b))
                        .collect();
                    worst.sort_by(|a, b| b.0.total_cmp(&a.0));
                    let bins: Vec<String> = worst[..3]
                        .iter()
                        .map(|&(_, b)| {
                            format!("bin ({}, {}): {} for {:.1}", b / P, b % P, counts[b], g.pdf[b] * n as f64)
                        })
                        .collect();
                    panic!(
                        "{what}: chi-square {chi2:.1} over {df} degrees of freedom (critical {critical:.1}); lost {lost} for {lost_e:.1}; worst {}",
                        bins.join(", ")
                    );
                }
                // What sampling estimates is what evaluation integrates to.
                let mean = sum / n as f64;
                let sd = ((sum2 / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
                let integral: f64 = g.f_cos.iter().sum();
                assert!(
                    (mean - integral).abs() <= 5.0 * sd + 0.01 * integral + 1e-3,
                    "{what}: mean sample weight {mean} vs integrated reflectance {integral}"
                );
                // No more out than in: the transmitted radiance, scaled back by eta^2.
                let eta2 = if !glass {
                    1.0
                } else if front {
                    2.25
                } else {
                    1.0 / 2.25
                };
                let (above, below) = g.above_below();
                let energy = above + eta2 * below;
                // glTF's reference model gains energy at grazing incidence: its diffuse
                // base loses only what the specular layer reflects about each half
                // vector (docs/materials.md gives the figures).
                let gain = if name.starts_with("plastic") || name.starts_with("half metal") { 0.06 } else { 0.01 };
                assert!(energy <= 1.0 + gain, "{what}: reflects and transmits {energy}");
                eprintln!(
                    "{what}: mean weight {mean:.4}, integral {integral:.4}, energy {energy:.4}, chi-square {chi2:.1} over {df}"
                );
                if name.starts_with("white") {
                    white_loss.push((roughness[white_loss.len() / 3], theta, mean));
                }
            }
        }
    }
    // A white conductor loses only what single scattering loses: more the rougher it
    // is, at each angle.
    for theta in [0.0f32, 40.0, 80.0] {
        let at: Vec<f64> = white_loss.iter().filter(|l| l.1 == theta).map(|l| l.2).collect();
        assert!(at.windows(2).all(|w| w[0] > w[1]) && at[0] <= 1.0 + 1e-3 && at[2] > 0.4, "{theta} degrees: {at:?}");
    }
}

/// The exact Fresnel reflectance of a conductor (f64), for one channel.
fn fresnel_conductor(c: f64, eta: f64, k: f64) -> f64 {
    let (c2, s2) = (c * c, 1.0 - c * c);
    let t0 = eta * eta - k * k - s2;
    let a2b2 = (t0 * t0 + 4.0 * eta * eta * k * k).sqrt();
    let a = (0.5 * (a2b2 + t0)).sqrt();
    let rs = (a2b2 + c2 - 2.0 * c * a) / (a2b2 + c2 + 2.0 * c * a);
    let rp = rs * (c2 * a2b2 + s2 * s2 - 2.0 * c * a * s2) / (c2 * a2b2 + s2 * s2 + 2.0 * c * a * s2);
    0.5 * (rs + rp)
}

#[test]
fn roughness_zero_is_the_mirror_and_the_smooth_glass() {
    let Some(ctx) = common::gpu() else { return };
    let glass =
        Material { kind: MaterialKind::Glass, ior: 1.5, ..Material::lambert("glass", Vec3::new(0.9, 0.8, 1.0)) };
    let smooth = Material { kind: MaterialKind::Dielectric, ..glass.clone() };
    let (ids, shading) = shading(vec![
        glass,
        smooth,
        conductor("gold", 0.0, Some(GOLD), Vec3::ONE),
        conductor("copper", 0.0, None, Vec3::new(0.95, 0.64, 0.54)),
    ]);
    let mut rng = Rng(13);
    for theta in [0.0f32, 30.0, 60.0, 85.0] {
        let wo = dir(theta);
        for front in [true, false] {
            let u: Vec<[f32; 4]> =
                (0..256).map(|_| [rng.next(), rng.next(), rng.next(), if front { 1.0 } else { 0.0 }]).collect();
            let run = |id: u32| {
                let input: Vec<[f32; 4]> = u.iter().flat_map(|&u| [[wo.x, wo.y, wo.z, id as f32], u]).collect();
                probe(&ctx, 0, &input, &shading, &GpuParams::default(), (0, 0))
            };
            let (a, b) = (run(ids[0]), run(ids[1]));
            let bits = |v: &[[f32; 4]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&a), bits(&b), "a dielectric of roughness 0 differs from glass at {theta} degrees");
        }
        for (k, &id) in ids[2..].iter().enumerate() {
            let input: Vec<[f32; 4]> =
                (0..64).flat_map(|_| [[wo.x, wo.y, wo.z, id as f32], [0.3, 0.6, 0.9, 1.0]]).collect();
            let out = probe(&ctx, 0, &input, &shading, &GpuParams::default(), (0, 0));
            let c = f64::from(wo.z);
            for r in out.chunks_exact(3) {
                assert_eq!(r[2][3] as u32 & 7, 3, "a smooth conductor samples one delta reflection");
                let want = Vec3::new(-wo.x, -wo.y, wo.z);
                assert!((Vec3::new(r[0][0], r[0][1], r[0][2]) - want).length() < 1e-5, "mirror direction");
                for ch in 0..3 {
                    let f = match k {
                        0 => fresnel_conductor(c, f64::from(GOLD.eta[ch]), f64::from(GOLD.k[ch])),
                        _ => {
                            let f0 = f64::from([0.95f32, 0.64, 0.54][ch]);
                            f0 + (1.0 - f0) * (1.0 - c).powi(5)
                        }
                    };
                    assert!((f64::from(r[1][ch]) - f).abs() < 2e-4, "channel {ch} at {theta}: {} vs {f}", r[1][ch]);
                }
            }
        }
    }
}

/// A rough conductor floor lit only through a rough dielectric slab between it and a
/// small light (the slab blocks the floor's shadow rays): light sampling alone (which
/// must sample the light through the slab, on the transmission side), BSDF sampling
/// alone and MIS estimate one integral, so their means agree within their confidence
/// intervals.
#[test]
fn through_rough_glass_light_bsdf_and_mis_sampling_agree() {
    let Some(ctx) = common::gpu() else { return };
    let mut b = SceneBuilder::new("rough glass slab");
    let floor = b.material(conductor("copper", 0.6, None, Vec3::new(0.95, 0.64, 0.54)));
    let slab = b.material(dielectric("frosted", 0.5));
    let half = 0.5f32;
    let light = b.material(path::emitter(1.0 / (half * half)));
    let v = Vec3::new;
    let g = 2.0;
    b.mesh(&quad([v(-g, 0.0, g), v(g, 0.0, g), v(g, 0.0, -g), v(-g, 0.0, -g)]), 1.0, Vec3::ZERO, Some(floor));
    let s = 1.5;
    b.mesh(&quad([v(-s, 0.5, s), v(s, 0.5, s), v(s, 0.5, -s), v(-s, 0.5, -s)]), 1.0, Vec3::ZERO, Some(slab));
    // Facing down: cross(b - a, c - a) points to -y.
    b.mesh(
        &quad([v(-half, 1.0, -half), v(half, 1.0, -half), v(half, 1.0, half), v(-half, 1.0, half)]),
        1.0,
        Vec3::ZERO,
        Some(light),
    );
    b.scene.background = Vec3::ZERO;
    b.scene.camera = Camera { eye: v(0.0, 0.3, 3.0), look_at: v(0.0, 0.0, 0.0), up: Vec3::Y, vfov: 40.0 };
    let scene = b.finish().expect("scene");
    let mut results = Vec::new();
    for mis in [Mis::Both, Mis::Light, Mis::Bsdf] {
        let mut s = path::settings(24, 16, 512);
        s.mis = mis;
        s.max_depth = Some(3);
        let f = path::render(&ctx, &scene, &s);
        ctx.check_validation().expect("no validation errors");
        // The floor (triangles 0 and 1), seen under the slab.
        results.push((mis, path::mean_and_error(&f, |k| f.prim[k] < 2)));
    }
    eprintln!("floor under rough glass, (mean, error) by strategy: {results:?}");
    let (_, (m0, e0)) = results[0];
    assert!(m0 > 0.01, "the floor is dark ({m0}): no light came through the slab");
    for &(mis, (m, e)) in &results[1..] {
        let bound = 4.0 * (e0 * e0 + e * e).sqrt();
        assert!((m - m0).abs() <= bound, "{mis:?} mean {m} vs MIS {m0} (bound {bound})");
    }
}

/// The Whitted preview lights rough conductors, dielectrics and metallic-roughness as the path tracer's
/// first bounce does (a point light, no ambient term, no other light): their image
/// means agree.
#[test]
fn whitted_lights_rough_surfaces_as_the_path_tracer_does() {
    let Some(ctx) = common::gpu() else { return };
    let mut b = SceneBuilder::new("rough spheres");
    let gold = b.material(conductor("gold", 0.4, Some(GOLD), Vec3::ONE));
    let glass = b.material(dielectric("frosted", 0.3));
    let plastic = b.material(pbr("plastic", 0.35, 0.2, Vec3::new(0.2, 0.5, 0.8)));
    let v = Vec3::new;
    let g = 3.0;
    b.mesh(&quad([v(-g, -1.0, g), v(g, -1.0, g), v(g, -1.0, -g), v(-g, -1.0, -g)]), 1.0, Vec3::ZERO, None);
    b.scene.spheres.push(Sphere { center: v(-0.6, -0.4, 0.0), radius: 0.6, material: gold });
    b.scene.spheres.push(Sphere { center: v(0.7, -0.5, 0.3), radius: 0.5, material: glass });
    b.scene.spheres.push(Sphere { center: v(0.1, -0.7, 1.0), radius: 0.3, material: plastic });
    b.scene.lights.push(Light::Point { position: v(1.0, 2.5, 2.0), intensity: Vec3::splat(6.0) });
    b.scene.background = Vec3::ZERO;
    b.scene.ambient = 0.0;
    b.scene.camera = Camera { eye: v(0.0, 0.5, 4.0), look_at: v(0.0, -0.4, 0.0), up: Vec3::Y, vfov: 40.0 };
    let scene = b.finish().expect("scene");
    let mut means = Vec::new();
    for integrator in [Integrator::Whitted, Integrator::Path] {
        let mut s = path::settings(32, 24, 8);
        s.integrator = integrator;
        s.max_depth = Some(2);
        let f = path::render(&ctx, &scene, &s);
        ctx.check_validation().expect("no validation errors");
        assert!(f.radiance.iter().flatten().all(|c| c.is_finite() && *c >= 0.0), "{integrator:?}: a bad pixel");
        // The spheres' pixels (primitives 2 to 4 follow the floor's two triangles).
        means.push(path::mean_and_error(&f, |k| f.prim[k] >= 2 && f.prim[k] < 5).0);
    }
    eprintln!("rough spheres, Whitted and path means: {means:?}");
    assert!(means[1] > 0.01, "the spheres are dark: {means:?}");
    assert!((means[0] - means[1]).abs() <= 0.03 * means[1], "Whitted {} vs path {}", means[0], means[1]);
}

/// A metallic-roughness quad seen head-on under a point light, `maps`: with textures
/// of one texel value (roughness and metallic from the metallic-roughness map, the
/// normal from the normal map) or, without, the factors and vertex normals those
/// texels stand for. UVs are turned a quarter: u runs along +y, v along -x.
fn mapped_quad(maps: Option<([u8; 4], [u8; 4])>, normal: Vec3) -> arbor::scene::Scene {
    use arbor::scene::{Maps, Texture};
    let v = Vec3::new;
    let mut mesh = quad([v(-1.0, -1.0, 0.0), v(1.0, -1.0, 0.0), v(1.0, 1.0, 0.0), v(-1.0, 1.0, 0.0)]);
    let uv = glam::Vec2::new;
    mesh.uvs = Some(vec![uv(0.0, 1.0), uv(0.0, 0.0), uv(1.0, 0.0), uv(1.0, 1.0)]);
    let mut m = pbr("mapped", 1.0, 1.0, Vec3::new(0.9, 0.6, 0.3));
    match maps {
        Some((mr, n)) => {
            let one = |name: &str, t: [u8; 4]| Texture {
                name: name.into(),
                width: 2,
                height: 2,
                texels: vec![t; 4],
                ..Default::default()
            };
            mesh.textures = vec![one("metal-rough", mr), one("normal", n)];
            m.maps = Maps { metal_rough: Some(0), normal: Some(1), ..Maps::default() };
            mesh.normals = Some(vec![Vec3::Z; 4]);
        }
        None => mesh.normals = Some(vec![normal; 4]),
    }
    mesh.materials = vec![m];
    mesh.tri_material = vec![0, 0];
    let mut b = SceneBuilder::new("mapped quad");
    b.mesh(&mesh, 1.0, Vec3::ZERO, None);
    b.scene.lights.push(Light::Point { position: v(1.5, -1.0, 2.0), intensity: Vec3::splat(4.0) });
    b.scene.background = Vec3::ZERO;
    b.scene.ambient = 0.0;
    b.scene.camera = Camera { eye: v(0.0, 0.0, 3.0), look_at: Vec3::ZERO, up: Vec3::Y, vfov: 30.0 };
    b.finish().expect("scene")
}

/// The metallic-roughness texture multiplies roughness (green) and metallic (blue),
/// and the normal map bends the shading normal along the triangle's tangent frame
/// (x where u grows, y where v grows): a quad textured with one texel value renders as
/// the same quad with those factors and that normal given as its vertex normals, and
/// differs from the quad with the map's normal left out.
#[test]
fn metallic_roughness_maps_act_as_their_factors_and_normals() {
    let Some(ctx) = common::gpu() else { return };
    let (mr, n) = ([0u8, 102, 191, 255], [200u8, 80, 220, 255]);
    let c = |b: u8| f32::from(b) / 255.0 * 2.0 - 1.0;
    // u along +y and v along -x: the map's x is +y, its y is -x.
    let bent = Vec3::new(-c(n[1]), c(n[0]), c(n[2])).normalize();
    let render = |scene: arbor::scene::Scene, factors: bool| {
        let mut scene = scene;
        if factors {
            scene.materials.iter_mut().filter(|m| m.kind == MaterialKind::Pbr).for_each(|m| {
                m.roughness = f32::from(mr[1]) / 255.0;
                m.metallic = f32::from(mr[2]) / 255.0;
            });
        }
        let mut s = path::settings(32, 32, 16);
        s.max_depth = Some(2);
        let f = path::render(&ctx, &scene, &s);
        ctx.check_validation().expect("no validation errors");
        f
    };
    let mapped = render(mapped_quad(Some((mr, n)), Vec3::Z), false);
    let given = render(mapped_quad(None, bent), true);
    let flat = render(mapped_quad(None, Vec3::Z), true);
    let mean = |f: &arbor::render::Frame| path::mean_and_error(f, |k| f.prim[k] != u32::MAX).0;
    let (a, b, c0) = (mean(&mapped), mean(&given), mean(&flat));
    eprintln!("mapped {a}, factors and vertex normals {b}, unbent {c0}");
    assert!(b > 0.01, "the quad is dark: {b}");
    assert!((a - b).abs() <= 0.01 * b, "mapped {a} vs the factors and normals it stands for {b}");
    assert!((c0 - b).abs() >= 0.1 * b, "the bent normal changes nothing ({c0} vs {b}): the test cannot tell");
    // Pixel by pixel too: the normal AOV is the bent normal.
    let k = 16 * 32 + 16;
    let got = Vec3::from_slice(&mapped.normal[k]);
    assert!((got - bent).length() < 1e-3, "normal AOV {got} vs {bent}");
}
