//! The LBVH and trbvh builders on the GPU (`--build gpu`): Karras, "Maximizing
//! parallelism in the construction of BVHs, octrees, and k-d trees" (HPG 2012), and
//! Karras & Aila, "Fast parallel construction of high-quality bounding volume
//! hierarchies" (HPG 2013), as Vulkan compute kernels (shaders/build_*.comp) recorded
//! into one command buffer with a barrier between dispatches and a timestamp after
//! every phase. No CPU round trip happens between phases.
//!
//! | phase | kernel | work |
//! |---|---|---|
//! | bounds | `build_bounds_<geometry>` | primitive boxes; centroid box by workgroup reduction and atomics |
//! | morton | `build_morton` | 30-bit codes, `(code, primitive)` pairs; the climb's arrival words |
//! | sort | `build_sort_{hist,scan,scatter}` x 4 | stable LSD radix sort, 8-bit digits |
//! | hierarchy + fit | `build_fit` | the radix tree with boxes, counts, costs and node heights, bottom-up with atomic arrival words |
//! | restructure round r | `build_levels`, `build_treelet` per height | 7-leaf treelets, lowest first (trbvh) |
//! | collapse (trbvh) | `build_levels`, `build_finalize` per height | collapse decisions, output-node counts |
//! | schedule (lbvh) | `build_levels` | every inner node listed by height (an LBVH collapses nothing: a subtree of k primitives has k - 1 inner nodes) |
//! | emit | `build_emit`, per height from the top | nodes and indices in the traversal layout |
//! | collapse to W-wide (bvh4, bvh8) | `build_wide`: mark per height from the top, count, scan, number; then write | the wide nodes, numbered in preorder |
//!
//! **The tree stays on the device** ([`super::device::DeviceTree`]): the trace kernel
//! binds the buffers `emit` (or `build_wide`) wrote. The host reads back only the
//! header (errors, node count, depth: a few words), and for a wide tree allocates the
//! wide nodes once their count is known, between the two submissions.
//!
//! **Passes by height.** llvmpipe runs the body of a divergent `if` under a lane mask
//! even when no lane is active, so a kernel that climbs from the leaves and does a
//! node's work where the climb arrives pays for that work at every step of every SIMD
//! group. Only `fit` climbs (building the radix tree on the way up, so no per-node
//! binary searches diverge either); it also computes every node's height (leaves 0).
//! The later passes list their nodes by height (`build_levels`: count, scan, scatter)
//! and run one indirect dispatch per height, one thread per node: lowest first where a
//! node needs its children final, highest first where it needs its parent's. The treelet
//! kernel updates the heights in the subtree it rewrites, so the next round's schedule
//! needs no new climb. Empty heights dispatch no workgroups.
//!
//! Every result equals the CPU builder's for the same scene, word for word: the Morton
//! codes round alike (see [`super::lbvh::MortonGrid`]), the sort is stable over
//! primitive order (equal codes order by index as the CPU's 64-bit keys do), the
//! hierarchy is the same function of the keys with the same node numbers, costs are
//! computed with the same operations in the same order (`precise`), a treelet is
//! optimised only after every treelet below it, as on the CPU, and the emit pass writes
//! the flattener's preorder (a node's preorder index and first primitive handed down
//! from its parent).
//! The tests check this equality, which implies the same SAH cost. The wide collapse
//! equals [`super::wide::WideBvh::collapse`] of the same binary tree, word for word:
//! the same `open_wide` choices (same areas, the first of equal ones), wide nodes in
//! preorder on both.
//!
//! Buffers (at most 6 per kernel): header, primitive boxes, two pair arrays, the sort's
//! histogram, canonical nodes (32 bytes), per-node aux words (16 bytes), the schedule
//! (per-height counters and dispatch arguments, a node list, node heights), output
//! nodes (64 bytes) and indices. `2n - 1` canonical nodes must fit the device's
//! storage-buffer range: about 4M primitives at 128 MiB.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Instant;

use super::device::DeviceTree;
use super::treelet::{TreeletParams, KEEP_FACTOR};
use super::wide::{Bvh4, Bvh8};
use super::{Bvh, BvhBuilder, MAX_BVH_DEPTH, MAX_BVH_PRIMS};
use crate::accel::gpu_layout::{
    gpu_spheres, gpu_triangles, gpu_vertices, GpuBuildPush as Push, GpuTriangle, GpuVertex,
};
use crate::accel::sah::SahCosts;
use crate::accel::{AccelKind, Geometry, Phase};
use crate::error::{Error, Result};
use crate::gpu::bindings::*;
use crate::gpu::{spirv, BindingDesc, BindingKind, Buffer, Context, Kernel, Step};
use crate::scene::Scene;

// Every height of a tree the traversal accepts has a slot in the schedule, and the
// one workgroup of `build_levels`'s scan covers every slot.
const _: () = assert!(BUILD_MAX_LEVELS > MAX_BVH_DEPTH && BUILD_GROUP > BUILD_MAX_LEVELS);

