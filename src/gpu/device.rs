//! The bottom of gpu/: the Vulkan objects every other one is made from, each owned
//! from the moment it exists, and the error helpers. Imports no other file of gpu/.
//!
//! - [`Instance`]: the loader and a VkInstance; destroys the instance on drop.
//! - [`Device`]: a VkDevice with one compute queue family; destroys it on drop.
//! - [`Messenger`]: the validation layer's debug messenger; destroyed on drop.
//! - [`Shared`]: the above with the allocator, held by the context and by every
//!   object it creates; dropped last.
//!
//! A step of opening a device that fails drops what the steps before it made, in
//! reverse order: no error path leaks a handle.

use std::ffi::{c_void, CStr, CString};
use std::ops::Deref;
use std::path::Path;
use std::sync::Mutex;

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

/// The device extensions `--accel rayquery` enables.
pub(crate) const RAY_QUERY_EXTENSIONS: [&CStr; 3] =
    [ash::khr::acceleration_structure::NAME, ash::khr::ray_query::NAME, ash::khr::deferred_host_operations::NAME];

/// The Vulkan loader and an instance (no surface), destroyed on drop.
pub(crate) struct Instance {
    raw: ash::Instance,
    /// Whether VK_EXT_debug_utils is enabled (debug names, labels, the messenger).
    pub has_debug: bool,
    /// Declared after `raw`: the loader stays loaded until the instance is gone.
    pub entry: ash::Entry,
}

impl Instance {
    /// Loads the system loader and creates an instance, with the Khronos validation
    /// layer where `validation` (an error if it is not installed).
    pub fn new(validation: bool) -> Result<Instance> {
        // The loader is opened now, not linked: a program (the Python module) that
        // never opens a device runs without one. ARBOR_VULKAN_LOADER names another.
        let entry = match std::env::var_os("ARBOR_VULKAN_LOADER") {
            // SAFETY: loading the named Vulkan loader; no other loader state exists yet.
            Some(path) => unsafe { ash::Entry::load_from(&path) }.map_err(|e| {
                Error::NoDevice(format!(
                    "cannot load the Vulkan loader {} (ARBOR_VULKAN_LOADER): {e}",
                    Path::new(&path).display()
                ))
            })?,
            // SAFETY: loading the system Vulkan loader, as above.
            None => unsafe { ash::Entry::load() }.map_err(|e| {
                Error::NoDevice(format!("cannot load the Vulkan loader (libvulkan.so.1; install libvulkan1): {e}"))
            })?,
        };
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
        let ext_ptrs = if has_debug { vec![ash::ext::debug_utils::NAME.as_ptr()] } else { vec![] };
        let layer_ptrs = if validation { vec![layer_name.as_ptr()] } else { vec![] };
        let info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_extension_names(&ext_ptrs)
            .enabled_layer_names(&layer_ptrs);
        // SAFETY: all pointers in `info` point at data alive for this call.
        let raw = unsafe { entry.create_instance(&info, None) }.map_err(|e| match e {
            vk::Result::ERROR_INCOMPATIBLE_DRIVER => Error::NoDevice(
                "no Vulkan driver found (install mesa-vulkan-drivers for lavapipe, or check VK_DRIVER_FILES)".into(),
            ),
            other => vk_err("vkCreateInstance")(other),
        })?;
        Ok(Instance { raw, has_debug, entry })
    }
}

impl Deref for Instance {
    type Target = ash::Instance;
    fn deref(&self) -> &ash::Instance {
        &self.raw
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        // SAFETY: every object made from the instance (device, messenger) has its own
        // guard, dropped before this one (Shared's field order, or a later local).
        unsafe { self.raw.destroy_instance(None) };
    }
}

/// What a device is opened with beyond one compute queue.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Features {
    /// VK_KHR_acceleration_structure + VK_KHR_ray_query with buffer device addresses.
    pub ray_query: bool,
    /// VK_EXT_calibrated_timestamps.
    pub calibrated: bool,
}

/// A logical device, destroyed on drop.
pub(crate) struct Device {
    raw: ash::Device,
}

impl Device {
    /// Opens `physical` with one queue of `queue_family` and the extensions `features` names.
    pub fn new(
        instance: &Instance,
        physical: vk::PhysicalDevice,
        queue_family: u32,
        features: Features,
    ) -> Result<Device> {
        let priorities = [1.0f32];
        let qinfo =
            [vk::DeviceQueueCreateInfo::default().queue_family_index(queue_family).queue_priorities(&priorities)];
        // Ray queries (`--accel rayquery`) are enabled wherever the device has them;
        // nothing else changes for the other structures.
        let mut ext_ptrs: Vec<*const std::ffi::c_char> =
            if features.ray_query { RAY_QUERY_EXTENSIONS.iter().map(|e| e.as_ptr()).collect() } else { Vec::new() };
        if features.calibrated {
            ext_ptrs.push(ash::ext::calibrated_timestamps::NAME.as_ptr());
        }
        let mut accel_features =
            vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default().acceleration_structure(true);
        let mut query_features = vk::PhysicalDeviceRayQueryFeaturesKHR::default().ray_query(true);
        let mut v12_features = vk::PhysicalDeviceVulkan12Features::default().buffer_device_address(true);
        let mut dev_info =
            vk::DeviceCreateInfo::default().queue_create_infos(&qinfo).enabled_extension_names(&ext_ptrs);
        if features.ray_query {
            dev_info =
                dev_info.push_next(&mut accel_features).push_next(&mut query_features).push_next(&mut v12_features);
        }
        // SAFETY: `physical` is from `instance`; pointers in dev_info live for the call.
        let raw = unsafe { instance.create_device(physical, &dev_info, None) }.map_err(vk_err("vkCreateDevice"))?;
        Ok(Device { raw })
    }
}

