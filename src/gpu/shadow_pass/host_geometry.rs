//! The shadow pass fed the host's own vertex and index buffers (issue 29's
//! point 2, "the geometry as the host's own vertex and index buffers, not
//! a copy"): made once for at most `max_triangles` in at most `max_draws`
//! draws, each frame's draws gathered on the GPU into the pass's
//! eye-relative triangles ([`crate::gpu::gather_draws`]) before its
//! G-buffer producer runs. The scene the pass is made with gives the first
//! view, the light and the image size; its triangles are not read.

use super::{GBufferInput, ShadowPass, ShadowPassConfig};
use crate::gpu::frame::GpuRenderer;
use crate::gpu::gather_draws::{draw_table, FrameGeometry};
use crate::gpu::shared::GpuDraw;
use crate::gpu::GpuError;
use crate::scene::Scene;
use ash::vk;
use glam::DVec3;

/// What a pass for the host's geometry is made for.
#[derive(Clone, Copy, Debug)]
pub struct HostGeometryConfig {
    /// The most triangles a frame's draws may hold together.
    pub max_triangles: u32,
    /// The most draws a frame may give.
    pub max_draws: u32,
    /// World-space bounds every drawn vertex stays within: the precision
    /// envelope is checked against them when a view is taken, and a frame
    /// whose vertices leave them says so in its status
    /// (`PassStatus::outside_bounds`).
    pub bounds: (DVec3, DVec3),
}

impl HostGeometryConfig {
    /// Refuses limits and inputs the pass cannot be made with.
    pub(super) fn check(&self, config: &ShadowPassConfig) -> Result<(), GpuError> {
        let refuse = |what: String| Err(GpuError::Unsupported(what));
        if matches!(
            config.gbuffer,
            GBufferInput::RayCast | GBufferInput::Uploaded
        ) {
            return refuse(
                "the host's geometry needs the host's G-buffer (a visibility buffer or depth \
                 + normal): the ray-cast G-buffer's BVH and an uploaded G-buffer are the \
                 resident triangles'"
                    .into(),
            );
        }
        if self.max_triangles == 0 || self.max_draws == 0 {
            return refuse(format!(
                "max_triangles {} and max_draws {}: at least 1 each",
                self.max_triangles, self.max_draws
            ));
        }
        if self.max_triangles >= izb_contract::word::DEPTH_SURFACE {
            return refuse(format!(
                "max_triangles {}: the G-buffer holds ids below 2^28 - 2",
                self.max_triangles
            ));
        }
        let (lo, hi) = self.bounds;
        if !(lo.is_finite() && hi.is_finite() && lo.cmple(hi).all()) {
            return refuse(format!(
                "host geometry bounds {lo} .. {hi}: finite, low at or below high"
            ));
        }
        Ok(())
    }
}

/// The pass's side of the host's geometry: its limits and what each frame
/// reuses (no heap growth after the first frame at the limits).
pub(super) struct HostGeometryState {
    pub(super) config: HostGeometryConfig,
    /// The last recorded frame's draws, as `B_DRAWS` holds them.
    pub(super) table: Vec<GpuDraw>,
    /// The buffers the slot being recorded names, rewritten into its set
    /// every frame: a handle equal to last frame's may be a new buffer
    /// (handles are reused after destruction), so nothing is skipped.
    pub(super) buffer_handles: Vec<vk::Buffer>,
}

impl HostGeometryState {
    pub(super) fn new(config: HostGeometryConfig) -> Self {
        HostGeometryState {
            config,
            table: Vec::with_capacity(config.max_draws as usize),
            buffer_handles: Vec::with_capacity(izb_contract::host_image::GEOMETRY_SLOTS as usize),
        }
    }
}

const _: () = assert!(size_of::<GpuDraw>().is_multiple_of(4));

impl<'r> ShadowPass<'r> {
    /// Makes the pass for the host's own vertex and index buffers: each
    /// frame's draws are given to [`Self::record_host_geometry`] and
    /// gathered on the GPU. `scene` gives the first view, the light and
    /// the image size (its triangles are not read); `config.gbuffer` is
    /// the host's visibility buffer (draw k's ids from
    /// [`crate::gpu::gather_draws::first_triangles`]) or depth + normal.
    pub fn with_host_geometry(
        renderer: &'r GpuRenderer,
        scene: Scene,
        config: ShadowPassConfig,
        geometry: HostGeometryConfig,
    ) -> Result<Self, GpuError> {
        Self::make(renderer, scene, config, Some(geometry), None, None)
    }

    /// Records frame `slot` for `view` with `geometry` as the scene: the
    /// host's buffers read where they lie (see
    /// [`crate::gpu::gather_draws`] for what is checked here and what on
    /// the device).
    ///
    /// # Safety
    /// [`Self::record`]'s, and every buffer in `geometry` is a live
    /// buffer of this device, declared truthfully (its size, usage and
    /// last write), alive and not written until the frame has executed.
    pub unsafe fn record_host_geometry(
        &mut self,
        cmd: vk::CommandBuffer,
        slot: usize,
        view: &super::FrameView,
        geometry: &FrameGeometry,
    ) -> Result<(), GpuError> {
        // SAFETY: the caller's promise.
        unsafe { self.record_frame(cmd, slot, view, Some(geometry)) }
    }

    /// The limits of the host's geometry this pass was made or last
    /// reserved for (`None`: the scene is resident).
    pub fn host_geometry(&self) -> Option<HostGeometryConfig> {
        self.host_geometry.as_ref().map(|h| h.config)
    }

    /// Checks `geometry` against the pass and the view's eye, and makes
    /// the frame's draw table; the triangles to gather (`None` for a
    /// resident scene).
    pub(super) fn take_geometry(
        &mut self,
        geometry: Option<&FrameGeometry>,
    ) -> Result<Option<u32>, GpuError> {
        let max_range = u64::from(self.renderer.shared().limits.max_storage_buffer_range);
        let eye = self.scene.camera.eye;
        let (h, g) = match (&mut self.host_geometry, geometry) {
            (None, None) => return Ok(None),
            (None, Some(_)) => {
                return Err(GpuError::Unsupported(
                    "this pass holds the scene's triangles: make it with \
                     ShadowPass::with_host_geometry to draw the host's buffers"
                        .into(),
                ))
            }
            (Some(_), None) => {
                return Err(GpuError::Unsupported(
                    "this pass draws the host's geometry: record it with \
                     record_host_geometry and the frame's draws"
                        .into(),
                ))
            }
            (Some(h), Some(g)) => (h, g),
        };
        let limits = h.config;
        if g.draws.len() > limits.max_draws as usize {
            return Err(GpuError::Unsupported(format!(
                "{} draws: the pass was made for at most {} (reserve_host_geometry)",
                g.draws.len(),
                limits.max_draws
            )));
        }
        let triangles = draw_table(g, eye, max_range, &mut h.table)?;
        if triangles == 0 {
            return Err(GpuError::Unsupported(
                "the frame's draws hold no triangles".into(),
            ));
        }
        if triangles > limits.max_triangles {
            return Err(GpuError::Unsupported(format!(
                "the frame's draws hold {triangles} triangles: more than the {} the pass \
                 was made for (reserve_host_geometry)",
                limits.max_triangles
            )));
        }
        self.frame_triangles = triangles;
        Ok(Some(triangles))
    }
}
