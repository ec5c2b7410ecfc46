//! The driver's own acceleration structure (VK_KHR_acceleration_structure), traced by
//! the trace kernel with VK_KHR_ray_query (`--accel rayquery`, src/accel/rayquery.rs).
//!
//! One bottom-level structure (BLAS) per geometry group the caller describes (each a
//! range of the scene's stored triangles and/or a list of boxes for analytic
//! spheres), one top-level structure (TLAS) over instances of them. Everything is
//! built on the device: BLASes in one submission, optionally compacted (a size query,
//! then a compacting copy), then the TLAS. The caller sees no `vk::` type: it passes
//! plain arrays and gets a [`RayStructure`] to bind and a [`RayBuildReport`].

use std::sync::Arc;

use ash::vk;

use super::buffer::{Buffer, BufferKind};
use super::context::{Context, Work};
use super::descriptor::BindingKind;
use super::device::{vk_err, Shared};
use super::kernel::Kernel;
use crate::error::{Error, Result};

/// Which of the driver's build trade-offs to ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RayBuildOptions {
    /// `PREFER_FAST_BUILD` instead of `PREFER_FAST_TRACE`.
    pub fast_build: bool,
    /// Compact every BLAS after its build (`ALLOW_COMPACTION`, then a compacting copy).
    pub compact: bool,
}

/// One bottom-level structure: stored triangles `[first, first + count)` (indices
/// into [`RayInputs::indices`], three per triangle) or boxes `aabbs` (analytic
/// primitives the kernel intersects itself: spheres); Vulkan allows one geometry
/// type per BLAS.
#[derive(Debug, Clone, Default)]
pub struct BlasDesc {
    pub first_triangle: u32,
    pub triangles: u32,
    /// Boxes as (min xyz, max xyz).
    pub aabbs: Vec<[f32; 6]>,
}

/// One instance of a BLAS in the TLAS.
#[derive(Debug, Clone, Copy)]
pub struct TlasInstance {
    /// Object-to-world, three rows of (3x3 | translation).
    pub transform: [[f32; 4]; 3],
    /// Index into the BLAS list.
    pub blas: usize,
    /// What the kernel reads back as the instance's custom index (24 bits).
    pub custom: u32,
}

/// What the builds read: vertex positions (16-byte stride: xyz then one unused
/// float, i.e. the first half of each 32-byte `GpuVertex` is not required; the caller
/// passes positions alone), triangle vertex indices (three per triangle), the BLASes
/// and the instances.
#[derive(Debug, Clone, Copy)]
pub struct RayInputs<'a> {
    pub positions: &'a [[f32; 4]],
    pub indices: &'a [u32],
    pub blases: &'a [BlasDesc],
    pub instances: &'a [TlasInstance],
}

/// What a build took and produced.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct RayBuildReport {
    /// Device time of the BLAS builds (GPU timestamps; host wall clock without them).
    pub blas_ms: f64,
    /// Device time of the compaction (size query and copies); 0 without compaction.
    pub compact_ms: f64,
    /// Device time of the TLAS build.
    pub tlas_ms: f64,
    /// Host time of the whole build: input upload, size queries, submissions.
    pub wall_ms: f64,
    /// Bytes of every BLAS as built, before any compaction.
    pub blas_bytes_built: u64,
    /// Bytes of every BLAS as kept (after compaction, if asked for).
    pub blas_bytes: u64,
    /// Bytes of the TLAS.
    pub tlas_bytes: u64,
    /// BLASes and instances built.
    pub blases: usize,
    pub instances: usize,
}

/// An acceleration structure object and its backing buffer.
struct Handle {
    shared: Arc<Shared>,
    raw: vk::AccelerationStructureKHR,
    _buffer: Buffer,
    size: u64,
}

