//! Built-in scenes that need no files.
//!
//! - `default`: a displaced procedural blob of ~100k triangles, a mirror sphere and
//!   a glass sphere on a ground plane, lit by a directional and a point light.
//! - `cornell`: the classic Cornell box (the published 556-unit data, scaled to about
//!   2 units): white floor, ceiling and back wall, red left and green right wall, a
//!   short and a tall block, lit only by a one-sided emissive quad under the ceiling
//!   facing down; the camera looks through the open front. Mirrored for Mitsuba 3 in
//!   scripts/peers/mitsuba_cornell.py.
//! - `caustic`: a glass ball (ior 1.5, radius 0.5) half a unit above a Lambert floor,
//!   under a point light 2.5 above it: the bright disk the ball focuses on the floor
//!   is light `path` cannot find and `sppm` can (docs/caustics.md).
//! - `caustic-lamp`: the same, lit by a small emissive sphere (radius 0.08) in the
//!   point light's place, which `path` finds but slowly.
//! - `blob:N`: one blob of about N triangles, auto-framed (benchmarks).
//! - `spheres`: spheres only, no triangles (tests the sphere-only kernel).
//! - `inside:N`: the camera at the centre of a closed blob of about N triangles,
//!   looking out: every camera ray must hit it, so a miss is a crack (robustness). A
//!   point light inside lights the walls.
//! - `stadium:N`: "the teapot in a stadium": a blob of about N triangles and radius 1
//!   inside a coarse blob of 2000 triangles and radius 500, seen from close to the
//!   small one, lit by a point light inside the stadium; uniform grids are known to
//!   fail here.

use glam::Vec3;

use super::mesh::{Material, MaterialKind};
use super::procedural::{blob, quad};
use super::{framed_camera, Camera, Light, Scene, SceneBuilder, Sphere};
use crate::error::{Error, Result};
use crate::math::Aabb;

/// Names accepted after `builtin:`.
pub const NAMES: &str =
    "default, cornell, spheres, caustic, caustic-lamp, blob:N, inside:N, stadium:N (N = triangle count)";

fn mat(name: &str, kind: MaterialKind, color: Vec3) -> Material {
    Material { kind, ..Material::lambert(name, color) }
}

