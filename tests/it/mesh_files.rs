//! Mesh loader tests: every OBJ/PLY/OFF model of Debian's `assimp-testmodels` package must
//! load or fail cleanly (never panic), known-good models must give hand-counted triangle
//! numbers, and small hand-written files check each error message (file name, line).

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use arbor::error::{Error, Result};
use arbor::scene::mesh::{MaterialKind, MeshData};
use arbor::scene::{obj, off, ply};

const MODELS: &str = "/usr/share/assimp/models";

/// The assimp model folder. Missing means a broken test setup, not a skipped test.
fn models() -> PathBuf {
    let dir = PathBuf::from(MODELS);
    assert!(
        dir.is_dir(),
        "{MODELS} is missing: install Debian's assimp-testmodels package \
         (apt-get install assimp-testmodels); these tests need its model files"
    );
    dir
}

type Loader = fn(&Path) -> Result<MeshData>;

fn loader_for(path: &Path) -> Option<Loader> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    match ext.as_str() {
        "obj" => Some(obj::load),
        "ply" => Some(ply::load),
        "off" => Some(off::load),
        _ => None,
    }
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            walk(&path, out);
        } else {
            out.push(path);
        }
    }
}

/// Invariants every successfully loaded mesh must satisfy.
fn check_invariants(path: &Path, m: &MeshData) {
    let n = m.positions.len();
    for t in &m.triangles {
        assert!(t.iter().all(|&i| (i as usize) < n), "{}: triangle {t:?} out of range ({n} vertices)", path.display());
    }
    assert!(m.positions.iter().all(|p| p.is_finite()), "{}: non-finite position", path.display());
    if let Some(normals) = &m.normals {
        assert_eq!(normals.len(), n, "{}: normals/positions length", path.display());
        assert!(
            normals.iter().all(|v| (v.length() - 1.0).abs() < 1e-4),
            "{}: normals must be unit length",
            path.display()
        );
    }
    if m.materials.is_empty() {
        assert!(m.tri_material.is_empty(), "{}: tri_material without materials", path.display());
    } else {
        assert_eq!(m.tri_material.len(), m.triangles.len(), "{}: one material per triangle", path.display());
        assert!(m.tri_material.iter().all(|&i| (i as usize) < m.materials.len()), "{}", path.display());
    }
}

fn run(load: Loader, path: &Path) -> std::thread::Result<Result<MeshData>> {
    catch_unwind(AssertUnwindSafe(|| load(path)))
}

#[test]
fn every_assimp_model_loads_or_errs_without_panicking() {
    let root = models();
    let mut files = Vec::new();
    walk(&root, &mut files);
    let mut targets: Vec<(PathBuf, Loader)> =
        files.into_iter().filter_map(|p| loader_for(&p).map(|l| (p, l))).collect();
    // An OFF file without extension (assimp's format detection test).
    targets.push((root.join("OFF/formatDetection"), off::load));
    assert!(targets.len() >= 40, "found only {} OBJ/PLY/OFF files under {MODELS}", targets.len());

    let mut panicked = Vec::new();
    for (path, load) in &targets {
        match run(*load, path) {
            Ok(Ok(mesh)) => {
                check_invariants(path, &mesh);
                eprintln!("loaded {}: {} triangles", path.display(), mesh.triangles.len());
            }
            Ok(Err(e)) => {
                let msg = e.to_string();
                eprintln!("error  {}: {msg}", path.display());
                let name = path.file_name().unwrap().to_string_lossy();
                assert!(msg.contains(&*name), "error for {} does not name the file: {msg}", path.display());
            }
            Err(_) => panicked.push(path.display().to_string()),
        }
    }
    assert!(panicked.is_empty(), "loaders panicked on: {panicked:?}");
}

