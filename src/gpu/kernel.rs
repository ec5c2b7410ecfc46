//! Compute pipelines with explicit descriptor-set layouts and specialization constants.

use std::sync::Arc;

use ash::vk;

use super::bindings::MAX_STORAGE_BUFFERS_PER_STAGE;
use super::buffer::{Buffer, BufferKind};
use super::cache::{KernelCacheStats, Pipeline};
use super::context::{Context, Work};
use super::descriptor::{BindingDesc, BindingKind};
use super::device::{vk_err, Shared};
use super::timing;
use crate::error::{Error, Result};

/// A compute pipeline (shared: kernels made alike share one, see cache.rs) with its own descriptor set; the set
/// and its pool are destroyed on drop.
pub struct Kernel {
    shared: Arc<Shared>,
    name: String,
    bindings: Vec<BindingDesc>,
    pipe: Arc<Pipeline>,
    pool: vk::DescriptorPool,
    set: vk::DescriptorSet,
    push_size: u32,
    bound: Vec<Option<u64>>,
    /// Buffer views of the texel bindings, by binding index (null where none).
    views: Vec<vk::BufferView>,
}

impl Kernel {
    /// The bindings of its descriptor set, in order.
    pub fn bindings(&self) -> &[BindingDesc] {
        &self.bindings
    }
    /// The label given at creation.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The descriptor set, after checking that `binding` exists and is of `kind`.
    pub(crate) fn descriptor_set_for(&self, binding: u32, kind: BindingKind) -> Result<vk::DescriptorSet> {
        match self.bindings.iter().find(|b| b.binding == binding) {
            Some(b) if b.kind == kind => Ok(self.set),
            Some(b) => Err(Error::Vulkan {
                what: format!("bind {} of kernel '{}'", b.name, self.name),
                result: format!("binding {binding} is {:?}, not {kind:?}", b.kind),
            }),
            None => Err(Error::Vulkan {
                what: format!("bind to kernel '{}'", self.name),
                result: format!("the kernel has no binding {binding}"),
            }),
        }
    }

    /// Records that `binding` now has something of `size` bytes bound.
    pub(crate) fn mark_bound(&mut self, binding: u32, size: u64) {
        if let Some(i) = self.bindings.iter().position(|b| b.binding == binding) {
            self.bound[i] = Some(size);
        }
    }

    /// Checks the project rule: at most [`MAX_STORAGE_BUFFERS_PER_STAGE`] storage buffers.
    pub fn check_storage_limit(name: &str, bindings: &[BindingDesc]) -> Result<()> {
        let count = bindings.iter().filter(|b| b.kind == BindingKind::Storage).count();
        if count > MAX_STORAGE_BUFFERS_PER_STAGE as usize {
            return Err(Error::TooManyStorageBuffers {
                name: name.to_string(),
                count,
                limit: MAX_STORAGE_BUFFERS_PER_STAGE as usize,
            });
        }
        Ok(())
    }
}

impl std::fmt::Debug for Kernel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Kernel").field("name", &self.name).field("bindings", &self.bindings).finish()
    }
}

impl Drop for Kernel {
    fn drop(&mut self) {
        // SAFETY: submissions complete before returning, so nothing uses these objects;
        // the pipeline goes with the last Arc (Pipeline's drop).
        unsafe {
            let d = &self.shared.device;
            for v in &self.views {
                if *v != vk::BufferView::null() {
                    d.destroy_buffer_view(*v, None);
                }
            }
            d.destroy_descriptor_pool(self.pool, None);
        }
    }
}

