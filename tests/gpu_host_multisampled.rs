//! The shadow pass fed the host's multisampled visibility buffer
//! (`izb::gpu::shadow_pass::GBufferInput::MultisampledVisibility`): an
//! `R32_UINT` image of 4 samples a pixel, which the test host fills in a
//! render pass of its own before each frame (`vkCmdClearAttachments`, one
//! value per rectangle: a multisampled image cannot be a copy's
//! destination), read unresolved by the pass. With `IZB_VALIDATION=1` the
//! device runs the validation layer with synchronization validation, and
//! any message fails the test. No Vulkan device: the test prints that it
//! skipped, unless `IZB_REQUIRE_GPU=1`.

mod common;

use ash::vk;
use common::gpu::assert_no_validation_messages;
use common::shadow_pass::{assert_refused, pass_renderer, view_at, HostTestImage};
use izb::cpu::{render_cpu_on, IzbSettings, SampleMode};
use izb::gbuffer::{gbuffer_from_multisampled_visibility, VisibilityGBuffer, NO_HIT};
use izb::gpu::context::DeviceShared;
use izb::gpu::host_images::{FrameImages, HostImage};
use izb::gpu::shadow_pass::{FrameView, GBufferInput, PassStatus, ShadowPass, ShadowPassConfig};
use izb::gpu::shared::unpack_id_flags;
use izb::gpu::{GBufferSource, GpuRenderer};
use izb::scene::{self, Scene};
use std::collections::BTreeMap;
use std::sync::Arc;

/// Samples a pixel of the test host's buffer.
const SAMPLES: u32 = 4;

/// Whether the renderer's device can draw and sample a 4× `R32_UINT`
/// image (Vulkan guarantees one sample only); prints a skip if not.
fn takes_four_samples(r: &GpuRenderer) -> bool {
    let limits = &r.context.shared.limits;
    let four = vk::SampleCountFlags::from_raw(SAMPLES);
    let takes = limits.sampled_image_integer_sample_counts.contains(four)
        && limits.framebuffer_color_sample_counts.contains(four);
    if !takes {
        eprintln!("skipped: the device has no 4x integer images ({limits:?})");
    }
    takes
}

/// The test host's multisampled visibility buffer: the image, and a
/// render pass and framebuffer that clear it to per-pixel ids.
struct MultisampledIds {
    image: HostTestImage,
    render_pass: vk::RenderPass,
    framebuffer: vk::Framebuffer,
    shared: Arc<DeviceShared>,
}

impl MultisampledIds {
    const USAGE: vk::ImageUsageFlags = vk::ImageUsageFlags::from_raw(
        vk::ImageUsageFlags::SAMPLED.as_raw() | vk::ImageUsageFlags::COLOR_ATTACHMENT.as_raw(),
    );

