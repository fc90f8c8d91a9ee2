//! What a run of the host is asked to do, and what it measured.

use crate::first_frame::{MultisampledCheck, TwinComparison};
use crate::gpu_timing::GpuMillis;
use crate::lighting::LightingComparison;
use crate::targets::HostDepth;
use izb::cpu::SampleMode;
use izb::gpu::context::HostCounts;
use izb::gpu::shadow_pass::{FrameView, PassFrame};

/// What a run is asked to do.
#[derive(Clone, Copy, Debug)]
pub struct HostOptions {
    pub frames: usize,
    pub frames_in_flight: usize,
    pub mode: SampleMode,
    /// Entries of the pass's cell list (`None`: its default).
    pub cell_capacity: Option<u64>,
    /// Evaluate's heavy-step threshold (`None`: the device's default).
    pub heavy_entries: Option<u32>,
    /// Before frame `.0`, the image becomes `.1` (a resized window).
    pub resize: Option<(usize, [u32; 2])>,
    /// The G-buffer the pass reads: the host's depth and normal in this
    /// format and convention, or (`None`) its visibility buffer.
    pub depth: Option<HostDepth>,
    /// Samples a pixel of the host's visibility buffer and depth (`--msaa
    /// N`; 1: single-sampled). Above 1 the pass reads the visibility
    /// buffer unresolved (`GBufferInput::MultisampledVisibility`), with
    /// edge pixels' surfaces from its samples.
    pub msaa: u32,
    /// Wait for frame 0 before recording frame 1, read its G-buffer and
    /// images back and run the CPU twin on them ([`HostRun::first_frame`]).
    pub check_first_frame: bool,
}

/// What a run measured, and its last frame read back after the loop.
#[derive(Debug, serde::Serialize)]
pub struct HostRun {
    pub scene: String,
    pub device: String,
    pub resolution: [u32; 2],
    pub triangles: usize,
    pub frames: usize,
    pub frames_in_flight: usize,
    /// Samples a pixel of the host's visibility buffer.
    pub msaa: u32,
    /// With `msaa` above 1: frame 0's centres, pass against the CPU twin
    /// fed the same samples.
    pub first_frame_multisampled: Option<MultisampledCheck>,
    /// izb's buffers and descriptor sets made inside `record` after the
    /// first frame (growth and resizes happen between frames).
    pub allocations_after_first_frame: [u64; 2],
    /// Times `ShadowPass::grow` made a larger cell list.
    pub grown: usize,
    /// izb's buffers and descriptor sets `ShadowPass::resize` made.
    pub resize_allocations: [u64; 2],
    /// `ShadowPass::record`'s host time per frame, µs.
    pub record_us: Vec<f64>,
    /// The CPU time `record` took on the host's thread per frame, µs
    /// (`CLOCK_THREAD_CPUTIME_ID`): its cost without the time the thread
    /// was not running — on lavapipe, the device's worker threads run the
    /// previous frame on the same cores and take it off the CPU.
    pub record_cpu_us: Vec<f64>,
    /// The host's time from the command buffer's begin to its submit,
    /// per frame, µs.
    pub frame_cpu_us: Vec<f64>,
    /// `record`'s host time with the device idle, µs: the last frame
    /// recorded again `RECORD_ALONE` times into a command buffer that is
    /// never submitted. On lavapipe the loop's own `record_us` also pays
    /// for the device's worker threads running the previous frame on the
    /// same cores.
    pub record_alone_us: Vec<f64>,
    /// `record`'s host time with the device idle and this core's caches
    /// swept before each recording, µs: what the loop's `record_us`
    /// pays on lavapipe, whose shader work between two recordings
    /// evicts `record`'s code and data.
    pub record_cold_us: Vec<f64>,
    /// Frames whose status said the cell list overran (the pass grew
    /// before the slot's next frame).
    pub overruns: usize,
    /// Frames a shader stopped at lavapipe's loop cap in (their masks
    /// are cut short), with the trips.
    pub loop_capped_frames: Vec<(usize, u32)>,
    pub validation_messages: Vec<String>,
    /// With a depth + normal G-buffer: the pass's G-buffer of the last
    /// frame read back and fed to the CPU twin (`render_cpu_on`) — of its
    /// pixels, how many masks equal the pass's, and how many there are.
    pub twin_masks_equal: Option<[usize; 2]>,
    /// What izb did on the host inside `record` in the frames after the
    /// first: buffers, descriptor sets and mappings made, submissions
    /// waited for (every read-back is one).
    pub in_frames_after_first: HostCounts,
    /// The host's GPU time per pass, milliseconds, median over the frames
    /// (timestamps; `None` where the queue has none).
    pub gpu_ms: Option<GpuMillis>,
    /// With `check_first_frame`: the CPU twin on frame 0's G-buffer.
    pub first_frame: Option<TwinComparison>,
    /// With `check_first_frame`: the host's lighting of frame 0 against
    /// izb's own shaded image of it.
    pub first_frame_lighting: Option<LightingComparison>,
    /// izb's own per-pass times of each frame whose status was read.
    #[serde(skip)]
    pub pass_millis: Vec<izb::settings::PassTimes>,
    /// With `check_first_frame`: frame 0's images, and its view.
    #[serde(skip)]
    pub first_frame_images: Option<(PassFrame, FrameView)>,
    /// With `check_first_frame`: the host's lighting of frame 0 (RGBA8
    /// words).
    #[serde(skip)]
    pub first_frame_host_shaded: Vec<u32>,
    /// The last frame's view (not serialised).
    #[serde(skip)]
    pub last_view: Option<FrameView>,
    /// The last frame's visibility buffer and masks, read back after the
    /// loop.
    #[serde(skip)]
    pub last_ids: Vec<u32>,
    #[serde(skip)]
    pub last_masks: Vec<u32>,
}
