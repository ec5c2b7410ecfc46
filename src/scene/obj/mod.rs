//! Wavefront OBJ loader with MTL materials, built on `tobj`.
//!
//! # Pipeline
//!
//! 1. The file is read and decoded as text: UTF-8 (a BOM is skipped), UTF-16 with a BOM, and
//!    invalid UTF-8 replaced by U+FFFD (names only ever need to match each other).
//! 2. A pre-pass, one output line per input line so line numbers stay valid, checks what
//!    `tobj` either does not check or reports without a location, and rewrites what it
//!    mishandles:
//!    * `v x y z [w | r g b ...]`: coordinates must be numbers, `w` non-zero, the result
//!      finite; the line is rewritten as `v x/w y/w z/w`. Colours `r g b` are kept when
//!      every vertex of the file has them (then they are the mesh's vertex colours,
//!      linear like glTF's, alpha 1; crate::scene::colors); otherwise they are dropped,
//!      so that vertices with and without colours can mix.
//!    * `vt u`: the missing second texture coordinate is written as 0.
//!    * `f`: every `v[/vt[/vn]]` reference must be a non-zero integer inside the file's
//!      vertex / texture / normal lists (negative = relative to the entries so far). `vt` and
//!      `vn` references are only checked when the file has that kind of entry (`tobj`
//!      ignores them otherwise). Faces with fewer than three vertices are dropped.
//!    * `l` (polylines) are dropped; `p` (points) are ignored by `tobj` anyway.
//!    * `usemtl` with no name selects the default material.
//! 3. `tobj` parses the result with `triangulate` (fans) and `single_index` (one index per
//!    unique `v/vt/vn` combination). Its remaining errors get the line it stopped on.
//! 4. All models are concatenated into one [`MeshData`].
//!
//! # Materials
//!
//! `mtllib` files are resolved relative to the OBJ file. A missing or malformed MTL is
//! not an error: its materials are absent and the faces using them get the default grey
//! Lambert material. An MTL that is not a regular file (a FIFO, a device) or is larger
//! than [`limits::MAX_TEXT_FILE_BYTES`] is an error at its `mtllib` line. Each distinct
//! library is read once however often it is named, at most [`limits::MAX_MTLLIBS`] of
//! them, defining at most [`limits::MAX_MATERIALS`] materials in all. When the file uses no materials at all (no `mtllib`, no `usemtl`)
//! `materials` and `tri_material` are empty; otherwise every triangle has a material and
//! the default is appended to `materials` if some triangle needs it.
//!
//! MTL → [`Material`]:
//! * `Kd` → `color` (grey 0.8 when absent), `Ks` → `specular`, `Ns` → `shininess`,
//!   `Ni` → `ior` (when positive), `Ke` → `emission`.
//! * kind, first match wins: `Emissive` if `Ke` is non-zero; `Mirror` if `illum 3`, `Ks`
//!   bright (largest component ≥ 0.5) and `Kd` black or absent (then `color` = `Ks`, the
//!   reflectance tint); `Glass` if `illum` is 4, 6 or 7 or `d` < 1 (then `color` = `Tf`
//!   when given, the transmission tint); `Phong` if `Ks` is non-zero; otherwise `Lambert`.
//!
//! # Normals
//!
//! Per-vertex normals are returned only when every vertex of every model has one, all
//! non-zero and finite; they are normalised. Otherwise `normals` is `None`.
//!
//! # Texture coordinates and textures
//!
//! `uvs` is returned only when every vertex of every model has a `vt` (v = 0 at the bottom
//! of the image). `map_Kd` gives a material a texture ([`crate::scene::load_texture`]); only
//! materials some face uses are looked at. The file is found relative to the MTL file's
//! folder, else the OBJ file's, also trying `\` as a folder separator; each file is read
//! once. Options before the file name: `-s u [v [w]]` and `-o u [v [w]]` transform the
//! coordinates of the faces using that material (`uv * s + o`; `w` ignored); `-blendu`,
//! `-blendv`, `-boost`, `-texres`, `-bm`, `-cc` are ignored; `-clamp off`, `-mm 0 1` and
//! `-t 0 0 0` (the defaults) are accepted; any other option is an error naming the MTL
//! file, the material and the option. A texture that cannot be read or decoded is an
//! error naming the texture file, the material and the MTL file.

