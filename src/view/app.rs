//! The window's event loop (winit): egui input and drawing on the window
//! thread, shadow frames and the truth on their own threads, scripted
//! actions, screenshots and the UI frame-time record.

use super::images::view_image;
use super::present::{Drawn, Presenter};
use super::script::Action;
use super::state::{ShadowKey, ViewState};
use super::truth::{TruthUpdate, TruthWorker};
use super::ui::{self, Shown, Status};
use super::worker::{FrameRequest, FrameResult, ShadowWorker};
use super::{screenshot, ViewOptions, ViewStats};
use crate::scene::Scene;
use anyhow::{anyhow, Result};
use std::collections::VecDeque;
use std::sync::Arc;
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, ControlFlow};
use winit::window::{Window, WindowId};

/// Sent by the worker threads to wake the loop.
#[derive(Debug, Clone, Copy)]
pub struct Wake;

/// Redraws while something is in flight, at most this often.
const BUSY_FRAME: Duration = Duration::from_millis(33);

pub struct App {
    options: ViewOptions,
    base: Arc<Scene>,
    /// `base`'s bounds, computed once (each view is checked against them).
    base_bounds: (glam::DVec3, glam::DVec3),
    pub state: ViewState,
    /// The generation of the state the window asks for (bumped on each
    /// change of [`ShadowKey`]).
    generation: u64,
    key: Option<ShadowKey>,
    /// When the current generation was requested, until its frame arrives.
    pending_since: Option<Instant>,
    /// Seconds the window thread took to make the current generation's
    /// scene and request.
    request_seconds: f64,
    current_scene: Option<Arc<Scene>>,
    truth_generation: u64,
    truth_key: Option<([f64; 3], [f64; 2], f64)>,
    truth_started: bool,
    truth: Option<TruthUpdate>,
    shown: Option<Shown>,
    messages: Vec<String>,
    magnify: Option<[u32; 2]>,
    script: VecDeque<Action>,
    script_wait_until: Option<Instant>,
    screenshot_to: Option<std::path::PathBuf>,
    pub stats: ViewStats,
    last_ui_millis: f64,
    last_redraw: Instant,
    /// Frames presented since `shown` last changed.
    frames_since_shown: u32,
    window: Option<Arc<Window>>,
    presenter: Option<Presenter>,
    egui_state: Option<egui_winit::State>,
    ctx: egui::Context,
    worker: Option<ShadowWorker>,
    truth_worker: Option<TruthWorker>,
    pub error: Option<anyhow::Error>,
}

impl App {
    pub fn new(options: ViewOptions, worker: ShadowWorker, truth_worker: TruthWorker) -> App {
        let base = Arc::new(options.scene.clone());
        let state = ViewState::new(&base);
        let script = options.script.iter().cloned().collect();
        App {
            base_bounds: base.bounds(),
            base,
            state,
            generation: 0,
            key: None,
            pending_since: None,
            request_seconds: 0.0,
            current_scene: None,
            truth_generation: 0,
            truth_key: None,
            truth_started: false,
            truth: None,
            shown: None,
            messages: Vec::new(),
            magnify: None,
            script,
            script_wait_until: None,
            screenshot_to: None,
            stats: ViewStats::default(),
            last_ui_millis: 0.0,
            last_redraw: Instant::now(),
            frames_since_shown: 0,
            window: None,
            presenter: None,
            egui_state: None,
            ctx: egui::Context::default(),
            worker: Some(worker),
            truth_worker: Some(truth_worker),
            error: None,
            options,
        }
    }

    /// Stops the threads and collects the presenting device's validation
    /// messages.
    pub fn shut_down(&mut self) {
        if let Some(t) = self.truth_worker.take() {
            t.stop();
        }
        if let Some(w) = self.worker.take() {
            w.stop(Duration::from_secs(5));
        }
        if let Some(p) = self.presenter.take() {
            self.stats.validation_messages.extend(p.take_messages());
        }
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, e: anyhow::Error) {
        self.error = Some(e);
        event_loop.exit();
    }