/// Sort tile: pairs per workgroup.
const TILE: u64 = (BUILD_GROUP * BUILD_SORT_ITEMS) as u64;
/// Output nodes per workgroup of the wide collapse's count and number passes.
const WIDE_BLOCK: u64 = (BUILD_GROUP * BUILD_WIDE_ITEMS) as u64;
fn storage(binding: u32, name: &'static str) -> BindingDesc {
    BindingDesc { binding, kind: BindingKind::Storage, name }
}

/// What `--build gpu` makes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// A binary BVH from this builder (`lbvh`, `trbvh`).
    Binary(BvhBuilder),
    /// The binary tree of `source` collapsed into `width`-wide nodes (`bvh4`, `bvh8`).
    Wide {
        /// The binary builder.
        source: BvhBuilder,
        /// Children per node.
        width: Width,
    },
}

/// Children per node of a wide target: the two layouts the collapse writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Width {
    /// `bvh4`.
    Four,
    /// `bvh8`.
    Eight,
}

impl Width {
    /// Children per node.
    pub fn children(self) -> u32 {
        match self {
            Width::Four => 4,
            Width::Eight => 8,
        }
    }

    /// Its collapse kernel in `GpuBuilder::wide`.
    fn index(self) -> usize {
        usize::from(self == Width::Eight)
    }

    /// 16-byte texels of one node in its layout.
    fn texels(self) -> u64 {
        (match self {
            Width::Four => Bvh4::TEXELS,
            Width::Eight => Bvh8::TEXELS,
        }) as u64
    }
}

impl Target {
    /// The target of `--accel kind --build gpu`, if the GPU builds that kind: the wide
    /// kinds collapse trbvh's tree (the CPU's collapse the binned SAH tree).
    pub fn of(kind: AccelKind) -> Option<Target> {
        match kind {
            AccelKind::Lbvh => Some(Target::Binary(BvhBuilder::Lbvh)),
            AccelKind::Trbvh => Some(Target::Binary(BvhBuilder::Trbvh)),
            AccelKind::Bvh4 => Some(Target::Wide { source: BvhBuilder::Trbvh, width: Width::Four }),
            AccelKind::Bvh8 => Some(Target::Wide { source: BvhBuilder::Trbvh, width: Width::Eight }),
            _ => None,
        }
    }

    /// The structure made.
    pub fn kind(self) -> AccelKind {
        match self {
            Target::Binary(BvhBuilder::Lbvh) => AccelKind::Lbvh,
            Target::Binary(_) => AccelKind::Trbvh,
            Target::Wide { width: Width::Eight, .. } => AccelKind::Bvh8,
            Target::Wide { width: Width::Four, .. } => AccelKind::Bvh4,
        }
    }

    /// Children per node: 2 for a binary tree.
    pub fn width(self) -> u32 {
        match self {
            Target::Binary(_) => 2,
            Target::Wide { width, .. } => width.children(),
        }
    }

    /// The binary builder.
    pub fn source(self) -> BvhBuilder {
        match self {
            Target::Binary(b) | Target::Wide { source: b, .. } => b,
        }
    }
}

/// The build pipelines, created once and reused for every build on one context.
pub struct GpuBuilder {
    bounds: HashMap<Geometry, Kernel>,
    morton: Kernel,
    hist: [Kernel; 2],
    scan: Kernel,
    scatter: [Kernel; 2],
    fit: Kernel,
    /// Threads per workgroup of `fit`: the device's subgroup size, within 8..=256.
    fit_group: u32,
    levels: Kernel,
    treelet: Kernel,
    finalize: Kernel,
    emit: Kernel,
    /// The wide collapse, 4 and 8 wide (`SPEC_WIDE_WIDTH`).
    wide: [Kernel; 2],
    /// Milliseconds spent creating the pipelines (once per process, not per build).
    pub setup_ms: f64,
}

impl std::fmt::Debug for GpuBuilder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuBuilder").field("setup_ms", &self.setup_ms).finish()
    }
}

fn kernel(ctx: &Context, name: &str, bindings: &[BindingDesc]) -> Result<Kernel> {
    kernel_with(ctx, name, bindings, &[])
}

/// [`kernel`] with specialization constants (id, value).
fn kernel_with(ctx: &Context, name: &str, bindings: &[BindingDesc], spec: &[(u32, u32)]) -> Result<Kernel> {
    let code = spirv::get(name)
        .ok_or_else(|| Error::Vulkan { what: format!("kernel '{name}'"), result: "not compiled".into() })?;
    ctx.create_kernel(name, code, bindings, spec, std::mem::size_of::<Push>() as u32)
}

