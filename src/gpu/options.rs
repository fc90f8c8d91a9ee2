//! How a renderer opens its device and runs its frames: the options a
//! caller (or the environment) chooses.

use std::time::Duration;

/// How long one submission may run before it is reported as hung, unless
/// `IZB_GPU_TIMEOUT_S` says otherwise. Generous for lavapipe on 2 cores at
/// 960×540; a real GPU takes milliseconds.
pub const FRAME_TIMEOUT: Duration = Duration::from_secs(600);

/// [`FRAME_TIMEOUT`] or the `IZB_GPU_TIMEOUT_S` override.
pub fn frame_timeout() -> Duration {
    std::env::var("IZB_GPU_TIMEOUT_S")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .filter(|s| *s > 0.0 && s.is_finite())
        .map_or(FRAME_TIMEOUT, Duration::from_secs_f64)
}

/// How to pick and set up the device.
#[derive(Clone, Debug, Default)]
pub struct GpuOptions {
    /// Index into the list of suitable devices (`izb devices` order);
    /// `None`: the best-ranked one.
    pub device_index: Option<usize>,
    /// Enable `VK_LAYER_KHRONOS_validation` and collect its messages; the
    /// device fails to open if the layer is missing.
    pub validation: bool,
    /// With `validation`, its synchronization validation too
    /// (`VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT`:
    /// hazards between commands and submissions without a barrier).
    pub sync_validation: bool,
    /// Evaluate's heavy-step threshold (`FrameParams::heavy_entries`, 0:
    /// off); `None`: the device's default (`frame_inputs::heavy_entries`).
    pub heavy_entries: Option<u32>,
}

impl GpuOptions {
    /// Options from the environment: `IZB_VALIDATION=1` turns validation
    /// on, `IZB_SYNC_VALIDATION=1` its synchronization checks too; `IZB_GPU_HEAVY_ENTRIES=N` sets the heavy-step threshold.
    pub fn from_env() -> Self {
        GpuOptions {
            device_index: None,
            validation: std::env::var("IZB_VALIDATION").is_ok_and(|v| v == "1"),
            sync_validation: std::env::var("IZB_SYNC_VALIDATION").is_ok_and(|v| v == "1"),
            heavy_entries: std::env::var("IZB_GPU_HEAVY_ENTRIES")
                .ok()
                .and_then(|v| v.parse().ok()),
        }
    }
}
