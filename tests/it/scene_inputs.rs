//! Scene inputs for the path tracer: texture coordinates (OBJ, PLY), textures (MTL
//! `map_Kd`, TOML `texture`), the TOML material keys `two_sided` and `absorption`, and
//! the `[environment]` table. Every file is written into a temporary folder here.

use std::path::{Path, PathBuf};

use arbor::scene::{load_environment, load_mesh, load_texture, MaterialKind, MeshData, Scene, SceneBuilder};
use glam::{Vec2, Vec3};

/// Writes `text` to `dir/name` and returns the path.
fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// A 2x1 PNG: red on the left, blue on the right.
fn png(dir: &Path, name: &str) -> PathBuf {
    let path = dir.join(name);
    image::RgbaImage::from_raw(2, 1, vec![255, 0, 0, 255, 0, 0, 255, 128]).unwrap().save(&path).unwrap();
    path
}

/// A 2x1 float image written by the `image` crate (format from the extension).
fn float_image(dir: &Path, name: &str, texels: [f32; 6]) -> PathBuf {
    let path = dir.join(name);
    image::Rgb32FImage::from_raw(2, 1, texels.to_vec()).unwrap().save(&path).unwrap();
    path
}

/// A quad with texture coordinates using material `wood` from `quad.mtl`.
const QUAD_OBJ: &str = "mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
    vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl wood\nf 1/1 2/2 3/3 4/4\n";

/// The same quad without texture coordinates.
const QUAD_OBJ_NO_UV: &str = "mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl wood\nf 1 2 3 4\n";

/// The error of loading `source` as a scene; checks it is one line and names `file`.
fn error(source: &Path, file: &str) -> String {
    let msg = Scene::load(&source.display().to_string()).err().map(|e| e.to_string()).expect("an error");
    assert!(!msg.chars().any(char::is_control), "{msg:?} is not one line");
    assert!(msg.contains(file), "{msg:?} should name {file}");
    msg
}

#[test]
fn obj_with_map_kd_loads_uvs_and_the_texture() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    png(d, "wood.png");
    // Two materials share the texture: it is loaded once. -s scales the coordinates.
    write(d, "quad.mtl", "newmtl wood\nKd 1 1 1\nmap_Kd -s 2 2 1 wood.png\nnewmtl oak\n  map_Kd wood.png\n");
    let obj = write(d, "quad.obj", &format!("{QUAD_OBJ}usemtl oak\nf 1/1 3/3 4/4\n"));
    let mesh = load_mesh(&obj).unwrap();
    let uvs = mesh.uvs.as_ref().expect("uvs");
    assert_eq!(uvs.len(), mesh.positions.len());
    assert!(uvs.contains(&Vec2::new(2.0, 2.0)), "-s 2 2 applies to the wood faces: {uvs:?}");
    assert!(uvs.contains(&Vec2::new(1.0, 1.0)), "the oak face is not scaled: {uvs:?}");
    assert_eq!(mesh.textures.len(), 1, "one file, loaded once");
    let t = &mesh.textures[0];
    assert_eq!((t.width, t.height), (2, 1));
    assert_eq!(t.texels, [[255, 0, 0, 255], [0, 0, 255, 128]]);
    assert!(mesh.materials.iter().filter(|m| m.name != "default").all(|m| m.texture == Some(0)));

    let scene = Scene::load(&obj.display().to_string()).unwrap();
    assert_eq!(scene.textures.len(), 1);
    assert_eq!(scene.uvs.len(), scene.positions.len());
    assert!(scene.materials.iter().any(|m| m.name == "wood" && m.texture == Some(0)));
}

#[test]
fn map_kd_errors_name_the_option_or_the_texture() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let obj = write(d, "quad.obj", QUAD_OBJ);
    write(d, "quad.mtl", "newmtl wood\nmap_Kd -imfchan r wood.png\n");
    let msg = error(&obj, "quad.mtl");
    assert!(msg.contains("-imfchan") && msg.contains("wood"), "{msg}");

    write(d, "quad.mtl", "newmtl wood\nmap_Kd missing.png\n");
    let msg = error(&obj, "missing.png");
    assert!(msg.contains("material 'wood'") && msg.contains("quad.mtl"), "{msg}");

    write(d, "garbage.png", "this is not a PNG file");
    write(d, "quad.mtl", "newmtl wood\nmap_Kd garbage.png\n");
    let msg = error(&obj, "garbage.png");
    assert!(msg.contains("decode"), "{msg}");
}

