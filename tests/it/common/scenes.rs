//! Scenes and ray sets shared by the structure tests.

use arbor::accel::none::BruteForce;
use arbor::accel::Traverse;
use arbor::accel::{Accel, KernelFamily};
use arbor::gpu::Context;
use arbor::math::{Aabb, Ray};
use arbor::render::{gpu, Frame, RenderSettings, RenderStats};
use arbor::scene::{procedural, Camera, Light, Material, MaterialKind, MeshData, Scene, SceneBuilder, Sphere};
use glam::Vec3;

/// A tiny deterministic generator (xorshift) so tests need no extra crates.
pub struct Rng(pub u64);
impl Rng {
    pub fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
    pub fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.next()
    }
    pub fn dir(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0));
            if v.length_squared() > 0.01 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }
}

pub fn scene_from(name: &str, mesh: Option<MeshData>, spheres: &[(Vec3, f32)]) -> Scene {
    let mut b = SceneBuilder::new(name);
    if let Some(m) = mesh {
        b.mesh(&m, 1.0, Vec3::ZERO, None);
    }
    for &(c, r) in spheres {
        b.scene.spheres.push(Sphere { center: c, radius: r, material: 0 });
    }
    b.scene.lights.push(Light::Directional { direction: Vec3::NEG_ONE, radiance: Vec3::ONE });
    let mut bounds = Aabb::EMPTY;
    for p in &b.scene.positions {
        bounds.grow(*p);
    }
    for &(c, r) in spheres {
        bounds.grow(c - r);
        bounds.grow(c + r);
    }
    b.scene.camera = arbor::scene::framed_camera(&bounds, 45.0);
    b.finish().expect("valid scene")
}

pub fn tris(list: &[[Vec3; 3]]) -> MeshData {
    let mut m = MeshData::default();
    for t in list {
        let base = m.positions.len() as u32;
        m.positions.extend_from_slice(t);
        m.triangles.push([base, base + 1, base + 2]);
    }
    m
}

/// Edge-case scenes by name.
pub fn edge_cases() -> Vec<Scene> {
    let v = Vec3::new;
    let mut out = Vec::new();
    out.push(scene_from("one triangle", Some(tris(&[[v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)]])), &[]));
    out.push(scene_from("one sphere", None, &[(Vec3::ZERO, 1.0)]));
    let same = [v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)];
    out.push(scene_from("identical", Some(tris(&vec![same; 50])), &[]));
    // All in one plane z = 0: a grid of triangles.
    let mut flat = Vec::new();
    for i in 0..12 {
        for j in 0..12 {
            let (x, y) = (i as f32, j as f32);
            flat.push([v(x, y, 0.), v(x + 1., y, 0.), v(x, y + 1., 0.)]);
            flat.push([v(x + 1., y, 0.), v(x + 1., y + 1., 0.), v(x, y + 1., 0.)]);
        }
    }
    out.push(scene_from("coplanar grid", Some(tris(&flat)), &[]));
    // Axis-aligned quads at integer planes (likely split positions) of a box lattice.
    let mut planes = Vec::new();
    for k in 0..6 {
        let z = k as f32;
        planes.push([v(0., 0., z), v(5., 0., z), v(0., 5., z)]);
        planes.push([v(k as f32, 0., 0.), v(k as f32, 5., 0.), v(k as f32, 0., 5.)]);
    }
    out.push(scene_from("axis planes", Some(tris(&planes)), &[(v(2.5, 2.5, 2.5), 0.5)]));
    // Degenerate triangles among good ones.
    out.push(scene_from(
        "degenerate",
        Some(tris(&[
            [v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)],
            [v(0., 0., 0.), v(0., 0., 0.), v(0., 0., 0.)],
            [v(0., 0., 1.), v(1., 1., 1.), v(2., 2., 1.)],
        ])),
        &[],
    ));
    // Huge and tiny coordinates.
    let mut big = procedural::blob(500, 0.1, 2);
    big.positions.iter_mut().for_each(|p| *p = *p * 1e6 + Vec3::splat(3e6));
    out.push(scene_from("huge", Some(big), &[]));
    let mut tiny = procedural::blob(500, 0.1, 2);
    tiny.positions.iter_mut().for_each(|p| *p *= 1e-5);
    out.push(scene_from("tiny", Some(tiny), &[]));
    out.push(scene_from(
        "blob and spheres",
        Some(procedural::blob(2000, 0.2, 4)),
        &[(v(1.2, 0., 0.), 0.3), (v(0., 0., 0.), 0.5)],
    ));
    out
}