    /// Sends a new request when the state changed since the last one.
    fn sync_requests(&mut self) {
        let key = self.state.shadow_key();
        if self.key.as_ref() == Some(&key) {
            return;
        }
        self.key = Some(key.clone());
        let truth_key = self.state.truth_key();
        if self.truth_key != Some(truth_key) {
            self.truth_key = Some(truth_key);
            self.truth_generation += 1;
            self.truth = None;
            self.truth_started = false;
            if let Some(t) = &self.truth_worker {
                t.invalidate(self.truth_generation);
            }
        }
        let made = Instant::now();
        match self.state.scene(&self.base, self.base_bounds) {
            Ok(scene) => {
                self.generation += 1;
                let scene = Arc::new(scene);
                self.current_scene = Some(scene.clone());
                self.pending_since = Some(Instant::now());
                self.messages.clear();
                if let Some(t) = &self.truth_worker {
                    t.pause(true);
                }
                if let Some(w) = &self.worker {
                    w.request(FrameRequest {
                        generation: self.generation,
                        scene,
                        methods: key.methods,
                        candidates: key.candidates,
                    });
                }
                self.request_seconds = made.elapsed().as_secs_f64();
            }
            Err(e) => self.messages = vec![format!("this view cannot be rendered: {e}")],
        }
    }

    /// Takes what the threads finished.
    fn collect(&mut self) {
        let mut newest: Option<FrameResult> = None;
        if let Some(w) = &self.worker {
            while let Ok(r) = w.results.try_recv() {
                self.stats.errors.extend(r.errors.iter().cloned());
                self.stats
                    .validation_messages
                    .extend(r.validation.iter().cloned());
                newest = Some(r);
            }
        }
        if let Some(r) = newest {
            if r.generation == self.generation {
                self.pending_since = None;
                if let Some(t) = &self.truth_worker {
                    t.pause(false);
                }
                self.stats.frame_seconds.push(r.wall_seconds);
                let host = r.host_cpu_seconds + self.request_seconds;
                self.stats.shadow_host_millis.push(host * 1e3);
                for made in r.frames.iter().filter_map(|f| f.made_pass) {
                    self.stats.passes_made += usize::from(made);
                    self.stats.resident_frames += usize::from(!made);
                }
            }
            self.frames_since_shown = 0;
            self.shown = Some(Shown {
                result: r,
                textures: Vec::new(),
                pixels: Vec::new(),
                texture_key: (self.state.view, u32::MAX),
            });
        }
        // The truth starts once the current frame is shown: it never
        // competes with the frame the user waits for.
        if self.pending_since.is_none() && !self.truth_started {
            if let (Some(t), Some(scene)) = (&self.truth_worker, &self.current_scene) {
                t.start_truth(self.truth_generation, scene.clone());
                self.truth_started = true;
            }
        }
        if let Some(t) = &self.truth_worker {
            while let Ok(u) = t.updates.try_recv() {
                if u.generation == self.truth_generation {
                    self.truth = Some(u);
                }
            }
        }
    }

    /// Builds the shown frame's textures for the current view.
    fn refresh_textures(&mut self) {
        let view = self.state.view;
        let truth_spp = self.truth.as_ref().map_or(0, |t| t.spp);
        let truth = self.truth.as_ref().map(|t| t.visibility.as_slice());
        let Some(shown) = &mut self.shown else { return };
        let key = (
            view,
            if view == super::state::ViewKind::Error {
                truth_spp
            } else {
                0
            },
        );
        if shown.texture_key == key && !shown.textures.is_empty() {
            return;
        }
        let [w, h] = shown.result.scene.resolution;
        let candidates = shown.result.candidates.as_deref();
        // A truth of another view size (a stale update) is not compared.
        let truth = truth.filter(|t| t.len() == (w * h) as usize);
        shown.pixels = shown
            .result
            .frames
            .iter()
            .map(|f| view_image(f, view, candidates, truth))
            .collect();
        shown.textures = shown
            .result
            .frames
            .iter()
            .zip(&shown.pixels)
            .map(|(f, rgba)| {
                let image = egui::ColorImage::from_rgba_unmultiplied(
                    [w as usize, h as usize],
                    bytemuck::cast_slice(rgba),
                );
                // The UI renderer samples bilinearly whatever the option says.
                self.ctx.load_texture(
                    format!("frame-{}", f.name),
                    image,
                    egui::TextureOptions::NEAREST,
                )
            })
            .collect();
        shown.texture_key = key;
    }

