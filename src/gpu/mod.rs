//! The only module with `unsafe`: a small, safe façade over raw Vulkan (`ash`) and
//! `gpu-allocator`. No `vk::` type leaves this module.
//!
//! - [`Context`]: instance (no surface), device choice, queue, allocator, optional
//!   Khronos validation with errors collected and turned into [`crate::Error::Validation`].
//! - [`Buffer`]: a named buffer with its allocation, freed on drop.
//! - [`Kernel`]: a compute pipeline with an explicit descriptor-set layout, at most
//!   [`bindings::MAX_STORAGE_BUFFERS_PER_STAGE`] storage buffers, every bound range
//!   checked against `maxStorageBufferRange`. The context keeps the pipelines it
//!   compiled: a kernel created again with the same SPIR-V, bindings and
//!   specialization constants gets its own descriptor set over the same pipeline.
//! - Every dispatch is bracketed by timestamp queries and reports its GPU time; while
//!   a timeline records, each submission is a GPU span on the CPU clock (timing.rs).

#[allow(missing_docs)] // constants documented where their values matter (comments); shared with the shaders
pub mod bindings;
mod buffer;
mod cache;
mod context;
#[allow(missing_docs)] // internal to the renderer; not the stable API
mod descriptor;
mod device;
mod flight;
#[allow(missing_docs)] // internal to the renderer; not the stable API
mod kernel;
#[allow(missing_docs)] // internal to the renderer; not the stable API
mod raytrace;
mod timing;

pub use buffer::{Buffer, BufferKind};
pub use cache::KernelCacheStats;
pub use context::{Context, ContextOptions, DeviceInfo};
pub use descriptor::{BindingDesc, BindingKind};
pub use flight::{DispatchRing, HeaderDispatch, Landed, COPY_BACK_BYTES, MAX_DEPTH as MAX_IN_FLIGHT};
pub use kernel::{Kernel, Step};
pub use raytrace::{BlasDesc, RayBuildOptions, RayBuildReport, RayInputs, RayStructure, TlasInstance};

/// Embedded SPIR-V of every kernel, by name (`trace_none_all`, `layout_probe`, ...).
pub mod spirv {
    include!(concat!(env!("OUT_DIR"), "/shaders.rs"));

    /// The SPIR-V bytes of kernel `name`, if it was compiled.
    pub fn get(name: &str) -> Option<&'static [u8]> {
        SHADERS.iter().find(|(n, _)| *n == name).map(|(_, b)| *b)
    }
}
