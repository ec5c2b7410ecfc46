//! Instancing: meshes stored once (prototypes) and drawn many times (instances), each
//! with its own affine transform. The renderer builds one structure per prototype
//! and a BVH over the instances' world boxes (`accel::instance`); everything that
//! needs one flat triangle list (brute force, the CPU reference) uses
//! [`Scene::flattened`].
//!
//! Primitive numbering of an instanced scene, as the primitive AOV reports it, is that
//! of its flattened copy: the scene's own triangles, then each instance's copy of its
//! prototype's triangles in instance order, then the spheres.

use glam::{Affine3A, Vec2, Vec3, Vec4};

use super::{MeshData, Scene, SceneBuilder};
use crate::error::{Error, Result};
use crate::math::Aabb;

/// Most instances a scene may hold.
pub const MAX_INSTANCES: usize = 1 << 24;

/// A mesh stored once, in its own coordinates.
#[derive(Debug, Clone)]
pub struct Prototype {
    /// The `name` of its `[[mesh]]` table (or glTF mesh).
    pub name: String,
    /// Geometry only: positions, normals, UVs, triangles and per-triangle material
    /// indices into the scene's materials; no spheres, lights or materials of its own.
    pub geometry: Scene,
    /// The box of its vertices.
    pub bounds: Aabb,
}

/// One placement of a prototype.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Instance {
    pub prototype: u32,
    /// Object to world.
    pub transform: Affine3A,
}

impl Instance {
    /// The box of the prototype's box transformed into the world.
    pub fn world_bounds(&self, proto: &Prototype) -> Aabb {
        transform_box(&self.transform, &proto.bounds)
    }
}

/// Whether `t` can place an instance: finite, non-singular, and with an inverse (which
/// moves rays into the instance) finite in single precision.
pub fn invertible(t: &Affine3A) -> bool {
    let det = t.matrix3.determinant();
    if !(det.is_finite() && det != 0.0 && t.translation.is_finite()) {
        return false;
    }
    let inv = t.inverse();
    inv.matrix3.determinant().is_finite() && inv.matrix3.is_finite() && inv.translation.is_finite()
}

/// The box around the eight transformed corners of `b`.
pub fn transform_box(t: &Affine3A, b: &Aabb) -> Aabb {
    let mut out = Aabb::EMPTY;
    if b.is_empty() {
        return out;
    }
    for k in 0..8 {
        let c = Vec3::new(
            if k & 1 == 0 { b.min.x } else { b.max.x },
            if k & 2 == 0 { b.min.y } else { b.max.y },
            if k & 4 == 0 { b.min.z } else { b.max.z },
        );
        out.grow(t.transform_point3(c));
    }
    out
}

/// The prototypes and instances of a scene.
#[derive(Debug, Clone, Default)]
pub struct Instancing {
    pub prototypes: Vec<Prototype>,
    pub instances: Vec<Instance>,
}

impl Instancing {
    /// Triangles stored once: every prototype's.
    pub fn prototype_triangles(&self) -> u64 {
        self.prototypes.iter().map(|p| p.geometry.triangles.len() as u64).sum()
    }

    /// Triangles drawn through instances (each instance counts its prototype's).
    pub fn instanced_triangles(&self) -> u64 {
        self.instances.iter().map(|i| self.prototypes[i.prototype as usize].geometry.triangles.len() as u64).sum()
    }
}