/// One indirect dispatch of `kernel` per height 1..BUILD_MAX_LEVELS (inner nodes have
/// heights from 1), lowest first or, with `descending`, highest first, over the nodes
/// the last schedule in `schedule` listed; push constants `p` with the height in `c`.
/// Empty heights dispatch no workgroups.
fn per_height<'a>(kernel: &'a Kernel, schedule: &'a Buffer, p: Push, descending: bool) -> Vec<Step<'a>> {
    let mut heights: Vec<u32> = (1..BUILD_MAX_LEVELS).collect();
    if descending {
        heights.reverse();
    }
    heights
        .into_iter()
        .map(|h| Step::DispatchIndirect {
            kernel,
            push: bytemuck::bytes_of(&Push { c: h, ..p }).to_vec(),
            args: schedule,
            offset: u64::from(BUILD_LV_ARGS + 3 * h) * 4,
        })
        .collect()
}

/// The steps of one pass by height: `levels` lists the inner nodes with at least
/// `gamma` primitives (every inner node for gamma 0) by height into `schedule`, then
/// `kernel` runs once per height, lowest first ([`per_height`]).
fn by_height<'a>(
    levels: &'a Kernel,
    kernel: &'a Kernel,
    schedule: &'a Buffer,
    inner: [u32; 3],
    gamma: u32,
    p: Push,
) -> Vec<Step<'a>> {
    let mut steps = self::schedule(levels, inner, gamma, p);
    steps.extend(per_height(kernel, schedule, p, false));
    steps
}

/// The three dispatches of `levels` (count, scan, scatter) that list the inner nodes
/// with at least `gamma` primitives by height.
fn schedule(levels: &Kernel, inner: [u32; 3], gamma: u32, p: Push) -> Vec<Step<'_>> {
    [(BUILD_LEVELS_COUNT, inner), (BUILD_LEVELS_SCAN, [1, 1, 1]), (BUILD_LEVELS_SCATTER, inner)]
        .into_iter()
        .map(|(mode, groups)| Step::Dispatch {
            kernel: levels,
            push: bytemuck::bytes_of(&Push { a: mode, b: gamma, ..p }).to_vec(),
            groups,
        })
        .collect()
}

/// Geometry of the bounds kernel: only the buffers the scene has.
fn geometry(scene: &Scene) -> Geometry {
    Geometry::of(!scene.triangles.is_empty(), !scene.spheres.is_empty())
}

/// Buffers of one build.
struct Buffers {
    header: Buffer,
    prim_bounds: Buffer,
    pairs: Buffer,
    pairs_out: Buffer,
    hist: Buffer,
    nodes: Buffer,
    aux: Buffer,
    levels: Buffer,
    out_nodes: Buffer,
    out_indices: Buffer,
    /// The wide collapse's words (a stand-in for binary targets).
    wide: Buffer,
    /// The scene's geometry in the render's layout, kept for the trace.
    geometry: Vec<(u32, Arc<Buffer>)>,
}

impl GpuBuilder {
    /// Creates every build pipeline on `ctx`.
    pub fn new(ctx: &Context) -> Result<GpuBuilder> {
        let t = Instant::now();
        let hdr = storage(BINDING_BUILD_HEADER, "build_header");
        let pb = storage(BINDING_BUILD_PRIM_BOUNDS, "prim_bounds");
        let pairs = storage(BINDING_BUILD_PAIRS, "pairs");
        let pairs_out = storage(BINDING_BUILD_PAIRS_OUT, "pairs_out");
        let hist = storage(BINDING_BUILD_HIST, "sort_hist");
        let nodes = storage(BINDING_BUILD_NODES, "build_nodes");
        let aux = storage(BINDING_BUILD_AUX, "build_aux");
        let levels = storage(BINDING_BUILD_LEVELS, "build_levels");
        let out_nodes = storage(BINDING_BUILD_OUT_NODES, "accel_nodes");
        let out_idx = storage(BINDING_BUILD_OUT_INDICES, "accel_indices");
        let mut bounds = HashMap::new();
        for geo in Geometry::ALL {
            let mut b = vec![hdr.clone(), pb.clone()];
            if geo.has_triangles() {
                b.push(storage(BINDING_VERTICES, "vertices"));
                b.push(storage(BINDING_TRIANGLES, "triangles"));
            }
            if geo.has_spheres() {
                b.push(storage(BINDING_SPHERES, "spheres"));
            }
            bounds.insert(geo, kernel(ctx, &format!("build_bounds_{geo}"), &b)?);
        }
        let fit_group = ctx.info().subgroup_size.clamp(8, 256);
        let scatter_group = ctx.info().subgroup_size.clamp(8, BUILD_SCATTER_MAX_GROUP);
        let scatter_b = [pairs.clone(), pairs_out.clone(), hist.clone()];
        let fit_b = [hdr.clone(), pairs.clone(), pb.clone(), nodes.clone(), aux.clone(), levels.clone()];
        let g = GpuBuilder {
            bounds,
            morton: kernel(ctx, "build_morton", &[hdr.clone(), pb.clone(), pairs.clone(), aux.clone()])?,
            hist: [
                kernel(ctx, "build_sort_hist", &[pairs.clone(), hist.clone()])?,
                kernel(ctx, "build_sort_hist", &[pairs.clone(), hist.clone()])?,
            ],
            scan: kernel(ctx, "build_sort_scan", std::slice::from_ref(&hist))?,
            scatter: [
                kernel_with(ctx, "build_sort_scatter", &scatter_b, &[(SPEC_SCATTER_GROUP, scatter_group)])?,
                kernel_with(ctx, "build_sort_scatter", &scatter_b, &[(SPEC_SCATTER_GROUP, scatter_group)])?,
            ],
            fit: kernel_with(ctx, "build_fit", &fit_b, &[(SPEC_FIT_GROUP, fit_group)])?,
            fit_group,
            levels: kernel(ctx, "build_levels", &[hdr.clone(), nodes.clone(), aux.clone(), levels.clone()])?,
            treelet: kernel(ctx, "build_treelet", &[hdr.clone(), nodes.clone(), aux.clone(), levels.clone()])?,
            finalize: kernel(ctx, "build_finalize", &[hdr.clone(), nodes.clone(), aux.clone(), levels.clone()])?,
            emit: kernel(ctx, "build_emit", &[hdr.clone(), nodes, aux, levels, out_nodes.clone(), out_idx])?,
            wide: {
                let [four, eight] = [4, 8].map(|w| {
                    let b = [
                        hdr.clone(),
                        out_nodes.clone(),
                        storage(BINDING_BUILD_WIDE, "build_wide"),
                        storage(BINDING_BUILD_WIDE_NODES, "accel_wide_nodes"),
                    ];
                    kernel_with(ctx, "build_wide", &b, &[(SPEC_WIDE_WIDTH, w)])
                });
                [four?, eight?]
            },
            setup_ms: 0.0,
        };
        Ok(GpuBuilder { setup_ms: t.elapsed().as_secs_f64() * 1e3, ..g })
    }

