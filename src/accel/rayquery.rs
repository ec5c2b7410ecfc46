//! `rayquery`: the device driver's own acceleration structure, built through
//! VK_KHR_acceleration_structure and traced in the trace kernel with VK_KHR_ray_query
//! (`shaders/accel/rayquery.glsl`). It is the structure a Vulkan user would pick
//! instead of arbor's, measured on the same device with the same kernels around it.
//!
//! - One BLAS over the scene's own triangles (opaque triangle geometry), one over its
//!   spheres (box geometry: the kernel intersects each candidate sphere analytically
//!   and commits it; a BLAS holds one geometry type), one BLAS per prototype of an instanced scene, and a TLAS with one
//!   instance per scene instance plus one (identity) for the scene's own primitives.
//!   An instance's custom index is its entry number in the two-level records of
//!   [`super::instance`], which the kernel reads for the hit's transform and number.
//! - The driver's structure is opaque: its nodes, leaves and depth are not visible,
//!   and the kernel cannot count nodes visited or primitives tested (the cost AOV and
//!   the stats say so instead of reporting zeros). Watertightness is the driver's:
//!   closed-mesh escapes are counted like the fast intersection mode's.
//! - The CPU traversal ([`Traverse`], the test oracle) cannot see the driver's
//!   structure; it is the `bvh-sah` traversal over the same primitives, built on first
//!   use.
//! - Build parameters (`--rayquery`): `fast-trace` (the default: PREFER_FAST_TRACE) or
//!   `fast-build` (PREFER_FAST_BUILD), and `compact=true|false` (compaction after the
//!   BLAS builds, default true).

#![forbid(unsafe_code)]

use std::sync::{Arc, OnceLock};

use super::params::{Key, Preset};
use super::{Accel, AccelKind, BuildStats, GpuImage, KernelFamily, Phase, Prims, TraceLoop, Traverse};
use crate::accel::validate::ValidateError;
use crate::error::Result;
use crate::gpu::{BlasDesc, Context, RayBuildOptions, RayBuildReport, RayInputs, RayStructure, TlasInstance};
use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

/// Parameters of the driver's build.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct RayQueryParams {
    /// Ask for PREFER_FAST_BUILD instead of PREFER_FAST_TRACE.
    pub fast_build: bool,
    /// Compact the BLASes after building them.
    pub compact: bool,
}

impl Default for RayQueryParams {
    fn default() -> Self {
        RayQueryParams { fast_build: false, compact: true }
    }
}

/// `--rayquery`: presets `fast-trace` (default) and `fast-build`; key `compact`.
impl super::params::Params for RayQueryParams {
    const FLAG: &'static str = "rayquery";
    const PRESETS: &'static [Preset<Self>] = &[
        ("default", RayQueryParams::default),
        ("fast-trace", RayQueryParams::default),
        ("fast-build", || RayQueryParams { fast_build: true, ..RayQueryParams::default() }),
    ];
    const KEYS: &'static [Key<Self>] = &[Key {
        name: "compact",
        expects: "true or false",
        set: |p, v| {
            p.compact = v.parse().ok()?;
            Some(())
        },
    }];
}

/// The driver's structure for one scene on one device.
#[derive(Debug, Clone)]
pub struct RayQuery {
    params: RayQueryParams,
    /// Built on a device by [`RayQuery::build`]; `None` for a structure made without
    /// one ([`RayQuery::cpu_only`]), which the kernel cannot trace.
    device: Option<Arc<RayStructure>>,
    report: RayBuildReport,
    /// The two-level records of an instanced scene (bvh-sah per prototype): the kernel
    /// reads each entry's transform and numbers from them; also the CPU oracle there.
    records: Option<Box<Accel>>,
    records_ms: f64,
    /// The CPU oracle of a scene without instances, built on first use.
    cpu: OnceLock<Box<Accel>>,
    bounds: Aabb,
    prims: u64,
}

