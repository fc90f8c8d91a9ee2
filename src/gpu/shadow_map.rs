//! The shadow-map baseline on the GPU (`shaders/shadow_map.vert` on the
//! hardware rasteriser, [`super::shadow_raster`];
//! `shaders/shadow_lookup.comp`): the twins of
//! [`crate::baseline::shadow_map::shadow_map`] and
//! [`crate::baseline::shadow_map::shadow_lookup`], run after the IZB's own
//! G-buffer and light-setup passes in a frame of their own
//! ([`GpuRenderer::render_shadow_map`], below).

use super::frame::{GBufferSource, GpuRenderer, GpuShadowMapRender};
use super::frame_inputs::SceneUpload;
use super::frame_report::{BaselinePasses, FrameOutput};
use super::shadow_raster::{ShadowDepthTarget, ShadowRaster};
use super::{GpuError, Kernels, Recorder};
use crate::baseline::pcss::PcssLight;
use crate::baseline::raster::RasterBias;
use crate::baseline::{Filter, ShadowMapSettings};
use crate::cpu::light_setup::Projection;
use crate::scene::Scene;
use crate::settings::IzbSettings;
use glam::Vec3;
use izb_contract::{FrameParams, GpuTriangle};

/// The shadow-map fields of `params` for `map`: side, filter code, margin
/// and, for PCSS, the light ([`PcssLight`], computed from the uploaded
/// vertices exactly as the CPU twin computes it from its own).
pub(super) fn map_params(
    params: &mut FrameParams,
    scene: &Scene,
    triangles: &[GpuTriangle],
    map: ShadowMapSettings,
) {
    params.map_side = map.side;
    params.map_filter = match map.filter {
        Filter::OneTap => 0,
        Filter::Pcf(k) => k,
        Filter::Pcss => izb_contract::pcss::FILTER,
        Filter::Vsm => izb_contract::filtered::VSM,
        Filter::Msm => izb_contract::filtered::MSM,
        Filter::Esm => izb_contract::filtered::ESM,
    };
    params.map_reach = map.filter.reach();
    params.map_contact = map.contact as u32;
    if map.filter == Filter::Pcss {
        let vertices = triangles
            .iter()
            .flat_map(|t| [t.a, t.b, t.c])
            .map(Vec3::from);
        let light = PcssLight::new(scene, vertices);
        params.map_light_size = light.size;
        params.map_near = light.near;
    }
}

/// Records the raster pass of `map`: `drawn` is the triangle count and
/// whether the light is a point light (perspective map).
pub fn shadow_map(
    rec: &Recorder,
    raster: &ShadowRaster,
    target: &ShadowDepthTarget,
    map_buffer: ash::vk::Buffer,
    (triangles, point_light): (u32, bool),
    map: ShadowMapSettings,
) {
    let projection = if point_light {
        Projection::Perspective
    } else {
        Projection::Orthographic
    };
    let bias = RasterBias::for_map(projection, map.filter);
    super::shadow_raster::shadow_map(rec, raster, target, map_buffer, triangles, projection, bias);
}

/// Records a filtered map's blur (nothing for the others): rows, then
/// columns, one invocation per texel of every cascade.
pub fn shadow_blur(rec: &Recorder, kernels: &Kernels, map: ShadowMapSettings) {
    if map.filter.moments().is_none() {
        return;
    }
    rec.begin_label("shadow_blur");
    let size = [map.side, map.side * map.cascades];
    rec.dispatch_pixels(&kernels.shadow_blur_x, size);
    rec.barrier();
    rec.dispatch_pixels(&kernels.shadow_blur_y, size);
    rec.barrier();
    rec.end_label();
}

/// Records the lookup pass: one invocation per pixel.
pub fn shadow_lookup(rec: &Recorder, kernels: &Kernels, size: [u32; 2]) {
    rec.begin_label("shadow_lookup");
    rec.dispatch_pixels(&kernels.shadow_lookup, size);
    rec.barrier();
    rec.end_label();
}

impl GpuRenderer {
    /// The raster pass and a depth target for `map`, or why not.
    pub(super) fn depth_target(
        &self,
        map: ShadowMapSettings,
    ) -> Result<(&ShadowRaster, ShadowDepthTarget), GpuError> {
        let raster = self.raster.as_ref().map_err(|why| {
            GpuError::Unsupported(format!("{map} draws on the rasteriser, and {why}"))
        })?;
        let target = ShadowDepthTarget::new(self.shared(), raster, map.side, map.cascades)?;
        Ok((raster, target))
    }

    /// Renders the shadow-map baseline `map` on the GPU: the IZB's
    /// G-buffer and light setup (with `map.cascades` cascades), then the
    /// raster and lookup passes; the twin of
    /// [`crate::baseline::render_shadow_map`].
    pub fn render_shadow_map(
        &self,
        scene: &Scene,
        map: ShadowMapSettings,
        source: GBufferSource,
    ) -> Result<GpuShadowMapRender, GpuError> {
        let passes = BaselinePasses::Map(map);
        let (upload, out, map_bytes) =
            self.run_baseline_frame(scene, source, map.cascades, passes, &map.to_string())?;
        if out.light.grid_disabled != 0 {
            return Err(GpuError::Unsupported(format!(
                "{map} on {}: the receivers surround the point light, which one shadow-map frustum cannot hold (a cube map would)",
                scene.name
            )));
        }
        Ok(GpuShadowMapRender::from_frame(
            scene, source, &upload, out, map_bytes,
        ))
    }

    /// The frame every rasterised baseline runs: the IZB's G-buffer and
    /// the light setup the CPU baselines ask for (`cascades` fixed
    /// cascades; the 8×8 grid is unused), then `passes`. Returns the
    /// upload, the frame and the bytes of `passes`' map buffer, which must
    /// fit the device's storage-buffer range (else the refusal names
    /// `method`).
    pub(super) fn run_baseline_frame(
        &self,
        scene: &Scene,
        source: GBufferSource,
        cascades: u32,
        passes: BaselinePasses,
        method: &str,
    ) -> Result<(SceneUpload, FrameOutput, u64), GpuError> {
        let map_bytes = passes.shadow_map_words(scene.pixel_count() as u64) * 4;
        let range = u64::from(self.shared().limits.max_storage_buffer_range);
        if map_bytes > range {
            return Err(GpuError::Unsupported(format!(
                "{method}: {} MiB of maps, above this device's {} MiB storage-buffer range",
                map_bytes >> 20,
                range >> 20
            )));
        }
        let upload = self.prepare_frame(scene, source)?;
        let bvh = super::gbuffer::frame_bvh(source, &upload.triangles)?;
        let settings = IzbSettings {
            cells: Some(8),
            cascades: crate::cascades::CascadeCount::Fixed(cascades),
            ..Default::default()
        };
        let max_cells = crate::cascades::max_total_cells(8);
        let out = self.run_frame(scene, settings, source, &upload, &bvh, max_cells, 1, passes)?;
        self.check_loop_budget(&out)?;
        Ok((upload, out, map_bytes))
    }
}
