//! Two-level structures for instanced scenes ([`crate::scene::instance`]): one
//! bottom-level structure of the chosen kind per prototype and one over the scene's
//! own primitives, and a top-level binned-SAH BVH over the world boxes of the
//! instances (and of the scene's own primitives, as one more entry with the identity
//! transform). A ray reaching an instance is moved into its prototype's coordinates
//! (origin and direction by the inverse transform, not renormalised, so t means the
//! same in both spaces) and traced through that prototype's structure.
//!
//! GPU image (`shaders/common/instances.glsl` reads it): the node buffer, in 16-byte
//! texels, holds
//!
//! ```text
//! texel 0: uvec4(top node base, top index base, entry record base, entry count)
//! texel 1: uvec4(prototype triangles P, own triangles, triangles drawn by instances, 0)
//! then each bottom-level structure's node bytes (prototypes in order, then the
//!      scene's own), each starting at a texel boundary;
//! then the top-level BVH nodes (the `bvh` layout, 4 texels each) and its entry
//!      indices (words, from a texel boundary);
//! then one 9-texel record per entry (instances in order, then the scene's own):
//!   0..3  world-to-object rows (xyz: 3x3 row, w: translation)
//!   3..6  object-to-world rows
//!   6     uvec4(node base, index base, first stored triangle, first drawn triangle)
//!   7     xyz box min (object space), w: flags (bit 0: the scene's own primitives)
//!   8     xyz box max
//! ```
//!
//! The index buffer holds each bottom-level structure's primitive indices, each
//! starting at a texel boundary. Triangles are stored prototypes first (prototype k's
//! from its first stored triangle on), then the scene's own from P, so that spheres
//! keep their numbers after every stored triangle.

use std::sync::OnceLock;
use std::time::Instant;

use glam::Vec3;

use super::bvh::{self, Bvh, BvhBuilder, PrimRefs, EMPTY_REF, LEAF_REF};
use super::{Accel, AccelKind, AccelParams, BuildStats, GpuImage, Phase, Prims, TraceLoop, Traverse};
use crate::accel::validate::ValidateError;
use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

/// Texels of one entry record (one source with the shaders: src/gpu/bindings.rs).
pub const RECORD_TEXELS: usize = crate::gpu::bindings::INST_ENTRY_TEXELS as usize;
/// Record flag: the entry is the scene's own primitives (identity transform).
pub const ENTRY_OWN: u32 = crate::gpu::bindings::INST_ENTRY_OWN;

/// What `arbor info` and the stats say of each level.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct LevelStats {
    pub instances: u64,
    pub prototypes: u64,
    /// Triangles stored: the scene's own plus each prototype's once.
    pub unique_triangles: u64,
    /// Triangles drawn through instances (each instance counts its prototype's).
    pub instanced_triangles: u64,
    /// Bytes of the bottom-level structures of the prototypes.
    pub prototype_bytes: u64,
    /// Bytes of the structure over the scene's own primitives.
    pub own_bytes: u64,
    /// Bytes of the top-level BVH.
    pub top_bytes: u64,
    /// Bytes of the per-instance records (transforms, references, boxes).
    pub record_bytes: u64,
}

/// The GPU buffers, assembled on first use.
#[derive(Debug, Clone)]
struct GpuParts {
    nodes: Vec<u8>,
    indices: Vec<u32>,
    stack_size: u32,
    cost_per_ray: u64,
}

/// A two-level structure (see the module docs).
#[derive(Debug, Clone)]
pub struct TwoLevel {
    pub kind: AccelKind,
    /// Over the scene's own primitives; `None` when it has none.
    pub own: Option<Box<Accel>>,
    /// One per prototype.
    pub prototypes: Vec<Accel>,
    /// Over the entries: instance k is entry k, the scene's own primitives the last.
    pub top: Bvh,
    /// First drawn (flattened) triangle number of each instance's copy, counted after
    /// the scene's own triangles.
    first_drawn: Vec<u32>,
    /// Triangles drawn through instances (where the spheres' numbers start, after the
    /// scene's own triangles).
    instanced_tris: u32,
    bounds: Aabb,
    build_ms: f64,
    phases: Vec<Phase>,
    gpu: OnceLock<Result<GpuParts, String>>,
}

