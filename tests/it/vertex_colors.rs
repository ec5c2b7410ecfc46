//! Vertex colours (glTF's COLOR_0, PLY's red/green/blue; docs/materials.md, "Vertex
//! colours"): a triangle with red, green and blue corners shows its interpolated
//! colours in every integrator; a colour on the vertices renders as the same colour in
//! the material would (SPPM's photons included); a vertex alpha cuts a masked quad on
//! the device as on the CPU; the loaders read every encoding.

use crate::common;

use arbor::accel::{Accel, AccelKind};
use arbor::math::Ray;
use arbor::render::integrators::sppm::{PhotonMap, SppmSettings};
use arbor::render::{gpu, Frame, Integrator, RenderSettings};
use arbor::scene::{load_mesh, Scene};
use glam::{Vec3, Vec4};

/// An ASCII PLY of `positions` with float colours `colors` (RGBA, linear) or none, and
/// the faces `faces`.
fn ply(positions: &[Vec3], colors: Option<&[Vec4]>, faces: &[&[u32]]) -> String {
    let mut s = format!("ply\nformat ascii 1.0\nelement vertex {}\n", positions.len());
    s += "property float x\nproperty float y\nproperty float z\n";
    if colors.is_some() {
        s += "property float red\nproperty float green\nproperty float blue\nproperty float alpha\n";
    }
    s += &format!("element face {}\nproperty list uchar int vertex_indices\nend_header\n", faces.len());
    for (k, p) in positions.iter().enumerate() {
        s += &format!("{} {} {}", p.x, p.y, p.z);
        if let Some(c) = colors {
            s += &format!(" {} {} {} {}", c[k].x, c[k].y, c[k].z, c[k].w);
        }
        s += "\n";
    }
    for f in faces {
        s += &format!("{} {}\n", f.len(), f.iter().map(u32::to_string).collect::<Vec<_>>().join(" "));
    }
    s
}

fn load(dir: &std::path::Path, name: &str, toml: &str) -> Scene {
    let path = dir.join(name);
    std::fs::write(&path, toml).expect("toml");
    Scene::load(&path.display().to_string()).expect("scene")
}

fn render(ctx: &arbor::gpu::Context, scene: &Scene, integrator: Integrator, w: u32, h: u32, spp: u32) -> Frame {
    let mut s = RenderSettings::for_size(w, h);
    s.integrator = integrator;
    s.accel = AccelKind::BvhSah;
    s.seed = 3;
    s.spp = spp;
    s.sppm = SppmSettings { photons: Some(20_000), radius: None, map: PhotonMap::Hashgrid };
    let (f, _) = gpu::render(ctx, scene, &s, |_, _| {}).expect("render");
    ctx.check_validation().expect("no validation errors");
    f
}

const CORNERS: [Vec3; 3] = [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];

/// The barycentric weights of `p` (in the triangle's plane) for [`CORNERS`].
fn weights(p: Vec3) -> Vec3 {
    let [a, b, c] = CORNERS;
    let area = |x: Vec3, y: Vec3, z: Vec3| (y - x).cross(z - x).z;
    let full = area(a, b, c);
    Vec3::new(area(p, b, c) / full, area(a, p, c) / full, area(a, b, p) / full)
}

