//! What a kernel's descriptor set 0 holds: the kinds of binding, one binding's
//! description, and how many bytes the device lets one binding cover. Imports no
//! other file of gpu/: the pipeline cache, the kernels and the context all use it.

use ash::vk;

use crate::error::{Error, Result};

/// The kind of one descriptor binding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BindingKind {
    Uniform,
    Storage,
    /// A read-only uniform texel buffer viewed as `R32G32B32A32_UINT` (GLSL
    /// `usamplerBuffer`, read with `texelFetch`) over a storage buffer. On llvmpipe a
    /// texel fetch is one vector gather, where a storage-buffer load is a branchy loop
    /// over the lanes (docs/lavapipe.md); it does not count as a storage buffer.
    Texel,
    /// The driver's top-level acceleration structure (GLSL `accelerationStructureEXT`,
    /// traced with ray queries), bound with `Context::bind_ray_structure`.
    RayStructure,
}

impl BindingKind {
    pub(crate) fn descriptor_type(self) -> vk::DescriptorType {
        match self {
            BindingKind::Uniform => vk::DescriptorType::UNIFORM_BUFFER,
            BindingKind::Storage => vk::DescriptorType::STORAGE_BUFFER,
            BindingKind::Texel => vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
            BindingKind::RayStructure => vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
        }
    }
}

/// One binding of a kernel's descriptor set 0.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BindingDesc {
    pub binding: u32,
    pub kind: BindingKind,
    /// What the binding holds, for errors and debug output.
    pub name: &'static str,
}

/// The device limits on the bytes one binding covers, read once when the context opens.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BindingLimits {
    /// `maxStorageBufferRange`, or the lower override where given.
    pub max_storage_range: u64,
    /// `maxTexelBufferElements`: texels a texel-buffer view may span.
    pub max_texel_elements: u64,
    /// `maxMemoryAllocationSize`: the most bytes one allocation (one buffer) may take.
    pub max_allocation: u64,
    /// `ContextOptions::max_storage_range` where given: a per-buffer limit for every
    /// binding, to check that a scene fits a smaller device.
    pub lowered: Option<u64>,
}

impl BindingLimits {
    /// The most bytes a buffer bound as `kind` may hold, and which limit that is, for
    /// messages: a storage binding's range, a texel view's texels (16 bytes each),
    /// within one allocation.
    pub fn named(&self, kind: BindingKind) -> (u64, &'static str) {
        let (range, per) = match kind {
            BindingKind::Texel => {
                (self.max_texel_elements.saturating_mul(16), "per texel buffer (maxTexelBufferElements x 16 bytes)")
            }
            _ => (self.max_storage_range, "per storage buffer (maxStorageBufferRange)"),
        };
        let (range, per) = if self.max_allocation < range {
            (self.max_allocation, "per allocation (maxMemoryAllocationSize)")
        } else {
            (range, per)
        };
        match self.lowered {
            Some(l) if l < range => {
                (l, "per buffer (maxStorageBufferRange, lowered for every buffer by ARBOR_MAX_STORAGE_RANGE)")
            }
            _ => (range, per),
        }
    }

    /// Fails with [`Error::BufferTooLarge`] if `size` bytes named `name` exceed what a
    /// binding of `kind` may cover.
    pub fn check(&self, kind: BindingKind, name: &str, size: u64) -> Result<()> {
        let (limit, per) = self.named(kind);
        if size > limit {
            return Err(Error::BufferTooLarge { name: name.to_string(), size, limit, per });
        }
        Ok(())
    }
}