#[test]
fn texture_on_a_mesh_without_uvs_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    png(d, "wood.png");
    write(d, "quad.mtl", "newmtl wood\nmap_Kd wood.png\n");
    let obj = write(d, "quad.obj", QUAD_OBJ_NO_UV);
    let msg = error(&obj, "quad.obj");
    assert!(msg.contains("material 'wood'") && msg.contains("texture coordinates"), "{msg}");

    // A TOML material with a texture on a mesh without UVs names the mesh file.
    write(d, "plain.mtl", "newmtl wood\nKd 1 1 1\n");
    write(d, "plain.obj", &QUAD_OBJ_NO_UV.replace("quad.mtl", "plain.mtl"));
    let toml = write(
        d,
        "s.toml",
        "[[material]]\nname = \"tex\"\ntype = \"lambert\"\ntexture = \"wood.png\"\n\
         [[mesh]]\nfile = \"plain.obj\"\nmaterial = \"tex\"\n",
    );
    let msg = error(&toml, "plain.obj");
    assert!(msg.contains("s.toml:5") && msg.contains("material 'tex'"), "{msg}");
}

#[test]
fn ply_u_v_and_s_t_load_as_uvs() {
    let dir = tempfile::tempdir().unwrap();
    for (u, v) in [("u", "v"), ("s", "t"), ("texture_u", "texture_v"), ("texture_s", "texture_t")] {
        let ply = write(
            dir.path(),
            "tri.ply",
            &format!(
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                 property float {u}\nproperty double {v}\nelement face 1\nproperty list uchar int vertex_indices\n\
                 end_header\n0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 0.5\n3 0 1 2\n"
            ),
        );
        let mesh = load_mesh(&ply).unwrap();
        assert_eq!(mesh.uvs, Some(vec![Vec2::ZERO, Vec2::X, Vec2::new(0.0, 0.5)]), "{u}/{v}");
    }
    let ply = write(
        dir.path(),
        "half.ply",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
         property float u\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n0 0 0 0\n1 0 0 1\n0 1 0 0\n",
    );
    assert_eq!(load_mesh(&ply).unwrap().uvs, None, "u without v is no texture coordinate");
}

#[test]
fn toml_material_keys_and_environment_parse() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    png(d, "wood.png");
    float_image(d, "sky.hdr", [1.0, 2.0, 3.0, 0.0, 0.5, 4.0]);
    write(d, "quad.mtl", "newmtl wood\nmap_Kd wood.png\n");
    write(d, "quad.obj", QUAD_OBJ);
    let toml = write(
        d,
        "s.toml",
        "[environment]\nfile = \"sky.hdr\"\nrotation = 90\nintensity = 2.5\n\
         [[material]]\nname = \"lamp\"\ntype = \"emissive\"\ntwo_sided = true\n\
         [[material]]\nname = \"sign\"\ntype = \"emissive\"\nemission = [2, 2, 2]\nemission_texture = \"wood.png\"\n\
         [[material]]\nname = \"tinted\"\ntype = \"glass\"\nabsorption = [0.5, 0.0, 2.0]\n\
         [[material]]\nname = \"wood2\"\ntype = \"lambert\"\ntexture = \"wood.png\"\n\
         [[mesh]]\nfile = \"quad.obj\"\n\
         [[mesh]]\nfile = \"quad.obj\"\nmaterial = \"wood2\"\n\
         [[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"tinted\"\n",
    );
    let scene = Scene::load(&toml.display().to_string()).unwrap();
    let by_name = |n: &str| scene.materials.iter().find(|m| m.name == n).unwrap();
    assert!(by_name("lamp").two_sided);
    assert!(!by_name("tinted").two_sided);
    assert_eq!(by_name("tinted").absorption, Vec3::new(0.5, 0.0, 2.0));
    // The TOML texture and the MTL's map_Kd are the same file: one texture.
    assert_eq!(scene.textures.len(), 1, "{:?}", scene.textures.iter().map(|t| &t.name).collect::<Vec<_>>());
    assert_eq!(by_name("wood2").texture, Some(0));
    assert_eq!(by_name("wood").texture, Some(0));
    assert_eq!((by_name("sign").maps.emission, by_name("sign").texture), (Some(0), None), "one file, read once");
    let env = scene.environment.as_ref().expect("environment");
    assert_eq!((env.width, env.height, env.rotation, env.intensity), (2, 1, 90.0, 2.5));
    let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 0.02 * y.max(0.1));
    assert!(close(env.texels[0], [1.0, 2.0, 3.0]) && close(env.texels[1], [0.0, 0.5, 4.0]), "{:?}", env.texels);
    assert!(scene.lights.is_empty(), "an environment replaces the default light");

    // Defaults: rotation 0, intensity 1; EXR works too.
    float_image(d, "sky.exr", [1.0; 6]);
    let toml = write(d, "e.toml", "[environment]\nfile = \"sky.exr\"\n[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\n");
    let scene = Scene::load(&toml.display().to_string()).unwrap();
    let env = scene.environment.as_ref().unwrap();
    assert_eq!((env.rotation, env.intensity, env.texels[1]), (0.0, 1.0, [1.0; 3]));
    assert_eq!(load_environment(&d.join("sky.exr"), 10.0, 0.0).unwrap().rotation, 10.0);
    assert_eq!(load_texture(&d.join("wood.png")).unwrap().width, 2);
}

