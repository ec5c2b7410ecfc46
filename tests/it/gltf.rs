//! glTF 2.0 scenes: the Khronos sample models in Debian's assimp-testmodels load with
//! the expected triangle counts and bounds (figures read from the files' JSON and
//! buffers by a separate script), cameras, materials and textures come through, and
//! every malformed file gives one error naming it.

use std::path::{Path, PathBuf};

use arbor::scene::{MaterialKind, Scene};

const MODELS: &str = "/usr/share/assimp/models/glTF2";

fn model(rel: &str) -> PathBuf {
    Path::new(MODELS).join(rel)
}

/// The end of a glTF JSON whose mesh 0 reads accessor 0: one triangle (0,0,0), (1,0,0),
/// (0,1,0) in an embedded buffer, and the closing brace.
const ONE_TRIANGLE: &str = r#"
      "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                     "min": [0, 0, 0], "max": [1, 1, 0]}],
      "bufferViews": [{"buffer": 0, "byteLength": 36}],
      "buffers": [{"byteLength": 36,
                   "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}]
    }"#;

/// The end of a glTF JSON whose accessors 0 and 1 are the positions and UVs of the
/// triangle [`write_uv_triangle`] writes, and the closing brace.
const UV_TRIANGLE: &str = r#"
      "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                     "min": [0, 0, 0], "max": [1, 1, 0]},
                    {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}],
      "bufferViews": [{"buffer": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 24}],
      "buffers": [{"byteLength": 60, "uri": "tri.bin"}]
    }"#;

/// Writes `tri.bin` into `dir`: the triangle (0,0,0), (1,0,0), (0,1,0), then its UVs
/// (0, 1), (1, 1), (0, 0) ([`UV_TRIANGLE`] reads it).
fn write_uv_triangle(dir: &std::path::Path) {
    let mut bin: Vec<u8> = Vec::new();
    for f in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0] {
        bin.extend_from_slice(&f.to_le_bytes());
    }
    std::fs::write(dir.join("tri.bin"), &bin).expect("bin");
}

fn have_models() -> bool {
    let ok = model("BoxTextured-glTF/BoxTextured.gltf").exists();
    if !ok {
        // CI installs assimp-testmodels (scripts/setup.sh): there it is a failure.
        assert!(std::env::var("ARBOR_REQUIRE_GPU").is_err(), "assimp-testmodels is missing");
        eprintln!("skipped: assimp-testmodels is not installed");
    }
    ok
}

