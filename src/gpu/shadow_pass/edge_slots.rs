//! Edge pixels' per-sample surfaces in the pass (Wyman et al. 2015 §4
//! put all 32 samples on the tangent plane at P; `edge_surfaces.comp`
//! traces them at pixels whose neighbours leave P's plane): with the
//! ray-cast G-buffer the pass runs the `edge_surfaces` step,
//! its extra surfaces as receivers in rows below the image.
//!
//! Their slots are sized once ([`super::ShadowPassConfig::edge_slots`],
//! else one per 8 pixels, one per 2 with a multisampled visibility
//! buffer) and never grown inside a frame: a frame whose
//! edge pixels need more keeps the surfaces that fit, and the pixels past
//! the capacity see all their samples on their centre's surface — the
//! pass without edge surfaces, tangent-plane masks, no occluder lost —
//! and its status says so ([`super::PassStatus::edge_slots_overrun`],
//! with the need). [`ShadowPass::grow`] makes room between frames.

use super::{GBufferInput, ShadowPass, ShadowPassConfig};
use crate::gpu::frame_inputs::check_workgroups;
use crate::gpu::frame_memory::{heavy_capacity, initial_edge_capacity, receivers, EdgeSlots};
use crate::gpu::shared::FrameParams;
use crate::gpu::GpuError;
use crate::scene::Scene;

/// The slots a pass for `scene` under `config` gives edge surfaces
/// (`None`: the pass traces none), or why it cannot trace them.
pub(super) fn edge_slots_for(
    scene: &Scene,
    config: &ShadowPassConfig,
) -> Result<Option<EdgeSlots>, GpuError> {
    if !config.settings.uses_edge_surfaces(scene) {
        return Ok(None);
    }
    if !config.gbuffer.finds_edge_surfaces() {
        return Err(GpuError::Unsupported(
            "edge pixels' per-sample surfaces need the ray-cast G-buffer (its BVH traces their \
             32 sample rays) or a multisampled visibility buffer (its samples nominate their \
             hits); a single-sampled visibility buffer or depth carry one surface a pixel: \
             make the pass with `edge_surfaces: false` (--no-edge-surfaces) for this input"
                .into(),
        ));
    }
    if config.settings.edge_halves(scene) == 2 {
        return Err(GpuError::Unsupported(
            "Paired64's edge surfaces from the pass's own G-buffer: its edge_surfaces step \
             traces the first half's µQuad pattern only (upload the CPU twin's G-buffer, or \
             turn edge surfaces off)"
                .into(),
        ));
    }
    let pixels = scene.pixel_count() as u64;
    let slots = match config.edge_slots {
        Some(0) => {
            return Err(GpuError::Unsupported(
                "edge_slots is 0: give edge surfaces at least one slot, or turn them off".into(),
            ))
        }
        Some(n) => n,
        // A raster's samples nominate more surfaces than the ray cast's
        // first guess holds: `default` at 96×54 needed 1 231 slots for
        // 5 184 pixels at 4× (one in eight, at least 1 024, overran).
        None if matches!(config.gbuffer, GBufferInput::MultisampledVisibility { .. }) => {
            (pixels / 2).max(initial_edge_capacity(pixels))
        }
        None => initial_edge_capacity(pixels),
    };
    Ok(Some(EdgeSlots {
        surfaces: slots,
        pixels: slots,
    }))
}

/// Rows of receivers at `resolution` with `slots`: the image's, then the
/// edge surfaces' below it.
pub(super) fn receiver_rows([w, h]: [u32; 2], slots: Option<EdgeSlots>) -> u32 {
    let extra = slots.map_or(0, |s| s.surfaces);
    (receivers([w, h], extra) / u64::from(w.max(1))) as u32
}

/// Receivers at `resolution` with `slots` (`FrameSizes::receivers`), once
/// their rows are known to fit the device's workgroup counts.
pub(super) fn checked_receivers(
    limits: &ash::vk::PhysicalDeviceLimits,
    resolution: [u32; 2],
    slots: Option<EdgeSlots>,
) -> Result<u64, GpuError> {
    let rows = receiver_rows(resolution, slots);
    check_workgroups(limits, [resolution[0], rows])?;
    Ok(u64::from(resolution[0]) * u64::from(rows))
}

impl ShadowPass<'_> {
    /// Slots for edge pixels' extra surfaces (0: the pass traces none).
    pub fn edge_slots(&self) -> u64 {
        self.sizes.edge_surfaces.map_or(0, |s| s.surfaces)
    }

    /// The edge surfaces' slots the pass's `edge_surfaces` step traces
    /// into (ray cast or multisampled visibility; an uploaded G-buffer
    /// brings its own).
    pub(super) fn traced_edge_slots(&self) -> Option<EdgeSlots> {
        self.sizes
            .edge_surfaces
            .filter(|_| self.config.gbuffer.finds_edge_surfaces())
    }

    /// Rows of receivers now: the image's and the edge surfaces'.
    pub(super) fn receiver_rows(&self) -> u32 {
        receiver_rows(self.scene.resolution, self.sizes.edge_surfaces)
    }

    /// `params` for a frame with edge surfaces (traced or uploaded), as
    /// the passes after the G-buffer read them; nothing without.
    pub(super) fn edge_params(&self, params: &mut FrameParams) {
        let Some(slots) = self.sizes.edge_surfaces else {
            return;
        };
        params.receiver_rows = self.receiver_rows();
        params.edge_surfaces = 1;
        params.edge_capacity = slots.surfaces.max(slots.pixels) as u32;
        // LightSetup::receiver_boxes' `covered_only`.
        params.covered_boxes = u32::from(!self.config.settings.light_samples(&self.scene));
        params.heavy_capacity = heavy_capacity(self.sizes.receivers) as u32;
    }

    /// Makes the edge surfaces hold half again `need` slots (new G-buffer,
    /// mask and receiver buffers, a new descriptor set), or for one view
    /// exactly `need`; whether they grew. As the cell list's growth.
    pub(super) fn grow_edge_slots(&mut self, need: u64) -> Result<bool, GpuError> {
        let Some(slots) = self.traced_edge_slots() else {
            return Ok(false);
        };
        if need <= slots.surfaces {
            return Ok(false);
        }
        let grown = match self.is_one_view() {
            true => need,
            false => need.saturating_add(need / 2),
        };
        let slots = Some(EdgeSlots {
            surfaces: grown,
            pixels: grown,
        });
        let limits = &self.renderer.shared().limits;
        let mut sizes = self.sizes;
        sizes.receivers = checked_receivers(limits, self.scene.resolution, slots)?;
        sizes.edge_surfaces = slots;
        self.replace_sized(sizes)?;
        Ok(true)
    }
}