impl Drop for Handle {
    fn drop(&mut self) {
        if let Some(ext) = &self.shared.accel_ext {
            // SAFETY: submissions always complete before returning, so no command uses
            // the structure; it was created from this device.
            unsafe { ext.destroy_acceleration_structure(self.raw, None) };
        }
    }
}

/// The driver's structure: a TLAS and the BLASes it references, freed on drop.
pub struct RayStructure {
    tlas: Handle,
    _blases: Vec<Handle>,
}

impl std::fmt::Debug for RayStructure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RayStructure").field("tlas_bytes", &self.tlas.size).finish_non_exhaustive()
    }
}

/// `VkAccelerationStructureInstanceKHR` as bytes: 3x4 transform, custom index | mask,
/// SBT offset | flags, BLAS address (64 bytes).
fn instance_bytes(transform: &[[f32; 4]; 3], custom: u32, address: u64) -> [u8; 64] {
    let mut out = [0u8; 64];
    for (r, row) in transform.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            out[(r * 4 + c) * 4..(r * 4 + c) * 4 + 4].copy_from_slice(&v.to_ne_bytes());
        }
    }
    let mask = (custom & 0x00ff_ffff) | (0xff << 24);
    out[48..52].copy_from_slice(&mask.to_ne_bytes());
    let flags = vk::GeometryInstanceFlagsKHR::TRIANGLE_FACING_CULL_DISABLE.as_raw() << 24;
    out[52..56].copy_from_slice(&flags.to_ne_bytes());
    out[56..64].copy_from_slice(&address.to_ne_bytes());
    out
}

impl Context {
    /// Whether this device traces with the driver's structure (`--accel rayquery`).
    pub fn has_ray_query(&self) -> bool {
        self.shared.accel_ext.is_some()
    }

    /// The error `--accel rayquery` gives on a device without ray queries.
    pub fn ray_query_error(&self) -> Error {
        Error::Failed(format!(
            "--accel rayquery needs VK_KHR_acceleration_structure and VK_KHR_ray_query; {} lacks {} (`arbor devices` lists support; Mesa 24.1+ lavapipe has them: scripts/setup.sh --mesa-backports)",
            self.info().name,
            self.info().ray_query_missing.as_deref().unwrap_or("them")
        ))
    }

    fn host_buffer(&self, name: &str, bytes: &[u8]) -> Result<Buffer> {
        let mut b = self.create_buffer(name, bytes.len() as u64, BufferKind::AccelInput)?;
        self.write_host(&mut b, bytes)?;
        Ok(b)
    }

    fn structure(
        &self,
        ext: &ash::khr::acceleration_structure::Device,
        name: &str,
        size: u64,
        top: bool,
    ) -> Result<Handle> {
        let buffer = self.create_buffer(name, size, BufferKind::AccelStorage)?;
        let ty = if top {
            vk::AccelerationStructureTypeKHR::TOP_LEVEL
        } else {
            vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL
        };
        let info = vk::AccelerationStructureCreateInfoKHR::default().buffer(buffer.raw).offset(0).size(size).ty(ty);
        // SAFETY: a live buffer with ACCELERATION_STRUCTURE_STORAGE usage of at least `size` bytes.
        let raw = unsafe { ext.create_acceleration_structure(&info, None) }
            .map_err(vk_err("vkCreateAccelerationStructureKHR"))?;
        self.shared.set_name(raw, name);
        Ok(Handle { shared: Arc::clone(&self.shared), raw, _buffer: buffer, size })
    }

    /// A scratch buffer of `size` bytes whose device address is aligned as the driver requires.
    fn scratch(&self, name: &str, size: u64) -> Result<(Buffer, u64)> {
        let align = self.scratch_align;
        let buf = self.create_buffer(name, size + align, BufferKind::AccelScratch)?;
        let addr = self.device_address(&buf).next_multiple_of(align);
        Ok((buf, addr))
    }