impl TwoLevel {
    /// Builds `kind` for every prototype and for the scene's own primitives, and the
    /// top level over them.
    pub fn build(kind: AccelKind, scene: &Scene, params: &AccelParams) -> TwoLevel {
        let start = Instant::now();
        let mut phases = Vec::new();
        let empty = crate::scene::Instancing::default();
        let inst = scene.instancing.as_ref().unwrap_or(&empty);
        let mut t = Instant::now();
        // Each builder is parallel inside; many small prototypes also build side by side.
        let prototypes: Vec<Accel> = {
            use rayon::prelude::*;
            inst.prototypes.par_iter().map(|p| Accel::build_own(kind, &p.geometry, params)).collect()
        };
        phases.push(Phase::since("prototypes", t).with_detail(format!("{} structures", prototypes.len())));
        t = Instant::now();
        let own = (scene.prim_count() > 0).then(|| Box::new(Accel::build_own(kind, scene, params)));
        phases.push(Phase::since("own primitives", t));
        t = Instant::now();
        let mut boxes: Vec<Aabb> = inst
            .instances
            .iter()
            .map(|i| crate::scene::instance::transform_box(&i.transform, &prototypes[i.prototype as usize].bounds()))
            .collect();
        if let Some(o) = &own {
            boxes.push(o.bounds());
        }
        let mut first_drawn = Vec::with_capacity(inst.instances.len());
        let mut acc = 0u64;
        for i in &inst.instances {
            first_drawn.push(acc as u32);
            acc += inst.prototypes[i.prototype as usize].geometry.triangles.len() as u64;
        }
        let centroids = boxes.iter().map(|b| (b.min + b.max) * 0.5).collect();
        let refs = PrimRefs { bounds: boxes, centroids };
        let bounds = refs.bounds.iter().fold(Aabb::EMPTY, |a, b| a.union(b));
        let bin = bvh::binned::build(&refs, &super::sah::SahCosts::default());
        let top = Bvh::flatten(&bin, &refs, bounds, BvhBuilder::Sah);
        phases.push(Phase::since("top level", t).with_detail(format!("{} entries", refs.bounds.len())));
        TwoLevel {
            kind,
            own,
            prototypes,
            top,
            first_drawn,
            instanced_tris: acc as u32,
            bounds: Aabb { min: bounds.min + Vec3::ZERO, max: bounds.max + Vec3::ZERO },
            build_ms: start.elapsed().as_secs_f64() * 1e3,
            phases,
            gpu: OnceLock::new(),
        }
    }

    /// Bytes and counts of each level.
    pub fn levels(&self, scene: &Scene) -> LevelStats {
        let empty = crate::scene::Instancing::default();
        let inst = scene.instancing.as_ref().unwrap_or(&empty);
        let bytes = |a: &Accel, s: &Scene| a.stats(s).bytes;
        LevelStats {
            instances: inst.instances.len() as u64,
            prototypes: inst.prototypes.len() as u64,
            unique_triangles: scene.triangles.len() as u64 + inst.prototype_triangles(),
            instanced_triangles: inst.instanced_triangles(),
            prototype_bytes: self.prototypes.iter().zip(&inst.prototypes).map(|(a, p)| bytes(a, &p.geometry)).sum(),
            own_bytes: self.own.as_ref().map_or(0, |o| bytes(o, scene)),
            top_bytes: self.top.bytes(),
            record_bytes: (self.top.prims * RECORD_TEXELS * 16) as u64,
        }
    }

