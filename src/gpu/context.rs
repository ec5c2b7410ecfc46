//! Vulkan instance, device and queue; validation and debug names.

use std::ffi::{c_void, CStr, CString};
use std::sync::{Arc, Mutex};

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use crate::error::{Error, Result};

/// Maps a failed Vulkan call to [`Error::Vulkan`].
pub(crate) fn vk_err(what: &str) -> impl FnOnce(vk::Result) -> Error + '_ {
    move |r| Error::Vulkan { what: what.to_string(), result: format!("{r:?}") }
}

/// Maps an allocator failure to [`Error::Vulkan`].
pub(crate) fn alloc_err(what: &str) -> impl FnOnce(gpu_allocator::AllocationError) -> Error + '_ {
    move |e| Error::Vulkan { what: what.to_string(), result: e.to_string() }
}

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

/// The device extensions `--accel rayquery` enables.
pub(crate) const RAY_QUERY_EXTENSIONS: [&CStr; 3] =
    [ash::khr::acceleration_structure::NAME, ash::khr::ray_query::NAME, ash::khr::deferred_host_operations::NAME];

/// State shared by the context and every object it created; dropped last.
pub(crate) struct Shared {
    pub entry: ash::Entry,
    pub instance: ash::Instance,
    pub device: ash::Device,
    pub allocator: Mutex<Option<Allocator>>,
    pub debug_instance: Option<ash::ext::debug_utils::Instance>,
    pub debug_device: Option<ash::ext::debug_utils::Device>,
    pub messenger: vk::DebugUtilsMessengerEXT,
    /// Validation errors collected by the messenger. Boxed so its address, passed
    /// to the driver as user data, stays fixed.
    pub messages: Box<Mutex<Vec<String>>>,
    /// VK_KHR_acceleration_structure's functions, where the device has ray queries
    /// (they were enabled at device creation).
    pub accel_ext: Option<ash::khr::acceleration_structure::Device>,
}

impl Shared {
    /// Gives `handle` the debug name `name` (no-op without VK_EXT_debug_utils).
    pub fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        if let Some(d) = &self.debug_device {
            let cname = CString::new(name.replace('\0', " ")).unwrap_or_default();
            let info = vk::DebugUtilsObjectNameInfoEXT::default().object_handle(handle).object_name(&cname);
            // SAFETY: `handle` is a live object of `self.device`; the name outlives the call.
            let _ = unsafe { d.set_debug_utils_object_name(&info) };
        }
    }
}

impl Drop for Shared {
    fn drop(&mut self) {
        // SAFETY: every object created from this device holds an Arc<Shared>, so none is
        // alive here; the allocator is dropped (freeing its memory) before the device.
        unsafe {
            let _ = self.device.device_wait_idle();
            if let Ok(mut a) = self.allocator.lock() {
                a.take();
            }
            self.device.destroy_device(None);
            if let Some(d) = &self.debug_instance {
                if self.messenger != vk::DebugUtilsMessengerEXT::null() {
                    d.destroy_debug_utils_messenger(self.messenger, None);
                }
            }
            self.instance.destroy_instance(None);
        }
        let _ = &self.entry;
    }
}

/// An open Vulkan device with one compute queue.
pub struct Context {
    pub(crate) shared: Arc<Shared>,
    pub(crate) queue: vk::Queue,
    pub(crate) command_pool: vk::CommandPool,
    pub(crate) query_pool: vk::QueryPool,
    pub(crate) timestamps: bool,
    pub(crate) max_storage_range: u64,
    /// `maxTexelBufferElements`: texels a texel-buffer view may span.
    pub(crate) max_texel_elements: u64,
    /// `maxMemoryAllocationSize`: the most bytes one allocation (one buffer) may take.
    max_allocation: u64,
    /// `ContextOptions::max_storage_range` where given: a per-buffer limit for every
    /// binding, to check that a scene fits a smaller device.
    lowered: Option<u64>,
    /// Bytes of the largest device-local memory heap.
    device_memory: u64,
    pub(crate) max_workgroups: [u32; 3],
    /// `minAccelerationStructureScratchOffsetAlignment` (ray queries only; else 1).
    pub(crate) scratch_align: u64,
    /// VK_EXT_calibrated_timestamps where the device has it (timeline placement).
    pub(crate) calibration: Option<ash::ext::calibrated_timestamps::Device>,
    /// Pipelines compiled on this device, reused by `create_kernel`.
    pub(crate) kernel_cache: Mutex<super::kernel::KernelCache>,
    info: DeviceInfo,
}

