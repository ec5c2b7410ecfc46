//! Numerical robustness at the extremes (scales 1e-6, 1 and 1e6, and far from the
//! origin): no cracks in watertight mode, the same picture at every scale, no shadow
//! acne, no black rings in glass, no NaN anywhere, and the robustness helpers agreeing
//! bit for bit between Rust and GLSL.

use crate::common;

use arbor::accel::{Accel, AccelKind, Prims, Traverse};
use arbor::gpu::bindings::*;
use arbor::gpu::{spirv, BindingDesc, BindingKind, BufferKind};
use arbor::math::float::{offset_ray_origin, triangle_point};
use arbor::math::intersect::{edge_function, IntersectMode};
use arbor::math::Ray;
use arbor::render::{cracks, gpu, Frame, RenderSettings};
use arbor::scene::{procedural, Camera, Light, Material, MaterialKind, MeshData, Scene, SceneBuilder, Sphere};
use common::scenes::Rng;
use glam::Vec3;

/// One structure of each traversal kernel, for the shading tests (the BVH builders
/// share one kernel, so trbvh stands for them).
const SHADED_KINDS: [AccelKind; 8] = [
    AccelKind::None,
    AccelKind::Kdtree,
    AccelKind::Trbvh,
    AccelKind::Bvh4,
    AccelKind::Bvh8,
    AccelKind::Cwbvh,
    AccelKind::Grid,
    AccelKind::Octree,
];

/// (name, scale, shift): the transforms every test runs at.
const SCALES: [(&str, f32, f32); 4] = [("unit", 1.0, 0.0), ("1e-6", 1e-6, 0.0), ("1e6", 1e6, 0.0), ("far", 1.0, 1e6)];

/// A closed, irregular mesh: the blob with every vertex jittered radially by a hash of
/// its position, so that coincident vertices (the blob's poles repeat one position)
/// move together and the surface stays closed.
fn irregular(n: usize) -> MeshData {
    let mut m = procedural::blob(n, 0.2, 21);
    for p in &mut m.positions {
        let h =
            (p.x.to_bits() ^ p.y.to_bits().rotate_left(11) ^ p.z.to_bits().rotate_left(22)).wrapping_mul(0x9e37_79b9);
        *p *= 1.0 + 0.02 * ((h >> 8) as f32 / (1u32 << 24) as f32 - 0.5);
    }
    m
}

fn mesh_scene(name: &str, mesh: &MeshData, scale: f32, shift: f32) -> Scene {
    let mut b = SceneBuilder::new(name);
    b.mesh(mesh, scale, Vec3::splat(shift), None);
    b.scene.lights.push(Light::Directional { direction: Vec3::NEG_ONE.normalize(), radiance: Vec3::ONE });
    b.finish().expect("valid scene")
}

#[test]
fn watertight_rays_never_escape_closed_meshes_on_the_cpu() {
    // 10^6 rays per mesh (250k at each of the four transforms), through a BVH (the
    // structures agree with brute force elsewhere; this tests the triangle test).
    let meshes = [("sphere", procedural::blob(20_000, 0.0, 1)), ("irregular", irregular(20_000))];
    let mut report = Vec::new();
    for (mesh_name, mesh) in &meshes {
        for (label, scale, shift) in SCALES {
            let scene = mesh_scene(mesh_name, mesh, scale, shift);
            let accel = Accel::build(AccelKind::BvhSah, &scene);
            let rays = cracks::aimed_rays(&scene, Vec3::splat(shift), 0.3 * scale, 250_000, 5);
            for mode in [IntersectMode::Watertight, IntersectMode::Fast] {
                let escapes = cracks::escapes(&scene, mode, &accel, &rays);
                report.push(format!("{mesh_name} {label} {mode}: {escapes} escapes of {}", rays.len()));
                if mode == IntersectMode::Watertight {
                    if escapes > 0 {
                        let bad: Vec<&Ray> =
                            rays.iter().filter(|r| accel.intersect(&scene, r).is_none()).take(3).collect();
                        let brute = Accel::build(AccelKind::None, &scene);
                        for r in &bad {
                            eprintln!(
                                "{r:?}: brute {:?} fast {:?}",
                                brute.intersect(&scene, r),
                                brute.intersect_with(&Prims::with_mode(&scene, IntersectMode::Fast), r)
                            );
                        }
                    }
                    assert_eq!(escapes, 0, "{mesh_name} at {label}: {escapes} watertight rays escaped");
                }
            }
        }
    }
    // The price of the fast mode, for the record (cargo test -- --nocapture).
    eprintln!("{}", report.join("\n"));
}

