//! What a pass is made for ([`ShadowPassConfig`]), and where its
//! G-buffer comes from ([`GBufferInput`]).

use crate::gpu::host_images::InputImages;
use crate::gpu::GpuError;
use crate::settings::IzbSettings;
use ash::vk;

/// What a pass is made for.
#[derive(Clone, Copy, Debug)]
pub struct ShadowPassConfig {
    /// Sample mode, skips, cascades, edge surfaces (with the ray cast, a
    /// multisampled visibility buffer or an uploaded G-buffer; not
    /// `Paired64`'s second half from the pass's own G-buffer).
    pub settings: IzbSettings,
    /// Frames the host records before it waits for the oldest: each has
    /// its own status buffer.
    pub frames_in_flight: usize,
    /// Entries of the cell list; `None`: max(4 × triangles, 2¹⁶).
    pub cell_capacity: Option<u64>,
    /// Slots for edge pixels' extra surfaces, with edge surfaces on;
    /// `None`: one per 8 pixels, at least 1 024 (one per 2 pixels with a
    /// multisampled visibility buffer, whose samples nominate more).
    pub edge_slots: Option<u64>,
    /// Where the G-buffer comes from.
    pub gbuffer: GBufferInput,
}

impl ShadowPassConfig {
    /// A pass of `settings` that casts its own G-buffer, with one frame
    /// slot and the first-guess capacities (the viewer's, the batch
    /// `render`'s).
    pub fn ray_cast(settings: IzbSettings) -> Self {
        ShadowPassConfig {
            settings,
            frames_in_flight: 1,
            cell_capacity: None,
            edge_slots: None,
            gbuffer: GBufferInput::RayCast,
        }
    }
}

/// The G-buffer's producer, the pass's first step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GBufferInput {
    /// Primary rays cast through a BVH of the scene (built once).
    RayCast,
    /// The host's visibility buffer, `FrameView::images.visibility`: per pixel
    /// the id of the scene triangle it sees (the scene's triangle order),
    /// `0xFFFFFFFF` for none. Each entry follows from the pixel's centre
    /// ray and that triangle's plane, as the ray cast derives it from its
    /// hit; no BVH is built.
    Visibility,
    /// The host's depth and geometric normal, `FrameView::images.depth`
    /// and `.normal`, the depth under this convention: each entry's point
    /// at the view depth its depth encodes on the pixel's centre ray, its
    /// µQuad from that point and the normal. The receiver's triangle is
    /// not known, so its own triangle is one more candidate that the
    /// depth tolerance must reject: the depth format's precision shows in
    /// the shadows (`paper-notes/embedding.md`, per format). No BVH.
    DepthNormal(crate::gbuffer::DepthConvention),
    /// The host's visibility buffer drawn with `samples` samples a pixel
    /// (2, 4 or 8, within the device's `sampledImageIntegerSampleCounts`)
    /// and not resolved, `FrameView::images.visibility` of that sample
    /// count: each centre's triangle is chosen among the ids its samples
    /// (or its 3×3 pixels' samples) saw by the centre ray's watertight
    /// test, and edge pixels get their per-sample surfaces from the 3×3
    /// pixels' ids (`edge_surfaces`), with no BVH. No sample position is
    /// assumed (any pattern, `VK_EXT_sample_locations` included: samples
    /// only nominate triangles, the rays are the pass's own); one sample
    /// whose id is past the pass's triangles (not `0xFFFFFFFF`) makes its
    /// whole pixel a miss, counted in `PassStatus::visibility_rejected`,
    /// and nominates nothing for its neighbours. The image declared each
    /// frame (`HostImage::samples`) must have this count. The twin is
    /// [`crate::gbuffer::gbuffer_from_multisampled_visibility`].
    MultisampledVisibility { samples: u32 },
    /// The CPU twin's G-buffer (with its edge surfaces, their sample rays
    /// cast in `f64`), written once by [`super::ShadowPass::with_uploaded_gbuffer`]:
    /// the passes after it see exactly the twin's inputs. It is one view's,
    /// so the camera, the light and the image size stay the pass's. For the twin tests
    /// and `izb render --backend vulkan` with edge surfaces.
    Uploaded,
}

impl GBufferInput {
    /// Whether the pass's `edge_surfaces` step finds edge pixels' sample
    /// hits for this producer: through the BVH, or among a multisampled
    /// visibility buffer's ids.
    pub(super) fn finds_edge_surfaces(&self) -> bool {
        matches!(
            self,
            GBufferInput::RayCast | GBufferInput::MultisampledVisibility { .. }
        )
    }

    /// Refuses a multisampled visibility buffer's sample count that is not
    /// 2, 4 or 8 or that the device cannot sample from an integer image
    /// (`sampledImageIntegerSampleCounts` of its `limits`).
    pub(super) fn check(&self, limits: &vk::PhysicalDeviceLimits) -> Result<(), GpuError> {
        let GBufferInput::MultisampledVisibility { samples } = *self else {
            return Ok(());
        };
        let most = crate::gbuffer::MAX_VISIBILITY_SAMPLES as u32;
        if !(2..=most).contains(&samples) || !samples.is_power_of_two() {
            return Err(GpuError::Unsupported(format!(
                "a multisampled visibility buffer of {samples} samples a pixel: the pass reads \
                 2, 4 or 8 (one sample is GBufferInput::Visibility)"
            )));
        }
        let counts = limits.sampled_image_integer_sample_counts;
        if !counts.contains(vk::SampleCountFlags::from_raw(samples)) {
            return Err(GpuError::Unsupported(format!(
                "the device cannot sample an integer image of {samples} samples a pixel \
                 (its sampledImageIntegerSampleCounts are {counts:?})"
            )));
        }
        Ok(())
    }

    /// The host images a frame gives this producer.
    pub(super) fn images(&self) -> InputImages {
        match self {
            GBufferInput::RayCast | GBufferInput::Uploaded => InputImages::None,
            GBufferInput::Visibility => InputImages::Visibility(vk::SampleCountFlags::TYPE_1),
            GBufferInput::MultisampledVisibility { samples } => {
                InputImages::Visibility(vk::SampleCountFlags::from_raw(*samples))
            }
            GBufferInput::DepthNormal(_) => InputImages::DepthNormal,
        }
    }
}