fn load(rel: &str) -> Scene {
    let p = model(rel);
    Scene::load(p.to_str().expect("utf-8")).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

fn assert_bounds(s: &Scene, lo: [f32; 3], hi: [f32; 3], tol: f32) {
    let b = s.bounds();
    for k in 0..3 {
        assert!((b.min[k] - lo[k]).abs() <= tol && (b.max[k] - hi[k]).abs() <= tol, "{}: bounds {b:?}", s.name);
    }
}

#[test]
fn sample_models_have_the_expected_triangles_and_bounds() {
    if !have_models() {
        return;
    }
    for (rel, tris, lo, hi, tol) in [
        ("BoxTextured-glTF/BoxTextured.gltf", 12, [-0.5; 3], [0.5; 3], 1e-5),
        ("BoxTextured-glTF-Binary/BoxTextured.glb", 12, [-0.5; 3], [0.5; 3], 1e-5),
        ("BoxTextured-glTF-Embedded/BoxTextured.gltf", 12, [-0.5; 3], [0.5; 3], 1e-5),
        ("BoxTexcoords-glTF/boxTexcoords.gltf", 12, [-1.0; 3], [1.0; 3], 1e-5),
        ("cameras/Cameras.gltf", 2, [0.0, 0.0, -0.708], [1.0, 0.707, 0.0], 1e-3),
        (
            "2CylinderEngine-glTF-Binary/2CylinderEngine.glb",
            121_496,
            [-371.692, -180.972, -140.0],
            [371.692, 92.042, 128.0],
            2e-3,
        ),
        // Triangles, a strip and a fan, indexed or not.
        (
            "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_04.gltf",
            2,
            [-0.5, -0.5, 0.0],
            [0.5, 0.5, 0.0],
            1e-6,
        ),
        (
            "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_05.gltf",
            2,
            [-0.5, -0.5, 0.0],
            [0.5, 0.5, 0.0],
            1e-6,
        ),
        (
            "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_06.gltf",
            2,
            [-0.5, -0.5, 0.0],
            [0.5, 0.5, 0.0],
            1e-6,
        ),
        (
            "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_11.gltf",
            2,
            [-0.5, -0.5, 0.0],
            [0.5, 0.5, 0.0],
            1e-6,
        ),
        (
            "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_12.gltf",
            2,
            [-0.5, -0.5, 0.0],
            [0.5, 0.5, 0.0],
            1e-6,
        ),
        (
            "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_13.gltf",
            2,
            [-0.5, -0.5, 0.0],
            [0.5, 0.5, 0.0],
            1e-6,
        ),
    ] {
        let s = load(rel);
        assert_eq!(s.drawn_triangles() as usize, tris, "{rel}");
        assert_bounds(&s, lo, hi, tol);
        // Meshes that several nodes draw are instances; flattened, they are the same
        // triangles in the same box.
        let f = s.flattened().expect("flattened");
        assert_eq!(f.triangles.len(), tris, "{rel}: flattened");
        assert_bounds(&f, lo, hi, tol);
        if rel.contains("2CylinderEngine") {
            let inst = s.instancing.as_ref().expect("2CylinderEngine's nodes share meshes");
            assert!(inst.instances.len() > inst.prototypes.len(), "{rel}: {} instances", inst.instances.len());
        }
        // Strips and fans keep one winding: every triangle faces +z like the quad.
        if rel.contains("PrimitiveMode") {
            for t in &s.triangles {
                let [a, b, c] = t.map(|i| s.positions[i as usize]);
                assert!((b - a).cross(c - a).z > 0.0, "{rel}: a triangle faces away");
            }
        }
    }
}

#[test]
fn textures_materials_and_cameras_come_through() {
    if !have_models() {
        return;
    }
    let s = load("BoxTextured-glTF-Binary/BoxTextured.glb");
    assert_eq!(s.textures.len(), 1, "the base colour texture");
    assert_eq!(s.uvs.len(), s.positions.len());
    let used = s.tri_material[0] as usize;
    assert_eq!(s.materials[used].texture, Some(0));
    // BoxTextured: metallic-roughness, metallic 0, roughness 1.
    let m = &s.materials[used];
    assert_eq!((m.kind, m.metallic, m.roughness), (MaterialKind::Pbr, 0.0, 1.0));
    assert!(!s.lights.is_empty(), "a default light when nothing lights the scene");
    // Cameras.gltf: its first camera is a perspective one with aspect 1.0.
    let c = load("cameras/Cameras.gltf");
    assert!((c.camera.eye - glam::Vec3::new(0.5, 0.5, 3.0)).length() < 1e-4, "{:?}", c.camera);
    assert!((c.camera.vfov - 0.7f32.to_degrees()).abs() < 1e-3, "{:?}", c.camera);
    assert_eq!((c.width, c.height), (512, 512));
}

#[test]
fn malformed_files_give_one_error_naming_the_file() {
    if !have_models() {
        return;
    }
    for rel in [
        "BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb",
        "MissingBin/BoxTextured.gltf",
        "IndexOutOfRange/IndexOutOfRange.gltf",
        "IndexOutOfRange/AllIndicesOutOfRange.gltf",
        "RecursiveNodes/RecursiveNodes.gltf",
        "SchemaFailures/sceneWrongType.gltf",
        "wrongTypes/badNumber.gltf",
        "wrongTypes/badObject.gltf",
        "wrongTypes/badUint.gltf",
        "wrongTypes/badArray.gltf",
        "wrongTypes/badString.gltf",
        "TestNoRootNode/SceneWithoutNodes.gltf",
        "TestNoRootNode/NoScene.gltf",
        "IncorrectVertexArrays/Cube.gltf",
        "draco/2CylinderEngine.gltf",
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_00.gltf",
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_01.gltf",
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_02.gltf",
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_03.gltf",
    ] {
        let p = model(rel);
        let err = Scene::load(p.to_str().expect("utf-8")).expect_err(rel).to_string();
        let file = p.file_name().and_then(|f| f.to_str()).expect("a file name");
        assert!(err.contains(file), "{rel}: {err}");
        assert_eq!(err.lines().count(), 1, "{rel}: {err}");
    }
    // The messages name what is wrong: the missing buffer file, a .glb that is a JPEG.
    let err =
        Scene::load(model("MissingBin/BoxTextured.gltf").to_str().expect("utf-8")).expect_err("no bin").to_string();
    assert!(err.contains("BoxTextured0.bin") && err.contains("cannot read it"), "{err}");
    let dir = tempfile::tempdir().expect("tempdir");
    let jpeg = dir.path().join("photo.glb");
    std::fs::write(&jpeg, [0xFF, 0xD8, 0xFF, 0xE0, 0, 0x10, b'J', b'F', b'I', b'F']).expect("write");
    let err = Scene::load(jpeg.to_str().expect("utf-8")).expect_err("a JPEG").to_string();
    assert!(err.contains("photo.glb") && err.contains("a JPEG image") && !err.contains("column"), "{err}");
    // Through the command line: exit status, one line, no image.
    let out = dir.path().join("x.png");
    let p = model("BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb");
    let run =
        std::process::Command::new(env!("CARGO_BIN_EXE_arbor")).args(["info"]).arg(&p).output().expect("run arbor");
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success() && err.trim_end().lines().count() == 1 && err.contains("BoxWithInfinites"), "{err}");
    assert!(!out.exists());
}