fn render(ctx: &arbor::gpu::Context, scene: &Scene, kind: AccelKind, w: u32, h: u32, primary: bool) -> Frame {
    let mut s = RenderSettings::for_size(w, h);
    s.accel = kind;
    s.primary_only = primary;
    let (f, _) = gpu::render(ctx, scene, &s, |_, _| {}).expect("render");
    ctx.check_validation().expect("no validation errors");
    for (i, px) in f.radiance.iter().enumerate() {
        assert!(px.iter().all(|v| v.is_finite()), "{} {kind}: pixel {i} radiance {px:?}", scene.name);
        assert!(f.normal[i].iter().all(|v| v.is_finite()), "{} {kind}: pixel {i} normal", scene.name);
        assert!(!f.depth[i].is_nan(), "{} {kind}: pixel {i} depth NaN", scene.name);
    }
    f
}

#[test]
fn watertight_camera_rays_never_escape_on_the_gpu_for_any_structure() {
    let Some(ctx) = common::gpu() else { return };
    let mesh = irregular(6000);
    for (label, scale, shift) in SCALES {
        let mut scene = mesh_scene("inside", &mesh, scale, shift);
        let c = Vec3::splat(shift);
        scene.camera = Camera {
            eye: c + Vec3::new(0.05, 0.03, -0.02) * scale,
            look_at: c + Vec3::new(1.0, 0.7, 0.4) * scale,
            up: Vec3::Y,
            vfov: 120.0,
        };
        for &kind in AccelKind::ALL {
            let f = render(&ctx, &scene, kind, 72, 64, true);
            let misses = f.prim.iter().filter(|&&p| p == u32::MAX).count();
            assert_eq!(misses, 0, "{label} {kind}: {misses} camera rays escaped the closed mesh");
        }
    }
}

/// Blob, a sphere and a plane, lit by a directional light, transformed.
fn composite(scale: f32, shift: f32) -> Scene {
    let mut b = SceneBuilder::new("composite");
    let glass = b.material(Material { kind: MaterialKind::Glass, ior: 1.5, ..Material::lambert("glass", Vec3::ONE) });
    let s = Vec3::splat(shift);
    b.mesh(&procedural::blob(3000, 0.2, 3), 0.6 * scale, s + Vec3::new(-0.5, 0.6, 0.0) * scale, None);
    let g = 3.0;
    let floor =
        procedural::quad([Vec3::new(-g, 0.0, g), Vec3::new(g, 0.0, g), Vec3::new(g, 0.0, -g), Vec3::new(-g, 0.0, -g)]);
    b.mesh(&floor, scale, s, None);
    b.scene.spheres.push(Sphere { center: s + Vec3::new(0.8, 0.5, 0.3) * scale, radius: 0.5 * scale, material: glass });
    b.scene.lights.push(Light::Directional { direction: Vec3::new(-0.3, -1.0, -0.4).normalize(), radiance: Vec3::ONE });
    b.scene.background = Vec3::new(0.6, 0.7, 0.8);
    b.scene.camera = Camera {
        eye: s + Vec3::new(0.0, 1.6, 3.5) * scale,
        look_at: s + Vec3::new(0.0, 0.4, 0.0) * scale,
        up: Vec3::Y,
        vfov: 45.0,
    };
    b.finish().expect("valid scene")
}