/// A white triangle with red, green and blue corners, lit from the camera, at one
/// sample: in Whitted, path and SPPM every pixel's albedo is the colours interpolated
/// at its hit point (Whitted's ray goes through the pixel's centre, the others' within
/// the pixel), and its radiance is the uncoloured triangle's times that colour. Near
/// each corner that corner's channel leads.
#[test]
fn a_triangle_with_red_green_and_blue_corners_shows_its_interpolated_colours() {
    let Some(ctx) = common::gpu() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let rgb = [Vec4::new(1.0, 0.0, 0.0, 1.0), Vec4::new(0.0, 1.0, 0.0, 1.0), Vec4::new(0.0, 0.0, 1.0, 1.0)];
    std::fs::write(dir.path().join("rgb.ply"), ply(&CORNERS, Some(&rgb), &[&[0, 1, 2]])).expect("ply");
    std::fs::write(dir.path().join("plain.ply"), ply(&CORNERS, None, &[&[0, 1, 2]])).expect("ply");
    let scene = |mesh: &str| {
        load(
            dir.path(),
            "tri.toml",
            &format!(
                "[camera]\neye = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 50.0\n\
                 [render]\nbackground = [0.0, 0.0, 0.0]\nambient = 0.0\n\
                 [[mesh]]\nfile = \"{mesh}\"\nmaterial = \"white\"\n\
                 [[material]]\nname = \"white\"\ntype = \"lambert\"\ncolor = [0.9, 0.9, 0.9]\n\
                 [[light]]\ntype = \"point\"\nposition = [0.0, 0.0, 3.0]\nintensity = [9.0, 9.0, 9.0]\n"
            ),
        )
    };
    let (coloured, plain) = (scene("rgb.ply"), scene("plain.ply"));
    assert!(coloured.has_vertex_colors() && !plain.has_vertex_colors());
    let (w, h) = (48, 48);
    let basis = coloured.camera.basis(w, h);
    for (integrator, within) in [(Integrator::Whitted, 2e-3), (Integrator::Path, 0.06), (Integrator::Sppm, 0.06)] {
        let fc = render(&ctx, &coloured, integrator, w, h, 1);
        let fp = render(&ctx, &plain, integrator, w, h, 1);
        let mut on = 0;
        let mut lead = [0usize; 3];
        for k in 0..fc.prim.len() {
            if fc.prim[k] == u32::MAX {
                continue;
            }
            on += 1;
            let (i, j) = ((k % w as usize) as u32, (k / w as usize) as u32);
            let b = weights(basis.eye + basis.ray_dir(i, j, 0.5, 0.5, w, h) * fc.depth[k]);
            let tint = Vec3::from(fc.albedo[k]) / 0.9;
            assert!((tint - b).abs().max_element() < within, "{integrator:?} pixel {k}: colour {tint} at {b}");
            let (rc, rp) = (Vec3::from(fc.radiance[k]), Vec3::from(fp.radiance[k]));
            assert!(
                (rc - rp * tint).abs().max_element() <= 2e-3 * rp.max_element() + 1e-6,
                "{integrator:?} pixel {k}: {rc} against the plain triangle's {rp} times {tint}"
            );
            if b.max_element() > 0.8 {
                lead[b.max_position()] += usize::from(rc.max_position() == b.max_position());
            }
        }
        assert!(on > 500, "{integrator:?}: {on} pixels on the triangle");
        assert!(lead.iter().all(|&n| n > 3), "{integrator:?}: each corner's colour leads near it: {lead:?}");
    }
}

