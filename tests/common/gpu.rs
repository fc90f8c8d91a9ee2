//! The Vulkan renderer the GPU tests share: opened once per test binary
//! (tests run in parallel threads; one device is enough and lavapipe is
//! slow to open). Without a device the tests print that they skipped;
//! with `IZB_REQUIRE_GPU=1` they fail instead.

use izb::gpu::{GpuOptions, GpuRenderer};
use std::sync::{Mutex, MutexGuard, OnceLock};

/// The binary's renderer, or `None` (with a printed skip) without a
/// Vulkan device.
pub fn renderer() -> Option<&'static Mutex<GpuRenderer>> {
    static RENDERER: OnceLock<Result<Mutex<GpuRenderer>, String>> = OnceLock::new();
    match RENDERER.get_or_init(|| {
        GpuRenderer::new(&GpuOptions::from_env())
            .map(Mutex::new)
            .map_err(|e| e.to_string())
    }) {
        Ok(r) => Some(r),
        Err(e) => skip_without_gpu(e),
    }
}

/// A renderer of the test's own (not the binary's shared one), opened with
/// `options`, or `None` with a printed skip.
pub fn own_renderer(options: &GpuOptions) -> Option<GpuRenderer> {
    match GpuRenderer::new(options) {
        Ok(r) => Some(r),
        Err(e) => skip_without_gpu(e),
    }
}

/// Without a device: `None` and a printed skip, or a failure with
/// `IZB_REQUIRE_GPU=1` (CI).
fn skip_without_gpu<T>(e: impl std::fmt::Display) -> Option<T> {
    if std::env::var("IZB_REQUIRE_GPU").is_ok_and(|v| v == "1") {
        panic!("IZB_REQUIRE_GPU=1 but the Vulkan backend did not open: {e}");
    }
    eprintln!("skipped (no Vulkan device: {e})");
    None
}

/// Locks the renderer, through a poisoned lock (another test's panic).
pub fn lock(r: &'static Mutex<GpuRenderer>) -> MutexGuard<'static, GpuRenderer> {
    r.lock().unwrap_or_else(|e| e.into_inner())
}

/// Fails with every validation message since the last call.
pub fn assert_no_validation_messages(r: &GpuRenderer, what: &str) {
    let messages = r.take_validation_messages();
    assert!(
        messages.is_empty(),
        "{what}: {} validation message(s):\n{}",
        messages.join("\n").lines().count(),
        messages.join("\n")
    );
}
