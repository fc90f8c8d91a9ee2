//! The shadow worker: a thread that owns the compute device
//! ([`GpuRenderer`]) and renders the newest requested frame through the
//! real passes, while the window thread keeps presenting. Older requests
//! that piled up while a frame ran are dropped unrendered.
//!
//! Failures become messages the window shows: a lost device is reopened
//! for the next frame; a frame lavapipe's loop cap refuses is rendered by
//! the CPU twin instead (as `izb render --backend auto` does), and says so.

use super::resident::ResidentPasses;
use super::state::method_kind;
use crate::bench::MethodKind;
use crate::bvh::SceneBvh;
use crate::cpu::{candidate_counts, render_cpu, IzbSettings};
use crate::gbuffer::{gbuffer, GBuffer};
use crate::gpu::frame_report::GpuShadowMapRender;
use crate::gpu::{GBufferSource, GpuError, GpuOptions, GpuRenderer};
use crate::output::shade_pixel;
use crate::scene::Scene;
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Instant;

/// One frame to render.
pub struct FrameRequest {
    pub generation: u64,
    pub scene: Arc<Scene>,
    /// Left (or only) method first.
    pub methods: Vec<String>,
    /// Also count candidates per pixel (the heat map view).
    pub candidates: bool,
}

/// One method's image of a frame.
pub struct MethodFrame {
    pub name: String,
    /// Set for IZB methods (the magnifier's sample layout).
    pub izb: Option<IzbSettings>,
    pub visibility: Vec<f32>,
    /// The 32-bit masks of IZB methods, empty for shadow maps.
    pub masks: Vec<u32>,
    pub masks_high: Vec<u32>,
    pub shaded: Vec<[u8; 3]>,
    /// `vulkan` or `cpu`, with the reason when the CPU twin stood in.
    pub backend: String,
    /// Per pass: name and GPU milliseconds (CPU seconds × 1000 on the CPU).
    pub pass_millis: Vec<(&'static str, f64)>,
    /// Tests per shadow-tested pixel (IZB methods).
    pub tests_per_pixel: Option<f64>,
    pub memory_bytes: u64,
    /// The method's report, as `render` writes it in `report.json`.
    pub report: serde_json::Value,
    /// IZB methods on the GPU: the frame was recorded into the method's
    /// resident pass (`Some(true)` when it made the pass first).
    pub made_pass: Option<bool>,
}

/// What the worker sends back for a request.
pub struct FrameResult {
    pub generation: u64,
    pub scene: Arc<Scene>,
    pub frames: Vec<MethodFrame>,
    pub candidates: Option<Vec<u32>>,
    /// Why the frame (or one of its methods) is missing.
    pub errors: Vec<String>,
    /// The compute device's validation messages during this frame.
    pub validation: Vec<String>,
    pub wall_seconds: f64,
    /// CPU seconds the worker thread ran for the frame's methods (its
    /// host work: recording, read-back, conversion), not the seconds it
    /// waited for the device.
    pub host_cpu_seconds: f64,
}

/// The worker thread's handle.
pub struct ShadowWorker {
    requests: Option<Sender<FrameRequest>>,
    pub results: Receiver<FrameResult>,
    thread: Option<JoinHandle<()>>,
    pub device_name: Arc<std::sync::Mutex<String>>,
}

impl ShadowWorker {
    /// Starts the thread; `wake` is called after each result (it wakes the
    /// window's event loop).
    pub fn start(options: GpuOptions, wake: impl Fn() + Send + 'static) -> ShadowWorker {
        let (requests, inbox) = channel::<FrameRequest>();
        let (outbox, results) = channel();
        let device_name = Arc::new(std::sync::Mutex::new(String::from("(opening)")));
        let name = device_name.clone();
        let thread = std::thread::Builder::new()
            .name("izb-view-shadows".into())
            .spawn(move || run(options, inbox, outbox, wake, name))
            .expect("spawning a thread");
        ShadowWorker {
            requests: Some(requests),
            results,
            thread: Some(thread),
            device_name,
        }
    }