/// A box on a floor and a back wall under a point light, the floor `pbr` (its visible
/// points are not Lambert, so SPPM keeps their colour in the record): a colour on the
/// floor's vertices renders as the same colour in the floor's material, in path and
/// SPPM, to within the colour's 16-bit rounding.
#[test]
fn a_colour_on_the_vertices_renders_as_the_same_colour_in_the_material() {
    let Some(ctx) = common::gpu() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let c = Vec4::new(1.0, 0.25, 0.125, 1.0);
    let floor =
        [Vec3::new(-2.0, 0.0, -2.0), Vec3::new(2.0, 0.0, -2.0), Vec3::new(2.0, 0.0, 2.0), Vec3::new(-2.0, 0.0, 2.0)];
    std::fs::write(dir.path().join("floor.ply"), ply(&floor, Some(&[c; 4]), &[&[0, 3, 2, 1]])).expect("ply");
    std::fs::write(dir.path().join("plain.ply"), ply(&floor, None, &[&[0, 3, 2, 1]])).expect("ply");
    let wall =
        [Vec3::new(-2.0, 0.0, -2.0), Vec3::new(2.0, 0.0, -2.0), Vec3::new(2.0, 3.0, -2.0), Vec3::new(-2.0, 3.0, -2.0)];
    std::fs::write(dir.path().join("wall.ply"), ply(&wall, None, &[&[0, 1, 2, 3]])).expect("ply");
    let scene = |mesh: &str, color: Vec4| {
        load(
            dir.path(),
            "room.toml",
            &format!(
                "[camera]\neye = [0.0, 2.0, 5.0]\nlook_at = [0.0, 0.5, 0.0]\nvfov = 50.0\n\
                 [render]\nbackground = [0.0, 0.0, 0.0]\n\
                 [[mesh]]\nfile = \"{mesh}\"\nmaterial = \"floor\"\n\
                 [[mesh]]\nfile = \"wall.ply\"\nmaterial = \"wall\"\n\
                 [[sphere]]\ncenter = [0.0, 0.6, 0.0]\nradius = 0.6\nmaterial = \"wall\"\n\
                 [[material]]\nname = \"floor\"\ntype = \"pbr\"\ncolor = [{}, {}, {}]\nroughness = 0.7\nmetallic = 0.0\n\
                 [[material]]\nname = \"wall\"\ntype = \"lambert\"\ncolor = [0.8, 0.8, 0.8]\n\
                 [[light]]\ntype = \"point\"\nposition = [0.0, 2.5, 1.0]\nintensity = [20.0, 20.0, 20.0]\n",
                color.x, color.y, color.z
            ),
        )
    };
    let by_vertex = scene("floor.ply", Vec4::ONE);
    let by_material = scene("plain.ply", c);
    let (w, h) = (40, 32);
    for integrator in [Integrator::Path, Integrator::Sppm] {
        let (a, b) = (render(&ctx, &by_vertex, integrator, w, h, 2), render(&ctx, &by_material, integrator, w, h, 2));
        assert_eq!(a.prim, b.prim, "{integrator:?}: the same hits");
        let total: f64 = b.radiance.iter().flatten().map(|&x| f64::from(x)).sum();
        let diff: f64 =
            a.radiance.iter().flatten().zip(b.radiance.iter().flatten()).map(|(x, y)| f64::from((x - y).abs())).sum();
        assert!(
            total > 0.0 && diff / total < 1e-3,
            "{integrator:?}: images differ by {:.2e} of the total",
            diff / total
        );
    }
}