    fn new(shared: &Arc<DeviceShared>, extent: [u32; 2]) -> Self {
        let samples = vk::SampleCountFlags::from_raw(SAMPLES);
        let format = vk::Format::R32_UINT;
        let image = HostTestImage::with_samples(shared, extent, format, Self::USAGE, samples);
        let attachments = [vk::AttachmentDescription::default()
            .format(format)
            .samples(samples)
            .load_op(vk::AttachmentLoadOp::DONT_CARE)
            .store_op(vk::AttachmentStoreOp::STORE)
            .initial_layout(vk::ImageLayout::UNDEFINED)
            .final_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)];
        let colour = [vk::AttachmentReference::default()
            .attachment(0)
            .layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)];
        let subpass = [vk::SubpassDescription::default()
            .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)
            .color_attachments(&colour)];
        // The previous frame's pass read the image in compute shaders.
        let dependencies = [vk::SubpassDependency::default()
            .src_subpass(vk::SUBPASS_EXTERNAL)
            .dst_subpass(0)
            .src_stage_mask(
                vk::PipelineStageFlags::COMPUTE_SHADER
                    | vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
            )
            .src_access_mask(vk::AccessFlags::COLOR_ATTACHMENT_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT)
            .dst_access_mask(vk::AccessFlags::COLOR_ATTACHMENT_WRITE)];
        let info = vk::RenderPassCreateInfo::default()
            .attachments(&attachments)
            .subpasses(&subpass)
            .dependencies(&dependencies);
        let d = &shared.device;
        // SAFETY: `info` and its arrays outlive the call.
        let render_pass = unsafe { d.create_render_pass(&info, None) }.unwrap();
        let views = [image.view];
        let info = vk::FramebufferCreateInfo::default()
            .render_pass(render_pass)
            .attachments(&views)
            .width(extent[0])
            .height(extent[1])
            .layers(1);
        // SAFETY: the view is live and matches the attachment.
        let framebuffer = unsafe { d.create_framebuffer(&info, None) }.unwrap();
        MultisampledIds {
            image,
            render_pass,
            framebuffer,
            shared: shared.clone(),
        }
    }

    /// Records the clears that give every sample of pixel `i` the id
    /// `ids[i]` (row runs of one id, one clear per id) and returns the
    /// image as the frame declares it.
    ///
    /// # Safety
    /// `cmd` is recording outside a render pass on the image's device,
    /// after the previous frame that read the image.
    unsafe fn record_fill(&self, cmd: vk::CommandBuffer, ids: &[u32]) -> HostImage {
        let [w, h] = self.image.extent;
        let mut runs: BTreeMap<u32, Vec<vk::ClearRect>> = BTreeMap::new();
        for y in 0..h {
            let row = &ids[(y * w) as usize..((y + 1) * w) as usize];
            let mut x = 0;
            while x < w {
                let id = row[x as usize];
                let start = x;
                while x < w && row[x as usize] == id {
                    x += 1;
                }
                let rect = vk::Rect2D {
                    offset: vk::Offset2D {
                        x: start as i32,
                        y: y as i32,
                    },
                    extent: vk::Extent2D {
                        width: x - start,
                        height: 1,
                    },
                };
                runs.entry(id).or_default().push(vk::ClearRect {
                    rect,
                    base_array_layer: 0,
                    layer_count: 1,
                });
            }
        }
        let begin = vk::RenderPassBeginInfo::default()
            .render_pass(self.render_pass)
            .framebuffer(self.framebuffer)
            .render_area(vk::Rect2D::default().extent(vk::Extent2D {
                width: w,
                height: h,
            }));
        let d = &self.shared.device;
        // SAFETY: the caller's promise; the render pass and framebuffer
        // are live, every rectangle lies inside the render area.
        unsafe {
            d.cmd_begin_render_pass(cmd, &begin, vk::SubpassContents::INLINE);
            for (id, rects) in &runs {
                let clear = [vk::ClearAttachment {
                    aspect_mask: vk::ImageAspectFlags::COLOR,
                    color_attachment: 0,
                    clear_value: vk::ClearValue {
                        color: vk::ClearColorValue { uint32: [*id; 4] },
                    },
                }];
                d.cmd_clear_attachments(cmd, &clear, rects);
            }
            d.cmd_end_render_pass(cmd);
        }
        self.declared()
    }

    /// The image as a frame declares it after [`Self::record_fill`].
    fn declared(&self) -> HostImage {
        HostImage {
            image: self.image.image,
            view: self.image.view,
            format: vk::Format::R32_UINT,
            extent: self.image.extent,
            usage: Self::USAGE,
            samples: vk::SampleCountFlags::from_raw(SAMPLES),
            layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
            written_by: (
                vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
                vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
            ),
        }
    }
}

impl Drop for MultisampledIds {
    fn drop(&mut self) {
        let d = &self.shared.device;
        // SAFETY: every frame that used them was waited for.
        unsafe {
            d.destroy_framebuffer(self.framebuffer, None);
            d.destroy_render_pass(self.render_pass, None);
        }
    }
}

/// One frame: `ids` cleared into the image, the pass recorded after, one
/// submission waited for.
fn run_frame(
    r: &GpuRenderer,
    pass: &mut ShadowPass,
    image: &MultisampledIds,
    view: &FrameView,
    ids: &[u32],
) {
    let record = |cmd| {
        // SAFETY: `cmd` is recording outside a render pass; the previous
        // frame was waited for.
        let declared = unsafe { image.record_fill(cmd, ids) };
        let view = FrameView {
            images: FrameImages {
                visibility: Some(declared),
                ..view.images
            },
            ..*view
        };
        // SAFETY: the pass and the image outlive the submission, which
        // the call waits for.
        unsafe { pass.record(cmd, 0, &view) }
    };
    // SAFETY: as above.
    unsafe { r.context.submit_and_wait(record) }.unwrap();
}

