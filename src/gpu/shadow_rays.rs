//! The `rt32-rays` peer on the GPU (`shaders/shadow_rays.comp`): the 32
//! µQuad sample rays of every shadow-tested pixel traced through the
//! G-buffer pass's BVH, the twin of
//! [`crate::peer::shadow_rays::shadow_rays`]. It runs after the IZB's own
//! G-buffer and light-setup passes in a frame of its own, in the evaluate
//! slot, followed by resolve
//! ([`GpuRenderer::render_shadow_rays`]).

use super::frame::{GBufferSource, GpuRenderer};
use super::frame_report::BaselinePasses;
use super::frame_report::GpuPassMillis;
use super::shared;
use super::{GpuError, Kernels, Recorder};
use crate::scene::Scene;
use crate::settings::IzbSettings;

/// Records the pass: one invocation per pixel.
pub fn shadow_rays(rec: &Recorder, kernels: &Kernels, size: [u32; 2]) {
    rec.begin_label("shadow_rays");
    rec.dispatch_pixels(&kernels.shadow_rays, size);
    rec.barrier();
    rec.end_label();
}

/// What a GPU shadow-ray frame returns.
pub struct GpuShadowRaysRender {
    /// Occlusion mask per pixel (0 where not shadow-tested).
    pub masks: Vec<u32>,
    /// Lit fraction, NaN where not shadow-tested.
    pub visibility: Vec<f32>,
    /// GPU milliseconds: `evaluate` holds the ray tracing, `resolve` the
    /// shading; `bin` is 0.
    pub gpu_milliseconds: Option<GpuPassMillis>,
    pub wall_seconds: f64,
    pub memory_total_bytes: u64,
}

impl GpuRenderer {
    /// Traces the 32 sample rays of every shadow-tested pixel of `scene`
    /// (`rt32-rays`). The BVH is built whatever the G-buffer source: the
    /// rays need it.
    pub fn render_shadow_rays(
        &self,
        scene: &Scene,
        source: GBufferSource,
    ) -> Result<GpuShadowRaysRender, GpuError> {
        let upload = self.prepare_frame(scene, source)?;
        let bvh = super::gbuffer::build_bvh(&upload.triangles)?;
        // The smallest light setup: one 8×8 grid nobody reads.
        let settings = IzbSettings {
            cells: Some(8),
            cascades: crate::cascades::CascadeCount::Fixed(1),
            ..Default::default()
        };
        let max_cells = crate::cascades::max_total_cells(8);
        let out = self.run_frame(
            scene,
            settings,
            source,
            &upload,
            &bvh,
            max_cells,
            1,
            BaselinePasses::Rays,
        )?;
        self.check_loop_budget(&out)?;
        let visibility = out.per_tested_pixel(&out.shaded, |p| {
            shared::lit_fraction_of_alpha((p >> 24) as u8, 32)
        });
        Ok(GpuShadowRaysRender {
            masks: out.masks,
            visibility,
            gpu_milliseconds: out.millis,
            wall_seconds: out.wall_seconds,
            memory_total_bytes: out.memory.iter().map(|m| m.bytes).sum(),
        })
    }
}
