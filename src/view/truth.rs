//! The progressive ground truth: while the view is still, a background
//! thread traces the reference ([`crate::reference::reference`], `f64`,
//! stratified jittered pixel samples, light samples under an area light)
//! pass after pass with a new seed each, and sends the running mean. Any
//! change of the scene as seen abandons it after the current pass.

use crate::bvh::SceneBvh;
use crate::reference::{reference, ReferenceSettings};
use crate::scene::Scene;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;

/// Pixel samples per pass: 2 × 2 strata.
const SAMPLES_PER_SIDE: u32 = 2;
/// The truth stops refining at this many samples per pixel.
pub const MAX_SPP: u32 = 1024;

/// The running mean after a pass.
pub struct TruthUpdate {
    pub generation: u64,
    /// Lit fraction per pixel, NaN where the pixel centre is not
    /// shadow-tested.
    pub visibility: Vec<f32>,
    pub spp: u32,
}

pub struct TruthWorker {
    requests: Option<Sender<(u64, Arc<Scene>)>>,
    pub updates: Receiver<TruthUpdate>,
    /// The generation the window shows now: a pass for another one is
    /// the last of its run.
    current: Arc<AtomicU64>,
    /// Set while a shadow frame computes: the truth waits between passes
    /// so it never takes the cores a CPU device (lavapipe) renders on.
    paused: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl TruthWorker {
    /// Starts the thread with `threads` tracing threads; `wake` is called
    /// after each pass.
    pub fn start(threads: usize, wake: impl Fn() + Send + 'static) -> TruthWorker {
        let (requests, inbox) = channel::<(u64, Arc<Scene>)>();
        let (outbox, updates) = channel();
        let current = Arc::new(AtomicU64::new(0));
        let paused = Arc::new(AtomicBool::new(false));
        let now = current.clone();
        let hold = paused.clone();
        let thread = std::thread::Builder::new()
            .name("izb-view-truth".into())
            .spawn(move || {
                super::lower_thread_priority();
                let Ok(pool) = rayon::ThreadPoolBuilder::new().num_threads(threads).build() else {
                    return;
                };
                pool.install(|| run(inbox, outbox, now, hold, wake));
            })
            .expect("spawning a thread");
        TruthWorker {
            requests: Some(requests),
            updates,
            current,
            paused,
            thread: Some(thread),
        }
    }

    /// The view changed to `generation`: a running truth stops after its pass.
    pub fn invalidate(&self, generation: u64) {
        self.current.store(generation, Ordering::Relaxed);
    }

    /// Holds (or resumes) the truth between passes.
    pub fn pause(&self, paused: bool) {
        self.paused.store(paused, Ordering::Relaxed);
    }

    /// Starts refining the truth of `scene` (the view at `generation`).
    pub fn start_truth(&self, generation: u64, scene: Arc<Scene>) {
        self.invalidate(generation);
        if let Some(tx) = &self.requests {
            // A closed channel means the thread ended: no truth, no error view.
            let _ = tx.send((generation, scene));
        }
    }

    pub fn stop(mut self) {
        self.invalidate(u64::MAX);
        self.pause(false);
        self.requests = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn run(
    inbox: Receiver<(u64, Arc<Scene>)>,
    outbox: Sender<TruthUpdate>,
    current: Arc<AtomicU64>,
    paused: Arc<AtomicBool>,
    wake: impl Fn(),
) {
    let mut next = inbox.recv().ok();
    while let Some((generation, scene)) = next.take() {
        let bvh = SceneBvh::build(&scene);
        let n = scene.pixel_count();
        let mut sum = vec![0.0f64; n];
        let mut spp = 0;
        let mut pass = 0u64;
        while spp < MAX_SPP && current.load(Ordering::Relaxed) == generation {
            if let Ok(newer) = inbox.try_recv() {
                next = Some(newer);
                break;
            }
            if paused.load(Ordering::Relaxed) {
                std::thread::sleep(std::time::Duration::from_millis(20));
                continue;
            }
            pass += 1;
            let settings = ReferenceSettings {
                samples_per_side: SAMPLES_PER_SIDE,
                seed: pass,
            };
            let image = reference(&scene, &bvh, settings, &|_| {});
            for (s, v) in sum.iter_mut().zip(&image.visibility) {
                *s += f64::from(*v);
            }
            spp += settings.spp();
            let passes = pass as f64;
            let visibility = sum.iter().map(|s| (s / passes) as f32).collect();
            let update = TruthUpdate {
                generation,
                visibility,
                spp,
            };
            if outbox.send(update).is_err() {
                return;
            }
            wake();
        }
        if next.is_none() {
            next = inbox.recv().ok();
        }
    }
}
