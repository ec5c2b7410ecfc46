//! A BVH built on the device and kept there (`--build gpu`, [`super::gpu_build`]): the
//! trace kernel binds the buffers the build wrote, so no tree crosses the bus between
//! the build and the first ray. What needs the whole tree on the host (`validate`,
//! node statistics, CPU traversal) asks for it with [`DeviceTree::read_back`], whose
//! time then shows as a phase of the build.
//!
//! Without the host copy, [`DeviceTree::stats`] gives what the build's header says
//! (node count, depth, bytes, timing) and names the rest unknown in
//! `BuildStats::on_device`; `validate` is an error that says to read the tree back, and
//! CPU traversal panics (a caller's mistake, not a user's: every CLI path that
//! traverses on the CPU reads back first).

use std::sync::Arc;
use std::time::Instant;

use super::wide::{check_limits, Bvh4, Bvh8, WideBvh};
use super::{Bvh, BvhBuilder, GpuBvhNode};
use crate::accel::prim::Prims;
use crate::accel::validate::ValidateError;
use crate::accel::{Accel, AccelBuffers, AccelKind, BuildStats, GpuImage, KernelFamily, Phase, TraceLoop};
use crate::error::Result;
use crate::gpu::{Buffer, Context};
use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

/// A BVH (binary, 4- or 8-wide) whose nodes and indices are device buffers in the
/// layout its kernel reads (the host structures' `to_gpu`, word for word).
#[derive(Debug, Clone)]
pub struct DeviceTree {
    /// `lbvh`, `trbvh`, `bvh4` or `bvh8`.
    pub kind: AccelKind,
    /// The builder of the binary tree (collapsed for the wide kinds).
    pub source: BvhBuilder,
    /// Node buffer: `nodes` nodes of the kind's layout.
    pub nodes: Arc<Buffer>,
    /// Primitive index buffer: `prims` words.
    pub indices: Arc<Buffer>,
    /// The scene's geometry as the build uploaded it, in the render's layout, by
    /// binding (vertices and triangles, spheres): the trace binds these too, so the
    /// geometry crosses the bus once. Empty for a tree without primitives.
    pub geometry: Vec<(u32, Arc<Buffer>)>,
    /// Nodes in `nodes`.
    pub node_count: u64,
    /// Nodes on the longest root-to-leaf path (the host structure's `depth`).
    pub depth: u32,
    /// Primitives.
    pub prims: usize,
    /// The scene box.
    pub bounds: Aabb,
    /// Wall clock of the build, host part included.
    pub build_ms: f64,
    /// The build's phases: host parts by name, device parts (`gpu ...`) from timestamps.
    pub phases: Vec<Phase>,
    host: Option<Box<Accel>>,
}

