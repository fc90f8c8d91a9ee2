//! A pass fed the CPU twin's G-buffer ([`GBufferInput::Uploaded`]): its
//! entries — and with edge surfaces the twin's extra surfaces, whose
//! sample rays it cast in `f64` — written into the pass's G-buffer once
//! when the pass is made, so the passes after it (light setup, bin,
//! evaluate, resolve) see exactly the twin's inputs: the twin tests hold
//! them side by side bit for bit, and `izb render --backend vulkan` with
//! edge surfaces runs the rest of its frame on the device this way.
//! The G-buffer is one view's: the pass keeps its camera, light and size.

use super::{GBufferInput, ShadowPass, ShadowPassConfig};
use crate::gbuffer::GBuffer;
use crate::gpu::edge_surfaces::{self, EdgeUpload};
use crate::gpu::frame::{GBufferSource, GpuRenderer};
use crate::gpu::frame_inputs::SceneUpload;
use crate::gpu::pass_copies::upload_into;
use crate::gpu::shared::binding;
use crate::gpu::GpuError;
use crate::scene::Scene;

impl<'r> ShadowPass<'r> {
    /// Makes the pass for `scene` with `g` as its G-buffer (the CPU
    /// twin's for `scene`'s view and size, with the edge surfaces the
    /// settings ask for): `config.gbuffer` is [`GBufferInput::Uploaded`].
    /// Every frame recorded after it must keep `scene`'s view and size.
    pub fn with_uploaded_gbuffer(
        renderer: &'r GpuRenderer,
        scene: Scene,
        config: ShadowPassConfig,
        g: &GBuffer,
    ) -> Result<Self, GpuError> {
        if config.gbuffer != GBufferInput::Uploaded {
            return Err(GpuError::Unsupported(format!(
                "with_uploaded_gbuffer makes a pass whose G-buffer input is Uploaded, not {:?}",
                config.gbuffer
            )));
        }
        if [g.width, g.height] != scene.resolution {
            let [w, h] = scene.resolution;
            return Err(GpuError::Unsupported(format!(
                "uploaded G-buffer is {}x{}, the scene renders at {w}x{h}",
                g.width, g.height
            )));
        }
        let settings = config.settings;
        edge_surfaces::check_source(&scene, settings, GBufferSource::Upload(g))?;
        // The triangle normals the words' flipped flag refers to.
        let upload = SceneUpload::new(&scene);
        let edges = match g.edges {
            Some(_) => Some(EdgeUpload::new(g, &upload)?),
            None => None,
        };
        let halves = settings.mask_halves(&scene);
        let pixels = scene.pixel_count();
        let slots = edges.as_ref().map(EdgeUpload::slots);
        let pixel_words = match edges {
            Some(_) => Vec::new(),
            None => upload.gbuffer_words(g)?,
        };
        // The same upload gives the pass its eye-relative vertices.
        let mut pass = Self::make(renderer, scene, config, None, slots, Some(upload))?;
        let bytes = |v: &[glam::Vec3]| bytemuck::cast_slice::<_, u8>(v).to_vec();
        let words = |v: &[u32]| bytemuck::cast_slice::<_, u8>(v).to_vec();
        let uploads: Vec<(u32, Vec<u8>)> = match &edges {
            Some(e) => vec![
                (binding::G_POSITION, bytes(&e.position)),
                (binding::G_AXIS_X, bytes(&e.axis_x)),
                (binding::G_AXIS_Y, bytes(&e.axis_y)),
                (binding::G_ID_FLAGS, words(&e.id_flags)),
                (binding::EDGE_PIXELS, words(&e.pixel_words)),
                (binding::EDGE_COVERAGE, words(&e.coverage)),
            ],
            None => vec![
                (binding::G_POSITION, bytes(&g.position)),
                (binding::G_AXIS_X, bytes(&g.axis_x)),
                (binding::G_AXIS_Y, bytes(&g.axis_y)),
                (binding::G_ID_FLAGS, words(&pixel_words)),
            ],
        };
        upload_into(renderer, &pass.buffers, &uploads)?;
        pass.uploaded_counted = edges
            .is_some()
            .then(|| (0..pixels).map(|i| g.counted_samples(i, halves)).collect());
        Ok(pass)
    }
}