/// Triangle and vertex counts verified by hand (face lines and polygon sizes counted with
/// awk; binary PLY decoded with a separate script): triangles = sum over faces of (n - 2).
#[test]
fn known_good_models_have_the_expected_triangle_counts() {
    let root = models();
    let cases: [(&str, Loader, usize, Option<usize>, bool); 22] = [
        // path, loader, triangles, vertices (None: not checked), has normals
        ("OBJ/box.obj", obj::load, 12, Some(8), false),
        ("OBJ/box_without_lineending.obj", obj::load, 12, Some(8), false),
        ("OBJ/box_UTF16BE.obj", obj::load, 12, Some(8), false),
        ("OBJ/box_longline.obj", obj::load, 944, Some(8), false),
        ("OBJ/cube_usemtl.obj", obj::load, 12, None, true),
        ("OBJ/cube_with_vertexcolors.obj", obj::load, 12, None, true),
        ("OBJ/testmixed.obj", obj::load, 12, Some(8), false),
        ("OBJ/testline.obj", obj::load, 0, Some(0), false),
        ("OBJ/concave_polygon.obj", obj::load, 64, Some(64), true),
        // spider.obj has a zero-length "vn 0 0 0": the mesh is treated as having no normals.
        ("OBJ/spider.obj", obj::load, 1368, None, false),
        ("OBJ/WusonOBJ.obj", obj::load, 3732, None, true),
        ("OBJ/regr01.obj", obj::load, 2710, None, false),
        ("OBJ/empty_mat.obj", obj::load, 256, None, true),
        ("PLY/cube.ply", ply::load, 12, Some(8), false),
        ("PLY/cube_binary.ply", ply::load, 12, Some(8), false),
        ("PLY/cube_uv.ply", ply::load, 12, Some(24), true),
        ("PLY/Wuson.ply", ply::load, 3732, Some(11184), true),
        ("PLY/float-color.ply", ply::load, 1, Some(3), false),
        ("PLY/points.ply", ply::load, 0, Some(4), true),
        ("OFF/Cube.off", off::load, 12, Some(8), false),
        ("OFF/formatDetection", off::load, 12, Some(8), false),
        ("OFF/Wuson.off", off::load, 3732, Some(3205), false),
    ];
    for (rel, load, tris, verts, normals) in cases {
        let path = root.join(rel);
        let mesh = match run(load, &path) {
            Ok(Ok(m)) => m,
            Ok(Err(e)) => panic!("{rel} should load: {e}"),
            Err(_) => panic!("{rel}: loader panicked"),
        };
        check_invariants(&path, &mesh);
        assert_eq!(mesh.triangles.len(), tris, "{rel}: triangles");
        if let Some(v) = verts {
            assert_eq!(mesh.positions.len(), v, "{rel}: vertices");
        }
        assert_eq!(mesh.normals.is_some(), normals, "{rel}: normals");
    }
}

#[test]
fn assimp_models_materials() {
    let root = models();
    // usemtl mtl, mtl2 (from the MTL) and mtl3 (not defined: default).
    let m = obj::load(&root.join("OBJ/cube_usemtl.obj")).unwrap();
    let names: Vec<&str> = m.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["mtl", "mtl2", "default"]);
    assert_eq!(m.tri_material, [2, 2, 0, 0, 0, 1, 1, 1, 1, 0, 0, 0]);
    assert_eq!(m.materials[0].kind, MaterialKind::Phong);
    assert_eq!(m.materials[0].shininess, 200.0);
    assert_eq!(m.materials[2].kind, MaterialKind::Lambert);

    // `usemtl` without any mtllib: every face gets the default material.
    let m = obj::load(&root.join("OBJ/box.obj")).unwrap();
    assert_eq!(m.materials.len(), 1);
    assert_eq!(m.tri_material, [0; 12]);

    // The MTL named by mtllib does not exist (.mat): not fatal.
    let m = obj::load(&root.join("OBJ/cube_mtllib_after_g.obj")).unwrap();
    assert_eq!((m.triangles.len(), m.materials.len()), (12, 1));
    assert_eq!(m.materials[0].name, "default");

    // Latin-1 material name in both files; "Windows" has d 0.5.
    let m = obj::load(&root.join("OBJ/regr01.obj")).unwrap();
    let windows = m.materials.iter().find(|m| m.name == "Windows").expect("Windows material");
    assert_eq!(windows.kind, MaterialKind::Glass);
    assert!(m.materials.iter().all(|m| m.name != "default"), "all materials resolve");

    // Material name with spaces.
    let m = obj::load(&root.join("OBJ/box_mat_with_spaces.obj")).unwrap();
    assert_eq!(m.materials[m.tri_material[0] as usize].name, "Material name with many, many spaces");

    // No materials mentioned: no materials at all.
    let m = obj::load(&root.join("OBJ/WusonOBJ.obj")).unwrap();
    assert!(m.materials.is_empty() && m.tri_material.is_empty());
}