impl RayQuery {
    /// The structure without a device: CPU traversal only (`arbor info`, tests).
    pub fn cpu_only(scene: &Scene, params: &super::AccelParams) -> RayQuery {
        let start = std::time::Instant::now();
        let records =
            scene.has_instances().then(|| Box::new(Accel::build_with(AccelKind::CPU_REFERENCE, scene, params)));
        RayQuery {
            params: params.rayquery,
            device: None,
            report: RayBuildReport::default(),
            records_ms: if records.is_some() { start.elapsed().as_secs_f64() * 1e3 } else { 0.0 },
            records,
            cpu: OnceLock::new(),
            bounds: scene.bounds(),
            prims: scene.prim_count() as u64,
        }
    }

    /// Builds the BLASes and the TLAS on `ctx` (an error naming the missing extension
    /// where the device has no ray queries).
    pub fn build(ctx: &Context, scene: &Scene, params: &super::AccelParams) -> Result<RayQuery> {
        if !ctx.has_ray_query() {
            return Err(ctx.ray_query_error());
        }
        let mut rq = RayQuery::cpu_only(scene, params);
        let inputs = Inputs::new(scene);
        let opts = RayBuildOptions { fast_build: rq.params.fast_build, compact: rq.params.compact };
        let (structure, report) = ctx.build_ray_structure(
            "rayquery",
            &RayInputs {
                positions: &inputs.positions,
                indices: &inputs.indices,
                blases: &inputs.blases,
                instances: &inputs.instances,
            },
            opts,
        )?;
        rq.device = Some(Arc::new(structure));
        rq.report = report;
        Ok(rq)
    }

    /// What the driver's build took and produced.
    pub fn report(&self) -> &RayBuildReport {
        &self.report
    }

    fn oracle(&self, scene: &Scene) -> &Accel {
        if let Some(r) = &self.records {
            return r;
        }
        self.cpu.get_or_init(|| Box::new(Accel::build_own(AccelKind::CPU_REFERENCE, scene, &Default::default())))
    }
}

/// The build inputs in the kernel's numbering: stored triangles are prototypes' first
/// (prototype k from its first stored triangle), then the scene's own, as the trace
/// kernel's triangle buffer holds them (`render::dispatch::upload::GpuScene`).
struct Inputs {
    positions: Vec<[f32; 4]>,
    indices: Vec<u32>,
    blases: Vec<BlasDesc>,
    instances: Vec<TlasInstance>,
}

impl Inputs {
    fn new(scene: &Scene) -> Inputs {
        let mut positions = Vec::new();
        let mut indices = Vec::new();
        let mut blases = Vec::new();
        let mut first_blas = Vec::new();
        let empty = crate::scene::Instancing::default();
        let inst = scene.instancing.as_ref().unwrap_or(&empty);
        let append = |g: &Scene, positions: &mut Vec<[f32; 4]>, indices: &mut Vec<u32>| -> (u32, u32) {
            let base = positions.len() as u32;
            let first = (indices.len() / 3) as u32;
            positions.extend(g.positions.iter().map(|p| [p.x, p.y, p.z, 0.0]));
            indices.extend(g.triangles.iter().flat_map(|t| [t[0] + base, t[1] + base, t[2] + base]));
            (first, g.triangles.len() as u32)
        };
        for p in &inst.prototypes {
            let (first, n) = append(&p.geometry, &mut positions, &mut indices);
            // A prototype without triangles gets no BLAS; its instances are left out.
            first_blas.push((n > 0).then(|| {
                blases.push(BlasDesc { first_triangle: first, triangles: n, aabbs: Vec::new() });
                blases.len() - 1
            }));
        }
        let (own_first, own_n) = append(scene, &mut positions, &mut indices);
        let aabbs: Vec<[f32; 6]> = scene
            .spheres
            .iter()
            .map(|s| {
                let r = s.radius;
                [s.center.x - r, s.center.y - r, s.center.z - r, s.center.x + r, s.center.y + r, s.center.z + r]
            })
            .collect();
        let mut instances = Vec::new();
        for (e, i) in inst.instances.iter().enumerate() {
            if let Some(b) = first_blas[i.prototype as usize] {
                let m = i.transform.to_cols_array_2d();
                // glam is column-major: row r of the 3x4 is (m[0][r], m[1][r], m[2][r], m[3][r]).
                let row = |r: usize| [m[0][r], m[1][r], m[2][r], m[3][r]];
                instances.push(TlasInstance { transform: [row(0), row(1), row(2)], blas: b, custom: e as u32 });
            }
        }
        // A BLAS holds one geometry type: the scene's own triangles and its spheres are
        // two, both instanced with the identity as the last entry.
        let own_entry = inst.instances.len() as u32;
        let identity = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
        if own_n > 0 {
            blases.push(BlasDesc { first_triangle: own_first, triangles: own_n, aabbs: Vec::new() });
            instances.push(TlasInstance { transform: identity, blas: blases.len() - 1, custom: own_entry });
        }
        if !aabbs.is_empty() {
            blases.push(BlasDesc { first_triangle: 0, triangles: 0, aabbs });
            instances.push(TlasInstance { transform: identity, blas: blases.len() - 1, custom: own_entry });
        }
        Inputs { positions, indices, blases, instances }
    }
}