/// Loads built-in scene `name`.
pub fn load(name: &str) -> Result<Scene> {
    match name {
        "default" => default_scene(),
        "cornell" => cornell(),
        "spheres" => spheres(),
        "caustic" => caustic(false),
        "caustic-lamp" => caustic(true),
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

/// The Cornell box as measured: the published 556-unit data set
/// (<https://www.graphics.cornell.edu/online/box/data.html>), in its own coordinates
/// (millimetres; x = 0 is the green wall, the open front at z = 0, the camera at
/// z = -800 looking along +z). Each quad is wound as published: counter-clockwise seen
/// from the side its geometric normal `cross(b - a, c - a)` faces, which is into the
/// room for walls, out of each block, and down for the light.
///
/// scripts/peers/mitsuba_cornell.py builds the same scene for Mitsuba 3 from the same
/// numbers; the two must match.
pub mod cornell_data {
    type Quad = [[f32; 3]; 4];

    pub const FLOOR: Quad = [[552.8, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 559.2], [549.6, 0.0, 559.2]];
    pub const CEILING: Quad = [[556.0, 548.8, 0.0], [556.0, 548.8, 559.2], [0.0, 548.8, 559.2], [0.0, 548.8, 0.0]];
    pub const BACK_WALL: Quad = [[549.6, 0.0, 559.2], [0.0, 0.0, 559.2], [0.0, 548.8, 559.2], [556.0, 548.8, 559.2]];
    /// x = 0: green, on the right as seen from the camera.
    pub const GREEN_WALL: Quad = [[0.0, 0.0, 559.2], [0.0, 0.0, 0.0], [0.0, 548.8, 0.0], [0.0, 548.8, 559.2]];
    /// x = 556: red, on the left.
    pub const RED_WALL: Quad = [[552.8, 0.0, 0.0], [549.6, 0.0, 559.2], [556.0, 548.8, 559.2], [556.0, 548.8, 0.0]];
    /// The published light (130 x 105) lowered by `LIGHT_DROP` below the ceiling, so
    /// the two never share a plane.
    pub const LIGHT: Quad =
        [[343.0, 548.8, 227.0], [343.0, 548.8, 332.0], [213.0, 548.8, 332.0], [213.0, 548.8, 227.0]];
    pub const LIGHT_DROP: f32 = 0.5;
    /// Top, then four sides; no bottom (it rests on the floor).
    pub const SHORT_BLOCK: [Quad; 5] = [
        [[130.0, 165.0, 65.0], [82.0, 165.0, 225.0], [240.0, 165.0, 272.0], [290.0, 165.0, 114.0]],
        [[290.0, 0.0, 114.0], [290.0, 165.0, 114.0], [240.0, 165.0, 272.0], [240.0, 0.0, 272.0]],
        [[130.0, 0.0, 65.0], [130.0, 165.0, 65.0], [290.0, 165.0, 114.0], [290.0, 0.0, 114.0]],
        [[82.0, 0.0, 225.0], [82.0, 165.0, 225.0], [130.0, 165.0, 65.0], [130.0, 0.0, 65.0]],
        [[240.0, 0.0, 272.0], [240.0, 165.0, 272.0], [82.0, 165.0, 225.0], [82.0, 0.0, 225.0]],
    ];
    pub const TALL_BLOCK: [Quad; 5] = [
        [[423.0, 330.0, 247.0], [265.0, 330.0, 296.0], [314.0, 330.0, 456.0], [472.0, 330.0, 406.0]],
        [[423.0, 0.0, 247.0], [423.0, 330.0, 247.0], [472.0, 330.0, 406.0], [472.0, 0.0, 406.0]],
        [[472.0, 0.0, 406.0], [472.0, 330.0, 406.0], [314.0, 330.0, 456.0], [314.0, 0.0, 456.0]],
        [[314.0, 0.0, 456.0], [314.0, 330.0, 456.0], [265.0, 330.0, 296.0], [265.0, 0.0, 296.0]],
        [[265.0, 0.0, 296.0], [265.0, 330.0, 296.0], [423.0, 330.0, 247.0], [423.0, 0.0, 247.0]],
    ];
    /// Camera: at (278, 273, -800) looking along +z, up +y; a 35 mm lens on a
    /// 25 x 25 mm film: vfov = 2 atan(12.5 / 35) = 39.3076 degrees.
    pub const EYE: [f32; 3] = [278.0, 273.0, -800.0];
    pub const LOOK_AT: [f32; 3] = [278.0, 273.0, 0.0];
    pub const VFOV_DEG: f32 = 39.3076;
    /// To arbor's frame: x' = (CENTER_X - x) * SCALE, y' = y * SCALE,
    /// z' = (CENTER_Z - z) * SCALE (a half turn about y, which keeps the windings):
    /// the box spans x' in [-1, 1], y' in [0, 1.974], z' in [-1.006, 1.006], and the
    /// camera looks down -z' from z' = 3.88 with red on the left, like the other
    /// built-in scenes.
    pub const CENTER_X: f32 = 278.0;
    pub const CENTER_Z: f32 = 279.6;
    pub const SCALE: f32 = 1.0 / 278.0;
    /// Albedos (the common RGB values) and the light's radiance (one-sided, down).
    pub const WHITE: [f32; 3] = [0.73, 0.73, 0.73];
    pub const RED: [f32; 3] = [0.65, 0.05, 0.05];
    pub const GREEN: [f32; 3] = [0.12, 0.45, 0.15];
    pub const EMISSION: [f32; 3] = [17.0, 12.0, 4.0];

    /// A data-set point in arbor's frame.
    pub fn point(p: [f32; 3]) -> glam::Vec3 {
        glam::Vec3::new((CENTER_X - p[0]) * SCALE, p[1] * SCALE, (CENTER_Z - p[2]) * SCALE)
    }

    /// A data-set quad in arbor's frame.
    pub fn quad(q: &Quad) -> [glam::Vec3; 4] {
        q.map(point)
    }
}

/// The classic Cornell box, lit only by its one-sided ceiling light (no `Light`
/// entries, no ambient): the scene the path tracer is measured on against Mitsuba 3.
fn cornell() -> Result<Scene> {
    use cornell_data as d;
    let mut b = SceneBuilder::new("builtin:cornell");
    let white = b.material(Material::lambert("white", Vec3::from(d::WHITE)));
    let red = b.material(Material::lambert("red", Vec3::from(d::RED)));
    let green = b.material(Material::lambert("green", Vec3::from(d::GREEN)));
    let light = b.material(Material {
        emission: Vec3::from(d::EMISSION),
        two_sided: false,
        ..mat("light", MaterialKind::Emissive, Vec3::ZERO)
    });
    let lowered = d::LIGHT.map(|[x, y, z]| [x, y - d::LIGHT_DROP, z]);
    let mut quads = vec![
        (d::FLOOR, white),
        (d::CEILING, white),
        (d::BACK_WALL, white),
        (d::RED_WALL, red),
        (d::GREEN_WALL, green),
        (lowered, light),
    ];
    quads.extend(d::SHORT_BLOCK.iter().chain(&d::TALL_BLOCK).map(|q| (*q, white)));
    for (q, m) in &quads {
        b.mesh(&quad(d::quad(q)), 1.0, Vec3::ZERO, Some(*m));
    }
    b.scene.camera = Camera { eye: d::point(d::EYE), look_at: d::point(d::LOOK_AT), up: Vec3::Y, vfov: d::VFOV_DEG };
    b.scene.background = Vec3::ZERO;
    b.scene.ambient = 0.0;
    b.scene.width = 256;
    b.scene.height = 256;
    b.finish()
}

/// A glass ball under a lamp: a point light, or with `lamp` a small emissive sphere of
/// the same power (4 pi I = pi L 4 pi r^2: L = I / (pi r^2)).
fn caustic(lamp: bool) -> Result<Scene> {
    let mut b = SceneBuilder::new(if lamp { "builtin:caustic-lamp" } else { "builtin:caustic" });
    let floor = b.material(Material::lambert("floor", Vec3::splat(0.8)));
    let glass = b.material(Material { ior: 1.5, ..mat("glass", MaterialKind::Glass, Vec3::ONE) });
    let g = 3.0;
    b.mesh(
        &quad([Vec3::new(-g, 0.0, g), Vec3::new(g, 0.0, g), Vec3::new(g, 0.0, -g), Vec3::new(-g, 0.0, -g)]),
        1.0,
        Vec3::ZERO,
        Some(floor),
    );
    let ball = Vec3::new(0.0, 1.0, 0.0);
    b.scene.spheres.push(Sphere { center: ball, radius: 0.5, material: glass });
    let at = ball + Vec3::new(0.0, 2.5, 0.0);
    let intensity = 6.0;
    if lamp {
        let r: f32 = 0.08;
        let light = b.material(Material {
            emission: Vec3::splat(intensity / (std::f32::consts::PI * r * r)),
            ..mat("lamp", MaterialKind::Emissive, Vec3::ZERO)
        });
        b.scene.spheres.push(Sphere { center: at, radius: r, material: light });
    } else {
        b.scene.lights.push(Light::Point { position: at, intensity: Vec3::splat(intensity) });
    }
    b.scene.camera =
        Camera { eye: Vec3::new(0.0, 2.6, 3.4), look_at: Vec3::new(0.0, 0.35, 0.0), up: Vec3::Y, vfov: 40.0 };
    b.scene.background = Vec3::ZERO;
    b.scene.ambient = 0.0;
    b.scene.width = 320;
    b.scene.height = 240;
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
    // The stadium closes the scene: a light from outside (the default one) would leave
    // everything in its shadow. A point light inside, above and beside the camera.
    let eye = b.scene.camera.eye;
    b.scene.lights.push(Light::Point { position: eye + Vec3::new(-2.0, 3.0, 0.0), intensity: Vec3::splat(40.0) });
    b.finish()
}

fn inside_scene(n: usize) -> Result<Scene> {
    let mut b = SceneBuilder::new(&format!("builtin:inside:{n}"));
    b.mesh(&blob(n, 0.15, 1), 1.0, Vec3::ZERO, None);
    // Off-centre and looking at a slant, so rays meet edges at every angle.
    b.scene.camera =
        Camera { eye: Vec3::new(0.05, 0.03, -0.02), look_at: Vec3::new(1.0, 0.7, 0.4), up: Vec3::Y, vfov: 100.0 };
    // Closed around the camera: a point light inside (one outside would light nothing).
    b.scene.lights.push(Light::Point { position: Vec3::new(-0.2, 0.3, 0.1), intensity: Vec3::splat(0.3) });
    b.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The geometric normal of triangle `t` of `scene`, as the kernels compute it.
    fn normal(scene: &Scene, t: usize) -> Vec3 {
        let [a, b, c] = scene.triangles[t].map(|i| scene.positions[i as usize]);
        (b - a).cross(c - a).normalize()
    }

    fn centroid(scene: &Scene, t: usize) -> Vec3 {
        scene.triangles[t].iter().map(|&i| scene.positions[i as usize]).sum::<Vec3>() / 3.0
    }

    #[test]
    fn cornell_is_the_classic_box_lit_by_a_one_sided_light() {
        let s = load("cornell").expect("cornell");
        assert!(s.lights.is_empty() && s.spheres.is_empty() && s.ambient == 0.0 && s.background == Vec3::ZERO);
        assert_eq!((s.width, s.height, s.triangles.len()), (256, 256, 2 * (6 + 10)));
        let emissive: Vec<usize> = (0..s.triangles.len())
            .filter(|&t| s.materials[s.tri_material[t] as usize].kind == MaterialKind::Emissive)
            .collect();
        assert_eq!(emissive.len(), 2, "the light is one quad");
        let room = Vec3::new(0.0, 1.0, 0.0);
        let ceiling = 548.8 * cornell_data::SCALE;
        for t in 0..s.triangles.len() {
            let m = &s.materials[s.tri_material[t] as usize];
            let (n, c) = (normal(&s, t), centroid(&s, t));
            match (t / 2, m.name.as_str()) {
                (5, "light") => {
                    assert!(n.abs_diff_eq(-Vec3::Y, 1e-6), "light faces down: {n}");
                    assert!(!m.two_sided && m.emission == Vec3::new(17.0, 12.0, 4.0) && m.color == Vec3::ZERO);
                    assert!(c.y < ceiling && c.y > ceiling - 0.01, "just under the ceiling: {c}");
                }
                (0..=4, _) => assert!(n.dot(room - c) > 0.0, "wall {t} ({}) faces into the room: {n}", m.name),
                (6..=15, "white") => {
                    // Faces out of its block: away from the block's vertical axis.
                    let q = t / 2;
                    let block = if q < 11 { &cornell_data::SHORT_BLOCK } else { &cornell_data::TALL_BLOCK };
                    let axis = block[0].iter().map(|&p| cornell_data::point(p)).sum::<Vec3>() / 4.0;
                    let out = if q == 6 || q == 11 { Vec3::Y } else { (c - axis) * Vec3::new(1.0, 0.0, 1.0) };
                    assert!(n.dot(out) > 0.0, "block face {t} faces out: {n}");
                }
                other => panic!("unexpected triangle {t}: {other:?}"),
            }
        }
        // Red on the left, green on the right, as the camera sees them.
        let basis = s.camera.basis(s.width, s.height);
        let side = |name: &str| {
            let t = (0..s.triangles.len()).find(|&t| s.materials[s.tri_material[t] as usize].name == name);
            (centroid(&s, t.expect(name)) - s.camera.eye).dot(basis.right)
        };
        assert!(side("red") < 0.0 && side("green") > 0.0);
        assert!((s.camera.vfov - 39.3076).abs() < 1e-4);
    }
}