#[test]
fn assimp_malformed_models_are_errors() {
    let root = models();
    let cases: [(&str, Loader, Option<usize>, &str); 9] = [
        ("invalid/malformed.obj", obj::load, Some(23), "face references vertex 12 but the file has 8 vertices"),
        ("OBJ/number_formats.obj", obj::load, Some(11), "vertex 8: '3.1+e2' is not a number"),
        ("invalid/OutOfMemory.off", off::load, Some(2), "353535235358"),
        ("invalid/empty.off", off::load, Some(1), "empty"),
        // Line 7 is "2\r20": a face "2 20" (\r is whitespace inside a line).
        ("OFF/invalid.off", off::load, Some(7), "face 1 references vertex 20 but the file has 3 vertices"),
        ("invalid/empty.ply", ply::load, Some(1), "empty"),
        ("PLY/issue623.ply", ply::load, Some(13), "vertex_indices"),
        ("PLY/pond.0.ply", ply::load, None, "truncated"),
        ("invalid/empty.obj", obj::load, None, ""),
    ];
    for (rel, load, line, want) in cases {
        let path = root.join(rel);
        let result = run(load, &path).unwrap_or_else(|_| panic!("{rel}: loader panicked"));
        if rel == "invalid/empty.obj" {
            // An empty OBJ is a mesh with no triangles, not an error at this level.
            assert!(result.unwrap().triangles.is_empty());
            continue;
        }
        let e = result.err().unwrap_or_else(|| panic!("{rel} should fail"));
        let msg = e.to_string();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        assert!(msg.contains(&name) && msg.contains(want), "{rel}: {msg}");
        if let Some(line) = line {
            assert!(matches!(e, Error::Parse { line: l, .. } if l == line), "{rel}: want line {line}: {msg}");
        }
    }
}

// ---------------------------------------------------------------------------------------
// Hand-written files.

fn write(dir: &tempfile::TempDir, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.path().join(name);
    std::fs::write(&path, contents).unwrap();
    path
}

/// Asserts `result` is a parse error at `line` whose message names the file and contains `want`.
fn expect_parse(result: Result<MeshData>, name: &str, line: usize, want: &str) {
    let e = result.err().unwrap_or_else(|| panic!("{name}: expected an error"));
    let msg = e.to_string();
    assert!(msg.contains(name), "message should name {name}: {msg}");
    assert!(msg.contains(&format!(":{line}:")), "message should name line {line}: {msg}");
    assert!(matches!(e, Error::Parse { line: l, .. } if l == line), "{msg}");
    assert!(msg.contains(want), "message should contain '{want}': {msg}");
}

/// Asserts `result` is an error without a line whose message names the file and contains all of `want`.
fn expect_invalid(result: Result<MeshData>, name: &str, want: &[&str]) {
    let e = result.err().unwrap_or_else(|| panic!("{name}: expected an error"));
    let msg = e.to_string();
    assert!(matches!(e, Error::Invalid { .. }), "{msg}");
    assert!(msg.contains(name), "message should name {name}: {msg}");
    for w in want {
        assert!(msg.contains(w), "message should contain '{w}': {msg}");
    }
}

#[test]
fn missing_files_are_io_errors() {
    let dir = tempfile::tempdir().unwrap();
    for (name, load) in [("nope.obj", obj::load as Loader), ("nope.ply", ply::load), ("nope.off", off::load)] {
        let e = load(&dir.path().join(name)).unwrap_err();
        assert!(matches!(e, Error::Io { .. }), "{e}");
        assert!(e.to_string().contains(name), "{e}");
    }
}