/// The microfacet materials' keys (docs/scenes.md): a conductor by complex index or by
/// colour, a dielectric with ior and absorption, roughness 0 allowed; a misplaced,
/// half-given or out-of-range key is an error at its table's line.
#[test]
fn toml_conductor_and_dielectric_keys() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sphere = "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\n";
    let toml = |text: &str| write(d, "m.toml", &format!("{text}{sphere}"));
    let scene = Scene::load(
        &toml(
            "[[material]]\nname = \"gold\"\ntype = \"conductor\"\nroughness = 0.3\n\
             eta = [0.14, 0.37, 1.44]\nk = [3.98, 2.38, 1.60]\n\
             [[material]]\nname = \"copper\"\ntype = \"conductor\"\ncolor = [0.95, 0.64, 0.54]\n\
             [[material]]\nname = \"frosted\"\ntype = \"dielectric\"\nroughness = 0.2\nior = 1.33\n\
             absorption = [0.1, 0, 0]\n\
             [[material]]\nname = \"clear\"\ntype = \"dielectric\"\nroughness = 0\n\
             [[material]]\nname = \"brass\"\ntype = \"pbr\"\nmetallic = 0.9\nroughness = 0.4\nior = 2\n\
             [[material]]\nname = \"plastic\"\ntype = \"pbr\"\n",
        )
        .display()
        .to_string(),
    )
    .unwrap();
    let by_name = |n: &str| scene.materials.iter().find(|m| m.name == n).unwrap();
    let gold = by_name("gold");
    assert_eq!((gold.kind, gold.roughness, gold.color), (MaterialKind::Conductor, 0.3, Vec3::ONE));
    let ior = gold.complex_ior.expect("a complex index");
    assert_eq!((ior.eta, ior.k), (Vec3::new(0.14, 0.37, 1.44), Vec3::new(3.98, 2.38, 1.60)));
    let copper = by_name("copper");
    assert_eq!((copper.roughness, copper.complex_ior, copper.color), (0.0, None, Vec3::new(0.95, 0.64, 0.54)));
    let frosted = by_name("frosted");
    assert_eq!((frosted.kind, frosted.ior, frosted.absorption.x), (MaterialKind::Dielectric, 1.33, 0.1));
    assert!(!frosted.is_smooth_glass() && by_name("clear").is_smooth_glass());
    assert_eq!(by_name("clear").ior, 1.5, "the default ior");
    let brass = by_name("brass");
    assert_eq!((brass.kind, brass.metallic, brass.roughness), (MaterialKind::Pbr, 0.9, 0.4));
    assert!((brass.dielectric_f0 - Vec3::splat(1.0 / 9.0)).length() < 1e-6, "F0 from ior 2");
    let plastic = by_name("plastic");
    assert_eq!((plastic.metallic, plastic.roughness, plastic.color), (0.0, 0.5, Vec3::splat(0.7)), "pbr defaults");
    assert!((plastic.dielectric_f0 - Vec3::splat(0.04)).length() < 1e-6);

    for (table, want) in [
        ("type = \"conductor\"\nroughness = 1.5\n", "roughness 1.5 is outside [0, 1]"),
        ("type = \"dielectric\"\nroughness = -0.1\n", "outside [0, 1]"),
        ("type = \"conductor\"\neta = [1, 1, 1]\n", "eta and k go together"),
        ("type = \"conductor\"\neta = [0, 1, 1]\nk = [1, 1, 1]\n", "must be > 0"),
        ("type = \"conductor\"\neta = [1, 1, 1]\nk = [-1, 1, 1]\n", "k"),
        ("type = \"phong\"\nroughness = 0.5\n", "roughness is for type = \"conductor\", \"dielectric\" or \"pbr\""),
        ("type = \"conductor\"\nmetallic = 1\n", "metallic is for type = \"pbr\""),
        ("type = \"pbr\"\nmetallic = 1.5\n", "metallic 1.5"),
        ("type = \"pbr\"\nroughness = 2\n", "roughness 2 is outside [0, 1]"),
        ("type = \"dielectric\"\neta = [1, 1, 1]\nk = [0, 0, 0]\n", "a dielectric's index is ior"),
        ("type = \"metal\"\n", "metal"),
        ("type = \"conductor\"\nrougness = 0.5\n", "rougness"),
    ] {
        let msg = error(&toml(&format!("[[material]]\nname = \"m\"\n{table}")), "m.toml:");
        assert!(msg.contains(want), "{table:?}: {msg}");
    }
}