impl Context {
    /// Builds kernel `name` from SPIR-V with the given bindings, `(constant_id, u32 value)`
    /// specialization constants and push-constant size in bytes.
    pub fn create_kernel(
        &self,
        name: &str,
        spirv: &[u8],
        bindings: &[BindingDesc],
        spec: &[(u32, u32)],
        push_size: u32,
    ) -> Result<Kernel> {
        Kernel::check_storage_limit(name, bindings)?;
        let pipe = self.kernel_cache.pipeline(&self.shared, name, spirv, bindings, spec, push_size)?;
        let dev = &self.shared.device;
        // Wrapped at once, so that an error below destroys what exists.
        let mut k = Kernel {
            shared: Arc::clone(&self.shared),
            name: name.to_string(),
            bindings: bindings.to_vec(),
            pipe,
            pool: vk::DescriptorPool::null(),
            set: vk::DescriptorSet::null(),
            push_size,
            bound: vec![None; bindings.len()],
            views: vec![vk::BufferView::null(); bindings.len()],
        };
        let mut sizes = Vec::new();
        for kind in [BindingKind::Storage, BindingKind::Uniform, BindingKind::Texel, BindingKind::RayStructure] {
            let count = bindings.iter().filter(|b| b.kind == kind).count() as u32;
            if count > 0 {
                sizes.push(vk::DescriptorPoolSize { ty: kind.descriptor_type(), descriptor_count: count });
            }
        }
        // SAFETY: valid create info on a live device.
        k.pool = unsafe {
            dev.create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes), None)
        }
        .map_err(vk_err("vkCreateDescriptorPool"))?;
        self.shared.set_name(k.pool, name);
        let set_layouts = [k.pipe.set_layout];
        // SAFETY: the pool was made for one set of this layout.
        k.set = unsafe {
            dev.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default().descriptor_pool(k.pool).set_layouts(&set_layouts),
            )
        }
        .map_err(vk_err("vkAllocateDescriptorSets"))?[0];
        self.shared.set_name(k.set, name);
        self.check_validation()?;
        Ok(k)
    }

    /// How often [`Context::create_kernel`] reused a compiled pipeline.
    pub fn kernel_cache_stats(&self) -> KernelCacheStats {
        self.kernel_cache.stats()
    }

    /// Points `binding` of `kernel` at the whole of `buffer`, checking the device's
    /// storage-buffer range limit and the buffer's kind.
    pub fn bind(&self, kernel: &mut Kernel, binding: u32, buffer: &Buffer) -> Result<()> {
        let idx = kernel.bindings.iter().position(|b| b.binding == binding).ok_or_else(|| Error::Vulkan {
            what: format!("bind '{}' to kernel '{}'", buffer.name(), kernel.name),
            result: format!("the kernel has no binding {binding}"),
        })?;
        let desc = &kernel.bindings[idx];
        let ty = desc.kind.descriptor_type();
        let ok_kind = match desc.kind {
            BindingKind::Storage | BindingKind::Texel => buffer.kind() == BufferKind::Storage,
            BindingKind::Uniform => buffer.kind() == BufferKind::Uniform,
            BindingKind::RayStructure => false,
        };
        if !ok_kind {
            return Err(Error::Vulkan {
                what: format!("bind '{}' as {}", buffer.name(), desc.name),
                result: "wrong buffer kind".into(),
            });
        }
        if matches!(desc.kind, BindingKind::Storage | BindingKind::Texel) {
            self.limits.check(desc.kind, buffer.name(), buffer.size())?;
        }
        if desc.kind == BindingKind::Texel {
            let texels = buffer.size() / 16;
            let info = vk::BufferViewCreateInfo::default()
                .buffer(buffer.raw)
                .format(vk::Format::R32G32B32A32_UINT)
                .offset(0)
                .range(texels * 16);
            // SAFETY: a live storage buffer created with UNIFORM_TEXEL_BUFFER usage, a
            // range within it and a format every Vulkan device supports for texel buffers.
            let view =
                unsafe { self.shared.device.create_buffer_view(&info, None) }.map_err(vk_err("vkCreateBufferView"))?;
            let views = [view];
            let write = [vk::WriteDescriptorSet::default()
                .dst_set(kernel.set)
                .dst_binding(binding)
                .descriptor_type(ty)
                .texel_buffer_view(&views)];
            // SAFETY: the set is not in use by a pending submission (all submissions
            // wait), so the view it held before can go.
            unsafe {
                self.shared.device.update_descriptor_sets(&write, &[]);
                if kernel.views[idx] != vk::BufferView::null() {
                    self.shared.device.destroy_buffer_view(kernel.views[idx], None);
                }
            }
            kernel.views[idx] = view;
        } else {
            let info = [vk::DescriptorBufferInfo { buffer: buffer.raw, offset: 0, range: vk::WHOLE_SIZE }];
            let write = [vk::WriteDescriptorSet::default()
                .dst_set(kernel.set)
                .dst_binding(binding)
                .descriptor_type(ty)
                .buffer_info(&info)];
            // SAFETY: the set is not in use by a pending submission (all submissions wait).
            unsafe { self.shared.device.update_descriptor_sets(&write, &[]) };
        }
        kernel.bound[idx] = Some(buffer.size());
        Ok(())
    }

    /// Checks that `kernel` can be dispatched: every binding bound, push constants of
    /// the declared size, workgroup counts within the device limits.
    pub(super) fn check_dispatch(&self, kernel: &Kernel, push: &[u8], groups: [u32; 3]) -> Result<()> {
        if let Some(i) = kernel.bound.iter().position(Option::is_none) {
            return Err(Error::Vulkan {
                what: format!("dispatch '{}'", kernel.name),
                result: format!("binding {} ({}) has no buffer", kernel.bindings[i].binding, kernel.bindings[i].name),
            });
        }
        if push.len() as u32 != kernel.push_size {
            return Err(Error::Vulkan {
                what: format!("dispatch '{}'", kernel.name),
                result: format!("push constants are {} bytes, expected {}", push.len(), kernel.push_size),
            });
        }
        if groups[0] > self.max_workgroups[0]
            || groups[1] > self.max_workgroups[1]
            || groups[2] > self.max_workgroups[2]
        {
            return Err(Error::Vulkan {
                what: format!("dispatch '{}'", kernel.name),
                result: format!("{groups:?} workgroups exceed the device limit {:?}", self.max_workgroups),
            });
        }
        Ok(())
    }

    /// Runs `kernel` over `groups` workgroups with `push` constants in one submission
    /// bracketed by timestamps; returns the GPU milliseconds (None without timestamps).
    pub fn dispatch(&self, kernel: &Kernel, push: &[u8], groups: [u32; 3], label: &str) -> Result<Option<f64>> {
        self.check_dispatch(kernel, push, groups)?;
        self.submit_as(Work::new("dispatch").arg("kernel", kernel.name.as_str()), label, |dev, cb| {
            barrier_all(dev, cb);
            record_dispatch(dev, cb, kernel, push, groups);
        })
    }

    /// Workgroup counts covering `groups` workgroups in a 2D grid within the device
    /// limits (x first); kernels recover the linear index as
    /// `gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x` and skip past the end.
    pub fn grid_for(&self, groups: u64) -> Result<[u32; 3]> {
        let x = u64::from(self.max_workgroups[0].min(65_535));
        let y = groups.div_ceil(x).max(1);
        if y > u64::from(self.max_workgroups[1]) {
            return Err(Error::Failed(format!(
                "{groups} workgroups exceed the device limits {:?}",
                self.max_workgroups
            )));
        }
        Ok([groups.clamp(1, x) as u32, y as u32, 1])
    }

    /// Records `steps` (dispatches and timing marks) into one command buffer with a
    /// full memory barrier between consecutive steps, submits it and waits. Returns the
    /// GPU milliseconds of each [`Step::Mark`] (time since the previous mark or the
    /// start), in order; empty without timestamps.
    pub fn run_steps(&self, label: &str, steps: &[Step<'_>]) -> Result<Vec<(String, f64)>> {
        for s in steps {
            match s {
                Step::Dispatch { kernel, push, groups } => self.check_dispatch(kernel, push, *groups)?,
                Step::DispatchIndirect { kernel, push, args, offset } => {
                    self.check_dispatch(kernel, push, [0; 3])?;
                    if offset % 4 != 0 || offset + 12 > args.size() {
                        return Err(Error::Vulkan {
                            what: format!("indirect dispatch '{}'", kernel.name),
                            result: format!("arguments at byte {offset} of a {}-byte buffer", args.size()),
                        });
                    }
                }
                Step::Mark(_) => {}
            }
        }
        let marks: Vec<&str> =
            steps.iter().filter_map(|s| if let Step::Mark(m) = s { Some(*m) } else { None }).collect();
        let dev = &self.shared.device;
        let queries = marks.len() as u32 + 1;
        let pool = if self.timestamps {
            // SAFETY: valid create info on a live device; destroyed below.
            let p = unsafe {
                dev.create_query_pool(
                    &vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(queries),
                    None,
                )
            }
            .map_err(vk_err("vkCreateQueryPool"))?;
            self.shared.set_name(p, label);
            Some(p)
        } else {
            None
        };
        let result = self.submit_ticks(label, |dev, cb| {
            let mut q = 0;
            // SAFETY: recording scope; the pool is live and has `queries` entries.
            unsafe {
                if let Some(p) = pool {
                    dev.cmd_reset_query_pool(cb, p, 0, queries);
                    dev.cmd_write_timestamp(cb, vk::PipelineStageFlags::TOP_OF_PIPE, p, 0);
                }
            }
            for s in steps {
                barrier_all(dev, cb);
                match s {
                    Step::Dispatch { kernel, push, groups } => record_dispatch(dev, cb, kernel, push, *groups),
                    Step::DispatchIndirect { kernel, push, args, offset } => {
                        record_dispatch_indirect(dev, cb, kernel, push, args.raw, *offset)
                    }
                    Step::Mark(_) => {
                        q += 1;
                        if let Some(p) = pool {
                            // SAFETY: query `q` < `queries` was reset above.
                            unsafe { dev.cmd_write_timestamp(cb, vk::PipelineStageFlags::BOTTOM_OF_PIPE, p, q) };
                        }
                    }
                }
            }
            barrier_all(dev, cb);
        });
        let out = (|| -> Result<Vec<(String, f64)>> {
            let (ticks, submitted) = result?;
            let Some(p) = pool else { return Ok(Vec::new()) };
            let mut ts = vec![0u64; queries as usize];
            // SAFETY: every query was written by the completed submission.
            unsafe {
                dev.get_query_pool_results(p, 0, &mut ts, vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT)
            }
            .map_err(vk_err("vkGetQueryPoolResults"))?;
            let period = f64::from(self.info().timestamp_period_ns) * 1e-6;
            // On a timeline: the submission, and each marked phase inside it, placed alike.
            if let Some([begin, end]) = ticks {
                if let Some(place) = self.placement(begin, submitted) {
                    timing::record(&place, (label, "build", Default::default()), begin, end);
                    for (i, m) in marks.iter().enumerate() {
                        let (b, e) = (ts[i].clamp(begin, end), ts[i + 1].clamp(begin, end));
                        timing::record(&place, (m, "build", Default::default()), b, e);
                    }
                }
            }
            Ok(marks
                .iter()
                .enumerate()
                .map(|(i, m)| (m.to_string(), ts[i + 1].wrapping_sub(ts[i]) as f64 * period))
                .collect())
        })();
        if let Some(p) = pool {
            // SAFETY: the submission completed; nothing uses the pool.
            unsafe { dev.destroy_query_pool(p, None) };
        }
        out
    }
}

