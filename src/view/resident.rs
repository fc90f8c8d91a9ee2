//! The viewer's IZB frames on resident shadow passes
//! ([`crate::gpu::shadow_pass::ShadowPass`]): a pass is made once per
//! method and kind of light (its BVH and scene uploaded then, in anchor
//! space), and each later frame whose light, light size or camera moved —
//! an orbit or a zoom too: the pass makes its vertices and BVH nodes
//! eye-relative on the GPU — is recorded into it with new parameters: no
//! scene clone, BVH build or upload, as an engine would run it.
//!
//! The viewer then waits and reads the frame back (it shows the masks on
//! the CPU); a frame whose lists overran is exact the slow way or keeps
//! tangent-plane masks at the edge pixels past its slots, so it is
//! recorded once more after [`ShadowPass::grow`], as the batch `render`
//! reruns it.

use crate::gpu::host_images::FrameImages;
use crate::gpu::shadow_pass::{FrameView, PassFrame, PassStatus, ShadowPass, ShadowPassConfig};
use crate::gpu::{GpuError, GpuRenderer};
use crate::scene::{Scene, Triangle};
use crate::settings::{IzbSettings, PassTimes};
use std::sync::Arc;
use std::time::Instant;

/// A pass and what it was made for.
struct Resident<'r> {
    method: String,
    /// The scene's triangles (shared with every view of it).
    triangles: Arc<[Triangle]>,
    area_light: bool,
    pass: ShadowPass<'r>,
}

/// The viewer's passes on one device, one per IZB method shown.
pub struct ResidentPasses<'r> {
    renderer: &'r GpuRenderer,
    passes: Vec<Resident<'r>>,
}

/// One IZB frame of a resident pass, read back.
pub struct ResidentFrame {
    pub frame: PassFrame,
    pub status: PassStatus,
    /// This frame made its pass (the first, or the scene, method or kind
    /// of light changed); otherwise it only recorded parameters and
    /// commands.
    pub made_pass: bool,
    /// The lists overran and the frame was recorded again after growing.
    pub grown: bool,
    /// Host seconds inside `record` (the last recording).
    pub record_seconds: f64,
    /// Wall seconds from submission to the fence (the device's execution).
    pub device_seconds: f64,
    /// Bytes of the pass's buffers.
    pub memory_bytes: u64,
    /// GPU milliseconds per pass (its timestamps), where the queue has them.
    pub gpu_millis: Option<PassTimes>,
}

impl<'r> ResidentPasses<'r> {
    pub fn new(renderer: &'r GpuRenderer) -> Self {
        ResidentPasses {
            renderer,
            passes: Vec::new(),
        }
    }

    /// Drops the passes of methods no longer shown.
    pub fn retain(&mut self, methods: &[String]) {
        self.passes.retain(|r| methods.contains(&r.method));
    }

    /// Renders `method` (of `settings`) for `scene` on its resident pass,
    /// made first when there is none for this scene and kind of light.
    pub fn render(
        &mut self,
        scene: &Scene,
        method: &str,
        settings: IzbSettings,
    ) -> Result<ResidentFrame, GpuError> {
        let fits = |r: &Resident| {
            r.method == method
                && Arc::ptr_eq(&r.triangles, &scene.triangles)
                && r.area_light == scene.has_area_light()
        };
        let made_pass = !self.passes.iter().any(fits);
        if made_pass {
            self.passes.retain(|r| r.method != method);
            let config = ShadowPassConfig::ray_cast(settings);
            let pass = ShadowPass::new(self.renderer, scene.clone(), config)?;
            self.passes.push(Resident {
                method: method.into(),
                triangles: scene.triangles.clone(),
                area_light: scene.has_area_light(),
                pass,
            });
        }
        let resident = self
            .passes
            .iter_mut()
            .find(|r| fits(r))
            .expect("a resident pass was found or made above");
        let pass = &mut resident.pass;
        pass.resize(scene.resolution)?;
        let view = FrameView {
            camera: scene.camera,
            light: scene.light,
            light_radius: scene.light_radius,
            images: FrameImages::default(),
        };
        let mut grown = false;
        loop {
            let (record_seconds, device_seconds) = record_and_wait(self.renderer, pass, &view)?;
            // SAFETY: the frame was waited for; nothing else runs on slot 0.
            let status = unsafe { pass.status(0) }?;
            if let Some(e) = pass.loop_cap_error(&status) {
                return Err(e);
            }
            let overran = status.cell_list_overrun || status.edge_slots_overrun;
            if overran && !grown {
                grown = pass.grow(&status)?;
                if grown {
                    continue;
                }
            }
            // SAFETY: the frame was waited for.
            let (frame, gpu_millis) = unsafe { (pass.read_back_frame()?, pass.gpu_millis(0)?) };
            return Ok(ResidentFrame {
                frame,
                status,
                made_pass,
                grown,
                record_seconds,
                device_seconds,
                memory_bytes: pass.memory_bytes(),
                gpu_millis,
            });
        }
    }
}

/// Records one frame of `pass` into a command buffer of the renderer's
/// own, submits it and waits: host seconds in `record`, seconds waited.
fn record_and_wait(
    renderer: &GpuRenderer,
    pass: &mut ShadowPass,
    view: &FrameView,
) -> Result<(f64, f64), GpuError> {
    let mut record_seconds = 0.0;
    let mut recorded = Instant::now();
    let record = |cmd| {
        let start = Instant::now();
        // SAFETY: `cmd` is the context's, recording on this thread and
        // submitted to its compute queue after every earlier frame of the
        // pass, each of which was waited for; slot 0's previous frame is
        // done; the view holds no host images; the pass outlives the wait.
        unsafe { pass.record(cmd, 0, view) }?;
        record_seconds = start.elapsed().as_secs_f64();
        recorded = Instant::now();
        Ok(())
    };
    // SAFETY: everything the commands use (the pass's buffers, set,
    // pipelines) was made before this call and outlives it.
    unsafe { renderer.context.submit_and_wait(record) }?;
    Ok((record_seconds, recorded.elapsed().as_secs_f64()))
}