#[test]
fn toml_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sphere = "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\n";
    let toml = |text: &str| write(d, "s.toml", &format!("{text}{sphere}"));

    let msg = error(&toml("[[material]]\nname = \"g\"\ntype = \"glass\"\nabsorption = [0.1, -1, 0]\n"), "s.toml:1");
    assert!(msg.contains("absorption"), "{msg}");

    let msg = error(&toml("[[material]]\nname = \"w\"\ntype = \"lambert\"\ntexture = \"nope.png\"\n"), "nope.png");
    assert!(msg.contains("s.toml:1") && msg.contains("material 'w'"), "{msg}");
    let msg = error(
        &toml(
            "[[material]]\nname = \"e\"\ntype = \"emissive\"\nemission = [1, 1, 1]\nemission_texture = \"nope.png\"\n",
        ),
        "nope.png",
    );
    assert!(msg.contains("s.toml:1") && msg.contains("emission_texture"), "{msg}");
    let msg =
        error(&toml("[[material]]\nname = \"e\"\ntype = \"lambert\"\nemission_texture = \"nope.png\"\n"), "s.toml:1");
    assert!(msg.contains("emission_texture multiplies `emission`, which is zero"), "{msg}");

    write(d, "junk.jpg", "\u{1}\u{2}garbage");
    let msg = error(&toml("[[material]]\nname = \"w\"\ntype = \"lambert\"\ntexture = \"junk.jpg\"\n"), "junk.jpg");
    assert!(msg.contains("s.toml:1"), "{msg}");

    let msg = error(&toml("[environment]\nfile = \"missing.hdr\"\n"), "missing.hdr");
    assert!(msg.contains("s.toml:"), "{msg}");

    float_image(d, "nan.exr", [1.0, f32::NAN, 1.0, 1.0, 1.0, 1.0]);
    let msg = error(&toml("[environment]\nfile = \"nan.exr\"\n"), "nan.exr");
    assert!(msg.contains("texel (0, 0)") && msg.contains("finite"), "{msg}");

    float_image(d, "neg.exr", [1.0, 1.0, 1.0, 1.0, -2.0, 1.0]);
    let msg = error(&toml("[environment]\nfile = \"neg.exr\"\n"), "neg.exr");
    assert!(msg.contains("texel (1, 0)") && msg.contains(">= 0"), "{msg}");

    let msg = error(&toml("[environment]\nfile = \"neg.exr\"\nintensity = -1\n"), "s.toml");
    assert!(msg.contains("intensity"), "{msg}");

    let msg = error(&toml("[environment]\nfile = \"sky.hdr\"\nexposure = 2\n"), "s.toml:3");
    assert!(msg.contains("exposure"), "{msg}");
}

#[test]
fn mixing_meshes_with_and_without_uvs_keeps_one_uv_per_position() {
    let tri = |uvs: Option<Vec<Vec2>>| MeshData {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        triangles: vec![[0, 1, 2]],
        uvs,
        ..Default::default()
    };
    let mut b = SceneBuilder::new("mix");
    b.mesh(&tri(None), 1.0, Vec3::ZERO, None);
    assert!(b.scene.uvs.is_empty(), "no uvs until a mesh has them");
    b.mesh(&tri(Some(vec![Vec2::ONE, Vec2::new(f32::NAN, 0.0), Vec2::X])), 1.0, Vec3::Z, None);
    b.mesh(&tri(None), 1.0, Vec3::Z * 2.0, None);
    let scene = b.finish().unwrap();
    assert_eq!(scene.uvs.len(), scene.positions.len());
    assert_eq!(&scene.uvs[..4], &[Vec2::ZERO, Vec2::ZERO, Vec2::ZERO, Vec2::ONE]);
    assert_eq!(scene.uvs[4], Vec2::ZERO, "non-finite becomes 0");
    assert_eq!(&scene.uvs[6..], &[Vec2::ZERO; 3]);
}
