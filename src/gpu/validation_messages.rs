//! The validation layer's messages: the messenger every device of the
//! crate creates (the compute context and the viewer's window) appends
//! them to a list its owner keeps alive longer than the messenger.

use ash::vk;
use std::ffi::c_void;
use std::sync::Mutex;

/// The validation messenger every device of the crate uses (the compute
/// context and the viewer's window): warnings and errors of every type,
/// appended to `messages` by [`debug_callback`]. `messages` must outlive
/// the messenger.
pub(crate) fn messenger_info(
    messages: &Mutex<Vec<String>>,
) -> vk::DebugUtilsMessengerCreateInfoEXT<'static> {
    vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(
            vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
        )
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(debug_callback))
        .user_data(messages as *const Mutex<Vec<String>> as *mut c_void)
}

/// The validation layer's message callback: appends to the messages list.
///
/// # Safety
/// Called by the Vulkan loader only, with `data` valid for the call and
/// `user_data` the messenger's `Mutex<Vec<String>>` (see `GpuContext::new`).
// SAFETY: only the loader calls it, with the arguments its signature
// promises (`# Safety` above); the body checks both pointers for null.
unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user_data: *mut c_void,
) -> vk::Bool32 {
    if data.is_null() || user_data.is_null() {
        return vk::FALSE;
    }
    // SAFETY: the loader passes valid callback data for the duration of
    // the call (checked non-null above).
    let message = unsafe { (*data).message_as_c_str() }
        .map(|m| m.to_string_lossy().into_owned())
        .unwrap_or_default();
    // SAFETY: `user_data` is the `Mutex` the messenger was created with,
    // owned by `DeviceShared` (boxed, so it does not move) and destroyed
    // after the messenger.
    let messages = unsafe { &*(user_data as *const Mutex<Vec<String>>) };
    messages
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(format!("[{severity:?} {kind:?}] {message}"));
    vk::FALSE
}