/// Validation messages of severity error go to the context's list; others are dropped.
///
/// For an error the callback returns `VK_TRUE`, which makes the validation layer skip
/// the invalid call (it returns `VK_ERROR_VALIDATION_FAILED_EXT` instead). Passing an
/// invalid call on to the driver is undefined behaviour: lavapipe has crashed compiling
/// a pipeline whose layout lacks a binding its shader uses.
unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) && !data.is_null() && !user.is_null() {
        // SAFETY: the driver passes a valid callback-data struct; `user` is the boxed
        // Mutex in `Shared`, alive until the messenger is destroyed.
        let msg = unsafe {
            let d = &*data;
            if d.p_message.is_null() {
                String::from("(no message)")
            } else {
                CStr::from_ptr(d.p_message).to_string_lossy().into_owned()
            }
        };
        // SAFETY: see above.
        let list = unsafe { &*(user as *const Mutex<Vec<String>>) };
        if let Ok(mut l) = list.lock() {
            l.push(msg);
        }
        return vk::TRUE;
    }
    vk::FALSE
}

fn version_string(v: u32) -> String {
    format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
}

impl Context {
    fn load_entry() -> Result<ash::Entry> {
        // SAFETY: loading the system Vulkan loader; no other loader state exists yet.
        unsafe { ash::Entry::load() }
            .map_err(|e| Error::NoDevice(format!("cannot load the Vulkan loader (libvulkan.so.1): {e}")))
    }