#[test]
fn every_scale_gives_the_same_picture() {
    let Some(ctx) = common::gpu() else { return };
    let (w, h) = (80, 60);
    for &kind in AccelKind::ALL {
        let unit = render(&ctx, &composite(1.0, 0.0), kind, w, h, true);
        // Far from the origin, a unit scene is quantised to 1/16 at 1e6: use a
        // kilometre-sized scene there instead (the crack tests cover unit size).
        for (label, scale, shift) in [("1e-6", 1e-6, 0.0), ("1e6", 1e6, 0.0), ("1e3 at 1e6", 1e3, 1e6)] {
            let f = render(&ctx, &composite(scale, shift), kind, w, h, true);
            let differ = (0..f.prim.len()).filter(|&i| f.prim[i] != unit.prim[i]).count();
            // Only rays grazing an edge may change hands: at most 1% of the pixels.
            assert!(differ * 100 <= f.prim.len(), "{label} {kind}: {differ} of {} pixels differ", f.prim.len());
            if label != "1e3 at 1e6" {
                let rel: Vec<f32> = (0..f.depth.len())
                    .filter(|&i| f.prim[i] == unit.prim[i] && unit.prim[i] != u32::MAX)
                    .map(|i| (f.depth[i] / scale - unit.depth[i]).abs() / unit.depth[i])
                    .collect();
                assert!(rel.iter().all(|&r| r < 1e-4), "{label} {kind}: depths do not scale");
            }
        }
    }
}

#[test]
fn no_shadow_acne_at_grazing_light_and_no_black_rings_in_glass() {
    let Some(ctx) = common::gpu() else { return };
    for (label, scale, shift) in SCALES {
        // A plane of 800 triangles lit 2 degrees above the horizon: every plane pixel
        // must be lit alike (a self-shadowed speckle would be black).
        let mut b = SceneBuilder::new("grazing");
        let mut plane = MeshData::default();
        let k = 20;
        for j in 0..=k {
            for i in 0..=k {
                plane.positions.push(Vec3::new(i as f32 / k as f32 * 4.0 - 2.0, 0.0, j as f32 / k as f32 * 4.0 - 2.0));
            }
        }
        for j in 0..k {
            for i in 0..k {
                let v = |i: u32, j: u32| j * (k + 1) + i;
                plane.triangles.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
                plane.triangles.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            }
        }
        let s = Vec3::splat(shift);
        b.mesh(&plane, scale, s, None);
        let elev = 2.0f32.to_radians();
        b.scene.lights.push(Light::Directional {
            // From behind the camera (+z), 2 degrees above the plane.
            direction: -Vec3::new(elev.cos() * 0.2, elev.sin(), elev.cos()).normalize(),
            radiance: Vec3::ONE,
        });
        b.scene.background = Vec3::new(0.5, 0.6, 0.7);
        b.scene.ambient = 0.0;
        b.scene.camera = Camera { eye: s + Vec3::new(0.0, 2.5, 2.5) * scale, look_at: s, up: Vec3::Y, vfov: 50.0 };
        let scene = b.finish().expect("scene");
        let nt = scene.triangles.len() as u32;
        for kind in SHADED_KINDS {
            let f = render(&ctx, &scene, kind, 96, 96, false);
            // Plane pixels outside the sphere's shadow: those whose shadow ray toward the
            // light could only be blocked by the plane itself. Compare with the brightest.
            let lum = |i: usize| f.radiance[i].iter().sum::<f32>();
            let plane_px: Vec<usize> = (0..f.prim.len()).filter(|&i| f.prim[i] < nt).collect();
            let max = plane_px.iter().map(|&i| lum(i)).fold(0.0f32, f32::max);
            let dark = plane_px.iter().filter(|&&i| lum(i) < 0.5 * max).count();
            // Every plane pixel sees the light at the same angle with nothing in
            // between: any dark pixel is acne.
            assert_eq!(dark, 0, "{label} {kind}: {dark} of {} plane pixels self-shadowed", plane_px.len());
        }
        // A glass sphere on the plane, lit from above: a path that re-hits the surface
        // it left (acne inside the glass) ends black; none may.
        let mut glass_scene = scene.clone();
        // Some ambient light, so the plane in the glass's own shadow (seen through it)
        // is not black: only paths lost to self-intersection are.
        glass_scene.ambient = 0.3;
        let glass = glass_scene.materials.len() as u32;
        glass_scene.materials.push(Material {
            kind: MaterialKind::Glass,
            ior: 1.5,
            ..Material::lambert("glass", Vec3::ONE)
        });
        glass_scene.spheres.push(Sphere {
            center: s + Vec3::new(0.0, 0.45, 0.0) * scale,
            radius: 0.4 * scale,
            material: glass,
        });
        glass_scene.lights =
            vec![Light::Directional { direction: Vec3::new(-0.3, -1.0, -0.2).normalize(), radiance: Vec3::ONE }];
        glass_scene.camera = Camera {
            eye: s + Vec3::new(0.0, 0.8, 1.6) * scale,
            look_at: s + Vec3::new(0.0, 0.4, 0.0) * scale,
            up: Vec3::Y,
            vfov: 45.0,
        };
        for kind in SHADED_KINDS {
            let f = render(&ctx, &glass_scene, kind, 96, 96, false);
            let lum = |i: usize| f.radiance[i].iter().sum::<f32>();
            let sphere_px: Vec<usize> = (0..f.prim.len()).filter(|&i| f.prim[i] == nt).collect();
            let black = sphere_px.iter().filter(|&&i| lum(i) == 0.0).count();
            assert!(sphere_px.len() > 500, "{label}: the sphere fills the view");
            assert!(
                black * 500 <= sphere_px.len(),
                "{label} {kind}: {black} of {} glass pixels black",
                sphere_px.len()
            );
        }
    }
}