    /// The GPU buffers (see the module docs).
    fn assemble(&self, scene: &Scene) -> Result<GpuParts, String> {
        let empty = crate::scene::Instancing::default();
        let inst = scene.instancing.as_ref().unwrap_or(&empty);
        let texel_pad = |v: &mut Vec<u8>| v.resize(v.len().next_multiple_of(16), 0);
        let mut nodes: Vec<u8> = vec![0; 32];
        let mut indices: Vec<u32> = Vec::new();
        let (mut stack, mut cost) = (self.top.depth + 1, 0u64);
        // (node base, index base, box) of each bottom-level structure.
        let mut place = |a: &Accel, s: &Scene| -> Result<(u32, u32, Aabb), String> {
            let img = a.gpu_image(s).map_err(|e| e.to_string())?;
            let Some(crate::accel::AccelBuffers::Host(n, ix)) = img.buffers else {
                return Err(format!("the {} structure has no instance level", a.stats(s).kind));
            };
            stack = stack.max(img.stack_size);
            cost = cost.max(img.cost_per_ray);
            texel_pad(&mut nodes);
            let nb = nodes.len() / 16;
            nodes.extend_from_slice(&n);
            indices.resize(indices.len().next_multiple_of(4), 0);
            let ib = indices.len() / 4;
            indices.extend_from_slice(ix);
            Ok((nb as u32, ib as u32, a.bounds()))
        };
        let mut placed = Vec::with_capacity(self.prototypes.len());
        for (a, p) in self.prototypes.iter().zip(&inst.prototypes) {
            placed.push(place(a, &p.geometry)?);
        }
        let own = match &self.own {
            Some(o) => Some(place(o, scene)?),
            None => None,
        };
        texel_pad(&mut nodes);
        let top_base = nodes.len() / 16;
        for n in &self.top.nodes {
            nodes.extend_from_slice(bytemuck::cast_slice(n));
        }
        let top_index = nodes.len() / 16;
        nodes.extend_from_slice(bytemuck::cast_slice(&self.top.indices));
        texel_pad(&mut nodes);
        let records = nodes.len() / 16;
        let mut first_stored = Vec::with_capacity(inst.prototypes.len());
        let mut acc = 0u32;
        for p in &inst.prototypes {
            first_stored.push(acc);
            acc += p.geometry.triangles.len() as u32;
        }
        let proto_tris = acc;
        let mut record = |w2o: glam::Affine3A, o2w: glam::Affine3A, refs: [u32; 4], b: Aabb, flags: u32| {
            let rows = |m: glam::Affine3A| {
                let c = glam::Mat4::from(m);
                [c.row(0), c.row(1), c.row(2)]
            };
            for r in rows(w2o).into_iter().chain(rows(o2w)) {
                nodes.extend_from_slice(bytemuck::cast_slice(&r.to_array()));
            }
            nodes.extend_from_slice(bytemuck::cast_slice(&refs));
            nodes.extend_from_slice(bytemuck::cast_slice(&[b.min.x, b.min.y, b.min.z, f32::from_bits(flags)]));
            nodes.extend_from_slice(bytemuck::cast_slice(&[b.max.x, b.max.y, b.max.z, 0.0]));
        };
        for (k, i) in inst.instances.iter().enumerate() {
            let p = i.prototype as usize;
            let (nb, ib, b) = placed[p];
            record(i.transform.inverse(), i.transform, [nb, ib, first_stored[p], self.first_drawn[k]], b, 0);
        }
        if let Some((nb, ib, b)) = own {
            let id = glam::Affine3A::IDENTITY;
            record(id, id, [nb, ib, proto_tris, 0], b, ENTRY_OWN);
        }
        let entries = inst.instances.len() + usize::from(own.is_some());
        debug_assert_eq!(nodes.len(), (records + entries * RECORD_TEXELS) * 16, "entry record size");
        let header: [u32; 8] = [
            top_base as u32,
            top_index as u32,
            records as u32,
            entries as u32,
            proto_tris,
            scene.triangles.len() as u32,
            inst.instanced_triangles() as u32,
            0,
        ];
        nodes[..32].copy_from_slice(bytemuck::cast_slice(&header));
        if indices.is_empty() {
            indices.push(0);
        }
        Ok(GpuParts { nodes, indices, stack_size: stack, cost_per_ray: cost + 2 * u64::from(self.top.depth + 1) })
    }

