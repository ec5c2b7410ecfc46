//! A structure as the trace kernel reads it ([`GpuImage`]): its buffers, stack, loop
//! bounds and resume state.

use super::family::KernelFamily;

/// How a structure's kernel bounds its loops (llvmpipe, which has no watchdog, needs
/// every loop bounded; see docs/kernels.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TraceLoop {
    /// Loops over primitive lists of these lengths, unrolled as the kernel was compiled
    /// (`BRUTE_UNROLL`, one kernel per factor).
    Unrolled {
        /// The lengths of the (at most two) primitive lists.
        lengths: [u64; 2],
    },
    /// A traversal loop the kernel stops after `TREE_STEPS` steps (the dispatch
    /// header's `limits`): the trace is resumed in a following dispatch where the
    /// family can ([`GpuImage::resume_words`]), else the pixel is flagged.
    StepBudget,
}

impl TraceLoop {
    /// Loop iterations of one trace: with `unroll` for unrolled loops, or `budget`.
    pub fn iterations(self, unroll: u32, budget: u64) -> u64 {
        match self {
            TraceLoop::Unrolled { lengths } => {
                lengths.iter().map(|&n| n.div_ceil(u64::from(unroll.max(1)))).sum::<u64>() + 2
            }
            TraceLoop::StepBudget => budget,
        }
    }
}

/// A structure as the trace kernel reads it.
#[derive(Debug, Clone)]
pub struct GpuImage<'a> {
    /// Kernel family: `shaders/accel/<family>.glsl`, kernels `trace_<family>_<geometry>`.
    pub family: KernelFamily,
    /// Node words and index words; `None` binds neither buffer.
    pub buffers: Option<AccelBuffers<'a>>,
    /// Entries of the kernel's traversal stack (`SPEC_STACK_SIZE`).
    pub stack_size: u32,
    /// Estimated work (primitive tests or traversal steps) of one ray, to size dispatches.
    pub cost_per_ray: u64,
    /// How the kernel bounds its loops.
    pub trace_loop: TraceLoop,
    /// The driver's structure the kernel traces with ray queries (`rayquery`), bound
    /// at `BINDING_TLAS`; `None` for every structure of arbor's own.
    pub ray_structure: Option<&'a crate::gpu::RayStructure>,
    /// Words of traversal state the family's kernel saves when a trace runs out of
    /// steps, to resume it in a following dispatch ([`resume_words`]; docs/kernels.md,
    /// "Resumed traces"). 0: the family cannot suspend a trace (brute force, which needs
    /// no step budget; a traversal inside the driver), and a trace that runs out flags
    /// its pixel and fails the render.
    pub resume_words: u32,
}

/// Where a structure's node and index words are: on the host, uploaded for each
/// render, or already on the device that built them (`--build gpu`), bound as they are.
#[derive(Debug, Clone)]
pub enum AccelBuffers<'a> {
    /// Node bytes and index words on the host.
    Host(std::borrow::Cow<'a, [u8]>, &'a [u32]),
    /// Node and index buffers on the device, with the geometry the build uploaded
    /// (by binding, in the render's layout), which the trace binds instead of its own.
    Device {
        /// The node buffer.
        nodes: std::sync::Arc<crate::gpu::Buffer>,
        /// The primitive index buffer.
        indices: std::sync::Arc<crate::gpu::Buffer>,
        /// `(binding, buffer)` for vertices, triangles and spheres.
        geometry: &'a [(u32, std::sync::Arc<crate::gpu::Buffer>)],
    },
}

/// [`GpuImage::resume_words`] of a kernel that traverses `levels` levels (2 with
/// instances) with a stack of `stack_size` entries: per level the fixed words and two
/// stack arrays (shaders/common/resume.glsl).
pub fn resume_words(levels: u32, stack_size: u32) -> u32 {
    levels * (crate::gpu::bindings::RESUME_LEVEL_WORDS + 2 * stack_size)
}
