//! Evaluate's heavy step on Vulkan against the CPU twin, sample by sample
//! (paper-notes/gpu-backend.md, "Where a GPU frame's time went"): with a
//! low threshold many pixels hand their candidates to a workgroup that
//! splits them over its threads and ORs the masks, and the masks must be
//! the CPU's all the same — hard shadows in the LUT and exact modes, and
//! an area light's LUT and paired modes. Each case must have queued
//! pixels (else it compared nothing new). The CPU's G-buffer is uploaded,
//! so the passes see the twin's very input; on lavapipe no sample may
//! differ beyond the LUT's `atan` rounding, on a GPU the allowance of
//! `tests/gpu_backend.rs`.
//!
//! No Vulkan device: the test prints that it skipped — unless
//! `IZB_REQUIRE_GPU=1` (CI), where that fails. It fails on any
//! validation-layer message (`IZB_VALIDATION=1` turns the layer on).

mod common;

use common::gpu::{assert_mismatch_within, own_renderer, render_uploaded};
use izb::bvh::SceneBvh;
use izb::cpu::SampleMode;
use izb::gpu::{GpuOptions, GpuRenderer};
use izb::scene::Scene;

const RESOLUTION: [u32; 2] = [128, 72];

/// Low enough that the dense scenes queue pixels at this resolution,
/// high enough to keep most in the tile step (both steps are compared).
const HEAVY_ENTRIES: u32 = 24;

/// Compares `modes` on `scene`; returns how many it compared.
fn check(r: &GpuRenderer, scene: Scene, modes: &[SampleMode]) -> usize {
    let scene = scene.with_resolution(RESOLUTION).unwrap();
    let bvh = SceneBvh::build(&scene);
    let on_cpu = r.context.info().is_cpu();
    let mut compared = 0;
    for &mode in modes {
        // The LUT's row comes from atan2, which neither libm nor lavapipe
        // rounds correctly: hairball at this resolution has one sample of
        // 163 744 in the next row, with the heavy step off as well
        // (gpu_soft_shadows.rs saw 1 light sample in 332 416). Every other
        // mode is bit for bit on lavapipe.
        let allowed = match (on_cpu, mode) {
            (true, SampleMode::Lut32) => 1e-5,
            (true, _) => 0.0,
            (false, _) => 1e-4,
        };
        let (cpu, gpu, diff, total) = render_uploaded(r, &scene, &bvh, mode);
        let heavy = gpu.report.counters.heavy_pixels;
        println!(
            "{} {mode:?}: {heavy} pixels in the heavy step, {diff} of {total} samples differ; \
             tests GPU {} CPU {}",
            scene.name, gpu.report.counters.tests_spawned, cpu.report.evaluate.tests_spawned
        );
        assert!(
            heavy > 0,
            "{} {mode:?}: no pixel reached the heavy step",
            scene.name
        );
        assert_mismatch_within(diff, total, allowed, &format!("{} {mode:?}", scene.name));
        compared += 1;
    }
    compared
}

#[test]
fn heavy_step_masks_equal_the_cpu_twin() {
    let options = GpuOptions {
        heavy_entries: Some(HEAVY_ENTRIES),
        ..GpuOptions::from_env()
    };
    let Some(r) = own_renderer(&options) else {
        return;
    };
    let hard = [SampleMode::Lut32, SampleMode::Exact32];
    let mut compared = 0;
    for name in ["hairball", "wires", "grazing"] {
        compared += check(&r, izb::scene::load(name).unwrap(), &hard);
    }
    let mut shared = 0;
    for name in ["tablefan", "ficus"] {
        if let Some(scene) = common::shared_scene(name) {
            compared += check(&r, scene, &hard);
            shared += 1;
        }
    }
    // An area light: the light-sample test and the paired rays, split
    // (Paired64: both mask halves, each with its own heavy queue).
    let soft = izb::scene::load("hairball")
        .unwrap()
        .with_light_size(2.0)
        .unwrap();
    let soft_modes = [
        SampleMode::Lut32,
        SampleMode::Paired32,
        SampleMode::Paired64,
    ];
    compared += check(&r, soft, &soft_modes);
    assert_eq!(compared, 2 * (3 + shared) + 3, "cases compared");
}