impl Deref for Device {
    type Target = ash::Device;
    fn deref(&self) -> &ash::Device {
        &self.raw
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: every object created from the device holds an Arc<Shared> (or, while
        // a context opens, a guard dropped before this one), so none is alive here.
        unsafe { self.raw.destroy_device(None) };
    }
}

/// The debug messenger that sends validation errors to a list; destroyed on drop.
pub(crate) struct Messenger {
    loader: ash::ext::debug_utils::Instance,
    raw: vk::DebugUtilsMessengerEXT,
}

impl Messenger {
    /// Sends the validation layer's errors into `messages` until dropped; the caller
    /// keeps `messages` alive (at a fixed address) for longer than the messenger.
    pub fn new(instance: &Instance, messages: &Mutex<Vec<String>>) -> Result<Messenger> {
        let loader = ash::ext::debug_utils::Instance::new(&instance.entry, instance);
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
            .user_data(messages as *const Mutex<Vec<String>> as *mut c_void);
        // SAFETY: the callback is a plain function; its user data outlives the
        // messenger (the caller's promise, kept by `Shared`'s field order).
        let raw = unsafe { loader.create_debug_utils_messenger(&ci, None) }
            .map_err(vk_err("vkCreateDebugUtilsMessengerEXT"))?;
        Ok(Messenger { loader, raw })
    }
}

impl Drop for Messenger {
    fn drop(&mut self) {
        // SAFETY: created by this loader's instance, which outlives this guard.
        unsafe { self.loader.destroy_debug_utils_messenger(self.raw, None) };
    }
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

/// State shared by the context and every object it created; dropped last.
///
/// Fields drop in declaration order, after [`Shared`]'s `drop` has waited for the
/// device and freed the allocator: device, messenger, its message list, instance.
pub(crate) struct Shared {
    pub allocator: Mutex<Option<Allocator>>,
    /// VK_KHR_acceleration_structure's functions, where the device has ray queries
    /// (they were enabled at device creation).
    pub accel_ext: Option<ash::khr::acceleration_structure::Device>,
    /// VK_EXT_calibrated_timestamps' functions where the device has them (timeline placement).
    pub calibration: Option<ash::ext::calibrated_timestamps::Device>,
    pub debug_device: Option<ash::ext::debug_utils::Device>,
    pub device: Device,
    _messenger: Option<Messenger>,
    /// Validation errors collected by the messenger. Boxed so its address, passed
    /// to the driver as user data, stays fixed.
    messages: Box<Mutex<Vec<String>>>,
    pub instance: Instance,
}

impl Shared {
    /// Opens `physical` on `instance`: the device, the messenger (where `validation`
    /// and the instance has debug utils), the allocator. A failing step drops the
    /// ones before it.
    pub fn open(
        instance: Instance,
        physical: vk::PhysicalDevice,
        queue_family: u32,
        features: Features,
        validation: bool,
    ) -> Result<Shared> {
        let device = Device::new(&instance, physical, queue_family, features)?;
        let messages: Box<Mutex<Vec<String>>> = Box::default();
        let messenger =
            if instance.has_debug && validation { Some(Messenger::new(&instance, &messages)?) } else { None };
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: (*instance).clone(),
            device: (*device).clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: features.ray_query,
            allocation_sizes: Default::default(),
        })
        .map_err(alloc_err("create allocator"))?;
        Ok(Shared {
            allocator: Mutex::new(Some(allocator)),
            accel_ext: features.ray_query.then(|| ash::khr::acceleration_structure::Device::new(&instance, &device)),
            calibration: features.calibrated.then(|| ash::ext::calibrated_timestamps::Device::new(&instance, &device)),
            debug_device: instance.has_debug.then(|| ash::ext::debug_utils::Device::new(&instance, &device)),
            device,
            _messenger: messenger,
            messages,
            instance,
        })
    }

    /// Gives `handle` the debug name `name` (no-op without VK_EXT_debug_utils).
    pub fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        if let Some(d) = &self.debug_device {
            let cname = CString::new(name.replace('\0', " ")).unwrap_or_default();
            let info = vk::DebugUtilsObjectNameInfoEXT::default().object_handle(handle).object_name(&cname);
            // SAFETY: `handle` is a live object of `self.device`; the name outlives the call.
            let _ = unsafe { d.set_debug_utils_object_name(&info) };
        }
    }

    /// Fails with [`Error::Validation`] if the validation layer reported any error so far.
    pub fn check_validation(&self) -> Result<()> {
        let list = self.messages.lock().map_err(|_| Error::Validation { count: 1, first: "poisoned".into() })?;
        match list.first() {
            None => Ok(()),
            Some(first) => Err(Error::Validation { count: list.len(), first: first.clone() }),
        }
    }

    /// Takes the validation errors collected so far, leaving none.
    pub fn take_validation_errors(&self) -> Vec<String> {
        match self.messages.lock() {
            Ok(mut list) => std::mem::take(&mut *list),
            Err(poisoned) => std::mem::take(&mut *poisoned.into_inner()),
        }
    }
}

impl Drop for Shared {
    fn drop(&mut self) {
        // SAFETY: every object created from this device holds an Arc<Shared>, so none
        // is alive here; the allocator is dropped (freeing its memory) before the
        // fields drop, the device first among them.
        let _ = unsafe { self.device.device_wait_idle() };
        if let Ok(mut a) = self.allocator.lock() {
            a.take();
        }
    }
}