    /// Runs script actions until one has to wait.
    fn step_script(&mut self, event_loop: &ActiveEventLoop) {
        let now = Instant::now();
        if self.script_wait_until.is_some_and(|t| now < t) || self.screenshot_to.is_some() {
            return;
        }
        self.script_wait_until = None;
        while let Some(action) = self.script.front().cloned() {
            match action {
                Action::Wait(s) => {
                    self.script_wait_until = Some(now + Duration::from_secs_f64(s));
                    self.script.pop_front();
                    return;
                }
                Action::Screenshot(path) => {
                    // The frame shown must be the current state's.
                    self.sync_requests();
                    // ... and drawn before: egui lays a new area out
                    // invisibly in its first frame.
                    if self.pending_since.is_some()
                        || self.shown.as_ref().map(|s| s.result.generation) != Some(self.generation)
                        || self.frames_since_shown < 2
                    {
                        return;
                    }
                    self.screenshot_to = Some(path);
                    self.script.pop_front();
                    return;
                }
                Action::WaitTruth(spp) => {
                    // The actions before may have changed the view: its
                    // truth is a new one (an earlier version counted the
                    // previous view's samples and went on at once).
                    self.sync_requests();
                    let current = |t: &TruthUpdate| t.generation == self.truth_generation;
                    if self
                        .truth
                        .as_ref()
                        .is_some_and(|t| current(t) && t.spp >= spp)
                    {
                        self.script.pop_front();
                        continue;
                    }
                    return;
                }
                Action::Quit => {
                    self.script.pop_front();
                    event_loop.exit();
                    return;
                }
                Action::Method(m) => self.state.method = m,
                Action::Split(s) => self.state.split = s,
                Action::Divider(d) => self.state.divider = d,
                Action::View(v) => self.state.view = v,
                Action::Light(t) => self.state.light_turn = t,
                Action::LightSize(s) => self.state.light_size = s,
                Action::Orbit([yaw, pitch]) => {
                    self.state.orbit[0] = yaw;
                    self.state.orbit[1] = pitch;
                }
                Action::Zoom(z) => self.state.orbit[2] = z,
                Action::Resize([w, h]) => {
                    if let Some(window) = &self.window {
                        let _ = window.request_inner_size(winit::dpi::PhysicalSize::new(w, h));
                    }
                }
                Action::Magnify(p) => {
                    self.magnify = p;
                }
                Action::Overlay(on) => self.state.overlay = on,
            }
            self.script.pop_front();
        }
    }