    fn structure_address(ext: &ash::khr::acceleration_structure::Device, h: &Handle) -> u64 {
        let info = vk::AccelerationStructureDeviceAddressInfoKHR::default().acceleration_structure(h.raw);
        // SAFETY: a live structure of this device.
        unsafe { ext.get_acceleration_structure_device_address(&info) }
    }

    /// Builds the BLASes and the TLAS of `inputs` on the device.
    pub fn build_ray_structure(
        &self,
        label: &str,
        inputs: &RayInputs<'_>,
        opts: RayBuildOptions,
    ) -> Result<(RayStructure, RayBuildReport)> {
        let start = std::time::Instant::now();
        let ext = self.shared.accel_ext.as_ref().ok_or_else(|| self.ray_query_error())?;
        if inputs.blases.len() > 1 << 24 {
            return Err(Error::Failed(format!(
                "{label}: {} bottom-level structures, more than 2^24",
                inputs.blases.len()
            )));
        }
        let mut report =
            RayBuildReport { blases: inputs.blases.len(), instances: inputs.instances.len(), ..Default::default() };
        let prefer = if opts.fast_build {
            vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_BUILD
        } else {
            vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE
        };
        let blas_flags =
            if opts.compact { prefer | vk::BuildAccelerationStructureFlagsKHR::ALLOW_COMPACTION } else { prefer };

        // Inputs: positions, indices, every BLAS's boxes in one buffer.
        let positions = self.host_buffer(&format!("{label}.positions"), bytemuck::cast_slice(inputs.positions))?;
        let indices = self.host_buffer(&format!("{label}.indices"), bytemuck::cast_slice(inputs.indices))?;
        let all_boxes: Vec<[f32; 6]> = inputs.blases.iter().flat_map(|b| b.aabbs.iter().copied()).collect();
        let boxes = self.host_buffer(&format!("{label}.boxes"), bytemuck::cast_slice(&all_boxes))?;
        let (pos_addr, idx_addr, box_addr) =
            (self.device_address(&positions), self.device_address(&indices), self.device_address(&boxes));
        let max_vertex = (inputs.positions.len() as u32).saturating_sub(1);

        // Per BLAS: its geometries (triangles, then boxes) and ranges.
        let mut geometries: Vec<Vec<vk::AccelerationStructureGeometryKHR>> = Vec::new();
        let mut ranges: Vec<Vec<vk::AccelerationStructureBuildRangeInfoKHR>> = Vec::new();
        let mut box_offset = 0u64;
        for (k, b) in inputs.blases.iter().enumerate() {
            if b.triangles > 0 && !b.aabbs.is_empty() {
                return Err(Error::Failed(format!("{label}: bottom-level structure {k} mixes triangles and boxes")));
            }
            let mut g = Vec::new();
            let mut r = Vec::new();
            if b.triangles > 0 {
                let tris = vk::AccelerationStructureGeometryTrianglesDataKHR::default()
                    .vertex_format(vk::Format::R32G32B32_SFLOAT)
                    .vertex_data(vk::DeviceOrHostAddressConstKHR { device_address: pos_addr })
                    .vertex_stride(16)
                    .max_vertex(max_vertex)
                    .index_type(vk::IndexType::UINT32)
                    .index_data(vk::DeviceOrHostAddressConstKHR { device_address: idx_addr });
                g.push(
                    vk::AccelerationStructureGeometryKHR::default()
                        .geometry_type(vk::GeometryTypeKHR::TRIANGLES)
                        .geometry(vk::AccelerationStructureGeometryDataKHR { triangles: tris })
                        .flags(vk::GeometryFlagsKHR::OPAQUE),
                );
                r.push(vk::AccelerationStructureBuildRangeInfoKHR {
                    primitive_count: b.triangles,
                    primitive_offset: b.first_triangle * 12,
                    first_vertex: 0,
                    transform_offset: 0,
                });
            }
            if !b.aabbs.is_empty() {
                let aabbs = vk::AccelerationStructureGeometryAabbsDataKHR::default()
                    .data(vk::DeviceOrHostAddressConstKHR { device_address: box_addr })
                    .stride(24);
                g.push(
                    vk::AccelerationStructureGeometryKHR::default()
                        .geometry_type(vk::GeometryTypeKHR::AABBS)
                        .geometry(vk::AccelerationStructureGeometryDataKHR { aabbs })
                        .flags(vk::GeometryFlagsKHR::OPAQUE),
                );
                r.push(vk::AccelerationStructureBuildRangeInfoKHR {
                    primitive_count: b.aabbs.len() as u32,
                    primitive_offset: (box_offset * 24) as u32,
                    first_vertex: 0,
                    transform_offset: 0,
                });
            }
            box_offset += b.aabbs.len() as u64;
            geometries.push(g);
            ranges.push(r);
        }

        // Sizes, structures and one scratch buffer with a slice per BLAS.
        let mut blases = Vec::with_capacity(inputs.blases.len());
        let mut scratch_offsets = Vec::with_capacity(inputs.blases.len());
        let mut scratch_total = 0u64;
        for (k, g) in geometries.iter().enumerate() {
            if g.is_empty() {
                return Err(Error::Failed(format!("{label}: bottom-level structure {k} has no primitives")));
            }
            let info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
                .ty(vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL)
                .flags(blas_flags)
                .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
                .geometries(g);
            let counts: Vec<u32> = ranges[k].iter().map(|r| r.primitive_count).collect();
            let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
            // SAFETY: a valid build description; counts match its geometries.
            unsafe {
                ext.get_acceleration_structure_build_sizes(
                    vk::AccelerationStructureBuildTypeKHR::DEVICE,
                    &info,
                    &counts,
                    &mut sizes,
                )
            };
            blases.push(self.structure(ext, &format!("{label}.blas{k}"), sizes.acceleration_structure_size, false)?);
            scratch_offsets.push(scratch_total);
            scratch_total += sizes.build_scratch_size.next_multiple_of(self.scratch_align);
        }
        report.blas_bytes_built = blases.iter().map(|h| h.size).sum();
        let (_scratch, scratch_addr) = self.scratch(&format!("{label}.blas_scratch"), scratch_total.max(16))?;
        let infos: Vec<vk::AccelerationStructureBuildGeometryInfoKHR> = geometries
            .iter()
            .zip(&blases)
            .zip(&scratch_offsets)
            .map(|((g, h), off)| {
                vk::AccelerationStructureBuildGeometryInfoKHR::default()
                    .ty(vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL)
                    .flags(blas_flags)
                    .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
                    .dst_acceleration_structure(h.raw)
                    .geometries(g)
                    .scratch_data(vk::DeviceOrHostAddressKHR { device_address: scratch_addr + off })
            })
            .collect();
        let range_refs: Vec<&[vk::AccelerationStructureBuildRangeInfoKHR]> = ranges.iter().map(Vec::as_slice).collect();
        let timed = |t: Option<f64>, since: std::time::Instant| t.unwrap_or(since.elapsed().as_secs_f64() * 1e3);
        let t = std::time::Instant::now();
        let ms = self.submit_as(Work::new("build"), &format!("{label}: build {} BLAS", blases.len()), |_, cb| {
            if !infos.is_empty() {
                // SAFETY: every structure, scratch slice and input buffer is live and
                // sized by the driver's own size query; each BLAS has its own scratch slice.
                unsafe { ext.cmd_build_acceleration_structures(cb, &infos, &range_refs) };
            }
            structure_barrier(&self.shared.device, cb);
        })?;
        report.blas_ms = timed(ms, t);

        if opts.compact && !blases.is_empty() {
            let t = std::time::Instant::now();
            blases = self.compact(ext, label, blases, &mut report)?;
            if !self.timestamps {
                report.compact_ms = t.elapsed().as_secs_f64() * 1e3;
            }
        }
        report.blas_bytes = blases.iter().map(|h| h.size).sum();

        // The TLAS over the instances.
        let mut inst_bytes = Vec::with_capacity(inputs.instances.len() * 64);
        for i in inputs.instances {
            let h = blases.get(i.blas).ok_or_else(|| {
                Error::Failed(format!(
                    "{label}: an instance names bottom-level structure {}, of {}",
                    i.blas,
                    blases.len()
                ))
            })?;
            inst_bytes.extend_from_slice(&instance_bytes(&i.transform, i.custom, Self::structure_address(ext, h)));
        }
        let inst_buf = self.host_buffer(&format!("{label}.instances"), &inst_bytes)?;
        let inst_data = vk::AccelerationStructureGeometryInstancesDataKHR::default()
            .array_of_pointers(false)
            .data(vk::DeviceOrHostAddressConstKHR { device_address: self.device_address(&inst_buf) });
        let tlas_geom = [vk::AccelerationStructureGeometryKHR::default()
            .geometry_type(vk::GeometryTypeKHR::INSTANCES)
            .geometry(vk::AccelerationStructureGeometryDataKHR { instances: inst_data })];
        let count = inputs.instances.len() as u32;
        let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
        let size_info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
            .ty(vk::AccelerationStructureTypeKHR::TOP_LEVEL)
            .flags(prefer)
            .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
            .geometries(&tlas_geom);
        // SAFETY: a valid build description with one geometry.
        unsafe {
            ext.get_acceleration_structure_build_sizes(
                vk::AccelerationStructureBuildTypeKHR::DEVICE,
                &size_info,
                &[count],
                &mut sizes,
            )
        };
        let tlas = self.structure(ext, &format!("{label}.tlas"), sizes.acceleration_structure_size, true)?;
        let (_tscratch, taddr) = self.scratch(&format!("{label}.tlas_scratch"), sizes.build_scratch_size.max(16))?;
        let tinfo = [vk::AccelerationStructureBuildGeometryInfoKHR::default()
            .ty(vk::AccelerationStructureTypeKHR::TOP_LEVEL)
            .flags(prefer)
            .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
            .dst_acceleration_structure(tlas.raw)
            .geometries(&tlas_geom)
            .scratch_data(vk::DeviceOrHostAddressKHR { device_address: taddr })];
        let trange = [vk::AccelerationStructureBuildRangeInfoKHR {
            primitive_count: count,
            primitive_offset: 0,
            first_vertex: 0,
            transform_offset: 0,
        }];
        let t = std::time::Instant::now();
        let ms = self.submit_as(Work::new("build"), &format!("{label}: build TLAS"), |dev, cb| {
            structure_barrier(dev, cb);
            // SAFETY: live TLAS, scratch and instance buffer; every referenced BLAS was
            // built (and compacted) by an earlier, completed submission.
            unsafe { ext.cmd_build_acceleration_structures(cb, &tinfo, &[&trange]) };
            structure_barrier(dev, cb);
        })?;
        report.tlas_ms = timed(ms, t);
        report.tlas_bytes = tlas.size;
        report.wall_ms = start.elapsed().as_secs_f64() * 1e3;
        drop((positions, indices, boxes, inst_buf));
        Ok((RayStructure { tlas, _blases: blases }, report))
    }

