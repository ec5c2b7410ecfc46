//! An open device with one compute queue: choosing the device, opening it step by
//! step (device.rs owns each Vulkan object from its creation), the limits read once,
//! and one-time submissions bracketed by timestamps.

use std::ffi::CString;
use std::sync::Arc;

use ash::vk;

use super::cache::KernelCache;
use super::descriptor::{BindingKind, BindingLimits};
use super::device::{vk_err, Features, Instance, Shared, RAY_QUERY_EXTENSIONS};
use super::timing::{self, timestamp_ms, Placement};
use crate::error::{Error, Result};

/// How to create a [`Context`].
#[derive(Debug, Clone, Default)]
pub struct ContextOptions {
    /// `INDEX` or a case-insensitive substring of the device name; `None` picks a
    /// discrete GPU if there is one, else the first device.
    pub device: Option<String>,
    /// Enable VK_LAYER_KHRONOS_validation and fail on any error message.
    pub validation: bool,
    /// Override (lower) the storage-buffer range limit, for tests and for users who
    /// want to check a scene fits a smaller device.
    pub max_storage_range: Option<u64>,
}

/// What the user sees of a physical device.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct DeviceInfo {
    /// Index in the loader's enumeration (`--device INDEX`).
    pub index: usize,
    /// The device's name.
    pub name: String,
    /// Discrete, integrated, virtual or CPU.
    pub kind: String,
    /// Vulkan version the device supports.
    pub api_version: String,
    /// Driver name and version.
    pub driver: String,
    /// `maxStorageBufferRange` (or the lower override).
    pub max_storage_buffer_range: u64,
    /// Nanoseconds per timestamp tick.
    pub timestamp_period_ns: f32,
    /// Mesa's llvmpipe (lavapipe), which caps loop iterations per invocation.
    pub is_llvmpipe: bool,
    /// Invocations per subgroup (8 on lavapipe here, 32 on NVIDIA).
    pub subgroup_size: u32,
    /// Whether compute shaders have subgroup vote and arithmetic operations, which
    /// packet traversal (`--traversal packet`) and every trace kernel declare.
    pub subgroup_vote: bool,
    /// Why `--accel rayquery` cannot run here: the first missing extension or feature
    /// of VK_KHR_acceleration_structure + VK_KHR_ray_query; `None` where it can.
    pub ray_query_missing: Option<String>,
}

impl DeviceInfo {
    /// Whether the device traces with the driver's own structure (`--accel rayquery`).
    pub fn ray_query(&self) -> bool {
        self.ray_query_missing.is_none()
    }
}

/// An open Vulkan device with one compute queue.
pub struct Context {
    pub(crate) shared: Arc<Shared>,
    pub(crate) queue: vk::Queue,
    pub(crate) command_pool: vk::CommandPool,
    pub(crate) query_pool: vk::QueryPool,
    pub(crate) timestamps: bool,
    /// What one binding may cover (storage range, texel view, allocation).
    pub(crate) limits: BindingLimits,
    /// Bytes of the largest device-local memory heap.
    device_memory: u64,
    pub(crate) max_workgroups: [u32; 3],
    /// `minAccelerationStructureScratchOffsetAlignment` (ray queries only; else 1).
    pub(crate) scratch_align: u64,
    /// Pipelines compiled on this device, reused by `create_kernel`.
    pub(crate) kernel_cache: KernelCache,
    info: DeviceInfo,
}

fn version_string(v: u32) -> String {
    format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
}

