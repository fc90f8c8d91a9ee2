//! The Vulkan loader and an instance of izb's own (with the validation
//! layer, and its synchronization validation, when asked for), and the
//! list of devices that can run the passes.

use super::context::DeviceInfo;
use super::context::VALIDATION_LAYER;
use super::device_candidates::candidates;
use super::GpuError;
use ash::vk;

pub(crate) fn load_entry() -> Result<ash::Entry, GpuError> {
    // SAFETY: loading the system's Vulkan loader runs its initialisers;
    // it is the library this crate is written against.
    unsafe { ash::Entry::load() }.map_err(|e| GpuError::NoVulkan(format!("no Vulkan loader ({e})")))
}

pub(super) fn create_instance(
    entry: &ash::Entry,
    validation: bool,
    sync_validation: bool,
) -> Result<ash::Instance, GpuError> {
    let app = vk::ApplicationInfo::default()
        .application_name(c"izb")
        .engine_name(c"izb")
        .api_version(vk::API_VERSION_1_2);
    let mut layers = Vec::new();
    let mut extensions = Vec::new();
    if validation {
        // SAFETY: `entry` is a loaded Vulkan entry.
        let available = unsafe { entry.enumerate_instance_layer_properties() }
            .map_err(GpuError::vk)?
            .iter()
            .any(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER));
        if !available {
            return Err(GpuError::NoVulkan(
                "IZB_VALIDATION=1 but VK_LAYER_KHRONOS_validation is not installed \
                 (Debian: apt install vulkan-validationlayers)"
                    .into(),
            ));
        }
        layers.push(VALIDATION_LAYER.as_ptr());
        extensions.push(ash::ext::debug_utils::NAME.as_ptr());
    }
    let enabled = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
    let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&enabled);
    let sync = validation && sync_validation;
    if sync {
        // Provided by the validation layer.
        extensions.push(ash::ext::validation_features::NAME.as_ptr());
    }
    let mut info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(&layers)
        .enabled_extension_names(&extensions);
    if sync {
        info = info.push_next(&mut features);
    }
    // SAFETY: `info` and the name arrays it points to outlive the call.
    unsafe { entry.create_instance(&info, None) }.map_err(|e| {
        GpuError::NoVulkan(format!(
            "vkCreateInstance failed ({e}): no Vulkan 1.2 driver?"
        ))
    })
}

/// Lists the suitable devices, best first (the order `--device` indexes).
pub fn list_devices() -> Result<Vec<DeviceInfo>, GpuError> {
    let entry = load_entry()?;
    let instance = create_instance(&entry, false, false)?;
    let list = candidates(&instance).map(|c| c.into_iter().map(|c| c.info).collect());
    // SAFETY: nothing was created from this instance but the list.
    unsafe { instance.destroy_instance(None) };
    list
}