#[test]
fn robustness_helpers_agree_bit_for_bit_with_the_device() {
    let Some(ctx) = common::gpu() else { return };
    let mut rng = Rng(31);
    let mut input: Vec<[f32; 4]> = Vec::new();
    let mut expected: Vec<f32> = Vec::new();
    for k in 0..2048 {
        let scale = [1e-6f32, 1e-3, 1.0, 1e3, 1e6][k % 5];
        let shift = if k % 7 == 0 { 1e6 } else { 0.0 };
        let mut p =
            || Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)) * scale + Vec3::splat(shift);
        let (p0, p1, mut p2) = (p(), p(), p());
        if k % 11 == 0 {
            p2 = p0; // degenerate
        }
        let (u, v) = (rng.next() * 0.6, rng.next() * 0.4);
        let n = rng.dir();
        let w = if k % 2 == 0 { rng.dir() } else { -n };
        input.extend([
            [p0.x, p0.y, p0.z, u],
            [p1.x, p1.y, p1.z, v],
            [p2.x, p2.y, p2.z, 0.0],
            [n.x, n.y, n.z, 0.0],
            [w.x, w.y, w.z, 0.0],
        ]);
        let (tp, err) = triangle_point(p0, p1, p2, u, v);
        let o = offset_ray_origin(tp, err, n, w);
        let e = edge_function(p0.x, p1.y, p1.x, p0.y);
        expected.extend([tp.x, tp.y, tp.z, err.x, err.y, err.z, o.x, o.y, o.z, e, u.next_up(), v.next_down()]);
    }
    let records = input.len() / 5;
    let bindings = [
        BindingDesc { binding: BINDING_ACCEL_NODES, kind: BindingKind::Storage, name: "probe_in" },
        BindingDesc { binding: BINDING_ACCEL_INDICES, kind: BindingKind::Storage, name: "probe_out" },
    ];
    let spv = spirv::get("math_probe").expect("probe kernel compiled");
    let mut k = ctx.create_kernel("math_probe", spv, &bindings, &[], 32).expect("kernel");
    let inb = ctx.upload_storage("probe_in", bytemuck::cast_slice(&input)).expect("in");
    let out = ctx.create_buffer("probe_out", (expected.len() * 4) as u64, BufferKind::Storage).expect("out");
    ctx.bind(&mut k, BINDING_ACCEL_NODES, &inb).expect("bind");
    ctx.bind(&mut k, BINDING_ACCEL_INDICES, &out).expect("bind");
    let push: [u32; 8] = [0, records as u32, 0, 0, 0, 0, 0, 0];
    ctx.dispatch(&k, bytemuck::cast_slice(&push), [(records as u32).div_ceil(64), 1, 1], "math probe")
        .expect("dispatch");
    ctx.check_validation().expect("no validation errors");
    let back = ctx.read_storage(&out, 0, (expected.len() * 4) as u64).expect("read");
    let got: &[f32] = bytemuck::cast_slice(&back);
    let names = ["p.x", "p.y", "p.z", "err.x", "err.y", "err.z", "o.x", "o.y", "o.z", "edge", "up", "down"];
    for (i, (g, e)) in got.iter().zip(&expected).enumerate() {
        assert_eq!(g.to_bits(), e.to_bits(), "record {} {}: GPU {g:e} vs CPU {e:e}", i / 12, names[i % 12]);
    }
}