/// One 4× frame of `per_pixel` ids (every sample of a pixel holding its
/// id) on a fresh pass, against the CPU twin fed the same samples.
struct FrameAgainstTwin {
    status: PassStatus,
    gbuffer_words: Vec<u32>,
    masks: Vec<u32>,
    twin: VisibilityGBuffer,
    /// The twin's shadow-tested pixels, and how many of them have the
    /// twin's masks.
    tested: Vec<usize>,
    same: usize,
}

impl std::fmt::Debug for FrameAgainstTwin {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "{} of {} masks equal the twin's",
            self.same,
            self.tested.len()
        )
    }
}

fn frame_against_twin(
    r: &GpuRenderer,
    scene: &Scene,
    settings: IzbSettings,
    per_pixel: &[u32],
) -> FrameAgainstTwin {
    let ids: Vec<u32> = per_pixel
        .iter()
        .flat_map(|&id| [id; SAMPLES as usize])
        .collect();
    let mut pass = ShadowPass::new(r, scene.clone(), config(settings, SAMPLES)).unwrap();
    let image = MultisampledIds::new(&r.context.shared, scene.resolution);
    run_frame(r, &mut pass, &image, &view_at(scene, 0), per_pixel);
    // SAFETY: the frame was waited for.
    let (status, images) = unsafe { (pass.status(0).unwrap(), pass.read_back().unwrap()) };
    let halves = settings.edge_halves(scene);
    let twin = gbuffer_from_multisampled_visibility(scene, &ids, SAMPLES as usize, halves).unwrap();
    let cpu = render_cpu_on(scene, twin.gbuffer.clone(), settings);
    let tested: Vec<usize> = (0..per_pixel.len())
        .filter(|&i| twin.gbuffer.flags[i] & izb::gbuffer::flags::SHADOW_TESTED != 0)
        .collect();
    let same = tested
        .iter()
        .filter(|&&i| cpu.masks[i] == images.masks[i])
        .count();
    FrameAgainstTwin {
        status,
        gbuffer_words: images.gbuffer_words,
        masks: images.masks,
        twin,
        tested,
        same,
    }
}

fn config(settings: IzbSettings, samples: u32) -> ShadowPassConfig {
    ShadowPassConfig {
        settings,
        frames_in_flight: 1,
        cell_capacity: None,
        edge_slots: None,
        gbuffer: GBufferInput::MultisampledVisibility { samples },
    }
}

/// A multisampled visibility buffer whose samples all hold `render`'s
/// centre ids gives the pass `render`'s centre triangles on every pixel
/// (each pixel's samples agree, and its centre ray meets their triangle:
/// the ray cast hit it), edge pixels their sample surfaces from the 3×3
/// pixels' ids, and masks that equal the CPU twin's
/// (`gbuffer_from_multisampled_visibility`, f64 sample rays against the
/// pass's f32) on nearly every shadow-tested pixel, in the exact and LUT
/// modes; the validation layer stays silent.
#[test]
fn a_multisampled_visibility_buffer_gives_the_twin_s_masks() {
    let Some(r) = pass_renderer() else { return };
    if !takes_four_samples(&r) {
        return;
    }
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    let mut checked = 0;
    for mode in [SampleMode::Exact32, SampleMode::Lut32] {
        let settings = IzbSettings {
            mode,
            edge_surfaces: true,
            ..Default::default()
        };
        let batch = r.render(&scene, settings, GBufferSource::Gpu).unwrap();
        let centre = &batch.gbuffer.triangle_id;
        let f = frame_against_twin(&r, &scene, settings, centre);
        let (status, twin) = (&f.status, &f.twin);
        assert_eq!(status.visibility_rejected, 0, "{status:?}");
        assert_eq!(status.centre_uncovered, 0, "{status:?}");
        assert!(!status.edge_slots_overrun, "{status:?}");
        for (i, &word) in f.gbuffer_words.iter().enumerate() {
            assert_eq!(unpack_id_flags(word).0, centre[i], "{mode:?} pixel {i}");
        }
        assert_eq!((twin.rejected, twin.centre_uncovered), (0, 0));
        assert_eq!(&twin.gbuffer.triangle_id, centre);
        let edge_pixels = twin.gbuffer.edges.as_ref().unwrap().stats.edge_pixels;
        assert!(edge_pixels > 100, "{edge_pixels} edge pixels");
        let like_render = f
            .tested
            .iter()
            .filter(|&&i| batch.masks[i] == f.masks[i])
            .count();
        eprintln!(
            "{mode:?}: {} of {} shadow-tested masks equal the twin's, {like_render} \
             render's (BVH sample rays); {edge_pixels} edge pixels",
            f.same,
            f.tested.len()
        );
        assert!(f.tested.len() > 1000);
        assert!(f.same * 1000 >= f.tested.len() * 995, "{f:?}");
        assert!(centre.contains(&NO_HIT));
        assert_no_validation_messages(&r, "multisampled visibility input");
        checked += 1;
    }
    assert_eq!(checked, 2);
}