    /// Queries each BLAS's compacted size, copies it into a structure of that size and
    /// drops the original.
    fn compact(
        &self,
        ext: &ash::khr::acceleration_structure::Device,
        label: &str,
        blases: Vec<Handle>,
        report: &mut RayBuildReport,
    ) -> Result<Vec<Handle>> {
        let dev = &self.shared.device;
        let n = blases.len() as u32;
        // SAFETY: valid create info on a live device.
        let pool = unsafe {
            dev.create_query_pool(
                &vk::QueryPoolCreateInfo::default()
                    .query_type(vk::QueryType::ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR)
                    .query_count(n),
                None,
            )
        }
        .map_err(vk_err("vkCreateQueryPool"))?;
        let raws: Vec<vk::AccelerationStructureKHR> = blases.iter().map(|h| h.raw).collect();
        let result = (|| -> Result<Vec<Handle>> {
            let ms = self.submit_as(Work::new("build"), &format!("{label}: compacted sizes"), |dev, cb| {
                // SAFETY: the pool has `n` queries; every structure was built with
                // ALLOW_COMPACTION by a completed submission.
                unsafe {
                    dev.cmd_reset_query_pool(cb, pool, 0, n);
                    structure_barrier(dev, cb);
                    ext.cmd_write_acceleration_structures_properties(
                        cb,
                        &raws,
                        vk::QueryType::ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR,
                        pool,
                        0,
                    );
                }
            })?;
            report.compact_ms += ms.unwrap_or(0.0);
            let mut sizes = vec![0u64; n as usize];
            // SAFETY: all `n` queries were written by the completed submission.
            unsafe {
                dev.get_query_pool_results(
                    pool,
                    0,
                    &mut sizes,
                    vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
                )
            }
            .map_err(vk_err("vkGetQueryPoolResults"))?;
            let mut out = Vec::with_capacity(blases.len());
            for (k, &size) in sizes.iter().enumerate() {
                out.push(self.structure(ext, &format!("{label}.blas{k}.compact"), size.max(16), false)?);
            }
            let ms = self.submit_as(Work::new("build"), &format!("{label}: compact {n} BLAS"), |dev, cb| {
                for (src, dst) in blases.iter().zip(&out) {
                    let info = vk::CopyAccelerationStructureInfoKHR::default()
                        .src(src.raw)
                        .dst(dst.raw)
                        .mode(vk::CopyAccelerationStructureModeKHR::COMPACT);
                    // SAFETY: both structures are live; `dst` has the compacted size the
                    // driver reported for `src`.
                    unsafe { ext.cmd_copy_acceleration_structure(cb, &info) };
                }
                structure_barrier(dev, cb);
            })?;
            report.compact_ms += ms.unwrap_or(0.0);
            Ok(out)
        })();
        // SAFETY: every submission using the pool completed.
        unsafe { dev.destroy_query_pool(pool, None) };
        result
    }