const PLY_HEAD: &str = "ply\nformat ascii 1.0\ncomment hand written\nelement vertex 3\n\
    property float x\nproperty float y\nproperty float z\nelement face 1\n\
    property list uchar int vertex_indices\nend_header\n";

#[test]
fn ply_errors() {
    let dir = tempfile::tempdir().unwrap();
    let case = |name: &str, text: &str| ply::load(&write(&dir, name, text));
    // Header is lines 1-10; vertices are lines 11-13, the face line 14.
    expect_parse(case("magic.ply", "plx\nformat ascii 1.0\nend_header\n"), "magic.ply", 1, "not a PLY file");
    expect_parse(
        case("format.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n"),
        "format.ply",
        2,
        "unknown format",
    );
    expect_parse(case("noend.ply", "ply\nformat ascii 1.0\nelement vertex 1\n"), "noend.ply", 3, "end_header");
    expect_parse(
        case("trunc.ply", &format!("{PLY_HEAD}0 0 0\n1 0 0\n")),
        "trunc.ply",
        13,
        "file ends before vertex 2 of 3",
    );
    expect_parse(
        case("nan_text.ply", &format!("{PLY_HEAD}0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n")),
        "nan_text.ply",
        12,
        "'zero'",
    );
    expect_parse(
        case("range.ply", &format!("{PLY_HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 1 99\n")),
        "range.ply",
        14,
        "face 0 references vertex 99 but the file has 3 vertices",
    );
    expect_parse(
        case("nan.ply", &format!("{PLY_HEAD}0 0 0\n1 0 0\n0 NaN 0\n3 0 1 2\n")),
        "nan.ply",
        13,
        "vertex 2 has a non-finite coordinate",
    );
    expect_parse(case("inf.ply", &format!("{PLY_HEAD}0 0 0\n1e39 0 0\n0 1 0\n3 0 1 2\n")), "inf.ply", 12, "non-finite");
}

fn ply_binary(big_endian: bool, verts: &[[f32; 3]], faces: &[&[u32]], truncate: usize) -> Vec<u8> {
    let fmt = if big_endian { "binary_big_endian" } else { "binary_little_endian" };
    let mut out = format!(
        "ply\nformat {fmt} 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        verts.len(),
        faces.len()
    )
    .into_bytes();
    for v in verts {
        for c in v {
            out.extend(if big_endian { c.to_be_bytes() } else { c.to_le_bytes() });
        }
    }
    for f in faces {
        out.push(f.len() as u8);
        for i in *f {
            out.extend(if big_endian { i.to_be_bytes() } else { i.to_le_bytes() });
        }
    }
    out.truncate(out.len() - truncate);
    out
}

#[test]
fn ply_binary_files() {
    let dir = tempfile::tempdir().unwrap();
    let verts = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    for be in [false, true] {
        let m = ply::load(&write(&dir, "quad.ply", ply_binary(be, &verts, &[&[0, 1, 2, 3], &[3, 2]], 0))).unwrap();
        assert_eq!(m.triangles, [[0, 1, 2], [0, 2, 3]], "big endian {be}");
        assert_eq!(m.positions[2], glam::Vec3::new(1.0, 1.0, 0.0));
        assert!(m.materials.is_empty() && m.tri_material.is_empty());

        let r = ply::load(&write(&dir, "short.ply", ply_binary(be, &verts, &[&[0, 1, 2]], 1)));
        expect_invalid(r, "short.ply", &["truncated", "byte offset"]);

        let r = ply::load(&write(&dir, "index.ply", ply_binary(be, &verts, &[&[0, 1, 40]], 0)));
        expect_invalid(r, "index.ply", &["face 0 references vertex 40 but the file has 4 vertices", "byte offset"]);

        let mut bad = verts;
        bad[3][1] = f32::INFINITY;
        let r = ply::load(&write(&dir, "inf.ply", ply_binary(be, &bad, &[], 0)));
        expect_invalid(r, "inf.ply", &["vertex 3 has a non-finite coordinate", "byte offset"]);
    }
}