impl SceneBuilder {
    /// Stores `mesh` as a prototype named `name` (not drawn by itself) and returns its
    /// index. Materials and textures join the scene as [`SceneBuilder::mesh_transformed`]
    /// adds them.
    /// `pre` places the mesh in the prototype's own coordinates (identity as a rule).
    pub fn prototype(&mut self, name: &str, mesh: &MeshData, pre: &Affine3A, material: Option<u32>) -> u32 {
        let s = &mut self.scene;
        let saved = (
            std::mem::take(&mut s.positions),
            std::mem::take(&mut s.normals),
            std::mem::take(&mut s.uvs),
            std::mem::take(&mut s.triangles),
            std::mem::take(&mut s.tri_material),
            std::mem::take(&mut s.colors),
        );
        self.mesh_transformed(mesh, pre, material);
        let s = &mut self.scene;
        let mut geometry = SceneBuilder::new(name).scene;
        geometry.positions = std::mem::replace(&mut s.positions, saved.0);
        geometry.normals = std::mem::replace(&mut s.normals, saved.1);
        geometry.uvs = std::mem::replace(&mut s.uvs, saved.2);
        geometry.triangles = std::mem::replace(&mut s.triangles, saved.3);
        geometry.tri_material = std::mem::replace(&mut s.tri_material, saved.4);
        geometry.colors = std::mem::replace(&mut s.colors, saved.5);
        // The scene's UVs stay one per position or none: a prototype with UVs makes
        // the scene's own vertices have (zero) ones, as a mesh with UVs would.
        if !geometry.uvs.is_empty() && s.uvs.is_empty() && !s.positions.is_empty() {
            s.uvs.resize(s.positions.len(), Vec2::ZERO);
        }
        let mut bounds = Aabb::EMPTY;
        for t in &geometry.triangles {
            for &i in t {
                bounds.grow(geometry.positions[i as usize]);
            }
        }
        let inst = s.instancing.get_or_insert_with(Default::default);
        inst.prototypes.push(Prototype { name: name.to_string(), geometry, bounds });
        (inst.prototypes.len() - 1) as u32
    }

    /// Draws prototype `prototype` transformed by `transform`.
    pub fn instance(&mut self, prototype: u32, transform: Affine3A) {
        let inst = self.scene.instancing.get_or_insert_with(Default::default);
        inst.instances.push(Instance { prototype, transform });
    }
}

impl Scene {
    /// Whether the scene draws instances.
    pub fn has_instances(&self) -> bool {
        self.instancing.as_ref().is_some_and(|i| !i.instances.is_empty())
    }

    /// Triangles of the scene as drawn: its own plus every instance's.
    pub fn drawn_triangles(&self) -> u64 {
        self.triangles.len() as u64 + self.instancing.as_ref().map_or(0, |i| i.instanced_triangles())
    }

    /// Triangles the GPU stores: every prototype's once, then the scene's own (the
    /// order of the kernel's triangle buffer).
    pub fn stored_triangles(&self) -> u64 {
        self.instancing.as_ref().map_or(0, |i| i.prototype_triangles()) + self.triangles.len() as u64
    }

    /// The scene with every instance replaced by a transformed copy of its prototype
    /// (after the scene's own triangles, in instance order; spheres unchanged), so that
    /// primitive numbers are those the instanced render reports. An error when the
    /// copies would cross the scene limits.
    pub fn flattened(&self) -> Result<Scene> {
        let mut s = self.clone();
        let Some(inst) = s.instancing.take() else { return Ok(s) };
        let (tris, verts) = inst.instances.iter().fold((s.triangles.len() as u64, s.positions.len() as u64), |a, i| {
            let g = &inst.prototypes[i.prototype as usize].geometry;
            (a.0 + g.triangles.len() as u64, a.1 + g.positions.len() as u64)
        });
        if let Some(what) = super::limits::totals_error(tris, verts) {
            return Err(Error::scene(s.name.clone(), format!("flattening its instances gives {what}")));
        }
        let any_uvs = !s.uvs.is_empty() || inst.prototypes.iter().any(|p| !p.geometry.uvs.is_empty());
        if any_uvs {
            s.uvs.resize(s.positions.len(), Vec2::ZERO);
        }
        let any_colors = !s.colors.is_empty() || inst.prototypes.iter().any(|p| !p.geometry.colors.is_empty());
        if any_colors {
            s.colors.resize(s.positions.len(), Vec4::ONE);
        }
        for i in &inst.instances {
            let g = &inst.prototypes[i.prototype as usize].geometry;
            let base = s.positions.len() as u32;
            let t = &i.transform;
            s.positions.extend(g.positions.iter().map(|p| t.transform_point3(*p)));
            let nm = t.matrix3.inverse().transpose();
            s.normals.extend(g.normals.iter().map(|n| {
                if *n == Vec3::ZERO {
                    Vec3::ZERO
                } else {
                    (nm * *n).try_normalize().unwrap_or(Vec3::ZERO)
                }
            }));
            if any_uvs {
                if g.uvs.is_empty() {
                    s.uvs.resize(s.positions.len(), Vec2::ZERO);
                } else {
                    s.uvs.extend_from_slice(&g.uvs);
                }
            }
            if any_colors {
                if g.colors.is_empty() {
                    s.colors.resize(s.positions.len(), Vec4::ONE);
                } else {
                    s.colors.extend_from_slice(&g.colors);
                }
            }
            let mirrored = t.matrix3.determinant() < 0.0;
            s.triangles.extend(g.triangles.iter().map(|tri| {
                let [a, b, c] = tri.map(|k| k + base);
                if mirrored {
                    [a, c, b]
                } else {
                    [a, b, c]
                }
            }));
            s.tri_material.extend_from_slice(&g.tri_material);
        }
        s.degenerate_triangles = s.count_degenerate();
        Ok(s)
    }
}