    /// Points `binding` of `kernel` at the TLAS of `structure`.
    pub fn bind_ray_structure(&self, kernel: &mut Kernel, binding: u32, structure: &RayStructure) -> Result<()> {
        let set = kernel.descriptor_set_for(binding, BindingKind::RayStructure)?;
        let handles = [structure.tlas.raw];
        let mut as_info = vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(&handles);
        let mut write = vk::WriteDescriptorSet::default()
            .dst_set(set)
            .dst_binding(binding)
            .descriptor_type(vk::DescriptorType::ACCELERATION_STRUCTURE_KHR)
            .push_next(&mut as_info);
        write.descriptor_count = 1;
        // SAFETY: the set is not in use by a pending submission (all submissions wait);
        // the structure outlives the kernel's use of it (the caller keeps both).
        unsafe { self.shared.device.update_descriptor_sets(&[write], &[]) };
        kernel.mark_bound(binding, structure.tlas.size);
        Ok(())
    }
}

/// Orders acceleration-structure writes (builds, copies) before later reads: further
/// builds, copies, property queries and ray queries in compute shaders.
fn structure_barrier(dev: &ash::Device, cb: vk::CommandBuffer) {
    let barrier = [vk::MemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR)
        .dst_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR | vk::AccessFlags::SHADER_READ)];
    // SAFETY: recording scope of a live command buffer of `dev`.
    unsafe {
        dev.cmd_pipeline_barrier(
            cb,
            vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
            vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR | vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::DependencyFlags::empty(),
            &barrier,
            &[],
            &[],
        );
    }
}
