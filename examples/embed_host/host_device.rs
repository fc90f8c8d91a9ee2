//! The host's own Vulkan objects, made the way an engine makes them and
//! not through izb: the instance (with the validation layer and its
//! synchronization validation when asked), a debug messenger that keeps
//! every message, the device (graphics + compute queue, `geometryShader`
//! for the visibility buffer's `gl_PrimitiveID`, `scalarBlockLayout` for
//! izb's shaders), its queue behind the lock both submit under, and a
//! memory allocator for the host's images and buffers.

use ash::vk;
use gpu_allocator::vulkan::{
    Allocation, AllocationCreateDesc, AllocationScheme, Allocator, AllocatorCreateDesc,
};
use gpu_allocator::MemoryLocation;
use izb::gpu::context::SharedQueue;
use izb::gpu::host_device::HostDevice;
use std::ffi::c_void;
use std::mem::ManuallyDrop;
use std::sync::{Arc, Mutex};

const VALIDATION_LAYER: &std::ffi::CStr = c"VK_LAYER_KHRONOS_validation";

/// The host's device and what lives as long as it.
pub struct HostGpu {
    pub device: ash::Device,
    pub physical: vk::PhysicalDevice,
    pub family: u32,
    pub queue: SharedQueue,
    pub allocator: ManuallyDrop<Mutex<Allocator>>,
    pub instance: ash::Instance,
    pub name: String,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    /// The messenger's list (its `user_data`), freed after it.
    messages: Box<Mutex<Vec<String>>>,
    _entry: ash::Entry,
}