/// The edge cases of the kd-tree tests plus two primitives and a cloud of identical
/// centroids larger than a leaf.
pub fn bvh_cases() -> Vec<Scene> {
    let v = Vec3::new;
    let mut out = edge_cases();
    out.push(scene_from(
        "two",
        Some(tris(&[[v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.)], [v(0., 0., 2.), v(1., 0., 2.), v(0., 1., 2.)]])),
        &[],
    ));
    // 40 triangles with one centroid (every Morton code equal) but different shapes.
    let mut same_centroid = Vec::new();
    for k in 0..40 {
        let s = 0.1 + k as f32 * 0.05;
        same_centroid.push([v(-s, -s, 0.), v(2. * s, -s, 0.), v(-s, 2. * s, 0.)]);
    }
    out.push(scene_from("one centroid", Some(tris(&same_centroid)), &[(Vec3::ZERO, 0.3), (Vec3::ZERO, 0.2)]));
    out
}

/// Random rays from outside and inside plus adversarial ones must find the same
/// primitive as brute force, with t within 1e-6 relative.
pub fn compare_with_brute_force(scene: &Scene, tree: &Accel, n: usize, seed: u64, extra: &[Ray]) {
    let brute = BruteForce::build(scene);
    let b = scene.bounds();
    let c = b.center();
    let r = b.extent().length().max(1e-30);
    let mut rng = Rng(seed | 1);
    let mut rays = Vec::new();
    let verts: Vec<Vec3> = scene.positions.clone();
    for k in 0..n {
        let origin = match k % 4 {
            0 => c + rng.dir() * r * 1.5,                                            // outside
            1 => b.min + b.extent() * Vec3::new(rng.next(), rng.next(), rng.next()), // inside
            2 => Vec3::new(b.min.x + b.extent().x * rng.next(), c.y, c.z) + Vec3::Z * r * 2.0, // in a plane
            _ => c + rng.dir() * r * 0.1,
        };
        let dir = match k % 5 {
            0 => [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z][k % 6], // axis-parallel
            1 if !verts.is_empty() => {
                // At a vertex or along an edge midpoint.
                let v0 = verts[(rng.next() * verts.len() as f32) as usize % verts.len()];
                let v1 = verts[(rng.next() * verts.len() as f32) as usize % verts.len()];
                let target = if k % 2 == 0 { v0 } else { (v0 + v1) * 0.5 };
                (target - origin).try_normalize().unwrap_or(Vec3::X)
            }
            2 => {
                // Grazing: nearly parallel to an axis plane, with -0.0 components.
                let mut d = rng.dir();
                d.z = 1e-7 * d.z.signum();
                d.y = -0.0;
                d.normalize()
            }
            _ => rng.dir(),
        };
        rays.push(Ray { origin, dir, tmin: 0.0, tmax: f32::INFINITY });
    }
    // Rays whose t range is empty.
    rays.push(Ray { origin: c, dir: Vec3::X, tmin: 1.0, tmax: 0.5 });
    rays.extend_from_slice(extra);
    let mut hits = 0;
    for (k, ray) in rays.iter().enumerate() {
        let a = tree.intersect(scene, ray);
        let e = brute.intersect(scene, ray);
        match (a, e) {
            (None, None) => {}
            (Some(a), Some(e)) => {
                hits += 1;
                assert_eq!(
                    a.prim, e.prim,
                    "{}: ray {k} {ray:?}: tree prim {} t {} vs brute prim {} t {}",
                    scene.name, a.prim, a.t, e.prim, e.t
                );
                assert!((a.t - e.t).abs() <= 1e-6 * e.t.abs(), "{}: ray {k}: t {} vs {}", scene.name, a.t, e.t);
            }
            _ => panic!("{}: ray {k} {ray:?}: tree {a:?} vs brute {e:?}", scene.name),
        }
        assert_eq!(tree.occluded(scene, ray), brute.occluded(scene, ray), "{}: occluded ray {k} {ray:?}", scene.name);
    }
    assert!(hits > 0, "{}: no ray hit anything", scene.name);
}