#[test]
fn zero_triangles_is_not_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let m = ply::load(&write(&dir, "pts.ply", ply_binary(false, &[[1.0, 2.0, 3.0]], &[], 0))).unwrap();
    assert_eq!((m.positions.len(), m.triangles.len()), (1, 0));
    let m = off::load(&write(&dir, "none.off", "OFF\n1 0 0\n1 2 3\n")).unwrap();
    assert_eq!((m.positions.len(), m.triangles.len()), (1, 0));
    let m = obj::load(&write(&dir, "none.obj", "v 1 2 3\n")).unwrap();
    assert!(m.triangles.is_empty() && m.materials.is_empty());
}

#[test]
fn off_errors() {
    let dir = tempfile::tempdir().unwrap();
    let case = |name: &str, text: &str| off::load(&write(&dir, name, text));
    expect_parse(case("magic.off", "# comment\nOFX\n3 1 0\n"), "magic.off", 2, "not an OFF file");
    expect_parse(case("counts.off", "OFF\n3 many 0\n"), "counts.off", 2, "face count 'many'");
    expect_parse(case("trunc.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n"), "trunc.off", 5, "file ends after 2 of 3 vertices");
    expect_parse(case("text.off", "OFF\n3 1 0\n0 0 0\n1 O 0\n0 1 0\n3 0 1 2\n"), "text.off", 4, "'O' is not a number");
    expect_parse(
        case("range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n\n3 0 1 99\n"),
        "range.off",
        7,
        "face 0 references vertex 99 but the file has 3 vertices",
    );
    expect_parse(
        case("nan.off", "OFF\n3 1 0\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n"),
        "nan.off",
        4,
        "vertex 1 has a non-finite coordinate",
    );
    expect_parse(
        case("faces.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"),
        "faces.off",
        7,
        "file ends after 1 of 2 faces",
    );
}

#[test]
fn off_variants() {
    let dir = tempfile::tempdir().unwrap();
    let m = off::load(&write(
        &dir,
        "n.off",
        "NOFF\n# normals\n4 1 0\n0 0 0 0 0 5\n1 0 0 0 0 1\n1 1 0 0 0 1\n0 1 0 0 0 1\n4 0 1 2 3 1 0 0\n",
    ))
    .unwrap();
    assert_eq!(m.triangles, [[0, 1, 2], [0, 2, 3]]);
    assert_eq!(m.normals.unwrap()[0], glam::Vec3::Z);
    let m = off::load(&write(&dir, "c.off", "COFF\n3 1 0\n0 0 0 1 0 0 1\n1 0 0 0 1 0 1\n0 1 0 0 0 1 1\n3 0 1 2\n"))
        .unwrap();
    assert_eq!(m.triangles.len(), 1);
    assert!(m.normals.is_none());
}

#[test]
fn obj_errors() {
    let dir = tempfile::tempdir().unwrap();
    let case = |name: &str, text: &str| obj::load(&write(&dir, name, text));
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    expect_parse(case("text.obj", "v 0 0 0\nv 1 zero 0\n"), "text.obj", 2, "vertex 2: 'zero' is not a number");
    expect_parse(
        case("range.obj", &format!("# three vertices\n{tri}f 1 2 99\n")),
        "range.obj",
        5,
        "face references vertex 99 but the file has 3 vertices",
    );
    expect_parse(case("rel.obj", &format!("{tri}f -1 -2 -4\n")), "rel.obj", 4, "vertex -4 (relative)");
    expect_parse(
        case("nan.obj", "v 0 0 0\nv 1 0 0\nv 0 NaN 0\nf 1 2 3\n"),
        "nan.obj",
        3,
        "vertex 3 has a non-finite coordinate",
    );
    expect_parse(case("inf.obj", "v 0 0 0\nv 1e40 0 0\n"), "inf.obj", 2, "vertex 2 has a non-finite coordinate");
    // Errors tobj reports still carry the line it stopped on.
    expect_parse(case("vn.obj", &format!("{tri}vn 0 x 1\nf 1 2 3\n")), "vn.obj", 4, "normal");
    expect_parse(
        case("truncated.obj", &format!("{tri}f 1 2 3\nv 1 2")),
        "truncated.obj",
        5,
        "vertex 4 has 2 coordinates",
    );
}