    fn buffers(&self, ctx: &Context, scene: &Scene, wide: bool) -> Result<Buffers> {
        let n = scene.prim_count() as u64;
        let blocks = n.div_ceil(TILE);
        let mut header = vec![0u32; BUILD_HDR_WORDS as usize];
        for k in 0..3 {
            header[(BUILD_HDR_CMIN + k) as usize] = u32::MAX;
        }
        let mut geometry = Vec::new();
        // The render's layout (shading normals, texture coordinates, materials), which
        // the build ignores: the trace binds these buffers as they are.
        let mut upload = |binding: u32, name: &str, bytes: &[u8]| -> Result<()> {
            geometry.push((binding, Arc::new(ctx.upload_storage(name, bytes)?)));
            Ok(())
        };
        if !scene.triangles.is_empty() {
            let v: Vec<GpuVertex> = gpu_vertices(scene).collect();
            let t: Vec<GpuTriangle> = gpu_triangles(scene, 0).collect();
            upload(BINDING_VERTICES, "vertices", bytemuck::cast_slice(&v))?;
            upload(BINDING_TRIANGLES, "triangles", bytemuck::cast_slice(&t))?;
        }
        if !scene.spheres.is_empty() {
            upload(BINDING_SPHERES, "spheres", bytemuck::cast_slice(&gpu_spheres(scene)))?;
        }
        let storage = |name: &str, bytes: u64| ctx.create_buffer(name, bytes, crate::gpu::BufferKind::Storage);
        Ok(Buffers {
            header: ctx.upload_storage("build_header", bytemuck::cast_slice(&header))?,
            prim_bounds: storage("prim_bounds", n * 32)?,
            pairs: storage("pairs", n * 8)?,
            pairs_out: storage("pairs_out", n * 8)?,
            hist: storage("sort_hist", 256 * blocks * 4)?,
            nodes: storage("build_nodes", (2 * n - 1) * 32)?,
            aux: storage("build_aux", 2 * n * 16)?,
            // The schedule: per-height arrays, the node list (n - 1) and the heights
            // (2n, with the spare).
            levels: storage("build_levels", (u64::from(BUILD_LV_LIST) + n + 2 * n) * 4)?,
            out_nodes: storage("accel_nodes", n.saturating_sub(1).max(1) * 64)?,
            out_indices: storage("accel_indices", n * 4)?,
            wide: storage("build_wide", if wide { wide_words(n) * 4 } else { 16 })?,
            geometry,
        })
    }

    /// Builds the binary tree of `builder` (lbvh or trbvh; `tp` for trbvh's
    /// restructuring) on the GPU and keeps it there ([`GpuBuilder::build_target`]).
    pub fn build(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        builder: BvhBuilder,
        tp: &TreeletParams,
    ) -> Result<DeviceTree> {
        self.build_target(ctx, scene, Target::Binary(builder), tp)
    }

