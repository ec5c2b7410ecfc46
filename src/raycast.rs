//! Open3D's ray-casting surface (`open3d.t.geometry.RaycastingScene`) over arbor's
//! structures, on any Vulkan device or on the CPU: what the Python module of issue 68
//! wraps, and usable from Rust as it is.
//!
//! - [`RaycastingScene::add_triangles`] takes a mesh (vertices, triangles) and returns
//!   its geometry id; [`RaycastingScene::add_sphere`] a sphere (arbor's own).
//! - Rays are six floats, origin then direction, as Open3D's: the direction need not be
//!   unit, and `t_hit` is in units of its length (the hit is at `o + t_hit * d`).
//! - [`RaycastingScene::cast_rays`] gives Open3D's outputs ([`CastResult`]): `t_hit`
//!   (+inf on a miss), `geometry_ids` and `primitive_ids` ([`INVALID_ID`] on a miss),
//!   `primitive_uvs` (barycentrics of a triangle's second and third vertex) and
//!   `primitive_normals` (the unit geometric normal); [`RaycastingScene::test_occlusions`]
//!   whether anything lies between `tnear` and `tfar`.
//! - Bad input is an error naming the first bad row: a non-finite vertex or ray, an
//!   index out of range, a zero direction.
//! - The structure is built on the first cast (or [`RaycastingScene::build`]), again
//!   after geometry is added; [`RaycastingScene::auto`] lets the cost model pick it then.
//!   Large batches are traced in pieces of a quarter second (at most [`CAST_PIECE`]
//!   rays, the ray-batch loop's chunk), all through one upload of the scene;
//!   [`RaycastingScene::cast_rays_with`] is called back between pieces (the Python
//!   module checks Ctrl-C there).

use glam::Vec3;

use crate::accel::{Accel, AccelKind, AccelParams, BuildOn, BuildStats};
use crate::error::{Error, Result};
use crate::gpu::Context;
use crate::math::{Hit, Ray};
use crate::render::integrators::rays::{RayTracer, TraceOptions};
use crate::scene::{MeshData, Scene, SceneBuilder, Sphere};

/// Most rays a device cast traces between two calls of
/// [`RaycastingScene::cast_rays_with`]'s callback (pieces are sized by time, up to this).
pub const CAST_PIECE: usize = 1 << 20;

/// The time a piece of a device cast aims at, in seconds.
const PIECE_SECONDS: f64 = 0.25;
/// The first piece of a cast, before its rate is known, and the fewest rays a piece.
const FIRST_PIECE: usize = 1 << 16;
const MIN_PIECE: usize = 4096;

/// Rays the cost model of [`RaycastingScene::auto`] expects (a megapixel of camera rays).
const AUTO_RAYS: u64 = 1 << 20;

/// `geometry_ids` and `primitive_ids` of a ray that hits nothing (Open3D's
/// `INVALID_ID`, 2^32 - 1).
pub const INVALID_ID: u32 = u32::MAX;

/// What [`RaycastingScene::cast_rays`] returns, one entry a ray, in Open3D's names.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CastResult {
    /// The hit's parameter along the ray as given (`o + t_hit * d`); +inf on a miss.
    pub t_hit: Vec<f32>,
    /// Which `add_*` call added the primitive hit.
    pub geometry_ids: Vec<u32>,
    /// The primitive's index within its geometry (a triangle of the mesh; 0 for a
    /// sphere).
    pub primitive_ids: Vec<u32>,
    /// Barycentric coordinates of the hit for the triangle's second and third vertex
    /// (0, 0 for a sphere and on a miss).
    pub primitive_uvs: Vec<[f32; 2]>,
    /// The unit geometric normal at the hit (a triangle's winding, a sphere's outside);
    /// 0 on a miss.
    pub primitive_normals: Vec<[f32; 3]>,
}

/// One `add_*` call.
#[derive(Debug, Clone, Copy)]
enum Geometry {
    /// Triangles from `first` on of the scene.
    Triangles { first: u32 },
    /// A sphere of the scene.
    Sphere,
}

/// A scene to cast rays into, in Open3D's terms.
#[derive(Debug)]
pub struct RaycastingScene {
    builder: Option<SceneBuilder>,
    geometries: Vec<Geometry>,
    /// Per scene triangle, and per sphere: the geometry that added it.
    triangle_geometry: Vec<u32>,
    sphere_geometry: Vec<u32>,
    /// `None`: chosen by the cost model at build time.
    kind: Option<AccelKind>,
    params: AccelParams,
    built: Option<(Scene, Accel)>,
    /// Whether `built` was built with a device (a GPU build, the driver's structure).
    built_on_device: bool,
    /// The kind `built` is (the cost model's choice for [`RaycastingScene::auto`]).
    built_kind: Option<AccelKind>,
}