/// One step of [`Context::run_steps`].
#[derive(Debug)]
pub enum Step<'a> {
    /// Runs a kernel: push-constant bytes and workgroup counts.
    Dispatch { kernel: &'a Kernel, push: Vec<u8>, groups: [u32; 3] },
    /// Runs a kernel over the workgroup counts (three u32) that earlier steps wrote at
    /// byte `offset` of `args` (a storage buffer, which is also an indirect buffer).
    DispatchIndirect { kernel: &'a Kernel, push: Vec<u8>, args: &'a Buffer, offset: u64 },
    /// Ends a timed phase of this name.
    Mark(&'a str),
}

/// Checks a vkCmdUpdateBuffer before `kernel`'s dispatch: offset and size multiples
/// of 4, size 4..=65536, inside `buffer`.
pub(super) fn check_update(kernel: &Kernel, buffer: &Buffer, offset: u64, data: &[u8]) -> Result<()> {
    let len = data.len() as u64;
    let in_range = offset.checked_add(len).is_some_and(|end| end <= buffer.size());
    if offset % 4 != 0 || len % 4 != 0 || len == 0 || len > 65_536 || !in_range {
        return Err(Error::Vulkan {
            what: format!("write before dispatch '{}'", kernel.name),
            result: format!("{len} bytes at byte {offset} of the {}-byte buffer '{}'", buffer.size(), buffer.name()),
        });
    }
    Ok(())
}

/// A global barrier: every earlier transfer, shader or host write is visible to every
/// later transfer or shader access.
pub(super) fn barrier_all(dev: &ash::Device, cb: vk::CommandBuffer) {
    let barrier = [vk::MemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::TRANSFER_WRITE | vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::HOST_WRITE)
        .dst_access_mask(
            vk::AccessFlags::SHADER_READ
                | vk::AccessFlags::SHADER_WRITE
                | vk::AccessFlags::UNIFORM_READ
                | vk::AccessFlags::TRANSFER_READ
                | vk::AccessFlags::TRANSFER_WRITE
                | vk::AccessFlags::INDIRECT_COMMAND_READ,
        )];
    // SAFETY: recording scope of a live command buffer of `dev`.
    unsafe {
        dev.cmd_pipeline_barrier(
            cb,
            vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::HOST,
            vk::PipelineStageFlags::COMPUTE_SHADER
                | vk::PipelineStageFlags::TRANSFER
                | vk::PipelineStageFlags::DRAW_INDIRECT,
            vk::DependencyFlags::empty(),
            &barrier,
            &[],
            &[],
        );
    }
}