impl Traverse for RayQuery {
    fn traverse(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        self.oracle(prims.scene).traverse(prims, ray, best, any)
    }
}

impl super::Structure for RayQuery {
    fn validate(&self, scene: &Scene) -> std::result::Result<(), ValidateError> {
        match &self.records {
            Some(r) => r.validate(scene),
            None => Ok(()),
        }
    }

    fn stats(&self, _scene: &Scene) -> BuildStats {
        let (build_ms, phases) = self.timing();
        BuildStats {
            kind: AccelKind::RayQuery.name().into(),
            build_ms,
            bytes: self.report.blas_bytes + self.report.tlas_bytes,
            refs_per_prim: if self.prims > 0 { 1.0 } else { 0.0 },
            phases,
            opaque: Some("the driver's structure: nodes, leaves, depth and SAH cost are not visible to arbor".into()),
            ..Default::default()
        }
    }

    fn timing(&self) -> (f64, Vec<Phase>) {
        let r = &self.report;
        let mut phases = vec![
            Phase {
                name: "blas".into(),
                ms: r.blas_ms,
                detail: Some(format!(
                    "{} BLAS, {}, {} bytes as built",
                    r.blases,
                    if self.params.fast_build { "PREFER_FAST_BUILD" } else { "PREFER_FAST_TRACE" },
                    r.blas_bytes_built
                )),
            },
            Phase {
                name: "compact".into(),
                ms: r.compact_ms,
                detail: Some(if self.params.compact {
                    format!("{} to {} bytes", r.blas_bytes_built, r.blas_bytes)
                } else {
                    "off (compact=false)".into()
                }),
            },
            Phase { name: "tlas".into(), ms: r.tlas_ms, detail: Some(format!("{} instances", r.instances)) },
        ];
        if self.records.is_some() {
            phases.push(Phase {
                name: "instance records".into(),
                ms: self.records_ms,
                detail: Some(
                    "CPU: the bvh-sah two-level records the kernel reads per instance (not in build_ms)".into(),
                ),
            });
        }
        (r.blas_ms + r.compact_ms + r.tlas_ms, phases)
    }

    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn gpu_image(&self, scene: &Scene) -> std::result::Result<GpuImage<'_>, ValidateError> {
        let device = self.device.as_deref().ok_or_else(|| {
            ValidateError::whole("rayquery is built by the device's driver; this one was made without a device")
        })?;
        let (family, buffers, stack_size) = match &self.records {
            Some(r) => {
                let img = r.gpu_image(scene)?;
                (KernelFamily::InstRayQuery, img.buffers, img.stack_size)
            }
            None => (KernelFamily::RayQuery, None, 1),
        };
        Ok(GpuImage {
            family,
            buffers,
            stack_size,
            // About a log2(N)-deep descent with a few boxes per level, for dispatch sizing.
            cost_per_ray: 4 * u64::from(64 - self.prims.max(1).leading_zeros()) + 8,
            trace_loop: TraceLoop::StepBudget,
            ray_structure: Some(device),
            // The traversal runs inside the driver: it cannot be suspended.
            resume_words: 0,
        })
    }
}