/// Checks the instancing part of a scene (called by `SceneBuilder::finish`).
pub fn validate(s: &mut Scene) -> std::result::Result<(), String> {
    let nm = s.materials.len() as u32;
    let spheres = s.spheres.len() as u64;
    let own = s.triangles.len() as u64;
    // Instanced meshes that no instance draws are dropped: nothing would show them.
    if s.instancing.as_ref().is_some_and(|i| i.instances.is_empty()) {
        s.instancing = None;
    }
    let materials = &s.materials;
    let Some(inst) = s.instancing.as_mut() else { return Ok(()) };
    if inst.instances.len() > MAX_INSTANCES {
        return Err(format!("{} instances; at most {MAX_INSTANCES} are supported", inst.instances.len()));
    }
    for p in &mut inst.prototypes {
        let g = &mut p.geometry;
        let name = &p.name;
        if g.triangles.is_empty() {
            return Err(format!("instanced mesh '{name}' has no triangles"));
        }
        if g.triangles.len() >= super::MAX_PRIMS {
            return Err(format!("instanced mesh '{name}': {} triangles is too many", g.triangles.len()));
        }
        if let Some(i) = g.positions.iter().position(|p| !p.is_finite()) {
            return Err(format!("instanced mesh '{name}': vertex {i} has a non-finite coordinate"));
        }
        for n in &mut g.normals {
            if !n.is_finite() {
                *n = Vec3::ZERO;
            }
        }
        for uv in &mut g.uvs {
            if !uv.is_finite() {
                *uv = Vec2::ZERO;
            }
        }
        if !g.colors.is_empty() && g.colors.len() != g.positions.len() {
            return Err(format!(
                "instanced mesh '{name}': {} vertex colours for {} vertices",
                g.colors.len(),
                g.positions.len()
            ));
        }
        super::colors::clamp_colors(&mut g.colors);
        let nv = g.positions.len() as u32;
        if let Some((k, _)) = g.triangles.iter().enumerate().find(|(_, t)| t.iter().any(|&i| i >= nv)) {
            return Err(format!("instanced mesh '{name}': triangle {k} references a vertex out of range"));
        }
        for &m in &g.tri_material {
            let Some(mat) = materials.get(m as usize) else {
                return Err(format!("instanced mesh '{name}': material index {m} of {nm}"));
            };
            if mat.emission != Vec3::ZERO {
                return Err(format!(
                    "instanced mesh '{name}' uses the emitting material '{}': instances cannot be lights; \
                     draw it as a plain [[mesh]]",
                    mat.name
                ));
            }
        }
    }
    let np = inst.prototypes.len() as u32;
    for (k, i) in inst.instances.iter().enumerate() {
        if i.prototype >= np {
            return Err(format!("instance {k} names prototype {} of {np}", i.prototype));
        }
        if !invertible(&i.transform) {
            let det = i.transform.matrix3.determinant();
            return Err(format!(
                "instance {k}: the transform is singular, not finite, or not invertible in single precision (determinant {det})"
            ));
        }
    }
    // Primitive numbers of the flattened scene must fit a u32 below the "no hit" value.
    let total = own + inst.instanced_triangles() + spheres;
    if total >= u64::from(u32::MAX) {
        return Err(format!("the instances draw {total} primitives; at most {} are supported", u32::MAX - 1));
    }
    Ok(())
}