#[test]
fn a_gltf_file_is_a_mesh_of_a_scene_file_too() {
    if !have_models() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let toml = dir.path().join("s.toml");
    let glb = model("BoxTextured-glTF-Binary/BoxTextured.glb");
    std::fs::write(
        &toml,
        format!("[[mesh]]\nfile = \"{}\"\ntranslate = [10.0, 0.0, 0.0]\nscale = 2.0\n", glb.display()),
    )
    .expect("write");
    let s = Scene::load(toml.to_str().expect("utf-8")).expect("scene");
    assert_eq!(s.triangles.len(), 12);
    assert_bounds(&s, [9.0, -1.0, -1.0], [11.0, 1.0, 1.0], 1e-5);
}

/// A mesh three nodes draw: two become instances; the one scaled to nothing (as files
/// hide nodes) has no inverse and is drawn flat instead of failing the file.
#[test]
fn shared_meshes_become_instances_and_a_node_scaled_to_nothing_stays_flat() {
    let json = r#"{
      "asset": {"version": "2.0"},
      "scene": 0,
      "scenes": [{"nodes": [0, 1, 2]}],
      "nodes": [
        {"mesh": 0},
        {"mesh": 0, "scale": [0, 0, 0]},
        {"mesh": 0, "translation": [2, 0, 0], "rotation": [0, 0, 0.7071068, 0.7071068]}
      ],
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
"#;
    let json = [json, ONE_TRIANGLE].concat();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("shared.gltf");
    std::fs::write(&path, &json).expect("gltf");
    let s = Scene::load(&path.display().to_string()).expect("loads");
    let inst = s.instancing.as_ref().expect("instances");
    assert_eq!((inst.prototypes.len(), inst.instances.len()), (1, 2));
    assert_eq!((s.triangles.len(), s.drawn_triangles()), (1, 3));
    let f = s.flattened().expect("flattened");
    assert_eq!(f.triangles.len(), 3);
    // The rotated copy: (0,0,0), (1,0,0), (0,1,0) turned 90 degrees about z, moved by +2 x.
    let last = f.triangles[2].map(|i| f.positions[i as usize]);
    for (p, want) in last.iter().zip([[2.0, 0.0, 0.0], [2.0, 1.0, 0.0], [1.0, 0.0, 0.0]]) {
        assert!((*p - glam::Vec3::from(want)).length() < 1e-5, "{p} vs {want:?}");
    }
    // As the file of a [[mesh]], the whole file is one flat mesh.
    let mesh = arbor::scene::load_mesh(&path).expect("mesh");
    assert_eq!(mesh.triangles.len(), 3);
}

