//! `izb view`: an interactive window on the real passes. Drag to orbit,
//! right-drag (or the arrow keys) to turn the light, pick methods and
//! views, split the screen between two methods, read the pass times, work
//! counters, memory and the error against a progressive ray-traced truth.
//!
//! Three threads keep the window responsive: the window thread draws egui
//! on its own Vulkan device (`present`); the shadow worker ([`worker`])
//! renders the newest request through the compute passes on the compute
//! device; the truth thread ([`truth`]) traces the reference while the
//! view is still. A shadow frame that takes seconds (lavapipe) never
//! holds a UI frame. `--script` drives the same window from a file of
//! timed actions ([`script`]) for tests and screenshots.

pub mod app;
pub mod images;
mod present;
pub mod resident;
pub mod screenshot;
pub mod script;
pub mod state;
mod swapchain;
pub mod truth;
pub mod ui;
pub mod worker;

use crate::gpu::{list_devices, GpuOptions};
use crate::scene::Scene;
use anyhow::{anyhow, bail, Result};
use std::path::PathBuf;

/// How to run the viewer.
pub struct ViewOptions {
    pub scene: Scene,
    /// Scripted actions; empty: interactive.
    pub script: Vec<script::Action>,
    pub gpu: GpuOptions,
    /// Inner window size in pixels.
    pub window_size: [u32; 2],
    /// Where the screenshot key writes (`view-<unix seconds>/`).
    pub out: PathBuf,
    /// Threads tracing the progressive truth.
    pub truth_threads: usize,
}

/// What a session measured: UI frame times (the responsiveness target is
/// ≤ 50 ms while a shadow frame computes), shadow frame times, the
/// screenshots written, errors shown and validation messages.
#[derive(Default, serde::Serialize)]
pub struct ViewStats {
    pub ui_frames: usize,
    pub ui_millis_max: f64,
    pub ui_millis_mean: f64,
    /// UI frames drawn while a shadow frame was computing.
    pub ui_frames_while_computing: usize,
    pub ui_millis_max_while_computing: f64,
    /// The slowest 1 % of UI frames drawn while computing start here.
    pub ui_millis_p99_while_computing: f64,
    #[serde(skip)]
    computing_millis: Vec<f64>,
    /// Worker wall seconds of each shadow frame shown.
    pub frame_seconds: Vec<f64>,
    /// Host work of each shadow frame shown, in milliseconds: the CPU
    /// time of the worker thread (recording, read-back, conversion; not
    /// the time it waited for the device) plus the window thread's time to
    /// make the view's scene and send the request.
    pub shadow_host_millis: Vec<f64>,
    /// IZB frames recorded into a resident pass made by an earlier frame
    /// (parameters and commands only), and passes made.
    pub resident_frames: usize,
    pub passes_made: usize,
    pub screenshots: Vec<PathBuf>,
    pub errors: Vec<String>,
    pub validation_messages: Vec<String>,
}

impl ViewStats {
    pub fn record_ui_frame(&mut self, millis: f64, computing: bool) {
        let n = self.ui_frames as f64;
        self.ui_millis_mean = (self.ui_millis_mean * n + millis) / (n + 1.0);
        self.ui_frames += 1;
        self.ui_millis_max = self.ui_millis_max.max(millis);
        if computing {
            self.ui_frames_while_computing += 1;
            self.ui_millis_max_while_computing = self.ui_millis_max_while_computing.max(millis);
            self.computing_millis.push(millis);
        }
    }

    fn finish(&mut self) {
        let mut v = self.computing_millis.clone();
        v.sort_by(f64::total_cmp);
        if !v.is_empty() {
            self.ui_millis_p99_while_computing = v[(v.len() * 99 / 100).min(v.len() - 1)];
        }
    }
}

/// Opens the window and runs until it closes (or the script quits).
pub fn run_view(options: ViewOptions) -> Result<ViewStats> {
    // The shadow passes need a compute device: say so before a window opens.
    match list_devices() {
        Ok(list) if !list.is_empty() => {}
        Ok(_) => bail!(
            "izb view needs a Vulkan device with compute (none found; `izb devices` lists them, \
             `izb render --backend cpu` renders without one)"
        ),
        Err(e) => bail!("izb view needs a Vulkan device: {e}"),
    }
    let event_loop = winit::event_loop::EventLoop::<app::Wake>::with_user_event()
        .build()
        .map_err(|e| {
            anyhow!(
                "cannot reach a display ({e}): izb view needs a window; set DISPLAY, or run it \
                 under `xvfb-run -a`"
            )
        })?;
    let proxy = event_loop.create_proxy();
    let wake = move || {
        // A closed loop needs no waking.
        let _ = proxy.send_event(app::Wake);
    };
    let worker = worker::ShadowWorker::start(options.gpu.clone(), wake.clone());
    let truth = truth::TruthWorker::start(options.truth_threads, wake);
    let mut app = app::App::new(options, worker, truth);
    let ran = event_loop.run_app(&mut app);
    app.shut_down();
    app.stats.finish();
    if let Some(e) = app.error.take() {
        return Err(e);
    }
    ran.map_err(|e| anyhow!("the window's event loop failed: {e}"))?;
    Ok(std::mem::take(&mut app.stats))
}

/// Lowers the calling thread's CPU priority (nice 10) before it opens its
/// device or pool. On a CPU Vulkan device (lavapipe) the shadow passes
/// and the truth take every core; their threads inherit this priority, so
/// the window thread still gets a core when it wakes to draw. A no-op
/// where the call is refused.
pub(crate) fn lower_thread_priority() {
    // SAFETY: setpriority only reads its integer arguments; on Linux,
    // `who` 0 with PRIO_PROCESS names the calling thread.
    #[cfg(target_os = "linux")]
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, 0, 10);
    }
}
