//! The IZB's frames on the GPU: the checks before a frame allocates, the
//! frame itself ([`GpuRenderer::run_frame`]) and what follows a frame
//! whose lists did not fit. A cell-list overrun never loses an occluder:
//! the bin puts every placed triangle in the overflow list instead, so the
//! frame is exact the slow way, and reports the need; `render` then grows
//! the list and runs the frame again for its speed, while
//! `render_with_cell_capacity` keeps the one slow frame.

use super::frame::{GBufferSource, GpuRenderer, LLVMPIPE_LOOP_CAP};
use super::frame_inputs::{check_workgroups, grid_budget_side, triangle_normals, SceneUpload};
use super::frame_memory::{initial_cell_capacity, initial_edge_capacity};
use super::frame_report::{FrameOutput, FramePasses, GpuRender};
use super::shared::{self, counter};
use super::GpuError;
use crate::scene::Scene;
use crate::settings::IzbSettings;
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

    /// What a resident pass needs of its scene on top of the vertices it
    /// holds in anchor space (`translate_vertices`): the checks
    /// [`Self::prepare_frame`] makes, and the triangles' normals.
    pub(super) fn prepare_resident(&self, scene: &Scene) -> Result<Vec<[f32; 3]>, GpuError> {
        check_workgroups(&self.shared().limits, scene.resolution)?;
        check_triangle_ids(scene.triangles.len())?;
        Ok(triangle_normals(&scene.eye_relative_triangles()))
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
        let pixels = scene.pixel_count();
        let upload = self.prepare_frame(scene, source)?;
        let triangles = &upload.triangles;
        let bvh_start = Instant::now();
        let bvh = super::gbuffer::frame_bvh(source, triangles)?;
        let bvh_build_seconds = bvh_start.elapsed().as_secs_f64();

        let max_cells = max_cells(pixels, triangles.len(), settings)?;
        let mut capacity =
            fixed_cell_capacity.unwrap_or_else(|| initial_cell_capacity(triangles.len()));
        let mut edge_capacity = initial_edge_capacity(pixels as u64);
        let mut frames_run = 0;
        loop {
            frames_run += 1;
            // A frame that will be rerun after an overrun skips the slow
            // exact way (on lavapipe hairball's Paired64 frame took past
            // the 600 s limit with it).
            let passes = FramePasses::Izb {
                edge_capacity,
                overrun_exact: fixed_cell_capacity.is_some(),
            };
            let out = self.run_frame(
                scene, settings, source, &upload, &bvh, max_cells, capacity, passes,
            )?;
            let needed = u64::from(out.counters[counter::CELL_ENTRIES]);
            let cells_over =
                out.counters[counter::CAPACITY_EXCEEDED] != 0 && fixed_cell_capacity.is_none();
            let edges_needed = super::edge_surfaces::slots_needed(&out.counters);
            let edges_over = edges_needed > edge_capacity;
            if (cells_over || edges_over) && frames_run == 1 {
                capacity = if cells_over { needed } else { capacity };
                edge_capacity = edge_capacity.max(edges_needed);
                continue;
            }
            self.check_loop_budget(&out)?;
            if cells_over || edges_over {
                return Err(GpuError::Unsupported(format!(
                    "the cell list ({capacity} entries) or the edge surfaces' slots \
                     ({edge_capacity}) still overflowed after growing"
                )));
            }
            return Ok(self.finish(
                scene,
                settings,
                source,
                out,
                frames_run,
                bvh_build_seconds,
                &upload,
            ));
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