impl HostGpu {
    /// The first device with a graphics + compute family and the two
    /// features; `validation` loads the layer with synchronization
    /// validation and a messenger.
    pub fn new(validation: bool) -> Result<Self, String> {
        // SAFETY: loads the system's Vulkan loader.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| format!("no Vulkan loader: {e}"))?;
        let app = vk::ApplicationInfo::default()
            .application_name(c"izb embed_host")
            .api_version(vk::API_VERSION_1_2);
        let layers = [VALIDATION_LAYER.as_ptr()];
        let extensions = [
            ash::ext::debug_utils::NAME.as_ptr(),
            ash::ext::validation_features::NAME.as_ptr(),
        ];
        let enabled = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        let mut features =
            vk::ValidationFeaturesEXT::default().enabled_validation_features(&enabled);
        let mut info = vk::InstanceCreateInfo::default().application_info(&app);
        if validation {
            info = info
                .enabled_layer_names(&layers)
                .enabled_extension_names(&extensions)
                .push_next(&mut features);
        }
        // SAFETY: `info` and what it points to outlive the call.
        let instance = unsafe { entry.create_instance(&info, None) }
            .map_err(|e| format!("vkCreateInstance: {e}"))?;
        let messages = Box::new(Mutex::new(Vec::new()));
        let debug = if !validation {
            None
        } else {
            let debug = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
                .message_severity(
                    vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                        | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
                )
                .message_type(
                    vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                        | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                        | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
                )
                .pfn_user_callback(Some(keep_message))
                .user_data(&*messages as *const Mutex<Vec<String>> as *mut c_void);
            // SAFETY: the user data is boxed and freed after the messenger.
            let messenger = unsafe { debug.create_debug_utils_messenger(&info, None) }
                .map_err(|e| format!("vkCreateDebugUtilsMessengerEXT: {e}"))?;
            Some((debug, messenger))
        };
        // SAFETY: `instance` is live.
        let physicals = unsafe { instance.enumerate_physical_devices() }
            .map_err(|e| format!("vkEnumeratePhysicalDevices: {e}"))?;
        let wanted = vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE;
        let chosen = physicals.iter().find_map(|&p| {
            // SAFETY: `p` comes from the live instance.
            let features = unsafe { instance.get_physical_device_features(p) };
            // SAFETY: as above.
            let families = unsafe { instance.get_physical_device_queue_family_properties(p) };
            let family = families
                .iter()
                .position(|f| f.queue_flags.contains(wanted))?;
            // The lit fraction is an R16_UNORM storage image.
            // SAFETY: as above.
            let lit =
                unsafe { instance.get_physical_device_format_properties(p, vk::Format::R16_UNORM) };
            let storage = vk::FormatFeatureFlags::STORAGE_IMAGE;
            let ok = features.geometry_shader == vk::TRUE
                && lit.optimal_tiling_features.contains(storage);
            ok.then_some((p, family as u32))
        });
        let (physical, family) = chosen.ok_or(
            "no device with graphics + compute, geometryShader and R16_UNORM storage images",
        )?;
        let priorities = [1.0];
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family)
            .queue_priorities(&priorities)];
        let features = vk::PhysicalDeviceFeatures::default().geometry_shader(true);
        let mut f12 = vk::PhysicalDeviceVulkan12Features::default().scalar_block_layout(true);
        let info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queues)
            .enabled_features(&features)
            .push_next(&mut f12);
        // SAFETY: `physical` comes from `instance`; `info` outlives the call.
        let device = unsafe { instance.create_device(physical, &info, None) }
            .map_err(|e| format!("vkCreateDevice: {e}"))?;
        // SAFETY: the device has one queue of `family`.
        let queue = unsafe { device.get_device_queue(family, 0) };
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        })
        .map_err(|e| format!("allocator: {e}"))?;
        // SAFETY: as above.
        let props = unsafe { instance.get_physical_device_properties(physical) };
        let name = props
            .device_name_as_c_str()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        Ok(HostGpu {
            device,
            physical,
            family,
            queue: Arc::new(Mutex::new(queue)),
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            instance,
            name,
            debug,
            messages,
            _entry: entry,
        })
    }

    /// What izb's context is made on.
    pub fn host_device(&self) -> HostDevice {
        HostDevice {
            instance: self.instance.clone(),
            device: self.device.clone(),
            physical_device: self.physical,
            queue_family: self.family,
            queue: self.queue.clone(),
        }
    }

    /// Records `record` into a fresh primary command buffer of `pool`,
    /// submits it under the queue's lock and waits for it: the host's
    /// checks outside its measured frames (read-backs).
    ///
    /// # Safety
    /// `pool` is this device's, used by this thread only; what `record`
    /// records is valid on this device, and the objects it uses outlive
    /// the call (which waits).
    pub unsafe fn submit_once(
        &self,
        pool: vk::CommandPool,
        record: impl FnOnce(vk::CommandBuffer),
    ) {
        let d = &self.device;
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the caller's promise; the fence and command buffer are
        // freed after the wait.
        unsafe {
            let cmd = d
                .allocate_command_buffers(&alloc)
                .expect("a command buffer")[0];
            d.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default())
                .unwrap();
            record(cmd);
            d.end_command_buffer(cmd).unwrap();
            let fence = d
                .create_fence(&vk::FenceCreateInfo::default(), None)
                .unwrap();
            let submit = [vk::SubmitInfo::default().command_buffers(std::slice::from_ref(&cmd))];
            let queue = self.queue.lock().unwrap();
            d.queue_submit(*queue, &submit, fence).unwrap();
            drop(queue);
            d.wait_for_fences(&[fence], true, u64::MAX).unwrap();
            d.destroy_fence(fence, None);
            d.free_command_buffers(pool, &[cmd]);
        }
    }

    /// The validation messages since the last call.
    pub fn take_messages(&self) -> Vec<String> {
        std::mem::take(&mut *self.messages.lock().unwrap_or_else(|e| e.into_inner()))
    }

    /// Memory for `requirements` in `location`.
    pub fn allocate(
        &self,
        name: &str,
        requirements: vk::MemoryRequirements,
        location: MemoryLocation,
        linear: bool,
    ) -> Allocation {
        self.allocator
            .lock()
            .unwrap()
            .allocate(&AllocationCreateDesc {
                name,
                requirements,
                location,
                linear,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .expect("host memory")
    }

    /// Returns `allocation` to the allocator.
    pub fn free(&self, allocation: Allocation) {
        let _ = self.allocator.lock().unwrap().free(allocation);
    }
}

impl Drop for HostGpu {
    fn drop(&mut self) {
        // SAFETY: everything made on the device (the host's resources and
        // izb's pass and context) was dropped before (field and call
        // order in `frames::run`); after the idle wait nothing executes.
        unsafe {
            let _ = self.device.device_wait_idle();
            ManuallyDrop::drop(&mut self.allocator);
            self.device.destroy_device(None);
            if let Some((debug, messenger)) = &self.debug {
                debug.destroy_debug_utils_messenger(*messenger, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

/// The messenger's callback: keeps the message.
///
/// # Safety
/// Called by the loader with valid `data` and the boxed list as
/// `user_data`.
unsafe extern "system" fn keep_message(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user_data: *mut c_void,
) -> vk::Bool32 {
    if data.is_null() || user_data.is_null() {
        return vk::FALSE;
    }
    // SAFETY: valid for the call (the loader), checked non-null.
    let message = unsafe { (*data).message_as_c_str() }
        .map(|m| m.to_string_lossy().into_owned())
        .unwrap_or_default();
    // SAFETY: `user_data` is `HostGpu::messages`, alive while the
    // messenger is.
    let messages = unsafe { &*(user_data as *const Mutex<Vec<String>>) };
    messages
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(format!("[{severity:?}] {message}"));
    vk::FALSE
}
