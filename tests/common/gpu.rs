//! The Vulkan renderer the GPU tests share: opened once per test binary
//! (tests run in parallel threads; one device is enough and lavapipe is
//! slow to open). Without a device the tests print that they skipped;
//! with `IZB_REQUIRE_GPU=1` they fail instead.

use izb::bvh::SceneBvh;
use izb::cpu::{render_cpu, IzbSettings, SampleMode, ShadowRender};
use izb::gbuffer::flags;
use izb::gpu::{GBufferSource, GpuOptions, GpuRender, GpuRenderer};
use izb::scene::Scene;
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

/// One frame of `scene` on the CPU twin and on `r` from the CPU's
/// G-buffer (so every GPU pass after it sees the twin's very input), with
/// no validation message: both renders and (differing, compared) samples
/// over the shadow-tested pixels.
pub fn render_uploaded(
    r: &GpuRenderer,
    scene: &Scene,
    bvh: &SceneBvh,
    mode: SampleMode,
) -> (ShadowRender, GpuRender, u64, u64) {
    let settings = IzbSettings {
        mode,
        ..Default::default()
    };
    let cpu = render_cpu(scene, bvh, settings);
    let gpu = r
        .render(scene, settings, GBufferSource::Upload(&cpu.gbuffer))
        .unwrap_or_else(|e| panic!("{} {mode:?}: {e}", scene.name));
    assert_no_validation_messages(r, &scene.name);
    let tested = |i: usize| cpu.gbuffer.flags[i] & flags::SHADOW_TESTED != 0;
    let (mut diff, mut total) = izb::metrics::sample_mismatches(&gpu.masks, &cpu.masks, tested);
    // Paired64's bits 32–63, when the CPU twin formed them.
    assert_eq!(
        gpu.masks_high.len(),
        cpu.masks_high.len(),
        "{} {mode:?}: the second mask half",
        scene.name
    );
    if !cpu.masks_high.is_empty() {
        let (d, t) = izb::metrics::sample_mismatches(&gpu.masks_high, &cpu.masks_high, tested);
        (diff, total) = (diff + d, total + t);
    }
    (cpu, gpu, diff, total)
}

/// Fails when more than `allowed` of `total` samples differ (`diff`).
pub fn assert_mismatch_within(diff: u64, total: u64, allowed: f64, what: &str) {
    let rate = diff as f64 / total.max(1) as f64;
    assert!(
        rate <= allowed,
        "{what}: {diff} of {total} samples differ ({rate:.2e} > {allowed:.0e})"
    );
}