impl RaycastingScene {
    /// An empty scene whose rays `kind` traces, built with `params`.
    pub fn new(kind: AccelKind, params: AccelParams) -> RaycastingScene {
        RaycastingScene {
            builder: Some(SceneBuilder::new("raycasting scene")),
            geometries: Vec::new(),
            triangle_geometry: Vec::new(),
            sphere_geometry: Vec::new(),
            kind: Some(kind),
            params,
            built: None,
            built_on_device: false,
            built_kind: None,
        }
    }

    /// An empty scene whose structure the cost model picks when it is built (`--accel
    /// auto` for a megapixel of rays, among the kinds `params.build` builds).
    pub fn auto(params: AccelParams) -> RaycastingScene {
        RaycastingScene { kind: None, ..RaycastingScene::new(AccelKind::BvhSah, params) }
    }

    /// The structure: the one asked for, or the cost model's choice once built (`None`
    /// before).
    pub fn kind(&self) -> Option<AccelKind> {
        self.kind.or(self.built_kind)
    }

    fn builder(&mut self) -> &mut SceneBuilder {
        self.built = None;
        self.built_kind = None;
        self.builder.get_or_insert_with(|| SceneBuilder::new("raycasting scene"))
    }

    /// Adds a mesh: `vertices` positions, `triangles` indices into them. Its geometry id.
    pub fn add_triangles(&mut self, vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> Result<u32> {
        if let Some(row) = vertices.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
            return Err(Error::Usage(format!(
                "vertices row {row} is {:?}: every coordinate must be finite",
                vertices[row]
            )));
        }
        if let Some(row) = triangles.iter().position(|t| t.iter().any(|&i| i as usize >= vertices.len())) {
            return Err(Error::Usage(format!(
                "triangles row {row} is {:?}: an index is out of range (there are {} vertices)",
                triangles[row],
                vertices.len()
            )));
        }
        let id = self.geometries.len() as u32;
        let first = self.triangle_geometry.len() as u32;
        let mesh = MeshData {
            positions: vertices.iter().map(|&v| Vec3::from_array(v)).collect(),
            triangles: triangles.to_vec(),
            ..Default::default()
        };
        self.builder().mesh(&mesh, 1.0, Vec3::ZERO, None);
        self.geometries.push(Geometry::Triangles { first });
        self.triangle_geometry.extend(std::iter::repeat_n(id, triangles.len()));
        Ok(id)
    }

    /// Adds a sphere (arbor's analytic primitive). Its geometry id.
    pub fn add_sphere(&mut self, center: [f32; 3], radius: f32) -> Result<u32> {
        if !(center.iter().all(|c| c.is_finite()) && radius.is_finite() && radius > 0.0) {
            return Err(Error::Usage(format!(
                "a sphere needs a finite center and a positive finite radius, got {center:?} and {radius}"
            )));
        }
        let id = self.geometries.len() as u32;
        // The builder's default material (a sphere's material does not matter here).
        self.builder().scene.spheres.push(Sphere { center: Vec3::from_array(center), radius, material: 0 });
        self.geometries.push(Geometry::Sphere);
        self.sphere_geometry.push(id);
        Ok(id)
    }

    /// Builds the structure over the geometry added so far on the CPU (done by the
    /// first cast, and again after more geometry is added); its statistics. A GPU
    /// build or the driver's structure needs the device: [`RaycastingScene::build_on`].
    pub fn build(&mut self) -> Result<BuildStats> {
        self.ensure_built(None)?;
        Ok(self.stats())
    }

    /// [`RaycastingScene::build`] with `ctx`'s device, which builds where the
    /// parameters say (`BuildOn::Gpu`) and makes `rayquery`'s structure.
    pub fn build_on(&mut self, ctx: &Context) -> Result<BuildStats> {
        self.ensure_built(Some(ctx))?;
        Ok(self.stats())
    }

    fn stats(&self) -> BuildStats {
        match &self.built {
            Some((scene, accel)) => accel.stats(scene),
            None => {
                BuildStats { kind: self.kind.map(|k| k.name().to_string()).unwrap_or_default(), ..Default::default() }
            }
        }
    }

