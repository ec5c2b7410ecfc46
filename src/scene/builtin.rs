//! Built-in scenes that need no files.
//!
//! - `default`: a displaced procedural blob of ~100k triangles, a mirror sphere and
//!   a glass sphere on a ground plane, lit by a directional and a point light.
//! - `cornell`: a Cornell box (quads) with a mirror sphere and a glass sphere.
//! - `blob:N`: one blob of about N triangles, auto-framed (benchmarks).
//! - `spheres`: spheres only, no triangles (tests the sphere-only kernel).
//! - `inside:N`: the camera at the centre of a closed blob of about N triangles,
//!   looking out: every camera ray must hit it, so a miss is a crack (robustness).
//! - `stadium:N`: "the teapot in a stadium": a blob of about N triangles and radius 1
//!   inside a coarse blob of 2000 triangles and radius 500, seen from close to the
//!   small one; uniform grids are known to fail here.

use glam::Vec3;

use super::mesh::{Material, MaterialKind};
use super::procedural::{blob, quad};
use super::{framed_camera, Camera, Light, Scene, SceneBuilder, Sphere};
use crate::error::{Error, Result};
use crate::math::Aabb;

/// Names accepted after `builtin:`.
pub const NAMES: &str = "default, cornell, spheres, blob:N, inside:N, stadium:N (N = triangle count)";

fn mat(name: &str, kind: MaterialKind, color: Vec3) -> Material {
    Material { kind, ..Material::lambert(name, color) }
}

/// Loads built-in scene `name`.
pub fn load(name: &str) -> Result<Scene> {
    match name {
        "default" => default_scene(),
        "cornell" => cornell(),
        "spheres" => spheres(),
        _ => {
            if let Some(n) = name.strip_prefix("blob:") {
                let n: usize = n.parse().ok().filter(|&n| (8..=50_000_000).contains(&n)).ok_or_else(|| {
                    Error::scene(format!("builtin:{name}"), "blob:N needs N between 8 and 50000000 triangles")
                })?;
                return blob_scene(n);
            }
            if let Some(n) = name.strip_prefix("inside:") {
                let n: usize = n.parse().ok().filter(|&n| (8..=50_000_000).contains(&n)).ok_or_else(|| {
                    Error::scene(format!("builtin:{name}"), "inside:N needs N between 8 and 50000000 triangles")
                })?;
                return inside_scene(n);
            }
            if let Some(n) = name.strip_prefix("stadium:") {
                let n: usize = n.parse().ok().filter(|&n| (8..=50_000_000).contains(&n)).ok_or_else(|| {
                    Error::scene(format!("builtin:{name}"), "stadium:N needs N between 8 and 50000000 triangles")
                })?;
                return stadium_scene(n);
            }
            Err(Error::scene(format!("builtin:{name}"), format!("unknown built-in scene; known: {NAMES}")))
        }
    }
}

fn default_scene() -> Result<Scene> {
    let mut b = SceneBuilder::new("builtin:default");
    let clay = b.material(Material {
        kind: MaterialKind::Phong,
        specular: Vec3::splat(0.3),
        shininess: 40.0,
        ..Material::lambert("clay", Vec3::new(0.80, 0.45, 0.30))
    });
    let ground = b.material(Material::lambert("ground", Vec3::new(0.55, 0.6, 0.55)));
    let mirror = b.material(mat("mirror", MaterialKind::Mirror, Vec3::splat(0.9)));
    let glass = b.material(Material { ior: 1.5, ..mat("glass", MaterialKind::Glass, Vec3::splat(0.98)) });
    b.mesh(&blob(101_000, 0.12, 3), 0.5, Vec3::new(0.0, 0.55, 0.0), Some(clay));
    let g = 4.0;
    b.mesh(
        &quad([Vec3::new(-g, 0.0, g), Vec3::new(g, 0.0, g), Vec3::new(g, 0.0, -g), Vec3::new(-g, 0.0, -g)]),
        1.0,
        Vec3::ZERO,
        Some(ground),
    );
    b.scene.spheres.push(Sphere { center: Vec3::new(-1.0, 0.35, 0.2), radius: 0.35, material: mirror });
    b.scene.spheres.push(Sphere { center: Vec3::new(0.95, 0.3, 0.45), radius: 0.3, material: glass });
    b.scene.lights.push(Light::Directional { direction: Vec3::new(-0.4, -1.0, -0.5), radiance: Vec3::splat(2.2) });
    b.scene.lights.push(Light::Point { position: Vec3::new(1.5, 2.5, 2.0), intensity: Vec3::new(4.0, 3.6, 3.0) });
    b.scene.camera =
        Camera { eye: Vec3::new(0.0, 1.4, 3.6), look_at: Vec3::new(0.0, 0.45, 0.0), up: Vec3::Y, vfov: 40.0 };
    b.scene.background = Vec3::new(0.55, 0.65, 0.8);
    b.scene.width = 640;
    b.scene.height = 480;
    b.finish()
}

