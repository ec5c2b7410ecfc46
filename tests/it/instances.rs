//! Instancing: `[[instance]]` tables, two-level structures of every kind, and the
//! instanced trace kernels. Instances must hit exactly where their flattened copies
//! do (primitive and depth AOVs against the CPU reference of the flattened scene),
//! shade like them (no self-intersection from the transform), and scenes without
//! instances must not change.

use crate::common;

use arbor::accel::{Accel, AccelKind, Geometry, KernelFamily, Traverse};
use arbor::math::{Hit, Ray};
use arbor::render::{cpu, gpu, Integrator, RenderSettings};
use arbor::scene::{procedural, Light, Scene, SceneBuilder, Sphere};
use glam::{Affine3A, Quat, Vec3};

/// A ground quad and a sphere of the scene's own, and 12 instances of a blob under
/// rotations, non-uniform and mirroring scales and translations.
pub(crate) fn scene(blob_tris: usize, grid: i32) -> Scene {
    let mut b = SceneBuilder::new("instances");
    let ground = procedural::quad([
        Vec3::new(-20.0, -1.5, -20.0),
        Vec3::new(20.0, -1.5, -20.0),
        Vec3::new(20.0, -1.5, 20.0),
        Vec3::new(-20.0, -1.5, 20.0),
    ]);
    b.mesh(&ground, 1.0, Vec3::ZERO, None);
    b.scene.spheres.push(Sphere { center: Vec3::new(0.0, 2.2, 0.0), radius: 0.6, material: 0 });
    let p = b.prototype("blob", &procedural::blob(blob_tris, 0.3, 7), &Affine3A::IDENTITY, None);
    let mut k = 0;
    for x in -grid..=grid {
        for z in -grid..=grid {
            k += 1;
            let s = match k % 4 {
                0 => Vec3::splat(0.5),
                1 => Vec3::new(0.6, 0.35, 0.45),
                2 => Vec3::new(-0.5, 0.5, 0.5), // mirrored
                _ => Vec3::new(0.3, 0.55, 0.3),
            };
            let r = Quat::from_axis_angle(Vec3::new(0.2, 1.0, 0.4).normalize(), k as f32 * 0.7);
            let t = Vec3::new(x as f32 * 1.4, 0.15 * (k % 3) as f32, z as f32 * 1.4);
            b.instance(p, Affine3A::from_scale_rotation_translation(s, r, t));
        }
    }
    b.scene.lights.push(Light::Directional { direction: Vec3::new(-0.3, -1.0, -0.5), radiance: Vec3::ONE });
    b.scene.camera.eye = Vec3::new(0.5, 4.0, 6.5);
    b.scene.camera.look_at = Vec3::new(0.0, 0.0, 0.0);
    b.finish().expect("valid scene")
}

#[test]
fn flattening_places_every_copy_in_instance_order() {
    let s = scene(200, 1);
    let f = s.flattened().expect("flattened");
    let inst = s.instancing.as_ref().expect("instancing");
    let proto = &inst.prototypes[0].geometry;
    assert_eq!(f.triangles.len() as u64, s.drawn_triangles());
    assert_eq!(f.triangles.len(), 2 + 9 * proto.triangles.len());
    assert!(f.instancing.is_none());
    // Copy k's first triangle is the prototype's transformed (winding reversed where mirrored).
    for (k, i) in inst.instances.iter().enumerate() {
        let t = f.triangles[2 + k * proto.triangles.len()];
        let mut want = proto.triangles[0].map(|v| i.transform.transform_point3(proto.positions[v as usize]));
        if i.transform.matrix3.determinant() < 0.0 {
            want.swap(1, 2);
        }
        for (a, b) in t.map(|v| f.positions[v as usize]).iter().zip(want) {
            assert!((*a - b).length() < 1e-5, "copy {k}: {a} vs {b}");
        }
    }
    assert_eq!(s.bounds(), f.bounds(), "the instanced scene's box is its flattened copy's box");
}

