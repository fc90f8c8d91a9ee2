//! GPU pass 3, `evaluate` (`shaders/evaluate.comp`): per shadow-tested
//! pixel, the frustum-triangle test (paper-notes/frustum-test.md) against every candidate of
//! the cells under its µQuad and the overflow list, in 8×8 tiles with
//! cooperative shared-memory batches ([Compute IZB]) — the twin of
//! [`crate::cpu::evaluate::evaluate`]. Sample mode (1, 32 LUT, 32 exact)
//! comes from `FrameParams::mode`; the LUT is the build-time table.
//!
//! Two steps: the tiles, then the heavy step, where a workgroup takes
//! each pixel whose cells list more than `FrameParams::heavy_entries`
//! candidates (the tile step queued it). Only how the work is split
//! differs from the CPU twin: a mask is the OR of its candidates' masks
//! in any order.

use super::{Kernels, Recorder};

/// Workgroups of the heavy step on a GPU; each takes every n-th queued
/// pixel. About what an H200 keeps resident (132 multiprocessors, 8
/// workgroups of 256 each); idle ones cost nothing there.
const HEAVY_WORKGROUPS_GPU: u32 = 1024;

/// Workgroups of the heavy step on `device`: on a CPU implementation
/// (lavapipe) one per core, since each of its workgroups runs its 256
/// invocations in turn, queue or not (1 024 took 4 s at 160×90).
pub fn heavy_workgroups(device: &super::context::DeviceInfo) -> u32 {
    if device.is_cpu() {
        std::thread::available_parallelism().map_or(1, |n| n.get() as u32)
    } else {
        HEAVY_WORKGROUPS_GPU
    }
}

/// `evaluate`'s `heavy` argument for a frame of `params` on `device`:
/// the queue's length and the workgroups, or `None` when the step is off.
pub fn heavy_step(
    params: &super::shared::FrameParams,
    device: &super::context::DeviceInfo,
) -> Option<(u32, u32)> {
    (params.heavy_entries != 0).then(|| (params.heavy_capacity, heavy_workgroups(device)))
}

/// Records the pass; `heavy`: (the heavy step's queue length,
/// `FrameParams::heavy_capacity`, and its workgroups) when the step runs;
/// `halves`: 2 for `MODE_PAIRED64` under an area light. The second half
/// (`B_MASKS_HIGH`) runs first: both halves read the pixel's cascade from
/// its `B_MASKS` word, which the first half then overwrites.
pub fn evaluate(
    rec: &Recorder,
    kernels: &Kernels,
    size: [u32; 2],
    heavy: Option<(u32, u32)>,
    halves: usize,
) {
    rec.begin_label("evaluate");
    let steps = [
        (&kernels.evaluate_high, &kernels.evaluate_heavy_high),
        (&kernels.evaluate, &kernels.evaluate_heavy),
    ];
    for (tiles, heavy_step) in &steps[2 - halves.clamp(1, 2)..] {
        rec.dispatch_pixels(tiles, size);
        rec.barrier();
        if let Some((capacity, workgroups)) = heavy {
            rec.dispatch(heavy_step, [capacity.clamp(1, workgroups.max(1)), 1, 1]);
            rec.barrier();
        }
    }
    rec.end_label();
}