/// glTF's metals are metallic-roughness materials of metallic 1 (Schlick's Fresnel
/// from the base colour), transmissive materials rough dielectrics with KHR_materials_ior's index; an
/// extension the file uses but arbor does not read is named once in a warning, for
/// the scene and for a mesh of a scene file.
#[test]
fn metals_and_transmission_map_to_microfacet_materials() {
    let json = r#"{
      "asset": {"version": "2.0"},
      "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_clearcoat"],
      "scene": 0,
      "scenes": [{"nodes": [0, 1]}],
      "nodes": [{"mesh": 0}, {"mesh": 1, "translation": [2, 0, 0]}],
      "materials": [
        {"name": "gold", "pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.77, 0.34, 1],
                                                   "metallicFactor": 1, "roughnessFactor": 0.3}},
        {"name": "frosted", "pbrMetallicRoughness": {"metallicFactor": 0, "roughnessFactor": 0.4},
         "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1},
                        "KHR_materials_ior": {"ior": 1.33},
                        "KHR_materials_clearcoat": {"clearcoatFactor": 1}}}
      ],
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]},
                 {"primitives": [{"attributes": {"POSITION": 0}, "material": 1}]}],
"#;
    let json = [json, ONE_TRIANGLE].concat();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("materials.gltf");
    std::fs::write(&path, &json).expect("gltf");
    let s = Scene::load(&path.display().to_string()).expect("loads");
    let by_name = |n: &str| s.materials.iter().find(|m| m.name == n).expect(n);
    let gold = by_name("gold");
    assert_eq!((gold.kind, gold.roughness, gold.metallic), (MaterialKind::Pbr, 0.3, 1.0));
    assert!((gold.color - glam::Vec3::new(1.0, 0.77, 0.34)).length() < 1e-6, "F0 is the base colour");
    let frosted = by_name("frosted");
    assert_eq!((frosted.kind, frosted.roughness, frosted.ior), (MaterialKind::Dielectric, 0.4, 1.33));
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
    assert!(
        s.warnings[0].contains("KHR_materials_clearcoat") && s.warnings[0].contains("materials.gltf"),
        "{:?}",
        s.warnings
    );
    assert!(!s.warnings[0].contains("KHR_materials_ior"), "{:?}", s.warnings);
    // As the file of two [[mesh]] tables: still one warning.
    let toml = dir.path().join("s.toml");
    std::fs::write(&toml, "[[mesh]]\nfile = \"materials.gltf\"\n[[mesh]]\nfile = \"materials.gltf\"\n").expect("toml");
    let t = Scene::load(&toml.display().to_string()).expect("loads");
    assert_eq!(t.warnings, s.warnings);
}