/// A masked quad whose vertices' alpha goes from 0 on the left to 1 on the right
/// (cutoff 0.5): rays pass its left half, and the device's hits equal the CPU
/// reference's in every structure.
#[test]
fn a_vertex_alpha_cuts_a_masked_quad_on_the_device_as_on_the_cpu() {
    let Some(ctx) = common::gpu() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let quad =
        [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0)];
    let alpha = |a: f32| Vec4::new(0.5, 0.8, 0.3, a);
    std::fs::write(
        dir.path().join("quad.ply"),
        ply(&quad, Some(&[alpha(0.0), alpha(1.0), alpha(1.0), alpha(0.0)]), &[&[0, 1, 2, 3]]),
    )
    .expect("ply");
    std::fs::write(dir.path().join("wall.ply"), ply(&quad.map(|p| p * 2.0 - Vec3::Z), None, &[&[0, 1, 2, 3]]))
        .expect("ply");
    let scene = load(
        dir.path(),
        "cut.toml",
        "[[mesh]]\nfile = \"quad.ply\"\nmaterial = \"cut\"\n\
         [[mesh]]\nfile = \"wall.ply\"\nmaterial = \"wall\"\n\
         [[material]]\nname = \"cut\"\ntype = \"lambert\"\nalpha_mode = \"mask\"\nalpha_cutoff = 0.5\n\
         [[material]]\nname = \"wall\"\ntype = \"lambert\"\n",
    );
    let mut rng = common::scenes::Rng(0x2545_f491_4f6c_dd1d);
    let rays: Vec<Ray> = (0..3000)
        .map(|_| {
            let o = Vec3::new(rng.range(-1.2, 1.2), rng.range(-1.2, 1.2), 2.0);
            Ray {
                origin: o,
                dir: Vec3::new(rng.range(-0.05, 0.05), rng.range(-0.05, 0.05), -1.0).normalize(),
                tmin: 0.0,
                tmax: f32::INFINITY,
            }
        })
        .collect();
    let cpu = Accel::build(AccelKind::BvhSah, &scene).trace_cpu(&scene, &rays);
    // Rays that cross the quad: those on its right half meet it, the others pass.
    let (mut met, mut passed) = (0, 0);
    for (r, c) in rays.iter().zip(&cpu) {
        let p = r.origin + r.dir * (-r.origin.z / r.dir.z);
        if p.x.abs() < 0.95 && p.y.abs() < 0.95 && (p.x.abs() > 0.05) {
            let on_quad = c.is_some_and(|h| h.prim < 2);
            assert_eq!(on_quad, p.x > 0.0, "the cut at x = 0: ray through {p}");
            met += usize::from(on_quad);
            passed += usize::from(!on_quad);
        }
    }
    assert!(met > 500 && passed > 500, "{met} met, {passed} passed");
    crate::alpha::every_kind_hits_as_the_cpu(&ctx, &scene, &rays, &cpu);
}

/// PLY colours: 8-bit channels are sRGB over 255 (alpha linear), floats linear; a
/// colour without alpha is opaque; the `diffuse_` names are read too.
#[test]
fn ply_colours_are_read_in_each_encoding() {
    let dir = tempfile::tempdir().expect("tempdir");
    let head = |props: &str| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n{props}\
             element face 1\nproperty list uchar int vertex_indices\nend_header\n"
        )
    };
    let srgb = |b: u8| arbor::scene::colors::srgb_to_linear(f32::from(b) / 255.0);
    let cases = [
        (
            head("property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n")
                + "0 0 0 255 128 0 64\n1 0 0 0 0 0 255\n0 1 0 10 20 30 0\n3 0 1 2\n",
            [
                Vec4::new(1.0, srgb(128), 0.0, 64.0 / 255.0),
                Vec4::new(0.0, 0.0, 0.0, 1.0),
                Vec4::new(srgb(10), srgb(20), srgb(30), 0.0),
            ],
        ),
        (
            head("property float diffuse_red\nproperty float diffuse_green\nproperty float diffuse_blue\n")
                + "0 0 0 0.5 0.25 2\n1 0 0 0 1 0\n0 1 0 -1 0.125 1\n3 0 1 2\n",
            [Vec4::new(0.5, 0.25, 1.0, 1.0), Vec4::new(0.0, 1.0, 0.0, 1.0), Vec4::new(0.0, 0.125, 1.0, 1.0)],
        ),
    ];
    for (k, (text, want)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("c{k}.ply"));
        std::fs::write(&path, text).expect("ply");
        let colors = load_mesh(&path).expect("loads").colors.expect("colours");
        for (got, want) in colors.iter().zip(want) {
            assert!((*got - *want).abs().max_element() < 1e-6, "case {k}: {got} against {want}");
        }
    }
}