    fn create_instance(entry: &ash::Entry, validation: bool) -> Result<(ash::Instance, bool)> {
        // SAFETY: plain queries on a loaded entry.
        let exts = unsafe { entry.enumerate_instance_extension_properties(None) }.unwrap_or_default();
        let has_debug =
            exts.iter().any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == ash::ext::debug_utils::NAME));
        // SAFETY: as above.
        let layers = unsafe { entry.enumerate_instance_layer_properties() }.unwrap_or_default();
        let layer_name = c"VK_LAYER_KHRONOS_validation";
        let has_layer = layers.iter().any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == layer_name));
        if validation && !has_layer {
            return Err(Error::NoDevice(
                "validation was requested but VK_LAYER_KHRONOS_validation is not installed (apt-get install vulkan-validationlayers)".into(),
            ));
        }
        let app = vk::ApplicationInfo::default()
            .application_name(c"arbor")
            .engine_name(c"arbor")
            .api_version(vk::API_VERSION_1_2);
        let mut ext_ptrs = Vec::new();
        if has_debug {
            ext_ptrs.push(ash::ext::debug_utils::NAME.as_ptr());
        }
        let layer_ptrs = if validation { vec![layer_name.as_ptr()] } else { vec![] };
        let info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_extension_names(&ext_ptrs)
            .enabled_layer_names(&layer_ptrs);
        // SAFETY: all pointers in `info` point at data alive for this call.
        let instance = unsafe { entry.create_instance(&info, None) }.map_err(|e| match e {
            vk::Result::ERROR_INCOMPATIBLE_DRIVER => Error::NoDevice(
                "no Vulkan driver found (install mesa-vulkan-drivers for lavapipe, or check VK_DRIVER_FILES)".into(),
            ),
            other => vk_err("vkCreateInstance")(other),
        })?;
        Ok((instance, has_debug))
    }

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
        let entry = Self::load_entry()?;
        let (instance, _) = Self::create_instance(&entry, false)?;
        let list = Self::usable(&instance).into_iter().map(|(i, pd, _)| Self::describe(&instance, pd, i)).collect();
        // SAFETY: nothing was created from this instance.
        unsafe { instance.destroy_instance(None) };
        Ok(list)
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

    /// Opens a device as `opts` says.
    pub fn new(opts: &ContextOptions) -> Result<Context> {
        let entry = Self::load_entry()?;
        let (instance, has_debug) = Self::create_instance(&entry, opts.validation)?;
        let candidates = Self::usable(&instance);
        let pick = |instance: &ash::Instance| -> Result<(usize, vk::PhysicalDevice, u32)> {
            if candidates.is_empty() {
                return Err(Error::NoDevice("the Vulkan loader found no device supporting Vulkan 1.2 with a compute queue (install mesa-vulkan-drivers for lavapipe)".into()));
            }
            match &opts.device {
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
        };
        let (index, physical, queue_family) = match pick(&instance) {
            Ok(p) => p,
            Err(e) => {
                // SAFETY: nothing was created from this instance.
                unsafe { instance.destroy_instance(None) };
                return Err(e);
            }
        };
        let mut info = Self::describe(&instance, physical, index);

        let priorities = [1.0f32];
        let qinfo =
            [vk::DeviceQueueCreateInfo::default().queue_family_index(queue_family).queue_priorities(&priorities)];
        // Ray queries (`--accel rayquery`) are enabled wherever the device has them;
        // nothing else changes for the other structures.
        let ray_query = info.ray_query();
        let calibrated = super::timing::calibration_supported(&entry, &instance, physical);
        let mut ext_ptrs: Vec<*const std::ffi::c_char> =
            if ray_query { RAY_QUERY_EXTENSIONS.iter().map(|e| e.as_ptr()).collect() } else { Vec::new() };
        if calibrated {
            ext_ptrs.push(ash::ext::calibrated_timestamps::NAME.as_ptr());
        }
        let mut accel_features =
            vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default().acceleration_structure(true);
        let mut query_features = vk::PhysicalDeviceRayQueryFeaturesKHR::default().ray_query(true);
        let mut v12_features = vk::PhysicalDeviceVulkan12Features::default().buffer_device_address(true);
        let mut dev_info =
            vk::DeviceCreateInfo::default().queue_create_infos(&qinfo).enabled_extension_names(&ext_ptrs);
        if ray_query {
            dev_info =
                dev_info.push_next(&mut accel_features).push_next(&mut query_features).push_next(&mut v12_features);
        }
        // SAFETY: `physical` is from `instance`; pointers in dev_info live for the call.
        let device = match unsafe { instance.create_device(physical, &dev_info, None) } {
            Ok(d) => d,
            Err(e) => {
                // SAFETY: nothing else was created.
                unsafe { instance.destroy_instance(None) };
                return Err(vk_err("vkCreateDevice")(e));
            }
        };
        let messages: Box<Mutex<Vec<String>>> = Box::default();
        let (debug_instance, debug_device, messenger) = if has_debug {
            let di = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let dd = ash::ext::debug_utils::Device::new(&instance, &device);
            let messenger = if opts.validation {
                let ci = vk::DebugUtilsMessengerCreateInfoEXT::default()
                    .message_severity(
                        vk::DebugUtilsMessageSeverityFlagsEXT::ERROR | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
                    )
                    .message_type(
                        vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                            | vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                            | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
                    )
                    .pfn_user_callback(Some(debug_callback))
                    .user_data(&*messages as *const Mutex<Vec<String>> as *mut c_void);
                // SAFETY: the callback and its user data outlive the messenger (both owned by Shared).
                unsafe { di.create_debug_utils_messenger(&ci, None) }
                    .map_err(vk_err("vkCreateDebugUtilsMessengerEXT"))?
            } else {
                vk::DebugUtilsMessengerEXT::null()
            };
            (Some(di), Some(dd), messenger)
        } else {
            (None, None, vk::DebugUtilsMessengerEXT::null())
        };
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: ray_query,
            allocation_sizes: Default::default(),
        })
        .map_err(alloc_err("create allocator"))?;
        let accel_ext = ray_query.then(|| ash::khr::acceleration_structure::Device::new(&instance, &device));
        let calibration = calibrated.then(|| ash::ext::calibrated_timestamps::Device::new(&instance, &device));
        let shared = Arc::new(Shared {
            entry,
            instance,
            device,
            allocator: Mutex::new(Some(allocator)),
            debug_instance,
            debug_device,
            messenger,
            messages,
            accel_ext,
        });
        let dev = &shared.device;
        // SAFETY: queue family/index were requested at device creation.
        let queue = unsafe { dev.get_device_queue(queue_family, 0) };
        shared.set_name(queue, "arbor.compute_queue");
        // SAFETY: valid device and family.
        let command_pool = unsafe {
            dev.create_command_pool(
                &vk::CommandPoolCreateInfo::default()
                    .queue_family_index(queue_family)
                    .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                None,
            )
        }
        .map_err(vk_err("vkCreateCommandPool"))?;
        shared.set_name(command_pool, "arbor.command_pool");
        // SAFETY: physical/instance valid.
        let families = unsafe { shared.instance.get_physical_device_queue_family_properties(physical) };
        let props = unsafe { shared.instance.get_physical_device_properties(physical) };
        let timestamps =
            families[queue_family as usize].timestamp_valid_bits > 0 && props.limits.timestamp_period > 0.0;
        // SAFETY: valid device.
        let query_pool = unsafe {
            dev.create_query_pool(
                &vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(2),
                None,
            )
        }
        .map_err(vk_err("vkCreateQueryPool"))?;
        shared.set_name(query_pool, "arbor.timestamps");
        let scratch_align = if ray_query {
            let mut asp = vk::PhysicalDeviceAccelerationStructurePropertiesKHR::default();
            let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut asp);
            // SAFETY: the device has VK_KHR_acceleration_structure (checked by `describe`).
            unsafe { shared.instance.get_physical_device_properties2(physical, &mut p2) };
            u64::from(asp.min_acceleration_structure_scratch_offset_alignment).max(1)
        } else {
            1
        };
        let mut m3 = vk::PhysicalDeviceMaintenance3Properties::default();
        let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut m3);
        // SAFETY: physical/instance valid; Vulkan 1.1 core.
        unsafe { shared.instance.get_physical_device_properties2(physical, &mut p2) };
        let max_allocation = m3.max_memory_allocation_size;
        // SAFETY: physical/instance valid.
        let memory = unsafe { shared.instance.get_physical_device_memory_properties(physical) };
        let device_memory = memory.memory_heaps[..memory.memory_heap_count as usize]
            .iter()
            .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .map(|h| h.size)
            .max()
            .unwrap_or(0);
        let mut max_storage_range = info.max_storage_buffer_range;
        if let Some(lim) = opts.max_storage_range {
            max_storage_range = max_storage_range.min(lim);
            info.max_storage_buffer_range = max_storage_range;
        }
        Ok(Context {
            shared,
            queue,
            command_pool,
            query_pool,
            timestamps,
            max_storage_range,
            max_texel_elements: u64::from(props.limits.max_texel_buffer_elements),
            max_allocation,
            device_memory,
            lowered: opts.max_storage_range,
            max_workgroups: props.limits.max_compute_work_group_count,
            scratch_align,
            calibration,
            kernel_cache: Mutex::default(),
            info,
        })
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
        self.max_storage_range
    }

    /// `maxTexelBufferElements`: the most 16-byte texels one texel-buffer view spans.
    pub fn max_texel_elements(&self) -> u64 {
        self.max_texel_elements
    }

    /// `maxMemoryAllocationSize`: the most bytes one buffer may take.
    pub fn max_allocation(&self) -> u64 {
        self.max_allocation
    }

    /// Bytes of the device's largest device-local memory heap (on a CPU device, the
    /// host's memory).
    pub fn device_memory(&self) -> u64 {
        self.device_memory
    }

    /// The most bytes a buffer bound as `kind` may hold: a storage binding's range, a
    /// texel view's texels (16 bytes each), within one allocation.
    pub fn binding_limit(&self, kind: crate::gpu::BindingKind) -> u64 {
        self.binding_limit_named(kind).0
    }

    /// [`Context::binding_limit`], and which limit it is, for messages.
    pub fn binding_limit_named(&self, kind: crate::gpu::BindingKind) -> (u64, &'static str) {
        let (range, per) = match kind {
            crate::gpu::BindingKind::Texel => {
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

    /// Fails with [`Error::Validation`] if the validation layer reported any error so far.
    pub fn check_validation(&self) -> Result<()> {
        let list = self.shared.messages.lock().map_err(|_| Error::Validation { count: 1, first: "poisoned".into() })?;
        match list.first() {
            None => Ok(()),
            Some(first) => Err(Error::Validation { count: list.len(), first: first.clone() }),
        }
    }

    /// Takes the validation errors collected so far, leaving none: for a caller that
    /// reuses one context for independent pieces of work (a test suite) and wants each
    /// piece judged by its own messages.
    pub fn take_validation_errors(&self) -> Vec<String> {
        match self.shared.messages.lock() {
            Ok(mut list) => std::mem::take(&mut *list),
            Err(poisoned) => std::mem::take(&mut *poisoned.into_inner()),
        }
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
            super::timing::record(&place, (label, work.cat, work.args), begin, end);
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

/// Milliseconds between two timestamp query values, scaled by the device's
/// `timestampPeriod` (nanoseconds per tick); an error if they are out of order.
pub fn timestamp_ms(begin: u64, end: u64, period_ns: f32) -> Result<f64> {
    if end < begin {
        return Err(Error::Failed(format!("GPU timestamps out of order: {begin} then {end}")));
    }
    Ok((end - begin) as f64 * f64::from(period_ns) * 1e-6)
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

#[cfg(test)]
mod tests {
    #[test]
    fn timestamps_are_scaled_by_the_period_and_ordered() {
        let ms = |a, b, p| super::timestamp_ms(a, b, p).expect("ordered");
        assert!((ms(1_000, 3_000, 1.0) - 0.002).abs() < 1e-12);
        assert!((ms(1_000, 3_000, 40.0) - 0.08).abs() < 1e-12);
        assert_eq!(ms(7, 7, 1.0), 0.0);
        assert!(super::timestamp_ms(3_000, 1_000, 1.0).is_err());
    }
}
