//! Transforms in scene files: scale (uniform or per axis), rotate, translate, or a
//! row-major matrix; normals by the inverse transpose; mirrored meshes keep their
//! geometric normals facing out; spheres scale and move; every bad transform is one
//! line naming the file and line. CPU only.

use arbor::scene::Scene;
use glam::Vec3;

/// A tetrahedron around the origin with one vertex normal per corner (pointing out).
const TETRA: &str = "v 1 1 1\nv 1 -1 -1\nv -1 1 -1\nv -1 -1 1\n\
vn 1 1 1\nvn 1 -1 -1\nvn -1 1 -1\nvn -1 -1 1\n\
f 1//1 2//2 3//3\nf 1//1 4//4 2//2\nf 1//1 3//3 4//4\nf 2//2 4//4 3//3\n";

fn load(mesh_keys: &str, extra: &str) -> arbor::error::Result<Scene> {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("t.obj"), TETRA).expect("obj");
    let toml = format!("[[mesh]]\nfile = \"t.obj\"\n{mesh_keys}\n{extra}");
    let path = dir.path().join("s.toml");
    std::fs::write(&path, toml).expect("toml");
    Scene::load(&path.display().to_string())
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).length() < 1e-5
}

/// Every face's geometric normal points away from the centroid of the (convex) mesh.
fn faces_out(s: &Scene) -> bool {
    let c = s.positions.iter().copied().sum::<Vec3>() / s.positions.len() as f32;
    s.triangles.iter().all(|t| {
        let [a, b, d] = t.map(|i| s.positions[i as usize]);
        (b - a).cross(d - a).dot((a + b + d) / 3.0 - c) > 0.0
    })
}

#[test]
fn scale_rotate_translate_in_that_order() {
    let s = load("scale = [2, 1, 1]\nrotate = [0, 1, 0, 90]\ntranslate = [0, 0, 5]", "").expect("scene");
    let plain = load("", "").expect("scene");
    // (x, y, z) -> scale (2x, y, z) -> 90 degrees about +y (x -> -z, z -> x) -> + (0, 0, 5).
    for (p, q) in s.positions.iter().zip(&plain.positions) {
        let want = Vec3::new(q.z, q.y, -2.0 * q.x + 5.0);
        assert!(close(*p, want), "{p} vs {want}");
    }
    assert!(faces_out(&s), "a rotation keeps the winding");
    // Normals by the inverse transpose: scale (2, 1, 1) turns (1, 1, 1) into
    // (0.5, 1, 1) before the rotation.
    let n = s.normals[0];
    let want = Vec3::new(1.0, 1.0, -0.5).normalize();
    assert!(close(n, want), "normal {n} vs {want}");
}

#[test]
fn a_row_major_matrix_is_the_whole_transform() {
    let s = load("matrix = [1, 0, 0, 5,  0, 2, 0, 0,  0, 0, 1, -1,  0, 0, 0, 1]", "").expect("scene");
    let plain = load("", "").expect("scene");
    for (p, q) in s.positions.iter().zip(&plain.positions) {
        assert!(close(*p, Vec3::new(q.x + 5.0, 2.0 * q.y, q.z - 1.0)), "{p}");
    }
}

#[test]
fn a_mirror_keeps_normals_pointing_out() {
    for keys in ["scale = [-1, 1, 1]", "scale = -2", "matrix = [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, -1, 0,  0, 0, 0, 1]"] {
        let s = load(keys, "").expect("scene");
        assert!(faces_out(&s), "{keys}: geometric normals face in");
        let c = s.positions.iter().copied().sum::<Vec3>() / 4.0;
        for (p, n) in s.positions.iter().zip(&s.normals) {
            assert!(n.dot(*p - c) > 0.0, "{keys}: shading normal {n} at {p} faces in");
        }
    }
}

#[test]
fn spheres_scale_then_move() {
    let s =
        load("", "[[sphere]]\ncenter = [1, 0, 0]\nradius = 0.5\nscale = -2\ntranslate = [0, 1, 0]\n").expect("scene");
    let sp = s.spheres[0];
    assert!(close(sp.center, Vec3::new(-2.0, 1.0, 0.0)), "{}", sp.center);
    assert_eq!(sp.radius, 1.0);
}

#[test]
fn bad_transforms_name_the_file_and_line() {
    let cases = [
        ("scale = [1, 0, 1]", "singular"),
        ("scale = inf", "finite"),
        ("rotate = [0, 0, 0, 30]", "non-zero axis"),
        ("rotate = [0, 1, 0, nan]", "finite"),
        ("matrix = [1, 0, 0, 0]", "16 numbers"),
        ("matrix = [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 1, 1]", "last row"),
        ("matrix = [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 0, 0,  0, 0, 0, 1]", "singular"),
        ("matrix = [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1]\nscale = 2", "not both"),
    ];
    for (keys, want) in cases {
        let e = load(keys, "").expect_err(keys).to_string();
        assert!(e.contains("s.toml:1") && e.contains("t.obj") && e.contains(want), "{keys}: {e}");
        assert_eq!(e.lines().count(), 1, "{keys}: one line: {e}");
    }
    let e = load("", "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nscale = 0\n").expect_err("zero").to_string();
    assert!(e.contains("s.toml:") && e.contains("scale"), "{e}");
}