/// OBJ's `v x y z r g b`: the colours are read when every vertex has one (linear,
/// alpha 1, clamped) and dropped, without an error, when only some have one.
#[test]
fn obj_colours_are_read_when_every_vertex_has_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    let all = dir.path().join("all.obj");
    std::fs::write(&all, "v 0 0 0 1 0 0\nv 1 0 0 0 0.5 0\nv 0 1 0 0 0 2\nv 1 1 0 0.25 0.25 0.25\nf 1 2 4 3\n")
        .expect("obj");
    let mesh = load_mesh(&all).expect("loads");
    let colors = mesh.colors.expect("colours");
    // tobj numbers the vertices in the order the faces use them: compare by position.
    let want = |p: Vec3| match [p.x, p.y] {
        [0.0, 0.0] => Vec4::new(1.0, 0.0, 0.0, 1.0),
        [1.0, 0.0] => Vec4::new(0.0, 0.5, 0.0, 1.0),
        [0.0, 1.0] => Vec4::new(0.0, 0.0, 1.0, 1.0),
        _ => Vec4::new(0.25, 0.25, 0.25, 1.0),
    };
    assert_eq!(colors.len(), 4);
    for (p, c) in mesh.positions.iter().zip(&colors) {
        assert_eq!(*c, want(*p), "vertex at {p}");
    }
    let some = dir.path().join("some.obj");
    std::fs::write(&some, "v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0 0 0 1\nf 1 2 3\n").expect("obj");
    let mesh = load_mesh(&some).expect("loads");
    assert_eq!((mesh.colors, mesh.triangles.len()), (None, 1));
}

/// glTF's COLOR_0 as normalized bytes (RGBA), normalized shorts (RGB, strided) and
/// floats (RGBA), one primitive each, all linear; a primitive without COLOR_0 in a mesh
/// with them is white.
#[test]
fn gltf_color_0_is_read_in_each_encoding() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut bin: Vec<u8> = Vec::new();
    for f in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bin.extend_from_slice(&f.to_le_bytes());
    }
    bin.extend_from_slice(&[255, 0, 0, 255, 0, 255, 0, 128, 0, 0, 51, 0]); // 36..48
    for c in [[65535u16, 0, 0, 0], [0, 32768, 0, 0], [0, 0, 65535, 0]] {
        c.iter().for_each(|x| bin.extend_from_slice(&x.to_le_bytes())); // 48..72, stride 8
    }
    for f in [0.5f32, 0.25, 0.125, 1.0, 1.0, 1.0, 1.0, 0.5, 0.0, 0.0, 0.0, 0.0] {
        bin.extend_from_slice(&f.to_le_bytes()); // 72..120
    }
    std::fs::write(dir.path().join("c.bin"), &bin).expect("bin");
    let prim = |color: Option<u32>| match color {
        Some(k) => format!(r#"{{"attributes": {{"POSITION": 0, "COLOR_0": {k}}}}}"#),
        None => r#"{"attributes": {"POSITION": 0}}"#.to_string(),
    };
    let gltf = format!(
        r#"{{
      "asset": {{"version": "2.0"}},
      "scenes": [{{"nodes": [0]}}],
      "nodes": [{{"mesh": 0}}],
      "meshes": [{{"primitives": [{}, {}, {}, {}]}}],
      "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                      "min": [0, 0, 0], "max": [1, 1, 0]}},
                    {{"bufferView": 1, "componentType": 5121, "normalized": true, "count": 3, "type": "VEC4"}},
                    {{"bufferView": 2, "componentType": 5123, "normalized": true, "count": 3, "type": "VEC3"}},
                    {{"bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC4"}}],
      "bufferViews": [{{"buffer": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 12}},
                      {{"buffer": 0, "byteOffset": 48, "byteLength": 24, "byteStride": 8}},
                      {{"buffer": 0, "byteOffset": 72, "byteLength": 48}}],
      "buffers": [{{"byteLength": 120, "uri": "c.bin"}}]
    }}"#,
        prim(Some(1)),
        prim(None),
        prim(Some(2)),
        prim(Some(3))
    );
    let path = dir.path().join("c.gltf");
    std::fs::write(&path, gltf).expect("gltf");
    let s = Scene::load(&path.display().to_string()).expect("loads");
    assert!(s.warnings.iter().all(|w| !w.contains("COLOR_0")), "{:?}", s.warnings);
    let want = [
        [1.0, 0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0, 128.0 / 255.0],
        [0.0, 0.0, 0.2, 0.0],
        [1.0; 4],
        [1.0; 4],
        [1.0; 4],
        [1.0, 0.0, 0.0, 1.0],
        [0.0, 32768.0 / 65535.0, 0.0, 1.0],
        [0.0, 0.0, 1.0, 1.0],
        [0.5, 0.25, 0.125, 1.0],
        [1.0, 1.0, 1.0, 0.5],
        [0.0; 4],
    ];
    assert_eq!(s.colors.len(), want.len());
    for (k, (got, want)) in s.colors.iter().zip(want).enumerate() {
        assert!((*got - Vec4::from(want)).abs().max_element() < 1e-6, "vertex {k}: {got} against {want:?}");
    }
}