mod mtl;
mod prepass;
mod text;

use std::cell::RefCell;
use std::path::Path;

use glam::{Vec2, Vec3};

use crate::error::{Error, Result};
use crate::scene::limits::{self, FileKind};
use crate::scene::mesh::{Material, MeshData};

pub use mtl::DEFAULT_MATERIAL_NAME;
use mtl::{convert_material, default_material, load_textures, Libraries, UvMap};
use prepass::{find_late_reference, prepass_in};
use text::{decode_text, LineCounter};

/// Loads the OBJ file at `path` and the MTL libraries it names.
pub fn load(path: &Path) -> Result<MeshData> {
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let pre = {
        let text = decode_text(limits::read_file(path, FileKind::Mesh)?);
        prepass_in(path, &dir, &text)?
    };

    // `..Default::default()` covers the fields tobj's optional features add.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let mut reader = LineCounter::new(pre.text.as_bytes());
    let libraries = RefCell::new(Libraries::default());
    // The pre-pass removes the inputs known to make tobj panic; this catches the rest.
    let parsed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        tobj::load_obj_buf(&mut reader, &options, |mtl| libraries.borrow_mut().load(&dir.join(mtl)))
    }));
    let libraries = libraries.into_inner();
    if let Some(e) = libraries.error {
        return Err(e);
    }
    let (models, materials) = match parsed {
        Ok(Ok(result)) => result,
        Ok(Err(e)) => return Err(tobj_error(path, &pre.text, e, reader.line())),
        Err(_) => {
            return Err(Error::invalid(
                path,
                format!("the OBJ parser (tobj) failed unexpectedly near line {}", reader.line()),
            ))
        }
    };
    // A failed MTL only loses its materials; faces using them fall back to the default.
    let tobj_materials = materials.unwrap_or_default();
    let mut materials: Vec<Material> = tobj_materials.iter().map(convert_material).collect();
    let uses_materials = pre.mentions_materials || !materials.is_empty();
    let (textures, uv_maps) = load_textures(path, &dir, &models, &tobj_materials, &libraries.origins, &mut materials)?;
    let mut mesh = assemble(path, &models, materials, uses_materials, &uv_maps)?;
    mesh.textures = textures;
    Ok(mesh)
}

/// Turns a tobj error into an [`Error`]. Errors tobj raises while reading a line get that
/// line. Index errors are raised when a group ends (`o`, `g`, `usemtl`), at line `line`:
/// the face that caused it is found by [`find_late_reference`].
fn tobj_error(path: &Path, text: &str, e: tobj::LoadError, line: usize) -> Error {
    use tobj::LoadError as E;
    if matches!(e, E::FaceVertexOutOfBounds | E::FaceTexCoordOutOfBounds | E::FaceNormalOutOfBounds) {
        if let Some((face_line, msg)) = find_late_reference(text, line) {
            return Error::parse(path, face_line, msg);
        }
    }
    match e {
        E::FaceVertexOutOfBounds
        | E::FaceTexCoordOutOfBounds
        | E::FaceNormalOutOfBounds
        | E::FaceColorOutOfBounds
        | E::InvalidPolygon
        | E::InvalidLoadOptionConfig
        | E::GenericFailure
        | E::OpenFileFailed => Error::invalid(path, format!("invalid OBJ: {e}")),
        _ => Error::parse(path, line, format!("invalid OBJ: {e}")),
    }
}