/// Binds `kernel` with its descriptor set and push constants.
fn record_bind(dev: &ash::Device, cb: vk::CommandBuffer, kernel: &Kernel, push: &[u8]) {
    // SAFETY: recording scope; all handles belong to this device and are live.
    unsafe {
        dev.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, kernel.pipe.pipeline);
        dev.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::COMPUTE, kernel.pipe.layout, 0, &[kernel.set], &[]);
        if !push.is_empty() {
            dev.cmd_push_constants(cb, kernel.pipe.layout, vk::ShaderStageFlags::COMPUTE, 0, push);
        }
    }
}

/// Binds `kernel` and records one dispatch.
pub(super) fn record_dispatch(
    dev: &ash::Device,
    cb: vk::CommandBuffer,
    kernel: &Kernel,
    push: &[u8],
    groups: [u32; 3],
) {
    record_bind(dev, cb, kernel, push);
    // SAFETY: recording scope of a live command buffer with a compute pipeline bound.
    unsafe { dev.cmd_dispatch(cb, groups[0], groups[1], groups[2]) };
}

/// Binds `kernel` and records one dispatch whose workgroup counts are read from
/// `args` at byte `offset` (checked by `run_steps`: aligned, in range).
fn record_dispatch_indirect(
    dev: &ash::Device,
    cb: vk::CommandBuffer,
    kernel: &Kernel,
    push: &[u8],
    args: vk::Buffer,
    offset: u64,
) {
    record_bind(dev, cb, kernel, push);
    // SAFETY: recording scope; `args` is a live buffer with INDIRECT_BUFFER usage.
    unsafe { dev.cmd_dispatch_indirect(cb, args, offset) };
}
