//! The IZB's batch frames — `izb render --backend vulkan`, `izb bench` and
//! the tests — on the same shadow pass a host records into its own frame
//! (one GPU path, issue 29): a pass made for the view (its G-buffer ray
//! cast, or the CPU twin's uploaded), one frame per timed repetition
//! recorded into one submission, waited for and read back; the checks
//! before a frame allocates are here too. A cell-list overrun never loses
//! an occluder: the bin puts every placed triangle in the overflow list
//! instead, so the frame is exact the slow way, and reports the need;
//! `render` then grows the pass and records the frame again for its
//! speed (its first frame skips the slow way, `set_overrun_exact`), while
//! `render_with_cell_capacity` keeps the one slow frame.

use super::frame::{GBufferSource, GpuRenderer, LLVMPIPE_LOOP_CAP};
use super::frame_inputs::{check_workgroups, grid_budget_side, triangle_normals, SceneUpload};
use super::frame_report::{FrameOutput, GpuRender, IzbReadBack};
use super::shadow_pass::{FrameView, GBufferInput, PassStatus, ShadowPass, ShadowPassConfig};
use super::shared::{self, counter};
use super::GpuError;
use crate::scene::Scene;
use crate::settings::{IzbSettings, PassTimes};
use std::time::Instant;

impl GpuRenderer {
    /// What every frame checks before it allocates — the image's
    /// workgroups within the device's limits, an uploaded G-buffer of the
    /// scene's size, triangle ids that fit the G-buffer word — and then the
    /// scene as the GPU receives it.
    pub(super) fn prepare_frame(
        &self,
        scene: &Scene,
        source: GBufferSource,
    ) -> Result<SceneUpload, GpuError> {
        let [w, h] = scene.resolution;
        check_workgroups(&self.shared().limits, [w, h])?;
        if let GBufferSource::Upload(g) = source {
            if g.width != w || g.height != h {
                return Err(GpuError::Unsupported(format!(
                    "uploaded G-buffer is {}x{}, the scene renders at {w}x{h}",
                    g.width, g.height
                )));
            }
        }
        check_triangle_ids(scene.triangles.len())?;
        Ok(SceneUpload::new(scene))
    }

    /// What a pass holding the scene's triangles needs of its scene on top
    /// of the vertices it holds: the checks [`Self::prepare_frame`] makes,
    /// and the triangles' normals — `normals` where the caller made them
    /// already (a pass for one view, with its eye-relative upload).
    pub(super) fn prepare_resident(
        &self,
        scene: &Scene,
        normals: Option<&[[f32; 3]]>,
    ) -> Result<Vec<[f32; 3]>, GpuError> {
        check_workgroups(&self.shared().limits, scene.resolution)?;
        check_triangle_ids(scene.triangles.len())?;
        Ok(match normals {
            Some(n) => n.to_vec(),
            None => triangle_normals(&scene.eye_relative_triangles()),
        })
    }

    /// Renders `scene`'s shadow mask. A frame whose cell list overran is
    /// exact but slow; it is run again once with the list grown to its
    /// need (`GpuRenderReport::frames_run` 2).
    pub fn render(
        &self,
        scene: &Scene,
        settings: IzbSettings,
        source: GBufferSource,
    ) -> Result<GpuRender, GpuError> {
        self.render_frames(scene, settings, source, None)
    }

    /// Renders `scene`'s shadow mask with a cell list of `capacity`
    /// entries that is never grown: a frame past it is the slow exact one
    /// (`GpuCounters::cell_list_overrun`, with `cell_entries` the need).
    /// The edge surfaces' slots still grow.
    pub fn render_with_cell_capacity(
        &self,
        scene: &Scene,
        settings: IzbSettings,
        source: GBufferSource,
        capacity: u64,
    ) -> Result<GpuRender, GpuError> {
        self.render_frames(scene, settings, source, Some(capacity))
    }

