//! `arbor info`: what a scene holds and what a structure built over it looks like, with
//! the kernel and buffers a render would use. [`Report`] prints as text or JSON.

#![forbid(unsafe_code)]

use std::fmt;

use crate::accel::{Accel, AccelKind, BuildOn, BuildStats};
use crate::render::{gpu, KernelChoice};
use crate::scene::Scene;

/// Scene and structure statistics of `arbor info`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Report {
    pub scene: String,
    /// Triangles drawn (the scene's own plus every instance's; `build.levels` splits them).
    pub triangles: usize,
    /// Degenerate triangles (kept and never hit).
    pub degenerate_triangles: usize,
    pub vertices: usize,
    pub spheres: usize,
    pub materials: usize,
    /// Point and directional lights.
    pub lights: usize,
    /// Emissive primitives (area lights: what the path tracer samples besides `lights`).
    pub emitters: usize,
    /// The scene's film size.
    pub film: [u32; 2],
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    pub accel: String,
    pub built_on: String,
    /// Why `--accel auto` chose the structure (None when it was named).
    pub accel_auto_reason: Option<String>,
    pub build: BuildStats,
    pub valid: bool,
    /// The kernel a render would run (`trace_<family>_<geometry>`).
    pub kernel: String,
    /// The buffers it binds, by name.
    pub buffers: Vec<String>,
    /// Why the structure failed validation (the text report says).
    #[serde(skip)]
    pub validation: Result<(), crate::accel::ValidateError>,
    /// Primitives (triangles and spheres), for the per-primitive figures.
    #[serde(skip)]
    primitives: usize,
}

impl Report {
    /// The report of `built` (a `kind` built on `built_on` over `scene`; `why` the
    /// reason `auto` chose it).
    pub fn new(scene: &Scene, kind: AccelKind, built_on: BuildOn, why: Option<String>, built: &Accel) -> Report {
        let validation = built.validate(scene);
        let bounds = scene.bounds();
        let geometry = gpu::kernel_geometry(scene, KernelChoice::Specialized);
        let family = built.gpu_image(scene).map(|i| i.family).unwrap_or(kind.kernel());
        Report {
            scene: scene.name.clone(),
            triangles: scene.drawn_triangles() as usize,
            degenerate_triangles: scene.degenerate_triangles,
            vertices: scene.positions.len(),
            spheres: scene.spheres.len(),
            materials: scene.materials.len(),
            lights: scene.lights.len(),
            emitters: crate::render::dispatch::tables::emitters(scene).len(),
            film: [scene.width, scene.height],
            bounds_min: bounds.min.to_array(),
            bounds_max: bounds.max.to_array(),
            accel: kind.name().to_string(),
            built_on: built_on.name().to_string(),
            accel_auto_reason: why,
            build: built.stats(scene),
            valid: validation.is_ok(),
            kernel: format!("trace_{family}_{geometry}"),
            buffers: gpu::trace_bindings(family, geometry).iter().map(|b| b.name.to_string()).collect(),
            validation,
            primitives: scene.drawn_triangles() as usize + scene.spheres.len(),
        }
    }

    /// The report as pretty JSON (keys in alphabetical order, as `arbor info --json`
    /// has always printed them).
    pub fn to_json(&self) -> String {
        let value = serde_json::to_value(self).unwrap_or_default();
        serde_json::to_string_pretty(&value).unwrap_or_default()
    }
}

/// The text report, one `name  value` line each.
impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.primitives.max(1) as f64;
        let st = &self.build;
        writeln!(f, "scene           {}", self.scene)?;
        writeln!(
            f,
            "triangles       {} ({} degenerate, kept and never hit)",
            self.triangles, self.degenerate_triangles
        )?;
        writeln!(f, "vertices        {}", self.vertices)?;
        writeln!(f, "spheres         {}", self.spheres)?;
        writeln!(f, "materials       {}", self.materials)?;
        writeln!(
            f,
            "lights          {} point or directional, {} emissive primitives (area lights)",
            self.lights, self.emitters
        )?;
        writeln!(f, "film            {}x{}", self.film[0], self.film[1])?;
        writeln!(f, "bounds          {:?} .. {:?}", self.bounds_min, self.bounds_max)?;
        writeln!(f, "accel           {}", self.accel)?;
        writeln!(f, "  built on      {}", self.built_on.to_uppercase())?;
        if let Some(why) = &self.accel_auto_reason {
            writeln!(f, "  auto          {why}")?;
        }
        writeln!(f, "  build         {:.2} ms", st.build_ms)?;
        let empty = 100.0 * st.empty_leaves as f64 / st.leaves.max(1) as f64;
        writeln!(f, "  nodes         {} ({} leaves, {} empty: {empty:.1}%)", st.nodes, st.leaves, st.empty_leaves)?;
        if let Some(r) = st.resolution {
            writeln!(f, "  resolution    {} x {} x {} cells", r[0], r[1], r[2])?;
        }
        writeln!(f, "  depth         max {}, mean leaf {:.2}", st.max_depth, st.mean_leaf_depth)?;
        writeln!(f, "  refs/prim     {:.3} ({:.2} per leaf)", st.refs_per_prim, st.prims_per_leaf)?;
        writeln!(f, "  bytes         {} ({:.2} per primitive)", st.bytes, st.bytes as f64 / n)?;
        writeln!(f, "  SAH cost      {:.3}", st.sah_cost)?;
        if let Some(l) = &st.levels {
            writeln!(
                f,
                "  instances     {} of {} meshes: {} triangles stored, {} drawn by instances",
                l.instances, l.prototypes, l.unique_triangles, l.instanced_triangles
            )?;
            writeln!(
                f,
                "  level bytes   top {}, instance records {}, instanced meshes {}, own primitives {}",
                l.top_bytes, l.record_bytes, l.prototype_bytes, l.own_bytes
            )?;
        }
        for ph in &st.phases {
            match &ph.detail {
                Some(d) => writeln!(f, "  phase         {:<22} {:.2} ms  ({d})", ph.name, ph.ms)?,
                None => writeln!(f, "  phase         {:<22} {:.2} ms", ph.name, ph.ms)?,
            }
        }
        match &self.validation {
            Ok(()) => writeln!(f, "  validate      ok")?,
            Err(e) => writeln!(f, "  validate      FAILED: {e}")?,
        }
        writeln!(f, "kernel          {}", self.kernel)?;
        writeln!(f, "buffers         {}", self.buffers.join(", "))
    }
}