/// Pixels with ids past the pass's triangles are rejected misses that
/// nominate nothing for their neighbours, on the GPU as in the twin: the
/// same count of rejected and uncovered centres, the same centre
/// triangles everywhere, and the twin's masks around them.
#[test]
fn ids_past_the_triangles_are_rejected_as_the_twin_rejects_them() {
    let Some(r) = pass_renderer() else { return };
    if !takes_four_samples(&r) {
        return;
    }
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([64, 36])
        .unwrap();
    let settings = IzbSettings {
        mode: SampleMode::Lut32,
        edge_surfaces: true,
        ..Default::default()
    };
    let batch = r.render(&scene, settings, GBufferSource::Gpu).unwrap();
    let mut per_pixel = batch.gbuffer.triangle_id.clone();
    let triangles = scene.triangles.len() as u32;
    let hits: Vec<usize> = (0..per_pixel.len())
        .filter(|&i| per_pixel[i] != NO_HIT)
        .collect();
    for (k, &i) in hits.iter().step_by(13).enumerate() {
        per_pixel[i] = triangles + k as u32;
    }
    let bad = hits.iter().step_by(13).count();
    let f = frame_against_twin(&r, &scene, settings, &per_pixel);
    let (status, twin) = (&f.status, &f.twin);
    assert!(bad > 50, "{bad}");
    assert_eq!(twin.rejected, bad);
    assert_eq!(status.visibility_rejected as usize, bad, "{status:?}");
    assert_eq!(status.centre_uncovered as usize, twin.centre_uncovered);
    for (i, &word) in f.gbuffer_words.iter().enumerate() {
        assert_eq!(
            unpack_id_flags(word).0,
            twin.gbuffer.triangle_id[i],
            "pixel {i}"
        );
    }
    eprintln!(
        "{bad} rejected pixels; {} of {} masks equal the twin's",
        f.same,
        f.tested.len()
    );
    assert!(f.tested.len() > 500 && f.same * 1000 >= f.tested.len() * 995);
    assert_no_validation_messages(&r, "rejected multisampled ids");
}

/// Sample counts the pass cannot read are refused when it is made, and an
/// image of another sample count than the pass's at record time, before
/// any command: a single-sampled image to a multisampled pass and a
/// multisampled one to a single-sampled pass.
#[test]
fn multisampled_inputs_of_the_wrong_count_are_refused() {
    let Some(r) = pass_renderer() else { return };
    if !takes_four_samples(&r) {
        return;
    }
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([32, 18])
        .unwrap();
    let settings = IzbSettings {
        mode: SampleMode::Lut32,
        edge_surfaces: false,
        ..Default::default()
    };
    let mut refused = 0;
    for samples in [0, 1, 3, 16] {
        let e = ShadowPass::new(&r, scene.clone(), config(settings, samples))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains(&format!("{samples} samples")), "{e}");
        refused += 1;
    }
    assert_eq!(refused, 4);

    let image = MultisampledIds::new(&r.context.shared, scene.resolution);
    let single = HostTestImage::visibility(&r.context.shared, scene.resolution);
    let mut pass = ShadowPass::new(&r, scene.clone(), config(settings, SAMPLES)).unwrap();
    let mut view = view_at(&scene, 0);
    view.images.visibility = Some(HostImage {
        samples: vk::SampleCountFlags::TYPE_1,
        image: single.image,
        view: single.view,
        usage: HostTestImage::USAGE,
        ..image.declared()
    });
    assert_refused(
        &r,
        &mut pass,
        0,
        &view,
        "samples a pixel; the pass was made for TYPE_4",
    );
    let single_config = ShadowPassConfig {
        gbuffer: GBufferInput::Visibility,
        ..config(settings, SAMPLES)
    };
    let mut single_pass = ShadowPass::new(&r, scene.clone(), single_config).unwrap();
    view.images.visibility = Some(image.declared());
    assert_refused(&r, &mut single_pass, 0, &view, "TYPE_4 samples a pixel");
    assert_no_validation_messages(&r, "refused multisampled inputs");
}