#[test]
fn obj_materials_normals_and_models() {
    let dir = tempfile::tempdir().unwrap();
    write(
        &dir,
        "lib.mtl",
        "newmtl light\nKe 5 5 5\nKd 0 0 0\n\
         newmtl mirror\nillum 3\nKd 0 0 0\nKs 1 1 1\n\
         newmtl glass\nillum 7\nNi 1.45\nKd 1 1 1\n\
         newmtl plastic\nKd 0.5 0 0\nKs 0.5 0.5 0.5\nNs 64\n\
         newmtl chalk\nKd 0.9\n",
    );
    let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";
    let body = format!(
        "mtllib lib.mtl\no a\n{quad}\
         usemtl light\nf 1 2 3\nusemtl mirror\nf 1 3 4\nusemtl glass\nf 1 2 3\n\
         usemtl plastic\nf 1 2 3\nusemtl chalk\nf 1 2 3\nusemtl missing\nf 1 2 3\n\
         o b\nv 5 5 5\nv 6 5 5\nv 5 6 5\nf 5 6 7\nf -3 -2 -1\n"
    );
    let m = obj::load(&write(&dir, "scene.obj", &body)).unwrap();
    let kinds: Vec<_> = m.materials.iter().map(|m| (m.name.as_str(), m.kind)).collect();
    assert_eq!(
        kinds,
        [
            ("light", MaterialKind::Emissive),
            ("mirror", MaterialKind::Mirror),
            ("glass", MaterialKind::Glass),
            ("plastic", MaterialKind::Phong),
            ("chalk", MaterialKind::Lambert),
            ("default", MaterialKind::Lambert),
        ]
    );
    assert_eq!(m.materials[0].emission, glam::Vec3::splat(5.0));
    assert_eq!(m.materials[2].ior, 1.45);
    assert_eq!(m.materials[3].shininess, 64.0);
    assert_eq!(m.materials[4].color, glam::Vec3::splat(0.9));
    assert_eq!(m.triangles.len(), 8);
    assert_eq!(m.tri_material, [0, 1, 2, 3, 4, 5, 5, 5]);
    // Models are concatenated: the second one's triangles point at its own vertices.
    let last = m.triangles[7];
    assert!(last.iter().all(|&i| m.positions[i as usize].x >= 5.0), "{last:?}");

    // A missing MTL and a broken one are not fatal.
    let m = obj::load(&write(&dir, "nolib.obj", format!("mtllib absent.mtl\n{quad}usemtl x\nf 1 2 3 4\n"))).unwrap();
    assert_eq!((m.triangles.len(), m.materials.len(), m.tri_material.clone()), (2, 1, vec![0, 0]));
    write(&dir, "broken.mtl", "newmtl a\nKd 1 2\nnewmtl b\nNs many\n");
    let m = obj::load(&write(&dir, "broken.obj", format!("mtllib broken.mtl\n{quad}usemtl a\nf 1 2 3 4\n"))).unwrap();
    assert_eq!(m.materials.len(), 1);
    assert_eq!(m.materials[0].name, "default");

    // Normals: normalised when complete; dropped if any is zero or some vertex has none.
    let m = obj::load(&write(&dir, "n.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 3\nf 1//1 2//1 3//1\n")).unwrap();
    assert_eq!(m.normals.unwrap(), [glam::Vec3::Z; 3]);
    let m = obj::load(&write(&dir, "z.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nf 1//1 2//1 3//1\n")).unwrap();
    assert!(m.normals.is_none());
    let m = obj::load(&write(&dir, "p.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3\n")).unwrap();
    assert!(m.normals.is_none());
}
