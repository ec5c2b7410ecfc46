//! Named buffers with their allocation; uploads through a staging buffer, readback
//! through a host-visible copy.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::context::Context;
use super::device::{alloc_err, vk_err, Shared};
use crate::error::{Error, Result};

/// What a buffer is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BufferKind {
    /// Device-local storage buffer, filled by upload or by kernels; also usable for
    /// indirect dispatch arguments.
    Storage,
    /// Host-written uniform buffer.
    Uniform,
    /// Host-visible transfer source.
    Staging,
    /// Host-visible transfer destination.
    Readback,
    /// Device-local backing of a driver acceleration structure (ray queries).
    AccelStorage,
    /// Host-written input of an acceleration-structure build (vertices, indices,
    /// boxes, instances), read by the driver through its device address.
    AccelInput,
    /// Device-local scratch memory of an acceleration-structure build.
    AccelScratch,
}

/// A buffer and its memory; both freed on drop.
pub struct Buffer {
    shared: Arc<Shared>,
    pub(crate) raw: vk::Buffer,
    allocation: Option<Allocation>,
    size: u64,
    kind: BufferKind,
    name: String,
}

impl std::fmt::Debug for Buffer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Buffer").field("name", &self.name).field("size", &self.size).field("kind", &self.kind).finish()
    }
}

impl Buffer {
    /// The label given at creation (also the Vulkan debug name).
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Size in bytes (at least 16: Vulkan buffers cannot be empty).
    pub fn size(&self) -> u64 {
        self.size
    }
    /// The mapped bytes of a host-visible buffer (staging, readback, uniform).
    pub(crate) fn mapped(&self) -> Option<&[u8]> {
        self.allocation.as_ref().and_then(|a| a.mapped_slice())
    }

    /// What the buffer is for.
    pub fn kind(&self) -> BufferKind {
        self.kind
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        if let Some(a) = self.allocation.take() {
            if let Ok(mut guard) = self.shared.allocator.lock() {
                if let Some(alloc) = guard.as_mut() {
                    let _ = alloc.free(a);
                }
            }
        }
        // SAFETY: submissions always complete before returning, so the GPU no longer
        // uses this buffer; it was created from this device.
        unsafe { self.shared.device.destroy_buffer(self.raw, None) };
    }
}