/// Concatenates tobj's models into one mesh (see the module docs for materials and normals).
fn assemble(
    path: &Path,
    models: &[tobj::Model],
    mut materials: Vec<Material>,
    uses_materials: bool,
    uv_maps: &[Option<UvMap>],
) -> Result<MeshData> {
    let mut mesh = MeshData::default();
    let mut normals: Vec<Vec3> = Vec::new();
    let mut all_have_normals = true;
    let mut uvs: Vec<Vec2> = Vec::new();
    let mut all_have_uvs = true;
    let mut default_index = None;
    let mut colors: Vec<glam::Vec4> = Vec::new();

    for model in models {
        let m = &model.mesh;
        let base = u32::try_from(mesh.positions.len()).map_err(|_| Error::invalid(path, "more than 2^32 vertices"))?;
        let count = m.positions.len() / 3;
        mesh.positions.extend(m.positions.chunks_exact(3).filter_map(|c| match *c {
            [x, y, z] => Some(Vec3::new(x, y, z)),
            _ => None,
        }));
        if m.normals.len() == m.positions.len() {
            normals.extend(m.normals.chunks_exact(3).filter_map(|c| match *c {
                [x, y, z] => Some(Vec3::new(x, y, z)),
                _ => None,
            }));
        } else if count > 0 {
            all_have_normals = false;
        }
        // tobj gives a model texture coordinates only for the vertices that have one.
        if m.texcoords.len() == 2 * count {
            let (scale, offset) =
                m.material_id.and_then(|id| uv_maps.get(id).copied().flatten()).unwrap_or((Vec2::ONE, Vec2::ZERO));
            uvs.extend(m.texcoords.chunks_exact(2).filter_map(|c| match *c {
                [u, v] => Some(Vec2::new(u, v) * scale + offset),
                _ => None,
            }));
        } else {
            all_have_uvs = false;
        }
        // Colours: tobj has them when every vertex of the file had one (the pre-pass
        // keeps them only then).
        if m.vertex_color.len() == m.positions.len() {
            colors.extend(m.vertex_color.chunks_exact(3).map(|c| glam::Vec4::new(c[0], c[1], c[2], 1.0)));
        }

        let material = if uses_materials {
            match m.material_id.filter(|&id| id < materials.len()).and_then(|id| u32::try_from(id).ok()) {
                Some(id) => Some(id),
                None => Some(*default_index.get_or_insert_with(|| {
                    materials.push(default_material());
                    materials.len() as u32 - 1
                })),
            }
        } else {
            None
        };

        for tri in m.indices.chunks(3) {
            let &[a, b, c] = tri else {
                return Err(Error::invalid(path, format!("model '{}' has a partial triangle", model.name)));
            };
            let mut t = [0u32; 3];
            for (dst, i) in t.iter_mut().zip([a, b, c]) {
                if i as usize >= count {
                    return Err(Error::invalid(
                        path,
                        format!("model '{}' references vertex {i} of {count}", model.name),
                    ));
                }
                *dst = base.checked_add(i).ok_or_else(|| Error::invalid(path, "more than 2^32 vertices"))?;
            }
            mesh.triangles.push(t);
            if let Some(mat) = material {
                mesh.tri_material.push(mat);
            }
        }
    }

    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::invalid(path, format!("vertex {i} has a non-finite coordinate")));
    }
    if all_have_normals && !mesh.positions.is_empty() && normals.len() == mesh.positions.len() {
        mesh.normals = normals
            .into_iter()
            .map(|n| {
                let len = n.length();
                (len.is_finite() && len > 0.0).then(|| n / len)
            })
            .collect();
    }
    if all_have_uvs && !mesh.positions.is_empty() && uvs.len() == mesh.positions.len() {
        mesh.uvs = Some(uvs);
    }
    if !mesh.positions.is_empty() && colors.len() == mesh.positions.len() {
        crate::scene::colors::clamp_colors(&mut colors);
        mesh.colors = Some(colors);
    }
    if uses_materials {
        mesh.materials = materials;
    }
    Ok(mesh)
}