impl Context {
    fn describe(instance: &ash::Instance, pd: vk::PhysicalDevice, index: usize) -> DeviceInfo {
        // SAFETY: `pd` was enumerated from `instance`.
        let props = unsafe { instance.get_physical_device_properties(pd) };
        let mut driver = vk::PhysicalDeviceDriverProperties::default();
        let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
        let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut driver).push_next(&mut subgroup);
        // SAFETY: as above; Vulkan 1.1+ query with a valid chain.
        unsafe { instance.get_physical_device_properties2(pd, &mut p2) };
        let ray_query_missing = Self::ray_query_missing(instance, pd);
        DeviceInfo {
            index,
            name: props.device_name_as_c_str().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default(),
            kind: format!("{:?}", props.device_type).to_lowercase(),
            api_version: version_string(props.api_version),
            driver: driver.driver_info_as_c_str().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default(),
            max_storage_buffer_range: u64::from(props.limits.max_storage_buffer_range),
            timestamp_period_ns: props.limits.timestamp_period,
            is_llvmpipe: driver.driver_id == vk::DriverId::MESA_LLVMPIPE,
            subgroup_size: subgroup.subgroup_size,
            subgroup_vote: subgroup.supported_stages.contains(vk::ShaderStageFlags::COMPUTE)
                && subgroup
                    .supported_operations
                    .contains(vk::SubgroupFeatureFlags::VOTE | vk::SubgroupFeatureFlags::ARITHMETIC),
            ray_query_missing,
        }
    }

    /// The first extension or feature that ray queries need and `pd` lacks.
    fn ray_query_missing(instance: &ash::Instance, pd: vk::PhysicalDevice) -> Option<String> {
        // SAFETY: `pd` was enumerated from `instance`.
        let exts = unsafe { instance.enumerate_device_extension_properties(pd) }.unwrap_or_default();
        for want in RAY_QUERY_EXTENSIONS {
            if !exts.iter().any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == want)) {
                return Some(want.to_string_lossy().into_owned());
            }
        }
        let mut accel = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default();
        let mut query = vk::PhysicalDeviceRayQueryFeaturesKHR::default();
        let mut v12 = vk::PhysicalDeviceVulkan12Features::default();
        let mut f2 =
            vk::PhysicalDeviceFeatures2::default().push_next(&mut accel).push_next(&mut query).push_next(&mut v12);
        // SAFETY: as above; every struct in the chain is an extension the device has.
        unsafe { instance.get_physical_device_features2(pd, &mut f2) };
        if accel.acceleration_structure == vk::FALSE {
            return Some("the accelerationStructure feature".into());
        }
        if query.ray_query == vk::FALSE {
            return Some("the rayQuery feature".into());
        }
        if v12.buffer_device_address == vk::FALSE {
            return Some("the bufferDeviceAddress feature".into());
        }
        None
    }

    /// Lists the Vulkan 1.2+ devices with a compute queue, in enumeration order.
    pub fn list_devices() -> Result<Vec<DeviceInfo>> {
        let instance = Instance::new(false)?;
        Ok(Self::usable(&instance).into_iter().map(|(i, pd, _)| Self::describe(&instance, pd, i)).collect())
    }

    fn usable(instance: &ash::Instance) -> Vec<(usize, vk::PhysicalDevice, u32)> {
        // SAFETY: plain enumeration on a live instance.
        let pds = unsafe { instance.enumerate_physical_devices() }.unwrap_or_default();
        let mut out = Vec::new();
        for (i, pd) in pds.into_iter().enumerate() {
            // SAFETY: `pd` comes from this instance.
            let props = unsafe { instance.get_physical_device_properties(pd) };
            if props.api_version < vk::API_VERSION_1_2 {
                continue;
            }
            // SAFETY: as above.
            let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
            if let Some(q) = families.iter().position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE)) {
                out.push((i, pd, q as u32));
            }
        }
        out
    }

    /// The device `device` names (an index or part of a name), else the first discrete
    /// GPU, else the first device: its index, handle and compute queue family.
    fn pick(instance: &ash::Instance, device: Option<&str>) -> Result<(usize, vk::PhysicalDevice, u32)> {
        let candidates = Self::usable(instance);
        if candidates.is_empty() {
            return Err(Error::NoDevice("the Vulkan loader found no device supporting Vulkan 1.2 with a compute queue (install mesa-vulkan-drivers for lavapipe)".into()));
        }
        match device {
            Some(sel) => {
                if let Ok(idx) = sel.parse::<usize>() {
                    candidates.iter().find(|c| c.0 == idx).copied().ok_or_else(|| {
                        Error::NoDevice(format!("--device {idx}: no such device index (run `arbor devices`)"))
                    })
                } else {
                    let s = sel.to_lowercase();
                    candidates
                        .iter()
                        .find(|c| Self::describe(instance, c.1, c.0).name.to_lowercase().contains(&s))
                        .copied()
                        .ok_or_else(|| {
                            Error::NoDevice(format!(
                                "--device {sel:?}: no device name contains it (run `arbor devices`)"
                            ))
                        })
                }
            }
            None => Ok(candidates
                .iter()
                .find(|c| {
                    // SAFETY: c.1 is from this instance.
                    unsafe { instance.get_physical_device_properties(c.1) }.device_type
                        == vk::PhysicalDeviceType::DISCRETE_GPU
                })
                .copied()
                .unwrap_or(candidates[0])),
        }
    }

    /// Opens a device as `opts` says. Each step owns what it creates (device.rs), so a
    /// failing step frees everything made before it.
    pub fn new(opts: &ContextOptions) -> Result<Context> {
        let instance = Instance::new(opts.validation)?;
        let (index, physical, queue_family) = Self::pick(&instance, opts.device.as_deref())?;
        let mut info = Self::describe(&instance, physical, index);
        let features = Features {
            ray_query: info.ray_query(),
            calibrated: timing::calibration_supported(&instance.entry, &instance, physical),
        };
        let shared = Arc::new(Shared::open(instance, physical, queue_family, features, opts.validation)?);
        let instance = &shared.instance;
        // SAFETY: `physical` was enumerated from this instance (also below).
        let props = unsafe { instance.get_physical_device_properties(physical) };
        let limits = Self::binding_limits(instance, physical, &props, opts.max_storage_range);
        info.max_storage_buffer_range = limits.max_storage_range;
        // SAFETY: as above.
        let families = unsafe { instance.get_physical_device_queue_family_properties(physical) };
        let timestamps =
            families[queue_family as usize].timestamp_valid_bits > 0 && props.limits.timestamp_period > 0.0;
        let device_memory = Self::largest_device_heap(instance, physical);
        let scratch_align = Self::scratch_align(instance, physical, features.ray_query);
        // SAFETY: queue family/index were requested at device creation.
        let queue = unsafe { shared.device.get_device_queue(queue_family, 0) };
        shared.set_name(queue, "arbor.compute_queue");
        // The pools start null (destroying a null handle does nothing), so that an
        // error creating one drops the context and with it whatever exists.
        let mut ctx = Context {
            shared,
            queue,
            command_pool: vk::CommandPool::null(),
            query_pool: vk::QueryPool::null(),
            timestamps,
            limits,
            device_memory,
            max_workgroups: props.limits.max_compute_work_group_count,
            scratch_align,
            kernel_cache: KernelCache::default(),
            info,
        };
        ctx.create_pools(queue_family)?;
        Ok(ctx)
    }

    /// The storage-range, texel and allocation limits; the storage range lowered to
    /// `lowered` where given.
    fn binding_limits(
        instance: &ash::Instance,
        physical: vk::PhysicalDevice,
        props: &vk::PhysicalDeviceProperties,
        lowered: Option<u64>,
    ) -> BindingLimits {
        let mut m3 = vk::PhysicalDeviceMaintenance3Properties::default();
        let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut m3);
        // SAFETY: physical/instance valid; Vulkan 1.1 core.
        unsafe { instance.get_physical_device_properties2(physical, &mut p2) };
        let device_range = u64::from(props.limits.max_storage_buffer_range);
        BindingLimits {
            max_storage_range: lowered.map_or(device_range, |l| device_range.min(l)),
            max_texel_elements: u64::from(props.limits.max_texel_buffer_elements),
            max_allocation: m3.max_memory_allocation_size,
            lowered,
        }
    }

    /// Bytes of the largest device-local memory heap.
    fn largest_device_heap(instance: &ash::Instance, physical: vk::PhysicalDevice) -> u64 {
        // SAFETY: physical/instance valid.
        let memory = unsafe { instance.get_physical_device_memory_properties(physical) };
        memory.memory_heaps[..memory.memory_heap_count as usize]
            .iter()
            .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .map(|h| h.size)
            .max()
            .unwrap_or(0)
    }

    /// `minAccelerationStructureScratchOffsetAlignment` where ray queries are on; else 1.
    fn scratch_align(instance: &ash::Instance, physical: vk::PhysicalDevice, ray_query: bool) -> u64 {
        if !ray_query {
            return 1;
        }
        let mut asp = vk::PhysicalDeviceAccelerationStructurePropertiesKHR::default();
        let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut asp);
        // SAFETY: the device has VK_KHR_acceleration_structure (checked by `describe`).
        unsafe { instance.get_physical_device_properties2(physical, &mut p2) };
        u64::from(asp.min_acceleration_structure_scratch_offset_alignment).max(1)
    }

    /// Creates the command pool and the two-query timestamp pool into `self`, whose
    /// drop destroys them.
    fn create_pools(&mut self, queue_family: u32) -> Result<()> {
        let dev = &self.shared.device;
        // SAFETY: valid device and family.
        self.command_pool = unsafe {
            dev.create_command_pool(
                &vk::CommandPoolCreateInfo::default()
                    .queue_family_index(queue_family)
                    .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                None,
            )
        }
        .map_err(vk_err("vkCreateCommandPool"))?;
        self.shared.set_name(self.command_pool, "arbor.command_pool");
        // SAFETY: valid device.
        self.query_pool = unsafe {
            dev.create_query_pool(
                &vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(2),
                None,
            )
        }
        .map_err(vk_err("vkCreateQueryPool"))?;
        self.shared.set_name(self.query_pool, "arbor.timestamps");
        Ok(())
    }

    /// The chosen device.
    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }

    /// Whether dispatch times come from GPU timestamps.
    pub fn has_timestamps(&self) -> bool {
        self.timestamps
    }

    /// Loop iterations one invocation may run in total, where the driver limits it
    /// (llvmpipe); None where it does not.
    pub fn loop_budget(&self) -> Option<u64> {
        self.info.is_llvmpipe.then_some(super::bindings::LLVMPIPE_LOOP_BUDGET)
    }

    /// Most bytes one storage-buffer binding may cover.
    pub fn max_storage_range(&self) -> u64 {
        self.limits.max_storage_range
    }

    /// `maxTexelBufferElements`: the most 16-byte texels one texel-buffer view spans.
    pub fn max_texel_elements(&self) -> u64 {
        self.limits.max_texel_elements
    }

    /// `maxMemoryAllocationSize`: the most bytes one buffer may take.
    pub fn max_allocation(&self) -> u64 {
        self.limits.max_allocation
    }

    /// Bytes of the device's largest device-local memory heap (on a CPU device, the
    /// host's memory).
    pub fn device_memory(&self) -> u64 {
        self.device_memory
    }

    /// The most bytes a buffer bound as `kind` may hold: a storage binding's range, a
    /// texel view's texels (16 bytes each), within one allocation.
    pub fn binding_limit(&self, kind: BindingKind) -> u64 {
        self.limits.named(kind).0
    }

    /// [`Context::binding_limit`], and which limit it is, for messages.
    pub fn binding_limit_named(&self, kind: BindingKind) -> (u64, &'static str) {
        self.limits.named(kind)
    }

    /// Fails with [`crate::error::Error::BufferTooLarge`] if `size` bytes named `name`
    /// exceed what a binding of `kind` may cover ([`Context::binding_limit`]): the one
    /// check `bind` makes, for a caller to make before creating the buffer.
    pub fn check_binding(&self, kind: BindingKind, name: &str, size: u64) -> Result<()> {
        self.limits.check(kind, name, size)
    }

    /// Fails with [`Error::Validation`] if the validation layer reported any error so far.
    pub fn check_validation(&self) -> Result<()> {
        self.shared.check_validation()
    }

    /// Takes the validation errors collected so far, leaving none: for a caller that
    /// reuses one context for independent pieces of work (a test suite) and wants each
    /// piece judged by its own messages.
    pub fn take_validation_errors(&self) -> Vec<String> {
        self.shared.take_validation_errors()
    }

    /// How to place a submission whose first timestamp is `begin_ticks` and which the
    /// CPU submitted at `submitted`; `None` when this thread is not recording a
    /// timeline.
    pub(crate) fn placement(&self, begin_ticks: u64, submitted: std::time::Instant) -> Option<Placement> {
        timing::placement(self.shared.calibration.as_ref(), self.info.timestamp_period_ns, begin_ticks, submitted)
    }

    /// Records `record` into a one-time command buffer, submits it, waits, and returns
    /// the GPU time between the two timestamps written around it (ms), if supported.
    /// On a timeline it is a `transfer` span; [`Context::submit_as`] names another kind.
    pub(crate) fn submit(
        &self,
        label: &str,
        record: impl FnOnce(&ash::Device, vk::CommandBuffer),
    ) -> Result<Option<f64>> {
        self.submit_as(Work::new("transfer"), label, record)
    }

    /// [`Context::submit`] of `work` (its timeline category and span arguments).
    pub(crate) fn submit_as(
        &self,
        work: Work,
        label: &str,
        record: impl FnOnce(&ash::Device, vk::CommandBuffer),
    ) -> Result<Option<f64>> {
        let (ticks, submitted) = self.submit_ticks(label, record)?;
        let Some([begin, end]) = ticks else { return Ok(None) };
        if let Some(place) = self.placement(begin, submitted) {
            timing::record(&place, (label, work.cat, work.args), begin, end);
        }
        timestamp_ms(begin, end, self.info.timestamp_period_ns).map(Some)
    }

    /// [`Context::submit`] returning the raw timestamps written around the work (None
    /// without timestamps) and the CPU instant it was submitted.
    pub(crate) fn submit_ticks(
        &self,
        label: &str,
        record: impl FnOnce(&ash::Device, vk::CommandBuffer),
    ) -> Result<(Option<[u64; 2]>, std::time::Instant)> {
        let _span = crate::timeline::span("submit", || label);
        let mut submitted = std::time::Instant::now();
        let dev = &self.shared.device;
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(self.command_pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: pool belongs to this device; used from one thread (&self methods are
        // not called concurrently: Context is not Sync-shared across threads here).
        let cb = unsafe { dev.allocate_command_buffers(&alloc) }.map_err(vk_err("vkAllocateCommandBuffers"))?[0];
        self.shared.set_name(cb, label);
        // SAFETY: valid device.
        let fence =
            unsafe { dev.create_fence(&vk::FenceCreateInfo::default(), None) }.map_err(vk_err("vkCreateFence"))?;
        self.shared.set_name(fence, label);
        let result = (|| -> Result<Option<[u64; 2]>> {
            // SAFETY: `cb` is a fresh primary command buffer of this device.
            unsafe {
                dev.begin_command_buffer(
                    cb,
                    &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )
                .map_err(vk_err("vkBeginCommandBuffer"))?;
                let cname = CString::new(label.replace('\0', " ")).unwrap_or_default();
                if let Some(d) = &self.shared.debug_device {
                    d.cmd_begin_debug_utils_label(cb, &vk::DebugUtilsLabelEXT::default().label_name(&cname));
                }
                if self.timestamps {
                    dev.cmd_reset_query_pool(cb, self.query_pool, 0, 2);
                    dev.cmd_write_timestamp(cb, vk::PipelineStageFlags::TOP_OF_PIPE, self.query_pool, 0);
                }
            }
            record(dev, cb);
            // SAFETY: recording state; handles belong to this device.
            unsafe {
                if self.timestamps {
                    dev.cmd_write_timestamp(cb, vk::PipelineStageFlags::BOTTOM_OF_PIPE, self.query_pool, 1);
                }
                if let Some(d) = &self.shared.debug_device {
                    d.cmd_end_debug_utils_label(cb);
                }
                dev.end_command_buffer(cb).map_err(vk_err("vkEndCommandBuffer"))?;
                let cbs = [cb];
                let submit = [vk::SubmitInfo::default().command_buffers(&cbs)];
                submitted = std::time::Instant::now();
                dev.queue_submit(self.queue, &submit, fence).map_err(vk_err("vkQueueSubmit"))?;
                dev.wait_for_fences(&[fence], true, u64::MAX).map_err(vk_err("vkWaitForFences"))?;
            }
            if !self.timestamps {
                return Ok(None);
            }
            let mut ts = [0u64; 2];
            // SAFETY: both queries were written by the completed submission.
            unsafe {
                dev.get_query_pool_results(
                    self.query_pool,
                    0,
                    &mut ts,
                    vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
                )
            }
            .map_err(vk_err("vkGetQueryPoolResults"))?;
            if ts[1] < ts[0] {
                return Err(Error::Failed(format!("GPU timestamps out of order: {} then {}", ts[0], ts[1])));
            }
            Ok(Some(ts))
        })();
        // SAFETY: the fence was waited on (or the submission failed); nothing uses them now.
        unsafe {
            let _ = dev.queue_wait_idle(self.queue);
            dev.destroy_fence(fence, None);
            dev.free_command_buffers(self.command_pool, &[cb]);
        }
        // A skipped invalid call fails with VK_ERROR_VALIDATION_FAILED_EXT; the layer's
        // message says more than that code.
        self.check_validation()?;
        Ok((result?, submitted))
    }
}

/// What a submission does, for its span on the timeline: a category (`dispatch`,
/// `build`, `transfer`; see [`crate::timeline::Event::cat`]) and arguments.
#[derive(Debug, Default)]
pub(crate) struct Work {
    pub cat: &'static str,
    pub args: serde_json::Map<String, serde_json::Value>,
}

impl Work {
    pub fn new(cat: &'static str) -> Work {
        Work { cat, args: serde_json::Map::new() }
    }

    /// With argument `key: value`.
    pub fn arg(mut self, key: &str, value: impl Into<serde_json::Value>) -> Work {
        self.args.insert(key.to_string(), value.into());
        self
    }
}

impl std::fmt::Debug for Context {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Context").field("device", &self.info.name).finish()
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        // SAFETY: submissions always wait for completion, so the pools are idle.
        unsafe {
            let _ = self.shared.device.device_wait_idle();
            self.shared.device.destroy_query_pool(self.query_pool, None);
            self.shared.device.destroy_command_pool(self.command_pool, None);
        }
    }
}