/// Instances of a coloured blob over a ground of the scene's own without colours:
/// Whitted's albedo AOV of the instanced scene is that of its flattened copy (the
/// prototype's colours come first in the colour section, as its vertices do), and the
/// ground keeps its material's colour (white vertices).
#[test]
fn instanced_colours_shade_like_their_flattened_copies() {
    use arbor::scene::{procedural, SceneBuilder};
    let Some(ctx) = common::gpu() else { return };
    let mut b = SceneBuilder::new("coloured instances");
    let ground = procedural::quad([
        Vec3::new(-6.0, -1.0, -6.0),
        Vec3::new(6.0, -1.0, -6.0),
        Vec3::new(6.0, -1.0, 6.0),
        Vec3::new(-6.0, -1.0, 6.0),
    ]);
    b.mesh(&ground, 1.0, Vec3::ZERO, None);
    let mut blob = procedural::blob(600, 0.3, 5);
    blob.colors =
        Some(blob.positions.iter().map(|p| (*p * 0.5 + 0.5).clamp(Vec3::ZERO, Vec3::ONE).extend(1.0)).collect());
    let p = b.prototype("blob", &blob, &glam::Affine3A::IDENTITY, None);
    for (k, x) in [-2.5f32, 0.0, 2.5].into_iter().enumerate() {
        let r = glam::Quat::from_rotation_y(k as f32 * 1.1);
        b.instance(p, glam::Affine3A::from_scale_rotation_translation(Vec3::splat(0.9), r, Vec3::new(x, 0.0, 0.0)));
    }
    b.scene
        .lights
        .push(arbor::scene::Light::Directional { direction: Vec3::new(-0.3, -1.0, -0.5), radiance: Vec3::ONE });
    b.scene.camera.eye = Vec3::new(0.0, 3.0, 7.0);
    b.scene.camera.look_at = Vec3::ZERO;
    let s = b.finish().expect("valid scene");
    assert!(s.has_vertex_colors() && s.colors.is_empty(), "the colours are the prototype's");
    let flat = s.flattened().expect("flattened");
    assert_eq!(flat.colors.len(), flat.positions.len());
    let (w, h) = (64, 48);
    let (a, f) = (render(&ctx, &s, Integrator::Whitted, w, h, 1), render(&ctx, &flat, Integrator::Whitted, w, h, 1));
    let (mut blob_pixels, mut ground_pixels) = (0, 0);
    for k in 0..a.prim.len() {
        if a.prim[k] != f.prim[k] || a.prim[k] == u32::MAX {
            continue;
        }
        let (x, y) = (Vec3::from(a.albedo[k]), Vec3::from(f.albedo[k]));
        assert!((x - y).abs().max_element() < 2e-3, "pixel {k}: instanced albedo {x}, flattened {y}");
        if a.prim[k] < 2 {
            ground_pixels += 1;
            assert!((x - Vec3::splat(0.7)).abs().max_element() < 1e-6, "the ground is white-vertexed: {x}");
        } else {
            blob_pixels += 1;
        }
    }
    assert!(blob_pixels > 300 && ground_pixels > 300, "{blob_pixels} blob and {ground_pixels} ground pixels compared");
}