    /// Builds `target` for `scene` on the GPU and keeps it there. Phases: the host's
    /// upload of the geometry, each GPU phase (from timestamps, named `gpu ...`), and
    /// the host's read of the header (with, for a wide tree, the allocation of its
    /// nodes); `build_ms` is the wall clock of all. The stages: the binary tree's
    /// steps (`GpuBuilder::binary_steps`), for a wide target the collapse's plan
    /// (`GpuBuilder::wide_plan_steps`), one submission of them, the header read, and
    /// for a wide target the write of its nodes (`GpuBuilder::write_wide`).
    pub fn build_target(
        &mut self,
        ctx: &Context,
        scene: &Scene,
        target: Target,
        tp: &TreeletParams,
    ) -> Result<DeviceTree> {
        let builder = target.source();
        if builder == BvhBuilder::Sah {
            return Err(Error::Usage("--build gpu builds lbvh and trbvh trees; bvh-sah is built on the CPU".into()));
        }
        let n = scene.prim_count();
        if n == 0 {
            return empty_tree(ctx, scene, target, tp);
        }
        if n > MAX_BVH_PRIMS || 2 * n as u64 - 1 > u64::from(u32::MAX / 2) {
            return Err(Error::Failed(format!("{n} primitives: the GPU build handles at most {MAX_BVH_PRIMS}")));
        }
        let width = target.width();
        if width > 2 && n as u64 / 2 > 65_535 * u64::from(BUILD_GROUP) {
            return Err(Error::Failed(format!("{n} primitives: the GPU's wide collapse handles at most 33M")));
        }
        let start = Instant::now();
        let mut phases = Vec::new();
        let mut t = Instant::now();
        let b = self.buffers(ctx, scene, width > 2)?;
        super::lap(&mut phases, "upload geometry", &mut t);
        self.bind(ctx, scene, &b)?;
        let costs = SahCosts::default();
        let base = Push {
            n: n as u32,
            a: 0,
            b: 0,
            c: 0,
            ct: costs.traversal,
            ci: costs.intersect,
            keep: KEEP_FACTOR,
            d: width,
        };
        let names = StageNames::new(width, tp);
        let restructure = (builder == BvhBuilder::Trbvh).then_some(tp);
        let mut steps = self.binary_steps(ctx, scene, &b, base, restructure, &names)?;
        if let Target::Wide { width, .. } = target {
            steps.extend(self.wide_plan_steps(ctx, &b, base, width, &names)?);
        }
        let gpu = ctx.run_steps(&format!("build {}", target.kind()), &steps)?;
        drop(steps);
        let gpu_wall = t.elapsed().as_secs_f64() * 1e3;
        if gpu.is_empty() {
            phases.push(Phase { name: "gpu build (no timestamps)".into(), ms: gpu_wall, detail: None });
        }
        phases.extend(gpu.into_iter().map(|(name, ms)| Phase { name, ms, detail: None }));
        t = Instant::now();
        let header: Vec<u32> = ctx.read_storage_pod(&b.header, 0, BUILD_HDR_WORDS as usize)?;
        check_header(&header, n)?;
        let Buffers { out_nodes, out_indices, wide, geometry, .. } = b;
        let (nodes, count, depth) = match target {
            Target::Binary(_) => {
                super::lap(&mut phases, "read header", &mut t);
                let count = u64::from(header[BUILD_HDR_NODES as usize]);
                (out_nodes, count, header[BUILD_HDR_DEPTH as usize])
            }
            Target::Wide { width, .. } => {
                let tree = self.write_wide(ctx, target.kind(), width, &header, base, &names, (&mut phases, &mut t))?;
                drop((out_nodes, wide));
                tree
            }
        };
        Ok(DeviceTree::new(
            target.kind(),
            builder,
            (nodes, out_indices, geometry),
            count,
            depth,
            n,
            scene.bounds(),
            (start.elapsed().as_secs_f64() * 1e3, phases),
        ))
    }