    /// Children of top-level node `n`.
    fn top_children(&self, n: usize) -> [(u32, Aabb); 2] {
        self.top.children(n)
    }
}

impl Traverse for TwoLevel {
    fn traverse(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        let scene = prims.scene;
        let empty = crate::scene::Instancing::default();
        let inst = scene.instancing.as_ref().unwrap_or(&empty);
        let own_tris = scene.triangles.len() as u32;
        let sphere_base = own_tris + self.instanced_tris;
        // One entry: traced in its own space, its hit renumbered as the flattened scene's.
        let entry = |e: u32, best: &mut Hit| -> bool {
            let mut h = Hit::none(best.t);
            let hit = if (e as usize) < inst.instances.len() {
                let i = &inst.instances[e as usize];
                let p = i.prototype as usize;
                let w2o = i.transform.inverse();
                let r = Ray {
                    origin: w2o.transform_point3(ray.origin),
                    dir: w2o.transform_vector3(ray.dir),
                    tmin: ray.tmin,
                    tmax: best.t,
                };
                let pp = prims.prototype(&inst.prototypes[p].geometry);
                self.prototypes[p]
                    .traverse(&pp, &r, &mut h, any)
                    .then(|| own_tris + self.first_drawn[e as usize] + h.prim)
            } else {
                let r = Ray { tmax: best.t, ..*ray };
                let own = self.own.as_ref().expect("the last entry is the scene's own primitives");
                own.traverse(prims, &r, &mut h, any).then(|| {
                    if h.prim < own_tris {
                        h.prim
                    } else {
                        h.prim - own_tris + sphere_base
                    }
                })
            };
            match hit {
                Some(id) if best.closer(h.t, id) => {
                    *best = Hit { t: h.t, prim: id, u: h.u, v: h.v };
                    true
                }
                _ => false,
            }
        };
        self.top.walk(ray, best, |leaf, best| {
            let mut found = false;
            for &e in leaf {
                if entry(e, best) {
                    found = true;
                    if any {
                        return (true, true);
                    }
                }
            }
            (found, false)
        })
    }
}

impl super::Structure for TwoLevel {
    fn validate(&self, scene: &Scene) -> Result<(), ValidateError> {
        let empty = crate::scene::Instancing::default();
        let inst = scene.instancing.as_ref().unwrap_or(&empty);
        for (a, p) in self.prototypes.iter().zip(&inst.prototypes) {
            a.validate(&p.geometry).map_err(|e| ValidateError::whole(format!("prototype '{}': {e}", p.name)))?;
        }
        if let Some(o) = &self.own {
            o.validate(scene).map_err(|e| ValidateError::whole(format!("own primitives: {e}")))?;
        }
        // The top level: every entry in exactly one leaf, whose box holds the entry's.
        let entries = inst.instances.len() + usize::from(self.own.is_some());
        let mut seen = vec![false; entries];
        let boxes: Vec<Aabb> = inst
            .instances
            .iter()
            .map(|i| {
                crate::scene::instance::transform_box(&i.transform, &self.prototypes[i.prototype as usize].bounds())
            })
            .chain(self.own.iter().map(|o| o.bounds()))
            .collect();
        let contains = |o: &Aabb, i: &Aabb| i.min.cmpge(o.min).all() && i.max.cmple(o.max).all();
        for n in 0..self.top.nodes.len() {
            for (r, b) in self.top_children(n) {
                if r == EMPTY_REF || r & LEAF_REF == 0 {
                    continue;
                }
                let (first, count) = bvh::leaf_range(r);
                for &e in self.top.indices.get(first..first + count).unwrap_or(&[]) {
                    let Some(s) = seen.get_mut(e as usize) else {
                        return Err(ValidateError::whole(format!("top level names entry {e} of {entries}")));
                    };
                    if std::mem::replace(s, true) {
                        return Err(ValidateError::whole(format!("top level holds entry {e} twice")));
                    }
                    if !contains(&b, &boxes[e as usize]) {
                        return Err(ValidateError::whole(format!("top-level leaf box misses entry {e}")));
                    }
                }
            }
        }
        if let Some(e) = seen.iter().position(|s| !s) {
            return Err(ValidateError::whole(format!("top level lacks entry {e}")));
        }
        Ok(())
    }