    fn render_frames(
        &self,
        scene: &Scene,
        settings: IzbSettings,
        source: GBufferSource,
        fixed_cell_capacity: Option<u64>,
    ) -> Result<GpuRender, GpuError> {
        super::edge_surfaces::check_source(scene, settings, source)?;
        // Timed repetitions are frames of their own slots, recorded back
        // to back into one submission (`GpuRenderer::timed`).
        let repeats = self.timed_repeats() as usize;
        let config = ShadowPassConfig {
            frames_in_flight: repeats,
            cell_capacity: fixed_cell_capacity,
            ..ShadowPassConfig::ray_cast(settings)
        };
        let mut pass = match source {
            GBufferSource::Gpu => ShadowPass::for_one_view(self, scene.clone(), config)?,
            GBufferSource::Upload(g) => {
                let config = ShadowPassConfig {
                    gbuffer: GBufferInput::Uploaded,
                    ..config
                };
                ShadowPass::with_uploaded_gbuffer(self, scene.clone(), config, g)?
            }
        };
        // A frame that will be recorded again after an overrun skips the
        // slow exact way; one whose cell list never grows keeps it.
        pass.set_overrun_exact(fixed_cell_capacity.is_some());
        // SAFETY: the pass has recorded no frame yet.
        unsafe { pass.time_steps() }?;
        let view = FrameView {
            camera: scene.camera,
            light: scene.light,
            light_radius: scene.light_radius,
            images: Default::default(),
        };
        let last = repeats - 1;
        let mut frames_run = 0;
        loop {
            frames_run += 1;
            let wall_seconds = record_and_wait(self, &mut pass, &view, repeats)?;
            // SAFETY: the frames were waited for; none is executing.
            let status = unsafe { pass.status(last) }?;
            let cells_over = status.cell_list_overrun && fixed_cell_capacity.is_none();
            let edges_over = status.edge_slots_overrun;
            if (cells_over || edges_over) && frames_run == 1 {
                let grown = PassStatus {
                    cell_list_overrun: cells_over,
                    ..status
                };
                pass.grow(&grown)?;
                continue;
            }
            if let Some(e) = pass.loop_cap_error(&status) {
                return Err(e);
            }
            if cells_over || edges_over {
                return Err(GpuError::Unsupported(format!(
                    "the cell list ({} entries) or the edge surfaces' slots ({}) still \
                     overflowed after growing",
                    pass.cell_capacity(),
                    pass.edge_slots()
                )));
            }
            // SAFETY: the frames were waited for; none is executing.
            let read = unsafe {
                let slots = (0..repeats).map(|slot| pass.gpu_millis(slot));
                let millis: Vec<Option<PassTimes>> = slots.collect::<Result<_, _>>()?;
                let millis: Option<Vec<PassTimes>> = millis.into_iter().collect();
                // The repetitions after the first, as the clocks stay up.
                let timed = millis.map(|m| match m.len() {
                    1 => m[0].clone(),
                    _ => PassTimes::median(m[1..].iter()),
                });
                let (counters, light) = pass.read_back_counters_and_light()?;
                IzbReadBack {
                    frame: pass.read_back_frame()?,
                    gbuffer: match source {
                        GBufferSource::Upload(g) => g.clone(),
                        GBufferSource::Gpu => pass.read_back_gbuffer()?,
                    },
                    counters,
                    light,
                    millis: timed,
                    step_millis: pass.step_millis()?,
                    wall_seconds,
                    memory: pass.memory(),
                }
            };
            let bvh_seconds = pass.bvh_build_seconds();
            return Ok(self.finish(scene, settings, source, read, frames_run, bvh_seconds));
        }
    }

    /// A frame whose shader stopped at lavapipe's loop cap is refused
    /// (its masks would be cut short), never returned.
    pub(super) fn check_loop_budget(&self, out: &FrameOutput) -> Result<(), GpuError> {
        match out.counters[counter::LOOP_BUDGET_EXCEEDED] {
            0 => Ok(()),
            trips => Err(GpuError::LoopCap {
                device: self.context.info().name.clone(),
                cap: LLVMPIPE_LOOP_CAP,
                trips,
            }),
        }
    }
}

/// The cells an IZB frame of `pixels` and `triangles` may use, every
/// cascade's pyramid together: the light setup's largest budget.
pub(super) fn max_cells(
    pixels: usize,
    triangles: usize,
    settings: IzbSettings,
) -> Result<u64, GpuError> {
    let side = grid_budget_side(pixels, triangles, settings.cells);
    if side > 0xFFFF {
        return Err(GpuError::Unsupported(format!(
            "--cells {side}: the GPU's cell budget is at most 65535² cells"
        )));
    }
    Ok(crate::cascades::max_total_cells(side))
}

/// The GPU G-buffer's word holds triangle ids below `DEPTH_SURFACE`.
fn check_triangle_ids(triangles: usize) -> Result<(), GpuError> {
    if triangles >= izb_contract::word::DEPTH_SURFACE as usize {
        return Err(GpuError::Unsupported(format!(
            "{triangles} triangles: the GPU G-buffer holds ids below 2^{} - 2",
            shared::ID_BITS
        )));
    }
    Ok(())
}

/// Records `repeats` frames of `pass` — one per frame slot, back to back —
/// into one command buffer of the renderer's own, submits it and waits:
/// the wall seconds from recording to the fence.
fn record_and_wait(
    renderer: &GpuRenderer,
    pass: &mut ShadowPass,
    view: &FrameView,
    repeats: usize,
) -> Result<f64, GpuError> {
    let start = Instant::now();
    let record = |cmd| {
        for slot in 0..repeats {
            // SAFETY: `cmd` is the context's, recording on this thread and
            // submitted to its compute queue after every earlier frame of
            // the pass, each of which was waited for; the slots' previous
            // frames are done; the view holds no host images; the pass
            // outlives the wait.
            unsafe { pass.record(cmd, slot, view) }?;
        }
        Ok(())
    };
    // SAFETY: everything the commands use (the pass's buffers, sets,
    // pipelines, query pools) was made before this call and outlives it.
    unsafe { renderer.context.submit_and_wait(record) }?;
    Ok(start.elapsed().as_secs_f64())
}