    fn needs_device(&self, kind: AccelKind) -> bool {
        self.params.build == BuildOn::Gpu || kind == AccelKind::RayQuery
    }

    fn ensure_built(&mut self, ctx: Option<&Context>) -> Result<()> {
        if let (Some(_), Some(kind)) = (&self.built, self.built_kind) {
            // A structure built without the device is built again for a device cast
            // that needs it.
            if self.built_on_device || ctx.is_none() || !self.needs_device(kind) {
                return Ok(());
            }
            self.built = None;
        }
        if self.geometries.is_empty() {
            return Ok(());
        }
        let builder = self.builder.take().unwrap_or_else(|| SceneBuilder::new("raycasting scene"));
        if builder.scene.triangles.is_empty() && builder.scene.spheres.is_empty() {
            // Only empty meshes: nothing to hit.
            self.builder = Some(builder);
            return Ok(());
        }
        let scene = builder.finish()?;
        let kind = match self.kind {
            Some(k) => k,
            None => crate::accel::auto::choose_built(&scene, AUTO_RAYS, 1, self.params.build)?.0,
        };
        let on_device = ctx.is_some() && self.needs_device(kind);
        let accel = match ctx {
            Some(ctx) if on_device => Accel::build_on(ctx, kind, &scene, &self.params)?,
            _ if self.params.build == BuildOn::Gpu => {
                return Err(Error::Usage(format!(
                    "{kind} built on the GPU needs the device: cast on it, or build on the CPU"
                )))
            }
            _ => Accel::build_with(kind, &scene, &self.params),
        };
        // Keep adding to the same scene after a build.
        let mut again = SceneBuilder::new("raycasting scene");
        again.scene = scene.clone();
        self.builder = Some(again);
        self.built = Some((scene, accel));
        self.built_on_device = on_device;
        self.built_kind = Some(kind);
        Ok(())
    }

    /// Casts `rays` (origin, direction) on the device: the closest hit of each.
    pub fn cast_rays(&mut self, ctx: &Context, rays: &[[f32; 6]]) -> Result<CastResult> {
        self.cast_rays_with(ctx, rays, &mut |_| Ok(()))
    }

    /// [`RaycastingScene::cast_rays`], calling `between` with the rays done after each
    /// piece (a quarter second, at most [`CAST_PIECE`] rays); an error it returns ends
    /// the cast.
    pub fn cast_rays_with(
        &mut self,
        ctx: &Context,
        rays: &[[f32; 6]],
        between: &mut dyn FnMut(usize) -> Result<()>,
    ) -> Result<CastResult> {
        self.ensure_built(Some(ctx))?;
        self.cast(rays, |scene, accel, unit| trace_pieces(ctx, scene, accel, unit, between))
    }

    /// Casts `rays` on the CPU (arbor's reference traversal of the same structure).
    pub fn cast_rays_cpu(&mut self, rays: &[[f32; 6]]) -> Result<CastResult> {
        self.cast(rays, |scene, accel, unit| Ok(accel.trace_cpu(scene, unit)))
    }

    /// Whether anything lies along each ray between `tnear` and `tfar` (in units of the
    /// ray's direction, as `t_hit`), on the device.
    pub fn test_occlusions(&mut self, ctx: &Context, rays: &[[f32; 6]], tnear: f32, tfar: f32) -> Result<Vec<bool>> {
        self.test_occlusions_with(ctx, rays, tnear, tfar, &mut |_| Ok(()))
    }

    /// [`RaycastingScene::test_occlusions`] with `between` called as
    /// [`RaycastingScene::cast_rays_with`] calls it.
    pub fn test_occlusions_with(
        &mut self,
        ctx: &Context,
        rays: &[[f32; 6]],
        tnear: f32,
        tfar: f32,
        between: &mut dyn FnMut(usize) -> Result<()>,
    ) -> Result<Vec<bool>> {
        if !(tnear.is_finite() && tnear >= 0.0) || tfar.is_nan() || tfar < tnear {
            return Err(Error::Usage(format!(
                "tnear must be finite and at least 0, and tfar at least tnear; got {tnear} and {tfar}"
            )));
        }
        let unit = unit_rays(rays, tnear, tfar)?;
        self.ensure_built(Some(ctx))?;
        let Some((scene, accel)) = self.built.as_ref().filter(|_| !rays.is_empty()) else {
            return Ok(vec![false; rays.len()]);
        };
        let hits = trace_pieces(ctx, scene, accel, &unit, between)?;
        Ok(hits.iter().map(Option::is_some).collect())
    }