    /// The binary tree's steps: bounds, Morton codes, the radix sort, the hierarchy
    /// and its boxes, the restructuring rounds and collapse of `restructure` (trbvh;
    /// None: the LBVH's schedule), and the emit of the output nodes.
    fn binary_steps<'a>(
        &'a self,
        ctx: &Context,
        scene: &Scene,
        b: &'a Buffers,
        base: Push,
        restructure: Option<&TreeletParams>,
        names: &'a StageNames,
    ) -> Result<Vec<Step<'a>>> {
        let n = u64::from(base.n);
        let push = |a: u32, bb: u32| Push { a, b: bb, ..base };
        let blocks = n.div_ceil(TILE);
        let bounds_k = &self.bounds[&geometry(scene)];
        let mut steps = vec![
            Step::Dispatch {
                kernel: bounds_k,
                push: bytes(push(scene.triangles.len() as u32, 0)),
                groups: groups(ctx, n, BUILD_GROUP * BUILD_BOUNDS_ITEMS)?,
            },
            Step::Mark("gpu bounds"),
            Step::Dispatch { kernel: &self.morton, push: bytes(push(0, 0)), groups: groups(ctx, n, BUILD_GROUP)? },
            Step::Mark("gpu morton"),
        ];
        let tiles = ctx.grid_for(blocks)?;
        for pass in 0..4u32 {
            let p = bytes(push(8 * pass, blocks as u32));
            steps.push(Step::Dispatch { kernel: &self.hist[pass as usize % 2], push: p.clone(), groups: tiles });
            let scan = Push { n: (256 * blocks) as u32, ..push(0, 0) };
            steps.push(Step::Dispatch { kernel: &self.scan, push: bytes(scan), groups: [1, 1, 1] });
            steps.push(Step::Dispatch { kernel: &self.scatter[pass as usize % 2], push: p, groups: tiles });
        }
        steps.push(Step::Mark("gpu sort"));
        let leaves = groups(ctx, n, self.fit_group)?;
        steps.push(Step::Dispatch { kernel: &self.fit, push: bytes(push(0, 0)), groups: leaves });
        steps.push(Step::Mark("gpu hierarchy + fit"));
        let inner = groups(ctx, n - 1, BUILD_GROUP)?;
        // trbvh: the restructuring rounds, then the collapse and output-node counts
        // bottom-up; this leaves every inner node listed by height for the emit pass.
        // The LBVH collapses nothing, so a subtree of k primitives has k - 1 inner
        // nodes: it only lists the nodes.
        let unfinalized = if let Some(tp) = restructure {
            for (round, name) in names.rounds.iter().enumerate() {
                let gamma = tp.gamma(round as u32);
                let p = push(gamma, tp.leaves as u32);
                steps.extend(by_height(&self.levels, &self.treelet, &b.levels, inner, gamma, p));
                steps.push(Step::Mark(name));
            }
            let p = push(BUILD_FINALIZE_COLLAPSE, 0);
            steps.extend(by_height(&self.levels, &self.finalize, &b.levels, inner, 0, p));
            steps.push(Step::Mark("gpu collapse"));
            0
        } else {
            steps.extend(schedule(&self.levels, inner, 0, push(0, 0)));
            steps.push(Step::Mark("gpu schedule"));
            BUILD_EMIT_UNFINALIZED
        };
        let emit = |mode: u32| push(mode, unfinalized);
        steps.push(Step::Dispatch { kernel: &self.emit, push: bytes(emit(BUILD_EMIT_ROOT)), groups: [1, 1, 1] });
        steps.extend(per_height(&self.emit, &b.levels, emit(BUILD_EMIT_TOP), true));
        steps.push(Step::Mark("gpu emit"));
        Ok(steps)
    }

    /// The wide collapse's plan: mark the wide nodes from the top (one indirect
    /// dispatch per wide level), then count, scan and number them.
    fn wide_plan_steps<'a>(
        &'a self,
        ctx: &Context,
        b: &'a Buffers,
        base: Push,
        width: Width,
        names: &'a StageNames,
    ) -> Result<Vec<Step<'a>>> {
        let n = u64::from(base.n);
        let wb = n.div_ceil(WIDE_BLOCK) as u32;
        let wide_grid = ctx.grid_for(u64::from(wb))?;
        let kernel = &self.wide[width.index()];
        let push = |mode: u32| Push { a: mode, b: wb, ..base };
        let mut steps =
            vec![Step::Dispatch { kernel, push: bytes(push(BUILD_WIDE_SEED)), groups: groups(ctx, n, BUILD_GROUP)? }];
        // A wide tree is no deeper than its binary tree, which the traversal limits to
        // MAX_BVH_DEPTH.
        let levels_at = wide_words(n) - u64::from(4 * BUILD_LV_SLOTS);
        for level in 0..MAX_BVH_DEPTH {
            steps.push(Step::DispatchIndirect {
                kernel,
                push: bytes(Push { c: level, ..push(BUILD_WIDE_MARK) }),
                args: &b.wide,
                offset: (levels_at + u64::from(BUILD_LV_SLOTS + 3 * level)) * 4,
            });
        }
        steps.push(Step::Mark(&names.mark));
        for (mode, grid) in
            [(BUILD_WIDE_COUNT, wide_grid), (BUILD_WIDE_SCAN, [1, 1, 1]), (BUILD_WIDE_NUMBER, wide_grid)]
        {
            steps.push(Step::Dispatch { kernel, push: bytes(push(mode)), groups: grid });
        }
        steps.push(Step::Mark(&names.number));
        Ok(steps)
    }

    /// The wide tree's last stage, after the header read: its node count and depth
    /// checked, its nodes allocated and written. Returns them, their count and depth.
    #[allow(clippy::too_many_arguments)]
    fn write_wide(
        &mut self,
        ctx: &Context,
        kind: AccelKind,
        width: Width,
        header: &[u32],
        base: Push,
        names: &StageNames,
        (phases, t): (&mut Vec<Phase>, &mut Instant),
    ) -> Result<(Buffer, u64, u32)> {
        let binary_nodes = u64::from(header[BUILD_HDR_NODES as usize]);
        let count = u64::from(header[BUILD_HDR_WIDE_NODES as usize]);
        let depth = header[BUILD_HDR_WIDE_DEPTH as usize];
        let w = width.children();
        if count == 0 || count > binary_nodes || depth > MAX_BVH_DEPTH {
            return Err(Error::Vulkan {
                what: "GPU build".into(),
                result: format!("{count} {w}-wide nodes of depth {depth} from {binary_nodes} binary nodes"),
            });
        }
        let nodes = ctx.create_buffer("accel_nodes", count * width.texels() * 16, crate::gpu::BufferKind::Storage)?;
        ctx.bind(&mut self.wide[width.index()], BINDING_BUILD_WIDE_NODES, &nodes)?;
        super::lap(phases, "read header, allocate the wide nodes", t);
        let wb = u64::from(base.n).div_ceil(WIDE_BLOCK) as u32;
        let steps = [
            Step::Dispatch {
                kernel: &self.wide[width.index()],
                push: bytes(Push { a: BUILD_WIDE_WRITE, b: wb, ..base }),
                groups: groups(ctx, count, BUILD_GROUP)?,
            },
            Step::Mark(&names.write),
        ];
        let gpu = ctx.run_steps(&format!("build {kind} (write)"), &steps)?;
        if gpu.is_empty() {
            super::lap(phases, "gpu write (no timestamps)", t);
        }
        phases.extend(gpu.into_iter().map(|(name, ms)| Phase { name, ms, detail: None }));
        Ok((nodes, count, depth))
    }

    fn bind(&mut self, ctx: &Context, scene: &Scene, b: &Buffers) -> Result<()> {
        let geo = geometry(scene);
        let bounds_k = self.bounds.get_mut(&geo).ok_or_else(|| Error::Failed("no bounds kernel".into()))?;
        ctx.bind(bounds_k, BINDING_BUILD_HEADER, &b.header)?;
        ctx.bind(bounds_k, BINDING_BUILD_PRIM_BOUNDS, &b.prim_bounds)?;
        for (binding, buf) in &b.geometry {
            ctx.bind(bounds_k, *binding, buf)?;
        }
        ctx.bind(&mut self.morton, BINDING_BUILD_HEADER, &b.header)?;
        ctx.bind(&mut self.morton, BINDING_BUILD_PRIM_BOUNDS, &b.prim_bounds)?;
        ctx.bind(&mut self.morton, BINDING_BUILD_PAIRS, &b.pairs)?;
        let [h0, h1] = &mut self.hist;
        ctx.bind(h0, BINDING_BUILD_PAIRS, &b.pairs)?;
        ctx.bind(h0, BINDING_BUILD_HIST, &b.hist)?;
        ctx.bind(h1, BINDING_BUILD_PAIRS, &b.pairs_out)?;
        ctx.bind(h1, BINDING_BUILD_HIST, &b.hist)?;
        ctx.bind(&mut self.scan, BINDING_BUILD_HIST, &b.hist)?;
        // Even passes read `pairs` and write `pairs_out`, odd passes the reverse, so the
        // four passes leave the sorted pairs in `pairs`.
        let [s0, s1] = &mut self.scatter;
        ctx.bind(s0, BINDING_BUILD_PAIRS, &b.pairs)?;
        ctx.bind(s0, BINDING_BUILD_PAIRS_OUT, &b.pairs_out)?;
        ctx.bind(s0, BINDING_BUILD_HIST, &b.hist)?;
        ctx.bind(s1, BINDING_BUILD_PAIRS, &b.pairs_out)?;
        ctx.bind(s1, BINDING_BUILD_PAIRS_OUT, &b.pairs)?;
        ctx.bind(s1, BINDING_BUILD_HIST, &b.hist)?;
        ctx.bind(&mut self.morton, BINDING_BUILD_AUX, &b.aux)?;
        ctx.bind(&mut self.fit, BINDING_BUILD_PAIRS, &b.pairs)?;
        ctx.bind(&mut self.fit, BINDING_BUILD_PRIM_BOUNDS, &b.prim_bounds)?;
        for k in [&mut self.fit, &mut self.levels, &mut self.treelet, &mut self.finalize, &mut self.emit] {
            ctx.bind(k, BINDING_BUILD_HEADER, &b.header)?;
            ctx.bind(k, BINDING_BUILD_NODES, &b.nodes)?;
            ctx.bind(k, BINDING_BUILD_AUX, &b.aux)?;
            ctx.bind(k, BINDING_BUILD_LEVELS, &b.levels)?;
        }
        ctx.bind(&mut self.emit, BINDING_BUILD_OUT_NODES, &b.out_nodes)?;
        ctx.bind(&mut self.emit, BINDING_BUILD_OUT_INDICES, &b.out_indices)?;
        for (binding, buf) in [
            (BINDING_BUILD_HEADER, &b.header),
            (BINDING_BUILD_OUT_NODES, &b.out_nodes),
            (BINDING_BUILD_WIDE, &b.wide),
            // A stand-in until the wide nodes are counted and allocated.
            (BINDING_BUILD_WIDE_NODES, &b.wide),
        ] {
            for k in &mut self.wide {
                ctx.bind(k, binding, buf)?;
            }
        }
        Ok(())
    }
}

