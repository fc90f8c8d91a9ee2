//! What may change between a pass's frames ([`FrameView`]), and how a
//! frame takes it: checked against the scene and the precision envelope.

use super::ShadowPass;
use crate::gpu::host_images::FrameImages;
use crate::gpu::GpuError;
use crate::scene::{Camera, Light};
use ash::vk;

/// What may change between frames.
#[derive(Clone, Copy, Debug)]
pub struct FrameView {
    /// The camera; the eye may move (the vertices, and a ray cast's BVH
    /// nodes, are made eye-relative on the GPU from anchor-space ones;
    /// with the host's vertex buffers the draws' transforms place them),
    /// but not in a pass for one view.
    pub camera: Camera,
    pub light: Light,
    /// The light's size (`Scene::light_radius`); whether it is 0 must stay
    /// as the scene had it (it decides the masks' layout).
    pub light_radius: f64,
    /// The host's images: the visibility buffer in (with
    /// [`super::GBufferInput::Visibility`] or, of its sample count,
    /// [`super::GBufferInput::MultisampledVisibility`], and only then), the
    /// depth and normal in (with [`super::GBufferInput::DepthNormal`]), the masks and lit
    /// fraction out (optional); their declared state, barriers and the
    /// layouts they are left in: [`crate::gpu::host_images`].
    pub images: FrameImages,
}

/// The spacing of a unorm depth format's values (0 for a float one).
pub(super) fn unorm_depth_step(format: vk::Format) -> f32 {
    match format {
        vk::Format::D24_UNORM_S8_UINT | vk::Format::X8_D24_UNORM_PACK32 => {
            crate::gbuffer::UNORM24_DEPTH_STEP
        }
        _ => 0.0,
    }
}

impl ShadowPass<'_> {
    /// Checks `view` against the scene (the light's kind of size, the
    /// precision envelope) and takes it as the scene's.
    pub(super) fn take_view(&mut self, view: &FrameView) -> Result<(), GpuError> {
        if (view.light_radius > 0.0) != self.scene.has_area_light() {
            return Err(GpuError::Unsupported(
                "the light turned from point-like to area or back: the masks' layout follows \
                 it; make the pass again"
                    .into(),
            ));
        }
        let scene = &mut self.scene;
        let previous = (scene.camera, scene.light, scene.light_radius);
        let wanted = (view.camera, view.light, view.light_radius);
        if self.config.gbuffer == super::GBufferInput::Uploaded && wanted != previous {
            return Err(GpuError::Unsupported(
                "an uploaded G-buffer is one view's (its edge surfaces face that light): \
                 the camera and light stay the pass's; make the pass again"
                    .into(),
            ));
        }
        if self.one_view && view.camera != previous.0 {
            return Err(GpuError::Unsupported(
                "a pass for one view (the batch render's) is one view's: its vertices and BVH \
                 are that eye's; make the pass again, or a resident pass with ShadowPass::new"
                    .into(),
            ));
        }
        (scene.camera, scene.light, scene.light_radius) =
            (view.camera, view.light, view.light_radius);
        let checked = scene.validate_view(self.bounds);
        if let Err(e) = checked {
            (scene.camera, scene.light, scene.light_radius) = previous;
            return Err(GpuError::Unsupported(format!(
                "this view cannot be rendered: {e}"
            )));
        }
        Ok(())
    }
}