#[test]
fn tiny_far_and_huge_near_spheres_are_hit() {
    // A sphere of radius 1e-6 seen from 1e3 away, and one of radius 1e6 seen from 1
    // unit off its surface: rays at the centre hit at the right distance, rays just
    // past the silhouette miss.
    let cases = [(Vec3::new(0.0, 0.0, -1e3), 1e-6f32), (Vec3::new(0.0, 0.0, -(1e6 + 1.0)), 1e6)];
    let ctx = common::gpu();
    for (centre, radius) in cases {
        let mut b = SceneBuilder::new("sphere");
        b.scene.spheres.push(Sphere { center: centre, radius, material: 0 });
        b.scene.lights.push(Light::Directional { direction: Vec3::NEG_Z, radiance: Vec3::ONE });
        // A narrow camera that sees the sphere's edge: vfov spans 4 radii at the front.
        let front = -centre.z - radius;
        let half = (2.0 * radius / front).atan().to_degrees().min(80.0);
        b.scene.camera = Camera { eye: Vec3::ZERO, look_at: Vec3::NEG_Z, up: Vec3::Y, vfov: 2.0 * half };
        let scene = b.finish().expect("scene");
        for &kind in AccelKind::ALL {
            let accel = Accel::build(kind, &scene);
            let at = Ray { origin: Vec3::ZERO, dir: Vec3::NEG_Z, tmin: 0.0, tmax: f32::INFINITY };
            let h = accel.intersect(&scene, &at).unwrap_or_else(|| panic!("r {radius} {kind}: centre ray missed"));
            assert!((h.t - front).abs() <= front * 1e-5, "r {radius} {kind}: t {} vs {front}", h.t);
            let off = (2.0 * radius / front).atan();
            let past = Ray { dir: Vec3::new(off.sin(), 0.0, -off.cos()), ..at };
            assert!(accel.intersect(&scene, &past).is_none(), "r {radius} {kind}: ray past the edge hit");
            if let Some(ctx) = &ctx {
                let f = render(ctx, &scene, kind, 33, 33, false);
                let centre_px = 16 * 33 + 16;
                assert_eq!(f.prim[centre_px], 0, "r {radius} {kind}: GPU centre pixel");
                assert!(
                    (f.depth[centre_px] - front).abs() <= front * 1e-5,
                    "r {radius} {kind}: depth {}",
                    f.depth[centre_px]
                );
                let hits = f.prim.iter().filter(|&&p| p == 0).count();
                if radius < 1.0 {
                    // The disc spans half the image height: about pi/16 of the pixels.
                    assert!(hits > 100 && hits < 400, "r {radius} {kind}: {hits} pixels hit");
                } else {
                    // From 1 unit off its surface the sphere fills the 160-degree view.
                    assert_eq!(hits, f.prim.len(), "r {radius} {kind}");
                }
            }
        }
    }
}