impl Context {
    /// Creates an uninitialised buffer of `size` bytes (rounded up to at least 16).
    pub fn create_buffer(&self, name: &str, size: u64, kind: BufferKind) -> Result<Buffer> {
        let size = size.max(16).next_multiple_of(16);
        let (usage, location) = match kind {
            BufferKind::Storage => (
                vk::BufferUsageFlags::STORAGE_BUFFER
                    | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER
                    | vk::BufferUsageFlags::INDIRECT_BUFFER
                    | vk::BufferUsageFlags::TRANSFER_DST
                    | vk::BufferUsageFlags::TRANSFER_SRC,
                MemoryLocation::GpuOnly,
            ),
            BufferKind::Uniform => (vk::BufferUsageFlags::UNIFORM_BUFFER, MemoryLocation::CpuToGpu),
            BufferKind::Staging => (vk::BufferUsageFlags::TRANSFER_SRC, MemoryLocation::CpuToGpu),
            BufferKind::Readback => (vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuToCpu),
            BufferKind::AccelStorage => (
                vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                MemoryLocation::GpuOnly,
            ),
            BufferKind::AccelInput => (
                vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
                    | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                MemoryLocation::CpuToGpu,
            ),
            BufferKind::AccelScratch => (
                vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                MemoryLocation::GpuOnly,
            ),
        };
        let dev = &self.shared.device;
        let info = vk::BufferCreateInfo::default().size(size).usage(usage).sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid create info on a live device.
        let raw = unsafe { dev.create_buffer(&info, None) }.map_err(vk_err("vkCreateBuffer"))?;
        self.shared.set_name(raw, name);
        // SAFETY: `raw` is a live buffer of `dev`.
        let requirements = unsafe { dev.get_buffer_memory_requirements(raw) };
        let allocation = {
            let mut guard = self
                .shared
                .allocator
                .lock()
                .map_err(|_| Error::Vulkan { what: "allocator".into(), result: "poisoned lock".into() })?;
            let alloc =
                guard.as_mut().ok_or_else(|| Error::Vulkan { what: "allocator".into(), result: "gone".into() })?;
            alloc.allocate(&AllocationCreateDesc {
                name,
                requirements,
                location,
                linear: true,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
        };
        let allocation = match allocation {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: the buffer has no memory bound and is unused.
                unsafe { dev.destroy_buffer(raw, None) };
                return Err(alloc_err("allocate buffer memory")(e));
            }
        };
        let buffer = Buffer {
            shared: Arc::clone(&self.shared),
            raw,
            allocation: Some(allocation),
            size,
            kind,
            name: name.to_string(),
        };
        let a = buffer
            .allocation
            .as_ref()
            .ok_or_else(|| Error::Vulkan { what: "bind".into(), result: "no allocation".into() })?;
        // SAFETY: memory was allocated for these requirements and is not bound elsewhere.
        unsafe { dev.bind_buffer_memory(raw, a.memory(), a.offset()) }.map_err(vk_err("vkBindBufferMemory"))?;
        Ok(buffer)
    }

    /// The device address of a buffer made for acceleration structures (only those
    /// have SHADER_DEVICE_ADDRESS usage; the feature is on where ray queries are).
    pub(crate) fn device_address(&self, buffer: &Buffer) -> u64 {
        let info = vk::BufferDeviceAddressInfo::default().buffer(buffer.raw);
        // SAFETY: `buffer` is live and was created with SHADER_DEVICE_ADDRESS usage
        // (AccelStorage, AccelInput, AccelScratch) on a device with bufferDeviceAddress.
        unsafe { self.shared.device.get_buffer_device_address(&info) }
    }

    /// Writes `data` into a host-visible buffer (uniform or staging) at offset 0.
    pub fn write_host(&self, buffer: &mut Buffer, data: &[u8]) -> Result<()> {
        let name = buffer.name.clone();
        let a = buffer.allocation.as_mut().and_then(|a| a.mapped_slice_mut()).ok_or_else(|| Error::Vulkan {
            what: format!("write buffer '{name}'"),
            result: "not host visible".into(),
        })?;
        if data.len() > a.len() {
            return Err(Error::Vulkan {
                what: format!("write buffer '{name}'"),
                result: "data larger than buffer".into(),
            });
        }
        a[..data.len()].copy_from_slice(data);
        Ok(())
    }

    /// Creates a device-local storage buffer holding `data`.
    pub fn upload_storage(&self, name: &str, data: &[u8]) -> Result<Buffer> {
        let dst = self.create_buffer(name, data.len() as u64, BufferKind::Storage)?;
        if data.is_empty() {
            self.fill_zero(&dst)?;
            return Ok(dst);
        }
        let mut staging = self.create_buffer(&format!("{name}.staging"), data.len() as u64, BufferKind::Staging)?;
        self.write_host(&mut staging, data)?;
        let len = data.len() as u64;
        self.submit(&format!("upload {name}"), |dev, cb| {
            let region = [vk::BufferCopy { src_offset: 0, dst_offset: 0, size: len }];
            // SAFETY: both buffers are live, sized for `len`, and in recording scope.
            unsafe { dev.cmd_copy_buffer(cb, staging.raw, dst.raw, &region) };
        })?;
        Ok(dst)
    }

    /// Copies `data` into a storage buffer at byte `offset` (through a staging buffer).
    pub fn write_storage(&self, buffer: &Buffer, offset: u64, data: &[u8]) -> Result<()> {
        let len = data.len() as u64;
        if offset.checked_add(len).is_none_or(|end| end > buffer.size()) {
            return Err(Error::Vulkan {
                what: format!("write buffer '{}'", buffer.name),
                result: format!("{len} bytes at byte {offset} of {}", buffer.size()),
            });
        }
        if data.is_empty() {
            return Ok(());
        }
        let mut staging = self.create_buffer(&format!("{}.staging", buffer.name), len, BufferKind::Staging)?;
        self.write_host(&mut staging, data)?;
        self.submit(&format!("write {}", buffer.name), |dev, cb| {
            let region = [vk::BufferCopy { src_offset: 0, dst_offset: offset, size: len }];
            // SAFETY: both buffers are live and the range was checked above.
            unsafe { dev.cmd_copy_buffer(cb, staging.raw, buffer.raw, &region) };
        })?;
        Ok(())
    }

    /// Creates a uniform buffer holding `data`.
    pub fn upload_uniform(&self, name: &str, data: &[u8]) -> Result<Buffer> {
        let mut b = self.create_buffer(name, data.len() as u64, BufferKind::Uniform)?;
        self.write_host(&mut b, data)?;
        Ok(b)
    }

    /// Sets every byte of a storage buffer to zero.
    pub fn fill_zero(&self, buffer: &Buffer) -> Result<()> {
        self.submit(&format!("clear {}", buffer.name), |dev, cb| {
            // SAFETY: live buffer created with TRANSFER_DST; whole range.
            unsafe { dev.cmd_fill_buffer(cb, buffer.raw, 0, vk::WHOLE_SIZE, 0) };
        })?;
        Ok(())
    }

    /// Copies `len` bytes from `offset` of a storage buffer back to the host.
    pub fn read_storage(&self, buffer: &Buffer, offset: u64, len: u64) -> Result<Vec<u8>> {
        self.read_storage_with(buffer, offset, len, <[u8]>::to_vec)
    }

    /// Copies `count` values of `T` from byte `offset` of a storage buffer back to the
    /// host, straight into the returned vector (one copy out of the mapped memory).
    pub fn read_storage_pod<T: bytemuck::Pod>(&self, buffer: &Buffer, offset: u64, count: usize) -> Result<Vec<T>> {
        let len = (count * std::mem::size_of::<T>()) as u64;
        self.read_storage_with(buffer, offset, len, |bytes| {
            let mut out = vec![T::zeroed(); count];
            bytemuck::cast_slice_mut::<T, u8>(&mut out).copy_from_slice(bytes);
            out
        })
    }

    /// Copies `len` bytes from `offset` of a storage buffer into a readback buffer and
    /// hands its mapped bytes to `take`.
    fn read_storage_with<R>(&self, buffer: &Buffer, offset: u64, len: u64, take: impl FnOnce(&[u8]) -> R) -> Result<R> {
        if offset + len > buffer.size {
            return Err(Error::Vulkan {
                what: format!("read buffer '{}'", buffer.name),
                result: "range out of bounds".into(),
            });
        }
        if len == 0 {
            return Ok(take(&[]));
        }
        let rb = self.create_buffer(&format!("{}.readback", buffer.name), len, BufferKind::Readback)?;
        self.submit(&format!("readback {}", buffer.name), |dev, cb| {
            record_copy_to_host(dev, cb, (buffer, offset), (&rb, 0), len);
        })?;
        let a = rb
            .allocation
            .as_ref()
            .and_then(|a| a.mapped_slice())
            .ok_or_else(|| Error::Vulkan { what: "readback".into(), result: "not host visible".into() })?;
        Ok(take(&a[..len as usize]))
    }
}

/// Records a copy of `len` bytes from `src` at its offset into the host-visible `dst`
/// at its offset, after every earlier shader or transfer write and before the host
/// reads it (the submission's fence then makes it visible).
pub(super) fn record_copy_to_host(
    dev: &ash::Device,
    cb: vk::CommandBuffer,
    (src, src_offset): (&Buffer, u64),
    (dst, dst_offset): (&Buffer, u64),
    len: u64,
) {
    let before = [vk::MemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE)
        .dst_access_mask(vk::AccessFlags::TRANSFER_READ)];
    let after = [vk::MemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
        .dst_access_mask(vk::AccessFlags::HOST_READ)];
    let region = [vk::BufferCopy { src_offset, dst_offset, size: len }];
    // SAFETY: recording scope of a live command buffer of `dev`; both buffers are live
    // and the caller checked the ranges.
    unsafe {
        dev.cmd_pipeline_barrier(
            cb,
            vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
            vk::PipelineStageFlags::TRANSFER,
            vk::DependencyFlags::empty(),
            &before,
            &[],
            &[],
        );
        dev.cmd_copy_buffer(cb, src.raw, dst.raw, &region);
        dev.cmd_pipeline_barrier(
            cb,
            vk::PipelineStageFlags::TRANSFER,
            vk::PipelineStageFlags::HOST,
            vk::DependencyFlags::empty(),
            &after,
            &[],
            &[],
        );
    }
}
