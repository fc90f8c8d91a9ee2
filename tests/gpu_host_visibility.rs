//! The shadow pass fed the host's visibility buffer
//! (`izb::gpu::shadow_pass::GBufferInput::Visibility`): an `R32_UINT`
//! image of triangle ids the test host fills before each frame in the same
//! command buffer, read under the declared-state contract of
//! `izb::gpu::host_images`. With `IZB_VALIDATION=1` the device runs the
//! validation layer with synchronization validation, and any message
//! fails the test. No Vulkan device: the test prints that it skipped,
//! unless `IZB_REQUIRE_GPU=1`.

mod common;

use ash::vk;
use common::gpu::assert_no_validation_messages;
use common::shadow_pass::{
    assert_refused, pass_renderer, run_visibility_frame, scene_at, settings, view_at, HostTestImage,
};
use glam::{DVec3, Vec3};
use izb::cpu::translate_vertices::translate_vertices;
use izb::cpu::SampleMode;
use izb::gpu::host_images::{FrameImages, HostImage};
use izb::gpu::shadow_pass::{FrameView, GBufferInput, ShadowPass, ShadowPassConfig};
use izb::gpu::shared::unpack_id_flags;
use izb::gpu::translate_vertices::WorldVertices;
use izb::gpu::GBufferSource;
use izb::scene;

/// A pass fed the host's visibility buffer: the GPU ray cast's ids of each
/// frame's view, copied into an `R32_UINT` image before the pass in the
/// same command buffer, give `render`'s masks bit for bit (the same
/// triangle, the same plane) while the camera and light move; the pass's
/// G-buffer matches its CPU twin (`gbuffer_from_visibility`) entry by
/// entry; nothing is allocated while recording and the validation layer,
/// with synchronization validation, stays silent about the declared
/// layouts and barriers.
#[test]
fn a_host_visibility_buffer_gives_render_s_masks_bit_for_bit() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    let mut compared = 0;
    for mode in [SampleMode::Exact32, SampleMode::Lut32] {
        let s = settings(mode);
        let config = ShadowPassConfig {
            settings: s,
            frames_in_flight: 2,
            cell_capacity: None,
            edge_slots: None,
            gbuffer: GBufferInput::Visibility,
        };
        let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
        let mut image = HostTestImage::visibility(&r.context.shared, scene.resolution);
        for k in 0..VISIBILITY_FRAMES {
            let view = view_at(&scene, 3 * k);
            let moved = scene_at(&scene, &view);
            let batch = r.render(&moved, s, GBufferSource::Gpu).unwrap();
            let ids = &batch.gbuffer.triangle_id;
            let (_, made) = run_visibility_frame(&r, &mut pass, &mut image, k, &view, ids).unwrap();
            assert_eq!(
                made,
                [0, 0],
                "{mode:?} frame {k}: allocations while recording"
            );
            // SAFETY: the frame was waited for; nothing is executing.
            let (status, images) =
                unsafe { (pass.status(k % 2).unwrap(), pass.read_back().unwrap()) };
            assert_eq!(status.visibility_rejected, 0, "{status:?}");
            assert_eq!(status.shadow_tested, batch.report.counters.shadow_tested);
            assert_eq!(images.masks, batch.masks, "{mode:?} frame {k}: masks");
            let twin = izb::gbuffer::gbuffer_from_visibility(&moved, ids).unwrap();
            assert_eq!(twin.rejected, 0);
            let mut differ = 0;
            for (i, &word) in images.gbuffer_words.iter().enumerate() {
                let (id, f) = izb::gpu::shared::unpack_id_flags(word);
                let f = f & !izb::gpu::shared::FLAG_NORMAL_FLIPPED;
                assert_eq!(id, twin.gbuffer.triangle_id[i], "pixel {i}");
                differ += usize::from(f != twin.gbuffer.flags[i]);
            }
            // f32 against f64: a pixel whose N·L is within rounding of 0
            // may be shadow-tested on one side only.
            let pixels = images.gbuffer_words.len();
            assert!(differ * 1000 <= pixels, "{differ} of {pixels} flags differ");
            compared += 1;
        }
        assert_no_validation_messages(&r, "visibility input");
    }
    assert_eq!(compared, 2 * VISIBILITY_FRAMES);
}

/// Frames of the visibility test per mode.
const VISIBILITY_FRAMES: usize = 4;