    fn cast(
        &mut self,
        rays: &[[f32; 6]],
        trace: impl FnOnce(&Scene, &Accel, &[Ray]) -> Result<Vec<Option<Hit>>>,
    ) -> Result<CastResult> {
        let unit = unit_rays(rays, 0.0, f32::INFINITY)?;
        self.ensure_built(None)?;
        let n = rays.len();
        let mut out = CastResult {
            t_hit: vec![f32::INFINITY; n],
            geometry_ids: vec![INVALID_ID; n],
            primitive_ids: vec![INVALID_ID; n],
            primitive_uvs: vec![[0.0; 2]; n],
            primitive_normals: vec![[0.0; 3]; n],
        };
        let Some((scene, accel)) = &self.built else { return Ok(out) };
        if n == 0 {
            return Ok(out);
        }
        let hits = trace(scene, accel, &unit)?;
        let triangles = scene.triangles.len() as u32;
        for (k, hit) in hits.iter().enumerate() {
            let Some(h) = hit else { continue };
            let len = Vec3::new(rays[k][3], rays[k][4], rays[k][5]).length();
            out.t_hit[k] = h.t / len;
            let normal = if h.prim < triangles {
                let g = self.triangle_geometry[h.prim as usize];
                let Geometry::Triangles { first } = self.geometries[g as usize] else { unreachable!("a mesh's id") };
                out.geometry_ids[k] = g;
                out.primitive_ids[k] = h.prim - first;
                out.primitive_uvs[k] = [h.u, h.v];
                let [a, b, c] = scene.triangles[h.prim as usize].map(|v| scene.positions[v as usize]);
                (b - a).cross(c - a).normalize_or_zero()
            } else {
                let s = (h.prim - triangles) as usize;
                out.geometry_ids[k] = self.sphere_geometry[s];
                out.primitive_ids[k] = 0;
                let sphere = scene.spheres[s];
                let p = unit[k].origin + unit[k].dir * h.t;
                ((p - sphere.center) / sphere.radius).normalize_or_zero()
            };
            out.primitive_normals[k] = normal.to_array();
        }
        Ok(out)
    }
}

/// Traces `rays` on the device in pieces through one [`RayTracer`] (one upload of the
/// scene), calling `between` after each. Pieces are sized to take about
/// [`PIECE_SECONDS`] each (from 4096 rays up to [`CAST_PIECE`]), so that a caller
/// polling for Ctrl-C there answers within a second on any device.
fn trace_pieces(
    ctx: &Context,
    scene: &Scene,
    accel: &Accel,
    rays: &[Ray],
    between: &mut dyn FnMut(usize) -> Result<()>,
) -> Result<Vec<Option<Hit>>> {
    let tracer = RayTracer::new(ctx, scene, accel, &TraceOptions::default())?;
    let mut hits = Vec::with_capacity(rays.len());
    let mut piece = FIRST_PIECE;
    while hits.len() < rays.len() {
        let start = std::time::Instant::now();
        let n = piece.min(rays.len() - hits.len());
        hits.extend(tracer.trace(&rays[hits.len()..hits.len() + n])?);
        between(hits.len())?;
        let rate = n as f64 / start.elapsed().as_secs_f64().max(1e-6);
        piece = ((rate * PIECE_SECONDS) as usize).clamp(MIN_PIECE, CAST_PIECE);
    }
    Ok(hits)
}

/// Open3D's rays as arbor's: unit directions, `tnear..tfar` scaled by each direction's
/// length. Errors name the first bad row.
fn unit_rays(rays: &[[f32; 6]], tnear: f32, tfar: f32) -> Result<Vec<Ray>> {
    let mut out = Vec::with_capacity(rays.len());
    for (row, r) in rays.iter().enumerate() {
        if !r.iter().all(|c| c.is_finite()) {
            return Err(Error::Usage(format!("rays row {row} is {r:?}: every component must be finite")));
        }
        let d = Vec3::new(r[3], r[4], r[5]);
        let len = d.length();
        if !(len > 0.0 && len.is_finite()) {
            return Err(Error::Usage(format!("rays row {row} is {r:?}: the direction is zero")));
        }
        let tmax = if tfar.is_infinite() { f32::INFINITY } else { tfar * len };
        out.push(Ray { origin: Vec3::new(r[0], r[1], r[2]), dir: d / len, tmin: tnear * len, tmax });
    }
    Ok(out)
}