/// The names of the build's timed phases that are built at run time (a `Step::Mark`
/// borrows its name for as long as the steps live).
struct StageNames {
    /// trbvh's restructuring rounds (none for the LBVH).
    rounds: Vec<String>,
    mark: String,
    number: String,
    write: String,
}

impl StageNames {
    fn new(width: u32, tp: &TreeletParams) -> StageNames {
        StageNames {
            rounds: (0..tp.rounds).map(|r| format!("gpu restructure round {}", r + 1)).collect(),
            mark: format!("gpu {width}-wide: mark"),
            number: format!("gpu {width}-wide: number"),
            write: format!("gpu {width}-wide: write"),
        }
    }
}

/// A push constant's bytes.
fn bytes(p: Push) -> Vec<u8> {
    bytemuck::bytes_of(&p).to_vec()
}

/// Workgroups for `threads` threads, `size` a group.
fn groups(ctx: &Context, threads: u64, size: u32) -> Result<[u32; 3]> {
    ctx.grid_for(threads.div_ceil(u64::from(size)))
}

/// Words of the wide collapse's buffer for `n` primitives (shaders/build_wide.comp):
/// a word per output node, the block counts, two level lists of n / 2 + 1, and per
/// level a count and three dispatch arguments.
fn wide_words(n: u64) -> u64 {
    n + n.div_ceil(WIDE_BLOCK) + 2 * (n / 2 + 1) + u64::from(4 * BUILD_LV_SLOTS)
}