/// CPU traversal of the two-level structure against brute force over the flattened
/// scene: the same primitive (the flattened numbering) and depth for random rays.
#[test]
fn two_level_cpu_traversal_matches_brute_force_on_the_copies() {
    let s = scene(300, 1);
    let f = s.flattened().expect("flattened");
    let brute = Accel::build(AccelKind::None, &f);
    let mut rng = common::scenes::Rng(11);
    for kind in AccelKind::ALL.iter().copied().filter(|k| !k.is_brute_force()) {
        let two = Accel::build(kind, &s);
        assert!(matches!(two, Accel::TwoLevel(_)), "{kind}");
        two.validate(&s).unwrap_or_else(|e| panic!("{kind}: {e}"));
        let (mut same, mut hits) = (0, 0);
        for _ in 0..3000 {
            let origin = Vec3::new(rng.range(-5.0, 5.0), rng.range(-1.0, 4.0), rng.range(-5.0, 5.0));
            let target = Vec3::new(rng.range(-3.0, 3.0), rng.range(-1.0, 1.5), rng.range(-3.0, 3.0));
            let ray = Ray { origin, dir: (target - origin).normalize(), tmin: 0.0, tmax: f32::INFINITY };
            let a = two.intersect(&s, &ray);
            let b = brute.intersect(&f, &ray);
            assert_eq!(a.is_some(), b.is_some(), "{kind}: hit or miss differs for {ray:?}");
            if let (Some(a), Some(b)) = (a, b) {
                hits += 1;
                // Moving the origin into instance space rounds it: an absolute error
                // of a few ulps of its coordinates, besides the relative one.
                let tol = 1e-5 * b.t + 1e-6 * (1.0 + origin.abs().max_element());
                assert!((a.t - b.t).abs() <= tol, "{kind}: t {} vs {}", a.t, b.t);
                same += usize::from(a.prim == b.prim);
            }
            assert_eq!(two.occluded(&s, &ray), brute.occluded(&f, &ray), "{kind}: occlusion differs");
        }
        // A ray through a shared edge may report either triangle in instance space.
        assert!(hits > 1500 && same * 1000 >= hits * 998, "{kind}: {same} of {hits} hits on the same primitive");
    }
    let _ = Hit::none(1.0);
}

/// Every structure's instanced kernel against the CPU reference of the flattened
/// scene: primitive and depth AOVs, pixel by pixel.
#[test]
fn instances_hit_where_their_flattened_copies_do_on_the_gpu() {
    let Some(ctx) = common::gpu() else { return };
    let s = scene(600, 1);
    let f = s.flattened().expect("flattened");
    let (w, h) = (96, 72);
    let reference = cpu::reference_aovs(&f, w, h);
    for kind in AccelKind::ALL.iter().copied().filter(|k| !k.is_brute_force()) {
        let mut settings = RenderSettings::for_size(w, h);
        settings.accel = kind;
        settings.primary_only = true;
        let (g, st) = gpu::render(&ctx, &s, &settings, |_, _| {}).expect("render");
        ctx.check_validation().expect("no validation errors");
        assert!(st.kernel.starts_with("trace_inst_"), "{kind}: kernel {}", st.kernel);
        let mut differ = 0;
        for i in 0..g.prim.len() {
            if g.prim[i] != reference.prim[i] {
                differ += 1;
                continue;
            }
            let (a, b) = (g.depth[i], reference.depth[i]);
            assert!(a == b || (a - b).abs() <= 2e-5 * b.abs(), "{kind}: pixel {i} depth {a} vs {b}");
        }
        eprintln!("{kind}: {differ} of {} pixels name another primitive", g.prim.len());
        // Only pixels on shared edges may name the neighbouring triangle.
        assert!(differ * 1000 <= g.prim.len(), "{kind}: {differ} of {} pixels differ", g.prim.len());
        assert!(g.prim.iter().any(|&p| (2..2 + 9 * 600).contains(&p)), "{kind}: no instance was hit");
    }
}