/// The metallic-roughness texture, the normal texture (a 16-bit PNG) with its scale,
/// the emissive texture and KHR_materials_specular come through to the material; what
/// is not read (a texture of coordinate set 1, a specular texture) is named in one
/// warning, vertex colours are read, alphaMode MASK and its default cutoff are read; a file whose textures need UVs it lacks is an error naming the material.
#[test]
fn metallic_roughness_maps_and_specular_come_through() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, px) in [("mr.png", [0u8, 128, 255, 255]), ("e.png", [255, 0, 0, 255])] {
        image::RgbaImage::from_pixel(2, 2, image::Rgba(px)).save(dir.path().join(name)).expect("png");
    }
    // The normal map in 16 bits per channel, as many are: rounded to 8.
    let n16 = image::ImageBuffer::from_pixel(2, 2, image::Rgba([32_896u16, 32_896, 65_535, 65_535]));
    n16.save(dir.path().join("n.png")).expect("16-bit png");
    write_uv_triangle(dir.path());
    let gltf = |uvs: bool| {
        let attributes = if uvs { r#"{"POSITION": 0, "TEXCOORD_0": 1, "COLOR_0": 0}"# } else { r#"{"POSITION": 0}"# };
        format!(
            r#"{{
      "asset": {{"version": "2.0"}},
      "extensionsUsed": ["KHR_materials_specular", "KHR_materials_ior"],
      "scenes": [{{"nodes": [0]}}],
      "nodes": [{{"mesh": 0}}],
      "images": [{{"uri": "mr.png"}}, {{"uri": "n.png"}}, {{"uri": "e.png"}}],
      "textures": [{{"source": 0}}, {{"source": 1}}, {{"source": 2}}],
      "materials": [{{
        "name": "mapped", "alphaMode": "MASK",
        "pbrMetallicRoughness": {{"baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0.8,
                                 "roughnessFactor": 0.6, "metallicRoughnessTexture": {{"index": 0}},
                                 "baseColorTexture": {{"index": 2, "texCoord": 1}}}},
        "normalTexture": {{"index": 1, "scale": 0.5}},
        "emissiveFactor": [1, 1, 1], "emissiveTexture": {{"index": 2}},
        "extensions": {{"KHR_materials_specular": {{"specularFactor": 0.5, "specularColorFactor": [1, 0.5, 0.25],
                                                   "specularTexture": {{"index": 0}}}},
                       "KHR_materials_ior": {{"ior": 2.0}}}}
      }}],
      "meshes": [{{"primitives": [{{"attributes": {attributes}, "material": 0}}]}}],
"#
        ) + UV_TRIANGLE
    };
    let path = dir.path().join("mapped.gltf");
    std::fs::write(&path, gltf(true)).expect("gltf");
    let s = Scene::load(&path.display().to_string()).expect("loads");
    let m = s.materials.iter().find(|m| m.name == "mapped").expect("material");
    assert_eq!((m.kind, m.metallic, m.roughness, m.specular_weight), (MaterialKind::Pbr, 0.8, 0.6, 0.5));
    let f0 = (1.0f32 / 3.0).powi(2);
    assert!((m.dielectric_f0 - glam::Vec3::new(1.0, 0.5, 0.25) * f0).length() < 1e-6, "{}", m.dielectric_f0);
    let (mr, n) = (m.maps.metal_rough.expect("metallic-roughness"), m.maps.normal.expect("normal map"));
    assert_eq!(s.textures[mr as usize].texels[0], [0, 128, 255, 255]);
    assert_eq!(s.textures[n as usize].texels[0], [128, 128, 255, 255]);
    assert_eq!(m.maps.normal_scale, 0.5);
    assert_eq!(m.texture, None, "a base colour texture of set 1 is not read");
    let e = m.maps.emission.expect("emissive texture");
    assert_eq!((m.emission, s.textures[e as usize].texels[0]), (glam::Vec3::ONE, [255, 0, 0, 255]));
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
    for what in ["texture-coordinate set 1", "KHR_materials_specular textures"] {
        assert!(s.warnings[0].contains(what), "{what}: {:?}", s.warnings);
    }
    // COLOR_0 (here the positions' accessor, floats) is read, not warned about.
    assert!(!s.warnings[0].contains("COLOR_0"), "{:?}", s.warnings);
    let corners = [[0.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0]];
    assert_eq!(s.colors, corners.map(glam::Vec4::from).to_vec());
    assert!(!s.warnings[0].contains("alpha"), "{:?}", s.warnings);
    assert_eq!((m.alpha_mode, m.opacity), (arbor::scene::AlphaMode::Mask { cutoff: 0.5 }, 1.0));
    assert!(!s.warnings[0].contains("emissive"), "{:?}", s.warnings);
    std::fs::write(&path, gltf(false)).expect("gltf");
    let e = Scene::load(&path.display().to_string()).expect_err("maps without UVs").to_string();
    assert!(e.contains("'mapped'") && e.contains("texture coordinates"), "{e}");
}