    fn stats(&self, scene: &Scene) -> BuildStats {
        let empty = crate::scene::Instancing::default();
        let inst = scene.instancing.as_ref().unwrap_or(&empty);
        let top = self.top.stats();
        let parts: Vec<BuildStats> = self
            .prototypes
            .iter()
            .zip(&inst.prototypes)
            .map(|(a, p)| a.stats(&p.geometry))
            .chain(self.own.iter().map(|o| o.stats(scene)))
            .collect();
        let levels = self.levels(scene);
        let leaves: u64 = parts.iter().map(|p| p.leaves).sum();
        BuildStats {
            kind: self.kind.name().into(),
            build_ms: self.build_ms,
            bytes: levels.prototype_bytes + levels.own_bytes + levels.top_bytes + levels.record_bytes,
            nodes: top.nodes + parts.iter().map(|p| p.nodes).sum::<u64>(),
            max_depth: top.max_depth + 1 + parts.iter().map(|p| p.max_depth).max().unwrap_or(0),
            leaves: top.leaves + leaves,
            empty_leaves: top.empty_leaves + parts.iter().map(|p| p.empty_leaves).sum::<u64>(),
            mean_leaf_depth: parts.iter().map(|p| p.mean_leaf_depth * p.leaves as f64).sum::<f64>()
                / leaves.max(1) as f64,
            refs_per_prim: weighted(&parts, |p| p.refs_per_prim),
            prims_per_leaf: weighted(&parts, |p| p.prims_per_leaf),
            sah_cost: top.sah_cost,
            phases: self.phases.clone(),
            resolution: None,
            levels: Some(levels),
            opaque: None,
            on_device: None,
        }
    }

    fn timing(&self) -> (f64, Vec<Phase>) {
        (self.build_ms, self.phases.clone())
    }

    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn gpu_image(&self, scene: &Scene) -> Result<GpuImage<'_>, ValidateError> {
        let kind = self.kind;
        let family = kind.kernel().instanced().ok_or_else(|| {
            ValidateError::whole(format!(
                "{kind} tests every primitive and has no instance level; render the instanced scene with a structure"
            ))
        })?;
        let parts = self.gpu.get_or_init(|| self.assemble(scene)).as_ref().map_err(ValidateError::whole)?;
        Ok(GpuImage {
            family,
            buffers: Some(crate::accel::AccelBuffers::Host(std::borrow::Cow::Borrowed(&parts.nodes), &parts.indices)),
            stack_size: parts.stack_size,
            cost_per_ray: parts.cost_per_ray,
            trace_loop: TraceLoop::StepBudget,
            ray_structure: None,
            resume_words: super::resume_words(2, parts.stack_size),
        })
    }
}

/// Mean of `f` over the parts, each weighted by its leaves.
fn weighted(parts: &[BuildStats], f: impl Fn(&BuildStats) -> f64) -> f64 {
    let w: f64 = parts.iter().map(|p| p.leaves as f64).sum();
    if w == 0.0 {
        return 0.0;
    }
    parts.iter().map(|p| f(p) * p.leaves as f64).sum::<f64>() / w
}