/// The scenes the structures' GPU tests render: a mesh, spheres only, both, and the
/// Cornell box.
pub fn gpu_cases() -> Vec<Scene> {
    let v = Vec3::new;
    vec![
        scene_from("mesh", Some(procedural::blob(5000, 0.25, 11)), &[]),
        scene_from("spheres", None, &[(v(0., 0., 0.), 0.5), (v(1.1, 0.2, 0.), 0.4), (v(-1., -0.3, 0.3), 0.45)]),
        scene_from("both", Some(procedural::blob(3000, 0.2, 12)), &[(v(1.2, 0., 0.3), 0.4), (v(-1.3, 0.2, 0.), 0.5)]),
        Scene::load("builtin:cornell").expect("cornell"),
    ]
}

/// `scene` from two cameras (the origin from the front and from behind), or from its
/// own camera for a built-in scene.
pub fn gpu_views(scene: &Scene) -> Vec<Scene> {
    if scene.name.starts_with("builtin:") {
        return vec![scene.clone()];
    }
    [Vec3::new(0.3, 0.4, 4.0), Vec3::new(-3.0, 1.0, -2.0)]
        .into_iter()
        .map(|eye| {
            let mut s = scene.clone();
            s.camera = Camera { eye, look_at: Vec3::ZERO, up: Vec3::Y, vfov: 50.0 };
            s
        })
        .collect()
}

/// Renders `scene` on the GPU with `settings` and checks every pixel's primitive and
/// depth against the CPU `reference`, no validation error, and the kernel `family`.
pub fn gpu_matches_reference(
    ctx: &Context,
    scene: &Scene,
    settings: &RenderSettings,
    reference: &Frame,
    family: KernelFamily,
    what: &str,
) -> (Frame, RenderStats) {
    let (g, st) = gpu::render(ctx, scene, settings, |_, _| {}).expect("render");
    ctx.check_validation().expect("no validation errors");
    assert_eq!(st.kernel.split('_').nth(1), Some(family.name()), "{what}");
    for i in 0..g.prim.len() {
        assert_eq!(g.prim[i], reference.prim[i], "{what}: pixel {i}");
        let (a, b) = (g.depth[i], reference.depth[i]);
        assert!(a == b || (a - b).abs() <= 1e-5 * b.abs(), "{what}: pixel {i} depth {a} vs {b}");
    }
    (g, st)
}

/// A blob, a ground quad and a few spheres of every material, with two lights, seen from `eye`.
pub fn mixed_scene(eye: Vec3) -> Scene {
    let mut b = SceneBuilder::new("mixed");
    let mirror = b.material(Material { kind: MaterialKind::Mirror, ..Material::lambert("m", Vec3::splat(0.9)) });
    let glass = b.material(Material { kind: MaterialKind::Glass, ..Material::lambert("g", Vec3::ONE) });
    b.mesh(&procedural::blob(3000, 0.15, 5), 0.8, Vec3::new(0.0, 0.2, 0.0), None);
    b.mesh(
        &procedural::quad([
            Vec3::new(-3.0, -0.8, 3.0),
            Vec3::new(3.0, -0.8, 3.0),
            Vec3::new(3.0, -0.8, -3.0),
            Vec3::new(-3.0, -0.8, -3.0),
        ]),
        1.0,
        Vec3::ZERO,
        None,
    );
    b.scene.spheres.push(Sphere { center: Vec3::new(-1.3, -0.4, 0.3), radius: 0.4, material: mirror });
    b.scene.spheres.push(Sphere { center: Vec3::new(1.2, -0.4, 0.5), radius: 0.4, material: glass });
    b.scene.spheres.push(Sphere { center: Vec3::new(0.2, 1.2, -0.8), radius: 0.25, material: 0 });
    b.scene.lights.push(Light::Directional { direction: Vec3::new(-1.0, -1.0, -0.5), radiance: Vec3::splat(2.0) });
    b.scene.lights.push(Light::Point { position: Vec3::new(1.0, 2.0, 2.0), intensity: Vec3::splat(3.0) });
    b.scene.camera = Camera { eye, look_at: Vec3::ZERO, up: Vec3::Y, vfov: 50.0 };
    b.finish().expect("valid scene")
}