/// Checks the header of a build of `n` primitives: error bits, depth, node count.
fn check_header(header: &[u32], n: usize) -> Result<()> {
    if header[BUILD_HDR_ERRORS as usize] & BUILD_ERR_LEVELS != 0 {
        return Err(Error::Failed(format!(
            "GPU build: the tree is more than {} levels deep, deeper than the traversal kernel's limit \
             {MAX_BVH_DEPTH} (use --build cpu to see the final depth)",
            BUILD_MAX_LEVELS - 1
        )));
    }
    if header[BUILD_HDR_ERRORS as usize] & BUILD_ERR_WALK != 0 {
        return Err(Error::Failed(format!(
            "GPU build: a walk between a node and the root took over {BUILD_MAX_WALK} steps (use --build cpu)"
        )));
    }
    let depth = header[BUILD_HDR_DEPTH as usize];
    let count = u64::from(header[BUILD_HDR_NODES as usize]);
    if depth > MAX_BVH_DEPTH {
        return Err(Error::Failed(format!(
            "GPU build: the tree is {depth} deep, deeper than the traversal kernel's limit {MAX_BVH_DEPTH}"
        )));
    }
    if count == 0 || count > n.max(2) as u64 - 1 {
        return Err(Error::Vulkan {
            what: "GPU build".into(),
            result: format!("{count} output nodes for {n} primitives"),
        });
    }
    Ok(())
}

/// The tree of a scene without primitives (the one-empty-leaf tree every builder
/// makes), built on the host and put on the device like a built one.
fn empty_tree(ctx: &Context, scene: &Scene, target: Target, tp: &TreeletParams) -> Result<DeviceTree> {
    let start = Instant::now();
    let bin = Bvh::build_with(scene, target.source(), tp);
    let (words, count, depth): (Vec<u8>, u64, u32) = match target {
        Target::Binary(_) => (bytemuck::cast_slice(&bin.nodes).to_vec(), bin.nodes.len() as u64, bin.depth),
        Target::Wide { width: Width::Eight, .. } => {
            let w = Bvh8::collapse(&bin);
            (bytemuck::cast_slice(&w.nodes).to_vec(), w.node_count() as u64, w.depth)
        }
        Target::Wide { width: Width::Four, .. } => {
            let w = Bvh4::collapse(&bin);
            (bytemuck::cast_slice(&w.nodes).to_vec(), w.node_count() as u64, w.depth)
        }
    };
    let nodes = ctx.upload_storage("accel_nodes", &words)?;
    let indices = ctx.upload_storage("accel_indices", bytemuck::cast_slice(&bin.indices))?;
    let phases = vec![Phase::since("empty scene: one leaf, uploaded", start)];
    Ok(DeviceTree::new(
        target.kind(),
        target.source(),
        (nodes, indices, Vec::new()),
        count,
        depth,
        0,
        scene.bounds(),
        (start.elapsed().as_secs_f64() * 1e3, phases),
    ))
}