    pub fn request(&self, r: FrameRequest) {
        if let Some(tx) = &self.requests {
            // A closed channel means the thread ended; the window shows
            // the missing frames' absence, nothing to do here.
            let _ = tx.send(r);
        }
    }

    /// Stops the thread once its current frame ends, waiting at most
    /// `patience`: a frame lavapipe needs minutes for is left to the
    /// process's exit rather than holding the closed window.
    pub fn stop(mut self, patience: std::time::Duration) {
        self.requests = None;
        let Some(thread) = self.thread.take() else {
            return;
        };
        let start = Instant::now();
        while !thread.is_finished() && start.elapsed() < patience {
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        if thread.is_finished() {
            // A panic in the worker already printed itself.
            let _ = thread.join();
        }
    }
}

fn run(
    options: GpuOptions,
    inbox: Receiver<FrameRequest>,
    outbox: Sender<FrameResult>,
    wake: impl Fn(),
    device_name: Arc<std::sync::Mutex<String>>,
) {
    super::lower_thread_priority();
    let mut next = inbox.recv().ok();
    while let Some(request) = next.take() {
        // One device for as long as it lives; a failure to open it, or
        // its loss, is the frame's message, and the next request opens
        // it anew.
        match GpuRenderer::new(&options) {
            Ok(r) => {
                *device_name.lock().unwrap_or_else(|e| e.into_inner()) =
                    format!("{} ({})", r.context.info().name, r.context.info().kind);
                next = serve(&r, request, &inbox, &outbox, &wake);
            }
            Err(e) => {
                let error = format!("compute device: {e}");
                if !send(&outbox, &wake, frame(None, request, &inbox, vec![error])) {
                    return;
                }
                next = inbox.recv().ok();
            }
        }
    }
}

/// Renders requests on `r`, keeping its IZB passes resident, until the
/// device is lost (then returns the next request, for a new device) or
/// the window's side closed (`None`).
fn serve(
    r: &GpuRenderer,
    first: FrameRequest,
    inbox: &Receiver<FrameRequest>,
    outbox: &Sender<FrameResult>,
    wake: &impl Fn(),
) -> Option<FrameRequest> {
    let mut passes = ResidentPasses::new(r);
    let mut request = first;
    loop {
        passes.retain(&request.methods);
        let result = frame(Some((r, &mut passes)), request, inbox, Vec::new());
        if !send(outbox, wake, result) {
            return None;
        }
        if r.context.shared.is_poisoned() {
            return inbox.recv().ok();
        }
        request = inbox.recv().ok()?;
    }
}

/// Sends `result` and wakes the window; false once the window's side is
/// gone.
fn send(outbox: &Sender<FrameResult>, wake: &impl Fn(), result: FrameResult) -> bool {
    let sent = outbox.send(result).is_ok();
    if sent {
        wake();
    }
    sent
}

/// The newest of `request` and those queued behind it, rendered on
/// `device` (none: only `errors` and the candidates).
fn frame(
    device: Option<(&GpuRenderer, &mut ResidentPasses)>,
    mut request: FrameRequest,
    inbox: &Receiver<FrameRequest>,
    mut errors: Vec<String>,
) -> FrameResult {
    while let Ok(newer) = inbox.try_recv() {
        request = newer;
    }
    let start = Instant::now();
    let cpu_start = crate::thread_time::thread_cpu_seconds();
    let mut frames = Vec::new();
    let mut validation = Vec::new();
    if let Some((r, passes)) = device {
        for name in &request.methods {
            match render_method(r, passes, &request.scene, name) {
                Ok(f) => frames.push(f),
                Err(e) => errors.push(format!("{name}: {e:#}")),
            }
        }
        validation.extend(r.take_validation_messages());
        if r.context.shared.is_poisoned() {
            errors.push("the compute device was lost; it is reopened for the next frame".into());
        }
    }
    let host_cpu_seconds = crate::thread_time::thread_cpu_seconds() - cpu_start;
    let candidates = request.candidates.then(|| {
        let bvh = SceneBvh::build(&request.scene);
        let settings = frames.first().and_then(|f| f.izb).unwrap_or_default();
        candidate_counts(&request.scene, &bvh, settings)
    });
    FrameResult {
        generation: request.generation,
        scene: request.scene,
        frames,
        candidates,
        errors,
        validation,
        wall_seconds: start.elapsed().as_secs_f64(),
        host_cpu_seconds,
    }
}

/// Renders one method on the GPU, or on the CPU twin when lavapipe's
/// loop cap refuses the frame.
fn render_method(
    r: &GpuRenderer,
    passes: &mut ResidentPasses,
    scene: &Scene,
    name: &str,
) -> anyhow::Result<MethodFrame> {
    let kind = method_kind(name).map_err(anyhow::Error::msg)?;
    let device = format!("vulkan: {}", r.context.info().name);
    let light = scene.light.relative_to(scene.camera.eye);
    let shade = |g: &GBuffer, v: &[f32]| -> Vec<[u8; 3]> {
        (0..v.len())
            .map(|i| shade_pixel(g, i, &light, v[i]))
            .collect()
    };
    match kind {
        MethodKind::Izb(settings) => match passes.render(scene, name, settings) {
            Ok(out) => {
                let f = out.frame;
                let report = serde_json::json!({
                    "method": name,
                    "device": r.context.info().name,
                    "settings": settings,
                    "resident_pass": {
                        "made_pass": out.made_pass,
                        "grown": out.grown,
                        "record_microseconds": out.record_seconds * 1e6,
                        "device_milliseconds": out.device_seconds * 1e3,
                        "gpu_milliseconds": out.gpu_millis,
                        "cell_entries": out.status.cell_entries,
                        "edge_slots_needed": out.status.edge_slots_needed,
                    },
                    "counters": {
                        "shadow_tested": out.status.shadow_tested,
                        "pixels_tested": out.status.pixels_tested,
                        "tests_spawned": out.status.tests_spawned,
                    },
                });
                Ok(MethodFrame {
                    name: name.into(),
                    izb: Some(settings),
                    tests_per_pixel: Some(
                        out.status.tests_spawned as f64
                            / f64::from(out.status.pixels_tested.max(1)),
                    ),
                    memory_bytes: out.memory_bytes,
                    report,
                    pass_millis: match &out.gpu_millis {
                        Some(m) => vec![
                            ("gbuffer", m.gbuffer),
                            ("light setup", m.light_setup),
                            ("bin", m.bin),
                            ("evaluate", m.evaluate),
                            ("resolve", m.resolve),
                            ("total", m.total),
                            ("record (host)", out.record_seconds * 1e3),
                        ],
                        None => vec![
                            ("record (host)", out.record_seconds * 1e3),
                            ("frame (device)", out.device_seconds * 1e3),
                        ],
                    },
                    backend: device,
                    visibility: f.visibility,
                    masks: f.masks,
                    masks_high: f.masks_high,
                    shaded: f.shaded,
                    made_pass: Some(out.made_pass),
                })
            }
            Err(e @ GpuError::LoopCap { .. }) => {
                let bvh = SceneBvh::build(scene);
                let out = render_cpu(scene, &bvh, settings);
                let s = &out.report.seconds;
                let ev = &out.report.evaluate;
                Ok(MethodFrame {
                    name: name.into(),
                    izb: Some(settings),
                    tests_per_pixel: Some(ev.tests_spawned as f64 / ev.pixels_tested.max(1) as f64),
                    memory_bytes: 0,
                    report: serde_json::to_value(&out.report)?,
                    pass_millis: cpu_millis(s),
                    backend: format!("cpu twin ({e})"),
                    shaded: shade(&out.gbuffer, &out.visibility),
                    visibility: out.visibility,
                    masks: out.masks,
                    masks_high: out.masks_high,
                    made_pass: None,
                })
            }
            Err(e) => Err(e.into()),
        },
        MethodKind::ShadowMap(map) => baseline_frame(
            name,
            scene,
            device,
            r.render_shadow_map(scene, map, GBufferSource::Gpu),
            shade,
            |g| {
                let out = crate::baseline::render_shadow_map(scene, g, map)
                    .map_err(anyhow::Error::msg)?;
                let s = &out.report.seconds;
                Ok(CpuBaseline {
                    memory_bytes: out.report.map_bytes,
                    report: serde_json::to_value(&out.report)?,
                    pass_millis: vec![
                        ("light setup", s.light_setup * 1e3),
                        ("raster", s.shadow_map * 1e3),
                        ("lookup", s.shadow_lookup * 1e3),
                        ("total", s.shadow * 1e3),
                    ],
                    visibility: out.visibility,
                })
            },
        ),
        MethodKind::ShadowVolumes => baseline_frame(
            name,
            scene,
            device,
            r.render_shadow_volumes(scene, GBufferSource::Gpu),
            shade,
            |g| {
                let out = crate::baseline::volumes::shadow_volumes(scene, g);
                Ok(CpuBaseline {
                    memory_bytes: 0,
                    report: serde_json::to_value(&out.report)?,
                    pass_millis: vec![("volumes", out.report.seconds * 1e3)],
                    visibility: out.visibility,
                })
            },
        ),
        _ => anyhow::bail!("`{name}` is not a viewer method"),
    }
}

/// What a baseline's CPU twin gives the viewer.
struct CpuBaseline {
    visibility: Vec<f32>,
    memory_bytes: u64,
    report: serde_json::Value,
    pass_millis: Vec<(&'static str, f64)>,
}

/// The frame of a rasterised baseline (maps or volumes) from its GPU
/// render `gpu`, or from its CPU twin `cpu` (given the CPU's G-buffer)
/// when lavapipe's loop cap refused the frame.
fn baseline_frame(
    name: &str,
    scene: &Scene,
    device: String,
    gpu: Result<GpuShadowMapRender, GpuError>,
    shade: impl Fn(&GBuffer, &[f32]) -> Vec<[u8; 3]>,
    cpu: impl FnOnce(&GBuffer) -> anyhow::Result<CpuBaseline>,
) -> anyhow::Result<MethodFrame> {
    match gpu {
        Ok(out) => {
            let pass_millis = out.gpu_milliseconds.as_ref().map_or(Vec::new(), |m| {
                vec![
                    ("gbuffer", m.gbuffer),
                    ("light setup", m.light_setup),
                    ("raster", m.raster),
                    ("lookup", m.lookup),
                    ("total", m.total),
                ]
            });
            Ok(MethodFrame {
                name: name.into(),
                izb: None,
                tests_per_pixel: None,
                memory_bytes: out.memory_total_bytes,
                report: serde_json::json!({
                    "method": name,
                    "gpu_milliseconds": out.gpu_milliseconds,
                    "wall_seconds": out.wall_seconds,
                    "map_bytes": out.map_bytes,
                    "memory_total_bytes": out.memory_total_bytes,
                }),
                pass_millis,
                backend: device,
                shaded: shade(&out.gbuffer, &out.visibility),
                visibility: out.visibility,
                masks: Vec::new(),
                masks_high: Vec::new(),
                made_pass: None,
            })
        }
        Err(e @ GpuError::LoopCap { .. }) => {
            let bvh = SceneBvh::build(scene);
            let g = gbuffer(scene, &bvh);
            let out = cpu(&g)?;
            Ok(MethodFrame {
                name: name.into(),
                izb: None,
                tests_per_pixel: None,
                memory_bytes: out.memory_bytes,
                report: out.report,
                pass_millis: out.pass_millis,
                backend: format!("cpu twin ({e})"),
                shaded: shade(&g, &out.visibility),
                visibility: out.visibility,
                masks: Vec::new(),
                masks_high: Vec::new(),
                made_pass: None,
            })
        }
        Err(e) => Err(e.into()),
    }
}

fn cpu_millis(s: &crate::settings::PassSeconds) -> Vec<(&'static str, f64)> {
    vec![
        ("gbuffer", s.gbuffer * 1e3),
        ("light setup", s.light_setup * 1e3),
        ("bin", s.bin * 1e3),
        ("evaluate", s.evaluate * 1e3),
        ("resolve", s.resolve * 1e3),
        ("total", s.total * 1e3),
    ]
}