/// Shading: the path-traced image of the instanced scene is that of its flattened
/// copy (same seed), so the transformed hit points, normals and spawn offsets agree;
/// self-intersection would darken the instanced one.
#[test]
fn instances_shade_like_their_flattened_copies() {
    let Some(ctx) = common::gpu() else { return };
    let s = scene(400, 1);
    let f = s.flattened().expect("flattened");
    let mut settings = RenderSettings::for_size(80, 60);
    settings.accel = AccelKind::BvhSah;
    settings.integrator = Integrator::Path;
    settings.spp = 4;
    let (a, _) = gpu::render(&ctx, &s, &settings, |_, _| {}).expect("instanced");
    let (b, st) = gpu::render(&ctx, &f, &settings, |_, _| {}).expect("flattened");
    ctx.check_validation().expect("no validation errors");
    assert!(!st.kernel.contains("inst"), "the flattened scene runs no instance code: {}", st.kernel);
    let lum = |c: &[f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let (ma, mb) = (
        a.radiance.iter().map(lum).sum::<f32>() / a.radiance.len() as f32,
        b.radiance.iter().map(lum).sum::<f32>() / b.radiance.len() as f32,
    );
    assert!((ma - mb).abs() <= 0.01 * mb, "mean luminance {ma} vs {mb}");
    let far = a.radiance.iter().zip(&b.radiance).filter(|(x, y)| (lum(x) - lum(y)).abs() > 0.05).count();
    assert!(far * 100 <= a.radiance.len(), "{far} of {} pixels differ by more than 0.05", a.radiance.len());
    for (x, y) in a.normal.iter().zip(&b.normal).filter(|(x, _)| x.iter().any(|v| *v != 0.0)) {
        // Under a non-uniform scale, interpolating transformed unit normals (the copy)
        // and transforming the interpolated one (the instance) differ slightly.
        let d = Vec3::from(*x).dot(Vec3::from(*y));
        assert!(d > 0.99 || Vec3::from(*y) == Vec3::ZERO, "normals {x:?} vs {y:?}");
    }
}

/// A scene without instances keeps its kernels and buffers; the instanced kernels
/// stay within the 8 storage buffers of a stage.
#[test]
fn instancing_binds_no_more_than_eight_buffers_and_costs_plain_scenes_nothing() {
    for family in KernelFamily::EVERY.into_iter().filter_map(KernelFamily::instanced) {
        for geometry in [Geometry::Tris, Geometry::All] {
            let b = gpu::trace_bindings(family, geometry);
            let storage = b.iter().filter(|d| d.kind != arbor::gpu::BindingKind::Uniform).count();
            assert!(storage <= 8, "{family}_{geometry}: {storage} buffers");
        }
    }
    let plain = Scene::load("builtin:cornell").expect("cornell");
    assert!(!plain.has_instances());
    let a = Accel::build(AccelKind::BvhSah, &plain);
    assert!(matches!(a, Accel::Bvh(_)));
    assert_eq!(a.gpu_image(&plain).expect("image").family, KernelFamily::Bvh);
}

fn load_toml(text: &str) -> arbor::error::Result<Scene> {
    let dir = tempfile::tempdir().expect("tempdir");
    let tetra = "v 1 1 1\nv 1 -1 -1\nv -1 1 -1\nv -1 -1 1\nf 1 2 3\nf 1 4 2\nf 1 3 4\nf 2 4 3\n";
    std::fs::write(dir.path().join("t.obj"), tetra).expect("obj");
    let path = dir.path().join("s.toml");
    std::fs::write(&path, text).expect("toml");
    Scene::load(&path.display().to_string())
}

#[test]
fn scene_files_declare_instances_and_bad_ones_get_one_line() {
    let ok = load_toml(
        "[[mesh]]\nfile = \"t.obj\"\nname = \"t\"\ninstanced = true\n\
         [[instance]]\nmesh = \"t\"\ntranslate = [3, 0, 0]\n\
         [[instance]]\nmesh = \"t\"\nrotate = [0, 1, 0, 90]\nscale = [1, 2, 1]\n\
         [[instance]]\nmesh = \"t\"\nmatrix = [1, 0, 0, 0,  0, 1, 0, 5,  0, 0, 1, 0,  0, 0, 0, 1]\n",
    )
    .expect("scene");
    assert!(ok.triangles.is_empty(), "an instanced mesh is not drawn itself");
    assert_eq!(ok.drawn_triangles(), 12);
    let inst = ok.instancing.as_ref().expect("instancing");
    assert_eq!(inst.instances.len(), 3);
    assert_eq!(inst.instances[2].transform.translation, Vec3::new(0.0, 5.0, 0.0).into());
    // A named mesh without `instanced` is drawn once, as before.
    let drawn = load_toml("[[mesh]]\nfile = \"t.obj\"\nname = \"t\"\n").expect("scene");
    assert_eq!((drawn.triangles.len(), drawn.has_instances()), (4, false));
    // An instanced mesh that no instance draws is dropped; the rest renders as before.
    let unused = load_toml("[[mesh]]\nfile = \"t.obj\"\nname = \"t\"\ninstanced = true\n[[mesh]]\nfile = \"t.obj\"\n")
        .expect("scene");
    assert!(unused.instancing.is_none() && unused.stored_triangles() == 4);
    let only_unused = load_toml("[[mesh]]\nfile = \"t.obj\"\nname = \"t\"\ninstanced = true\n");
    assert!(only_unused.expect_err("empty").to_string().contains("empty"));

    let cases = [
        ("[[mesh]]\nfile = \"t.obj\"\ninstanced = true\n", 1, "needs a name"),
        ("[[mesh]]\nfile = \"t.obj\"\nname = \"t\"\n[[instance]]\nmesh = \"t\"\n", 4, "give it instanced = true"),
        ("[[mesh]]\nfile = \"t.obj\"\nname = \"t\"\ninstanced = true\n\n[[instance]]\nmesh = \"u\"\n", 6, "no [[mesh]] is named 'u'"),
        ("[[mesh]]\nfile = \"t.obj\"\nname = \"t\"\n[[mesh]]\nfile = \"t.obj\"\nname = \"t\"\n", 4, "used twice"),
        (
            "[[mesh]]\nfile = \"t.obj\"\nname = \"t\"\ninstanced = true\n[[instance]]\nmesh = \"t\"\nscale = [1, 0, 1]\n",
            5,
            "singular",
        ),
        (
            "[[mesh]]\nfile = \"t.obj\"\nname = \"t\"\ninstanced = true\n[[instance]]\nmesh = \"t\"\nmatrix = [1, 0]\n",
            5,
            "16 numbers",
        ),
        (
            "[[mesh]]\nfile = \"t.obj\"\nname = \"t\"\ninstanced = true\n[[instance]]\nmesh = \"t\"\ncolour = 1\n",
            7,
            "unknown field",
        ),
    ];
    for (text, line, want) in cases {
        let e = load_toml(text).expect_err(want).to_string();
        assert!(e.contains(want) && e.contains(&format!("s.toml:{line}")) && !e.contains('\n'), "{want}: {e}");
    }
    let e = load_toml(
        "[[material]]\nname = \"lamp\"\ntype = \"emissive\"\n\
         [[mesh]]\nfile = \"t.obj\"\nname = \"t\"\ninstanced = true\nmaterial = \"lamp\"\n[[instance]]\nmesh = \"t\"\n",
    )
    .expect_err("emissive")
    .to_string();
    assert!(e.contains("instances cannot be lights"), "{e}");
}

/// Scale: 10,000 instances of an 80,000-triangle mesh (800 million triangles drawn)
/// build and render on lavapipe within its 128 MiB buffers, storing the mesh once.
#[test]
fn ten_thousand_instances_of_an_80k_mesh_fit() {
    let mut b = SceneBuilder::new("forest");
    let p = b.prototype("blob", &procedural::blob(81_000, 0.3, 3), &Affine3A::IDENTITY, None);
    for k in 0..10_000 {
        let (x, z) = ((k % 100) as f32, (k / 100) as f32);
        let r = Quat::from_rotation_y(k as f32);
        b.instance(p, Affine3A::from_scale_rotation_translation(Vec3::splat(0.45), r, Vec3::new(x, 0.0, z)));
    }
    b.scene.lights.push(Light::Directional { direction: Vec3::new(-0.3, -1.0, -0.5), radiance: Vec3::ONE });
    b.scene.camera.eye = Vec3::new(-10.0, 15.0, -10.0);
    b.scene.camera.look_at = Vec3::new(50.0, 0.0, 50.0);
    let s = b.finish().expect("scene");
    let tris = s.instancing.as_ref().unwrap().prototypes[0].geometry.triangles.len() as u64;
    assert!(tris >= 80_000);
    assert_eq!(s.drawn_triangles(), 10_000 * tris);
    let a = Accel::build(AccelKind::BvhSah, &s);
    let st = a.stats(&s);
    let l = st.levels.clone().expect("levels");
    assert_eq!((l.instances, l.unique_triangles, l.instanced_triangles), (10_000, tris, 10_000 * tris));
    // One mesh's structure plus a small cost per instance.
    assert!(l.top_bytes + l.record_bytes < 300 * 10_000, "{l:?}");
    assert!(st.bytes < 32 << 20, "{} bytes", st.bytes);
    // `--accel auto` weighs builds by the triangles stored and rays by those drawn:
    // brute force over 800 million triangles is never the pick.
    let (auto, why) = arbor::accel::auto::choose(&s, 512 * 512, 1);
    assert!(!auto.is_brute_force(), "{why}");
    let Some(ctx) = common::gpu() else { return };
    let mut settings = RenderSettings::for_size(64, 48);
    settings.accel = AccelKind::BvhSah;
    settings.primary_only = true;
    let (g, _) = gpu::render_with(&ctx, &s, &settings, &a, |_, _| {}).expect("render");
    ctx.check_validation().expect("no validation errors");
    let hits = g.prim.iter().filter(|&&p| p != u32::MAX).count();
    assert!(hits > g.prim.len() / 4, "{hits} hits");
    assert!(g.prim.iter().all(|&p| p == u32::MAX || u64::from(p) < s.drawn_triangles()));
}

/// Render-farm parts of instanced scenes: moving one instance, or changing the
/// prototype's geometry, changes the settings hash that `arbor merge` checks.
#[test]
fn the_part_hash_sees_instances_and_prototypes() {
    let s = scene(200, 1);
    let settings = RenderSettings::for_size(32, 24);
    let base = arbor::render::output::part::settings_hash(&s, &settings);
    assert_eq!(base, arbor::render::output::part::settings_hash(&s.clone(), &settings));
    let mut moved = s.clone();
    moved.instancing.as_mut().unwrap().instances[3].transform.translation.x += 0.5;
    assert_ne!(base, arbor::render::output::part::settings_hash(&moved, &settings));
    let mut reshaped = s.clone();
    reshaped.instancing.as_mut().unwrap().prototypes[0].geometry.positions[5].y += 0.01;
    assert_ne!(base, arbor::render::output::part::settings_hash(&reshaped, &settings));
}