/// Bad visibility inputs are refused by name at record time, before any
/// command — a wrong format, size or usage, an undefined layout, a
/// visibility buffer to a ray-cast pass or none to a visibility pass —
/// and ids that name no triangle are stored as misses and counted, never
/// read out of bounds.
#[test]
fn bad_visibility_inputs_are_refused_or_counted() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([64, 36])
        .unwrap();
    let config = ShadowPassConfig {
        settings: settings(SampleMode::Lut32),
        frames_in_flight: 2,
        cell_capacity: None,
        edge_slots: None,
        gbuffer: GBufferInput::Visibility,
    };
    let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
    let mut image = HostTestImage::visibility(&r.context.shared, scene.resolution);
    let view = view_at(&scene, 0);
    let batch = r
        .render(&scene, config.settings, GBufferSource::Gpu)
        .unwrap();
    let mut ids = batch.gbuffer.triangle_id.clone();
    let triangles = scene.triangles.len() as u32;
    let hits: Vec<usize> = (0..ids.len()).filter(|&i| ids[i] != u32::MAX).collect();
    for &i in hits.iter().step_by(7) {
        ids[i] = triangles + i as u32;
    }
    let bad = hits.iter().step_by(7).count() as u32;
    run_visibility_frame(&r, &mut pass, &mut image, 0, &view, &ids).unwrap();
    // SAFETY: the frame was waited for.
    let status = unsafe { pass.status(0) }.unwrap();
    assert_eq!(status.visibility_rejected, bad);
    assert!(bad > 10);
    assert_no_validation_messages(&r, "out-of-range ids");

    let good = HostImage {
        image: image.image,
        view: image.view,
        format: vk::Format::R32_UINT,
        extent: scene.resolution,
        usage: HostTestImage::USAGE,
        samples: vk::SampleCountFlags::TYPE_1,
        layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        written_by: (vk::PipelineStageFlags::empty(), vk::AccessFlags::empty()),
    };
    let with = |change: &dyn Fn(&mut HostImage)| {
        let mut v = good;
        change(&mut v);
        FrameView {
            images: FrameImages {
                visibility: Some(v),
                ..FrameImages::default()
            },
            ..view
        }
    };
    let cases: [(FrameView, &str); 6] = [
        (with(&|v| v.format = vk::Format::R32_SFLOAT), "R32_UINT"),
        (
            with(&|v| v.samples = vk::SampleCountFlags::TYPE_4),
            "TYPE_4 samples a pixel",
        ),
        (with(&|v| v.extent = [32, 36]), "32x36"),
        (
            with(&|v| v.usage = vk::ImageUsageFlags::STORAGE),
            "lacks SAMPLED",
        ),
        (
            with(&|v| v.layout = vk::ImageLayout::UNDEFINED),
            "UNDEFINED",
        ),
        (
            FrameView {
                images: FrameImages::default(),
                ..view
            },
            "lacks a visibility buffer",
        ),
    ];
    let mut checked = 0;
    for (view, said) in &cases {
        assert_refused(&r, &mut pass, 1, view, said);
        checked += 1;
    }
    assert_eq!(checked, cases.len());
    let ray_cast = ShadowPassConfig {
        gbuffer: GBufferInput::RayCast,
        ..config
    };
    let mut ray_pass = ShadowPass::new(&r, scene.clone(), ray_cast).unwrap();
    let given = with(&|_| {});
    assert_refused(&r, &mut ray_pass, 0, &given, "gives a visibility buffer");
    assert_no_validation_messages(&r, "refused visibility inputs");
}

/// Frames of the moving-eye test per mode.
const MOVING_FRAMES: usize = 4;

/// With a visibility buffer the eye may move: each frame's vertices come
/// from the pass's anchor-relative double-singles (`translate_vertices`),
/// equal bit for bit to the CPU twin's, within one ulp of `render`'s
/// single rounding from `f64` — and the masks equal `render`'s for the
/// same moved view at ≥ 99.9 % of shadow-tested pixels (in practice all:
/// a vertex one ulp off moves no sample across an edge here).
#[test]
fn the_eye_moves_with_a_visibility_buffer() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    let (lo, hi) = scene.bounds();
    let world = WorldVertices::new(&scene, (lo + hi) * 0.5);
    let step = (hi - lo) * DVec3::new(0.013, 0.004, -0.009);
    let (mut compared, mut equal, mut tested) = (0, 0, 0);
    for mode in [SampleMode::Exact32, SampleMode::Lut32] {
        let s = settings(mode);
        let config = ShadowPassConfig {
            settings: s,
            frames_in_flight: 2,
            cell_capacity: None,
            edge_slots: None,
            gbuffer: GBufferInput::Visibility,
        };
        let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
        let mut image = HostTestImage::visibility(&r.context.shared, scene.resolution);
        for k in 0..MOVING_FRAMES {
            let mut view = view_at(&scene, 3 * k);
            view.camera.eye += step * k as f64;
            view.camera.target += step * k as f64;
            let moved = scene_at(&scene, &view);
            let batch = r.render(&moved, s, GBufferSource::Gpu).unwrap();
            let ids = &batch.gbuffer.triangle_id;
            let (_, made) = run_visibility_frame(&r, &mut pass, &mut image, k, &view, ids).unwrap();
            assert_eq!(
                made,
                [0, 0],
                "{mode:?} frame {k}: allocations while recording"
            );
            // SAFETY: the frame was waited for; nothing is executing.
            let (status, images, vertices) = unsafe {
                let status = pass.status(k % 2).unwrap();
                (
                    status,
                    pass.read_back().unwrap(),
                    pass.read_back_vertices().unwrap(),
                )
            };
            assert_eq!(status.visibility_rejected, 0, "{status:?}");
            let twin = translate_vertices(&world.pairs, world.eye(view.camera.eye));
            assert_eq!(vertices.len(), twin.len());
            let bits = |v: &[Vec3]| -> Vec<[u32; 3]> {
                v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
            };
            assert_eq!(bits(&vertices), bits(&twin), "{mode:?} frame {k}: vertices");
            for (i, &word) in images.gbuffer_words.iter().enumerate() {
                assert_eq!(unpack_id_flags(word).0, ids[i], "pixel {i}");
                if batch.gbuffer.flags[i] & izb::gbuffer::flags::SHADOW_TESTED != 0 {
                    tested += 1;
                    equal += usize::from(images.masks[i] == batch.masks[i]);
                }
            }
            compared += 1;
        }
        assert_no_validation_messages(&r, "moving eye");
    }
    assert_eq!(compared, 2 * MOVING_FRAMES);
    println!("moving eye: masks equal to render's at {equal} of {tested} shadow-tested pixels");
    assert!(
        tested > 1000 && equal * 1000 >= tested * 999,
        "{equal} of {tested}"
    );
}