fn cornell() -> Result<Scene> {
    let mut b = SceneBuilder::new("builtin:cornell");
    let white = b.material(Material::lambert("white", Vec3::splat(0.73)));
    let red = b.material(Material::lambert("red", Vec3::new(0.65, 0.05, 0.05)));
    let green = b.material(Material::lambert("green", Vec3::new(0.12, 0.45, 0.15)));
    let light = b.material(Material { emission: Vec3::splat(8.0), ..mat("light", MaterialKind::Emissive, Vec3::ONE) });
    let mirror = b.material(mat("mirror", MaterialKind::Mirror, Vec3::splat(0.95)));
    let glass = b.material(Material { ior: 1.5, ..mat("glass", MaterialKind::Glass, Vec3::ONE) });
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let walls = [
        ([v(-1., 0., 1.), v(1., 0., 1.), v(1., 0., -1.), v(-1., 0., -1.)], white), // floor
        ([v(-1., 2., -1.), v(1., 2., -1.), v(1., 2., 1.), v(-1., 2., 1.)], white), // ceiling
        ([v(-1., 0., -1.), v(1., 0., -1.), v(1., 2., -1.), v(-1., 2., -1.)], white), // back
        ([v(-1., 0., 1.), v(-1., 0., -1.), v(-1., 2., -1.), v(-1., 2., 1.)], red), // left
        ([v(1., 0., -1.), v(1., 0., 1.), v(1., 2., 1.), v(1., 2., -1.)], green),   // right
        ([v(-0.25, 1.999, -0.25), v(0.25, 1.999, -0.25), v(0.25, 1.999, 0.25), v(-0.25, 1.999, 0.25)], light),
    ];
    for (corners, m) in walls {
        b.mesh(&quad(corners), 1.0, Vec3::ZERO, Some(m));
    }
    b.scene.spheres.push(Sphere { center: v(-0.45, 0.35, -0.3), radius: 0.35, material: mirror });
    b.scene.spheres.push(Sphere { center: v(0.45, 0.35, 0.3), radius: 0.35, material: glass });
    b.scene.lights.push(Light::Point { position: v(0.0, 1.9, 0.0), intensity: Vec3::splat(1.6) });
    b.scene.camera = Camera { eye: v(0.0, 1.0, 3.9), look_at: v(0.0, 1.0, 0.0), up: Vec3::Y, vfov: 38.0 };
    b.scene.background = Vec3::ZERO;
    b.scene.ambient = 0.08;
    b.scene.width = 256;
    b.scene.height = 256;
    b.finish()
}

fn spheres() -> Result<Scene> {
    let mut b = SceneBuilder::new("builtin:spheres");
    let red = b.material(Material::lambert("red", Vec3::new(0.8, 0.2, 0.2)));
    let mirror = b.material(mat("mirror", MaterialKind::Mirror, Vec3::splat(0.9)));
    let glass = b.material(Material { ior: 1.5, ..mat("glass", MaterialKind::Glass, Vec3::ONE) });
    b.scene.spheres.push(Sphere { center: Vec3::new(0.0, -100.5, 0.0), radius: 100.0, material: 0 });
    b.scene.spheres.push(Sphere { center: Vec3::new(-1.1, 0.0, 0.0), radius: 0.5, material: red });
    b.scene.spheres.push(Sphere { center: Vec3::new(0.0, 0.0, -0.3), radius: 0.5, material: mirror });
    b.scene.spheres.push(Sphere { center: Vec3::new(1.1, 0.0, 0.2), radius: 0.5, material: glass });
    b.scene.lights.push(Light::Directional { direction: Vec3::new(-1.0, -2.0, -1.0), radiance: Vec3::splat(2.0) });
    b.scene.camera = Camera { eye: Vec3::new(0.0, 0.8, 3.5), look_at: Vec3::ZERO, up: Vec3::Y, vfov: 40.0 };
    b.scene.width = 256;
    b.scene.height = 160;
    b.finish()
}

fn blob_scene(n: usize) -> Result<Scene> {
    let mut b = SceneBuilder::new(&format!("builtin:blob:{n}"));
    b.mesh(&blob(n, 0.15, 1), 1.0, Vec3::ZERO, None);
    let mut bounds = Aabb::EMPTY;
    for p in &b.scene.positions {
        bounds.grow(*p);
    }
    b.scene.camera = framed_camera(&bounds, 45.0);
    b.scene.lights.push(super::default_light());
    b.finish()
}

fn stadium_scene(n: usize) -> Result<Scene> {
    let mut b = SceneBuilder::new(&format!("builtin:stadium:{n}"));
    let teapot = blob(n, 0.15, 1);
    let mut bounds = Aabb::EMPTY;
    for p in &teapot.positions {
        bounds.grow(*p);
    }
    b.mesh(&teapot, 1.0, Vec3::ZERO, None);
    b.mesh(&blob(2000, 0.05, 7), 500.0, Vec3::ZERO, None);
    b.scene.camera = framed_camera(&bounds, 45.0);
    b.scene.lights.push(super::default_light());
    b.finish()
}

fn inside_scene(n: usize) -> Result<Scene> {
    let mut b = SceneBuilder::new(&format!("builtin:inside:{n}"));
    b.mesh(&blob(n, 0.15, 1), 1.0, Vec3::ZERO, None);
    // Off-centre and looking at a slant, so rays meet edges at every angle.
    b.scene.camera =
        Camera { eye: Vec3::new(0.05, 0.03, -0.02), look_at: Vec3::new(1.0, 0.7, 0.4), up: Vec3::Y, vfov: 100.0 };
    b.scene.lights.push(super::default_light());
    b.finish()
}