    fn busy(&self) -> bool {
        self.pending_since.is_some()
            || !self.script.is_empty()
            || self
                .truth
                .as_ref()
                .is_none_or(|t| t.spp < super::truth::MAX_SPP)
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let started = Instant::now();
        self.last_redraw = started;
        self.collect();
        self.step_script(event_loop);
        self.sync_requests();
        self.refresh_textures();
        let (Some(window), Some(egui_state)) = (self.window.clone(), self.egui_state.as_mut())
        else {
            return Ok(());
        };
        let input = egui_state.take_egui_input(&window);
        let compute_device = self
            .worker
            .as_ref()
            .map(|w| {
                w.device_name
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .clone()
            })
            .unwrap_or_default();
        let present_device = self
            .presenter
            .as_ref()
            .map_or(String::new(), |p| p.device_name.clone());
        let status = Status {
            computing: self.pending_since.map(|t| t.elapsed().as_secs_f64()),
            truth: self
                .truth
                .as_ref()
                .map(|t| (t.visibility.as_slice(), t.spp)),
            messages: &self.messages,
            compute_device,
            present_device: &present_device,
            ui_millis: self.last_ui_millis,
        };
        let mut requests = ui::UiRequests::default();
        let (state, base, shown, magnify) = (
            &mut self.state,
            &self.base,
            self.shown.as_ref(),
            &mut self.magnify,
        );
        let output = self.ctx.run_ui(input, |root| {
            requests = ui::draw(root, state, base, shown, &status, magnify);
        });
        egui_state.handle_platform_output(&window, output.platform_output.clone());
        if requests.screenshot && self.screenshot_to.is_none() {
            let stamp = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs());
            self.screenshot_to = Some(self.options.out.join(format!("view-{stamp}")));
        }
        let size = window.inner_size();
        let presenter = self
            .presenter
            .as_mut()
            .ok_or_else(|| anyhow!("no presenter"))?;
        let capture = self.screenshot_to.is_some();
        let (drawn, image) =
            presenter.draw(&self.ctx, output, [size.width, size.height], capture)?;
        let millis = started.elapsed().as_secs_f64() * 1e3;
        // A screenshot frame waits for its read-back on purpose: not a UI frame.
        if drawn == Drawn::Presented {
            self.frames_since_shown += 1;
        }
        if drawn == Drawn::Presented && !capture {
            self.last_ui_millis = millis;
            self.stats
                .record_ui_frame(millis, self.pending_since.is_some());
        }
        if let (Some(dir), Some(image)) = (self.screenshot_to.take(), image) {
            match &self.shown {
                Some(shown) => {
                    let written = screenshot::write(
                        &dir,
                        &image,
                        requests.image_rect_px,
                        shown,
                        &self.state,
                        self.truth.as_ref(),
                    );
                    match written {
                        Ok(()) => {
                            eprintln!("screenshot -> {}", dir.display());
                            self.stats.screenshots.push(dir);
                        }
                        Err(e) => self.messages.push(format!("screenshot failed: {e:#}")),
                    }
                }
                None => self.messages.push("screenshot: no frame yet".into()),
            }
        }
        Ok(())
    }
}

impl ApplicationHandler<Wake> for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let [w, h] = self.options.window_size;
        let attributes = Window::default_attributes()
            .with_title(format!("izb view: {}", self.base.name))
            .with_inner_size(winit::dpi::PhysicalSize::new(w, h));
        let window = match event_loop.create_window(attributes) {
            Ok(w) => Arc::new(w),
            Err(e) => return self.fail(event_loop, anyhow!("cannot open a window: {e}")),
        };
        let presenter = match Presenter::new(&window, self.options.gpu.validation) {
            Ok(p) => p,
            Err(e) => return self.fail(event_loop, e.context("presenting to the window")),
        };
        let max_side = presenter.max_image_side as usize;
        self.egui_state = Some(egui_winit::State::new(
            self.ctx.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(max_side),
        ));
        self.presenter = Some(presenter);
        self.window = Some(window.clone());
        self.sync_requests();
        window.request_redraw();
    }

    fn user_event(&mut self, _: &ActiveEventLoop, _: Wake) {
        if let Some(w) = &self.window {
            w.request_redraw();
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        let Some(window) = self.window.clone() else {
            return;
        };
        if let Some(s) = &mut self.egui_state {
            let response = s.on_window_event(&window, &event);
            // egui asks to repaint after every redraw too; that would spin.
            if response.repaint && event != WindowEvent::RedrawRequested {
                window.request_redraw();
            }
        }
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(_) => window.request_redraw(),
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw(event_loop) {
                    self.fail(event_loop, e);
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        if self.busy() {
            // At most one redraw per BUSY_FRAME: on a CPU device every
            // UI frame takes time from the shadow frame.
            let next = self.last_redraw + BUSY_FRAME;
            if Instant::now() >= next {
                if let Some(w) = &self.window {
                    w.request_redraw();
                }
                event_loop.set_control_flow(ControlFlow::WaitUntil(Instant::now() + BUSY_FRAME));
            } else {
                event_loop.set_control_flow(ControlFlow::WaitUntil(next));
            }
        } else {
            event_loop.set_control_flow(ControlFlow::Wait);
        }
    }
}