impl DeviceTree {
    /// A tree the build wrote into `nodes` and `indices`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        kind: AccelKind,
        source: BvhBuilder,
        (nodes, indices, geometry): (Buffer, Buffer, Vec<(u32, Arc<Buffer>)>),
        node_count: u64,
        depth: u32,
        prims: usize,
        bounds: Aabb,
        (build_ms, phases): (f64, Vec<Phase>),
    ) -> DeviceTree {
        DeviceTree {
            kind,
            source,
            nodes: Arc::new(nodes),
            indices: Arc::new(indices),
            geometry,
            node_count,
            depth,
            prims,
            bounds,
            build_ms,
            phases,
            host: None,
        }
    }

    /// The kernel family of the layout.
    pub fn family(&self) -> KernelFamily {
        match self.kind {
            AccelKind::Bvh4 => KernelFamily::Bvh4,
            AccelKind::Bvh8 => KernelFamily::Bvh8,
            _ => KernelFamily::Bvh,
        }
    }

    /// Texels (16 bytes) per node of the layout.
    fn node_texels(&self) -> u64 {
        match self.kind {
            AccelKind::Bvh4 => Bvh4::TEXELS as u64,
            AccelKind::Bvh8 => Bvh8::TEXELS as u64,
            _ => 4,
        }
    }

    /// Bytes on the device (nodes and indices), as `BuildStats::bytes` counts them.
    pub fn bytes(&self) -> u64 {
        self.node_count * self.node_texels() * 16 + self.prims as u64 * 4
    }

    /// The host copy, if [`DeviceTree::read_back`] made one.
    pub fn host(&self) -> Option<&Accel> {
        self.host.as_deref()
    }

    /// Copies the tree to the host (once), as the host structure of its kind with the
    /// device build's timing; the copy's time is the phase `readback for the host`.
    pub fn read_back(&mut self, ctx: &Context) -> Result<()> {
        if self.host.is_none() {
            let t = Instant::now();
            let host = self.to_host(ctx)?;
            self.phases.push(Phase::since("readback for the host", t));
            self.host = Some(Box::new(host));
        }
        Ok(())
    }

    /// The tree as the host structure of its kind, read from the device.
    pub fn to_host(&self, ctx: &Context) -> Result<Accel> {
        let texels = (self.node_count * self.node_texels()) as usize;
        let indices: Vec<u32> = ctx.read_storage_pod(&self.indices, 0, self.prims)?;
        Ok(match self.kind {
            AccelKind::Bvh4 => Accel::Bvh4(self.wide_host(ctx, texels, indices)?),
            AccelKind::Bvh8 => Accel::Bvh8(self.wide_host(ctx, texels, indices)?),
            _ => {
                let nodes: Vec<GpuBvhNode> = ctx.read_storage_pod(&self.nodes, 0, self.node_count as usize)?;
                Accel::Bvh(Bvh {
                    bounds: self.bounds,
                    nodes,
                    indices,
                    depth: self.depth,
                    prims: self.prims,
                    builder: self.source,
                    build_ms: self.build_ms,
                    phases: self.phases.clone(),
                })
            }
        })
    }

    /// The W-wide host structure of `texels` node texels and the read `indices`.
    fn wide_host<const W: usize>(&self, ctx: &Context, texels: usize, indices: Vec<u32>) -> Result<WideBvh<W>> {
        Ok(WideBvh {
            bounds: self.bounds,
            nodes: ctx.read_storage_pod(&self.nodes, 0, texels)?,
            indices,
            depth: self.depth,
            prims: self.prims,
            source: self.source,
            build_ms: self.build_ms,
            phases: self.phases.clone(),
        })
    }

    /// The statistics: the host copy's where there is one (with this build's timing),
    /// else what the device build reported.
    pub fn stats(&self, scene: &Scene) -> BuildStats {
        let mut st = match &self.host {
            Some(h) => h.stats(scene),
            None => BuildStats {
                nodes: self.node_count,
                max_depth: self.depth,
                on_device: Some(
                    "kept on the device: leaf counts and the SAH cost need the tree on the host (read back)".into(),
                ),
                ..Default::default()
            },
        };
        st.kind = self.kind.name().to_string();
        st.bytes = self.bytes();
        st.build_ms = self.build_ms;
        st.phases = self.phases.clone();
        st
    }
}

impl crate::accel::Traverse for DeviceTree {
    /// # Panics
    /// Without the host copy ([`DeviceTree::read_back`]).
    fn traverse(&self, prims: &Prims, ray: &Ray, best: &mut Hit, any: bool) -> bool {
        self.host
            .as_deref()
            .expect("a tree kept on the device is traversed on the CPU only after read_back")
            .traverse(prims, ray, best, any)
    }
}

impl crate::accel::Structure for DeviceTree {
    fn validate(&self, scene: &Scene) -> std::result::Result<(), ValidateError> {
        match &self.host {
            Some(h) => h.validate(scene),
            None => Err(ValidateError::whole("the tree is on the device; read it back (read_back) to validate it")),
        }
    }
    fn stats(&self, scene: &Scene) -> BuildStats {
        DeviceTree::stats(self, scene)
    }
    fn timing(&self) -> (f64, Vec<Phase>) {
        (self.build_ms, self.phases.clone())
    }
    fn bounds(&self) -> Aabb {
        self.bounds
    }
    fn gpu_image(&self, _scene: &Scene) -> std::result::Result<GpuImage<'_>, ValidateError> {
        check_limits(self.depth, self.prims)?;
        let family = self.family();
        // As the host structures' gpu_image: a binary node pushes one child, a W-wide
        // node at most W - 1.
        let (stack_size, width) = match family {
            KernelFamily::Bvh4 => (3 * self.depth + 1, 4),
            KernelFamily::Bvh8 => (7 * self.depth + 1, 8),
            _ => (self.depth + 1, 4),
        };
        Ok(GpuImage {
            family,
            buffers: Some(AccelBuffers::Device {
                nodes: Arc::clone(&self.nodes),
                indices: Arc::clone(&self.indices),
                geometry: &self.geometry,
            }),
            stack_size,
            cost_per_ray: width * (u64::from(self.depth) + 8),
            trace_loop: TraceLoop::StepBudget,
            ray_structure: None,
            resume_words: crate::accel::resume_words(1, stack_size),
        })
    }
}