/// KHR_texture_transform: a material's transform (offset, then rotation, then scale,
/// on glTF's UVs) is baked into its primitives' texture coordinates; the extension is
/// not named as unread; textures of one material with different transforms are. An
/// image under two samplers is two textures, each with its sampler's wrap modes.
#[test]
fn texture_transforms_move_the_texture_coordinates() {
    let dir = tempfile::tempdir().expect("tempdir");
    image::RgbaImage::from_pixel(2, 2, image::Rgba([255, 255, 255, 255])).save(dir.path().join("t.png")).expect("png");
    write_uv_triangle(dir.path());
    let gltf = |emissive: &str| {
        format!(
            r#"{{
      "asset": {{"version": "2.0"}},
      "extensionsUsed": ["KHR_texture_transform"],
      "scenes": [{{"nodes": [0]}}],
      "nodes": [{{"mesh": 0}}],
      "images": [{{"uri": "t.png"}}],
      "samplers": [{{"wrapS": 33071, "wrapT": 33648}}],
      "textures": [{{"source": 0, "sampler": 0}}, {{"source": 0}}],
      "materials": [{{
        "pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0, "extensions": {{"KHR_texture_transform":
            {{"offset": [0.5, 0], "rotation": 1.5707963267948966, "scale": [2, 1]}}}}}}}},
        "emissiveFactor": [1, 1, 1], "emissiveTexture": {{"index": 1{emissive}}}
      }}],
      "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}}, "material": 0}}]}}],
"#
        ) + UV_TRIANGLE
    };
    let path = dir.path().join("moved.gltf");
    let same = r#", "extensions": {"KHR_texture_transform": {"offset": [0.5, 0], "rotation": 1.5707963267948966, "scale": [2, 1]}}"#;
    std::fs::write(&path, gltf(same)).expect("gltf");
    let s = Scene::load(&path.display().to_string()).expect("loads");
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    // One image under two samplers: two textures, each with its sampler's wrap.
    use arbor::scene::Wrap;
    let m = s.materials.iter().find(|m| m.name == "gltf material 0").expect("the material");
    let (base, glow) = (m.texture.expect("base colour"), m.maps.emission.expect("emissive"));
    assert_eq!(s.textures.len(), 2);
    assert_eq!(s.textures[base as usize].wrap, [Wrap::Clamp, Wrap::Mirror]);
    assert_eq!(s.textures[glow as usize].wrap, [Wrap::Repeat, Wrap::Repeat]);
    // glTF (u, v): scaled by (2, 1), turned a quarter (u' = v, v' = -u), moved by
    // (0.5, 0); then arbor's v = 1 - v.
    for (k, want) in [[1.5, 1.0], [1.5, 3.0], [0.5, 1.0]].into_iter().enumerate() {
        assert!((s.uvs[k] - glam::Vec2::from(want)).length() < 1e-5, "vertex {k}: {} vs {want:?}", s.uvs[k]);
    }
    std::fs::write(&path, gltf("")).expect("gltf");
    let s = Scene::load(&path.display().to_string()).expect("loads");
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
    assert!(s.warnings[0].contains("KHR_texture_transform differing"), "{:?}", s.warnings);
    assert!((s.uvs[1] - glam::Vec2::new(1.5, 3.0)).length() < 1e-5, "the base colour's transform: {}", s.uvs[1]);
    // Khronos's test file loads without a warning.
    if have_models() {
        let s = load("textureTransform/TextureTransformTest.gltf");
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    }
}
