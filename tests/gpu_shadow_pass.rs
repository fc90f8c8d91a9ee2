//! The IZB as a pass recorded into the caller's command buffers
//! (`izb::gpu::shadow_pass`): made once, then per frame only commands —
//! no buffer, descriptor set, mapping, wait or read-back — with masks
//! bit-identical to `GpuRenderer::render`'s for the same view, a cell
//! list that overruns staying exact and growing between frames, and bad
//! views refused by name. With `IZB_VALIDATION=1` the device runs the
//! validation layer with synchronization validation, and any message
//! fails the test. No Vulkan device: the test prints that it skipped,
//! unless `IZB_REQUIRE_GPU=1`.

mod common;

use ash::vk;
use common::gpu::assert_no_validation_messages;
use common::shadow_pass::{
    assert_refused, pass_renderer, run_frame, scene_at, settings, view_at, HostTestImage,
};
use glam::DVec3;
use izb::cpu::{export_images, IzbSettings, SampleMode};
use izb::gpu::host_images::{FrameImages, HostImage};
use izb::gpu::resources::{BufferDesc, BufferDomain, GpuBuffer};
use izb::gpu::shadow_pass::{FrameView, GBufferInput, ShadowPass, ShadowPassConfig};
use izb::gpu::GBufferSource;
use izb::scene::{self, Light};

/// Frames recorded per mode.
const FRAMES: usize = 30;
/// Every this many frames, the pass's masks are compared with `render`'s.
const COMPARE_EVERY: usize = 10;

#[test]
fn a_resident_pass_records_frames_equal_to_render_allocating_nothing() {
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
            gbuffer: GBufferInput::RayCast,
        };
        let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
        let mut record_us = Vec::new();
        let (mut buffers, mut sets) = (0, 0);
        for k in 0..FRAMES {
            let view = view_at(&scene, k);
            let before = r.context.shared.allocations();
            record_us.push(run_frame(&r, &mut pass, k, &view));
            let after = r.context.shared.allocations();
            buffers += after[0] - before[0];
            sets += after[1] - before[1];
            // SAFETY: the frame's submission was waited for.
            let status = unsafe { pass.status(k % 2) }.unwrap();
            assert!(
                !status.cell_list_overrun && status.loop_cap_trips == 0,
                "{status:?}"
            );
            if k % COMPARE_EVERY == 0 {
                // SAFETY: nothing of the pass is executing.
                let images = unsafe { pass.read_back() }.unwrap();
                let moved = scene_at(&scene, &view);
                let batch = r.render(&moved, s, GBufferSource::Gpu).unwrap();
                assert_eq!(images.masks, batch.masks, "{mode:?}, frame {k}");
                assert_eq!(status.shadow_tested, batch.report.counters.shadow_tested);
                compared += 1;
            }
        }
        record_us.sort_by(f64::total_cmp);
        println!(
            "{mode:?}: {FRAMES} frames, record median {:.1} µs (max {:.1}); buffers {buffers}, \
             descriptor sets {sets} made while recording",
            record_us[FRAMES / 2],
            record_us[FRAMES - 1]
        );
        assert_eq!(
            (buffers, sets),
            (0, 0),
            "{mode:?}: allocations inside frames"
        );
        // The camera and light moved every frame: parameters only, so each
        // slot recorded its fixed commands once and executed them since.
        assert_eq!(pass.fixed_command_recordings(), 2, "{mode:?}");
        assert_no_validation_messages(&r, "shadow pass");
    }
    assert_eq!(compared, 2 * FRAMES / COMPARE_EVERY);
}

#[test]
fn an_overrun_frame_is_exact_says_so_and_the_pass_grows() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    let s = settings(SampleMode::Exact32);
    let config = ShadowPassConfig {
        settings: s,
        frames_in_flight: 2,
        cell_capacity: Some(64),
        edge_slots: None,
        gbuffer: GBufferInput::RayCast,
    };
    let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
    let view = view_at(&scene, 0);
    let batch = r
        .render(&scene_at(&scene, &view), s, GBufferSource::Gpu)
        .unwrap();
    let need = u64::from(batch.report.counters.cell_entries);
    // The old list is released once both slots have recorded after the
    // growth: still held after frame 1 (slot 1), gone after frame 2.
    let retired_after = [1, 1, 0];
    let mut frames = 0;
    for (k, retired) in retired_after.into_iter().enumerate() {
        run_frame(&r, &mut pass, k, &view);
        // SAFETY: the frame was waited for; nothing is executing.
        let (status, images) = unsafe { (pass.status(k % 2).unwrap(), pass.read_back().unwrap()) };
        assert_eq!(status.cell_list_overrun, k == 0, "frame {k}: {status:?}");
        assert_eq!(status.cell_entries, need);
        assert_eq!(images.masks, batch.masks, "frame {k}'s masks");
        assert_eq!(pass.grow(&status).unwrap(), k == 0);
        assert_eq!(pass.retired_sets(), retired, "after frame {k}");
        frames += 1;
    }
    // Slot 0 before and after the growth, slot 1 once (after it).
    assert_eq!(pass.fixed_command_recordings(), 3);
    assert_eq!(pass.cell_capacity(), need + need / 2, "half again the need");
    assert_eq!(frames, 3);
    assert_no_validation_messages(&r, "shadow pass overrun");
}

#[test]
fn bad_views_and_configurations_are_refused_by_name() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([64, 36])
        .unwrap();
    let edge = ShadowPassConfig {
        settings: IzbSettings {
            edge_surfaces: true,
            ..IzbSettings::default()
        },
        frames_in_flight: 2,
        cell_capacity: None,
        edge_slots: None,
        gbuffer: GBufferInput::Visibility,
    };
    // Edge surfaces with a visibility buffer (one surface a pixel), and
    // with no slot for them.
    let no_slots = ShadowPassConfig {
        edge_slots: Some(0),
        gbuffer: GBufferInput::RayCast,
        ..edge
    };
    for (config, said) in [(edge, "edge_surfaces"), (no_slots, "edge_slots is 0")] {
        let refused = ShadowPass::new(&r, scene.clone(), config).err().unwrap();
        assert!(refused.to_string().contains(said), "{refused}");
    }
    let config = ShadowPassConfig {
        settings: settings(SampleMode::Lut32),
        gbuffer: GBufferInput::RayCast,
        ..edge
    };
    let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
    let good = view_at(&scene, 1);
    let mut far_light = good;
    far_light.light = Light::Point {
        position: DVec3::splat(1e12),
    };
    let mut area = good;
    area.light_radius = 0.05;
    let cases: [(&FrameView, usize, &str); 3] = [
        (&far_light, 0, "point light"),
        (&area, 0, "area"),
        (&good, 2, "frame slot 2"),
    ];
    let mut checked = 0;
    for (view, slot, said) in cases {
        assert_refused(&r, &mut pass, slot, view, said);
        checked += 1;
    }
    assert_eq!(checked, cases.len());
    // The refused views left the scene's view as it was: a good frame
    // still records.
    run_frame(&r, &mut pass, 0, &good);
    assert_no_validation_messages(&r, "refused views");
}

/// Edge pixels' per-sample surfaces in a ray-cast pass: with slots far
/// too few the first frame keeps the surfaces that fit, says so with the
/// need, grows, and the next frames' masks equal `render`'s, whose batch
/// frame traces the same surfaces.
#[test]
fn edge_surfaces_in_the_pass_overrun_say_so_grow_and_equal_render() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    const SLOTS: u64 = 16;
    let mut checked = 0;
    for mode in [SampleMode::Exact32, SampleMode::Lut32] {
        let s = IzbSettings {
            edge_surfaces: true,
            ..settings(mode)
        };
        assert!(s.uses_edge_surfaces(&scene));
        let config = ShadowPassConfig {
            settings: s,
            frames_in_flight: 2,
            cell_capacity: None,
            edge_slots: Some(SLOTS),
            gbuffer: GBufferInput::RayCast,
        };
        let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
        let mut first_need = 0;
        for k in 0..3 {
            let view = view_at(&scene, k);
            let before = r.context.shared.allocations();
            run_frame(&r, &mut pass, k, &view);
            assert_eq!(r.context.shared.allocations(), before, "frame {k}");
            // SAFETY: the frame was waited for; nothing is executing.
            let (status, images) =
                unsafe { (pass.status(k % 2).unwrap(), pass.read_back().unwrap()) };
            assert_eq!(
                status.edge_slots_overrun,
                k == 0,
                "{mode:?} frame {k}: {status:?}"
            );
            assert!(status.edge_slots_needed > SLOTS, "{status:?}");
            let batch = r
                .render(&scene_at(&scene, &view), s, GBufferSource::Gpu)
                .unwrap();
            let differing = images
                .masks
                .iter()
                .zip(&batch.masks)
                .filter(|(a, b)| a != b)
                .count();
            if k == 0 {
                // The pixels past the slots kept tangent-plane masks.
                first_need = status.edge_slots_needed;
                println!("{mode:?}: {differing} pixels without their edge surfaces");
                assert!(differing > 0);
            } else {
                assert_eq!(differing, 0, "{mode:?} frame {k}");
            }
            assert_eq!(pass.grow(&status).unwrap(), k == 0);
            checked += 1;
        }
        assert_eq!(pass.edge_slots(), first_need + first_need / 2);
    }
    assert_eq!(checked, 6);
    assert_no_validation_messages(&r, "edge surfaces in the pass");
}

/// The pass writes the host's output images — the masks (`R32_UINT`, or
/// `R32G32_UINT` with `Paired64`'s two halves under an area light) and the
/// lit fraction (`R16_UNORM`, `R8_UNORM`) — equal to the CPU twin's
/// (`izb::cpu::export_images`) of `render`'s masks and G-buffer, over two
/// frames per case (the second declares the layout and the copy-out read
/// the first left); bad output declarations are refused by name.
#[test]
fn the_pass_writes_the_host_s_mask_and_lit_fraction_images() {
    let Some(r) = pass_renderer() else { return };
    let shared = &r.context.shared;
    let point = scene::load("default")
        .unwrap()
        .with_resolution([64, 36])
        .unwrap();
    let mut area = point.clone();
    area.light_radius = 0.02;
    // The last case traces edge surfaces: its lit fraction is over the
    // samples each edge pixel counts.
    let cases = [
        (
            &point,
            SampleMode::Exact32,
            vk::Format::R32_UINT,
            vk::Format::R16_UNORM,
            16,
            false,
        ),
        (
            &area,
            SampleMode::Paired64,
            vk::Format::R32G32_UINT,
            vk::Format::R8_UNORM,
            8,
            false,
        ),
        (
            &point,
            SampleMode::Lut32,
            vk::Format::R32_UINT,
            vk::Format::R16_UNORM,
            16,
            true,
        ),
    ];
    let mut checked = 0;
    for (scene, mode, mask_format, lit_format, bits, edge_surfaces) in cases {
        let s = IzbSettings {
            edge_surfaces,
            ..settings(mode)
        };
        assert_eq!(s.uses_edge_surfaces(scene), edge_surfaces);
        let config = ShadowPassConfig {
            settings: s,
            frames_in_flight: 2,
            cell_capacity: None,
            edge_slots: None,
            gbuffer: GBufferInput::RayCast,
        };
        let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
        let halves = s.mask_halves(scene);
        assert_eq!(halves, 1 + usize::from(mode == SampleMode::Paired64));
        let pixels = scene.pixel_count();
        let mut masks_out = HostTestImage::output(shared, scene.resolution, mask_format);
        let mut lit_out = HostTestImage::output(shared, scene.resolution, lit_format);
        for k in 0..2 {
            let view = view_at(scene, 5 * k);
            let copy = |bytes| {
                let desc = BufferDesc {
                    name: "copy out",
                    pass: "test",
                    size: bytes as u64,
                    domain: BufferDomain::Readback,
                };
                GpuBuffer::new(shared, desc).unwrap()
            };
            let (masks_copy, lit_copy) = (copy(pixels * 4 * halves), copy(pixels * bits / 8));
            let record = |cmd| {
                let view = FrameView {
                    images: FrameImages {
                        masks: Some(masks_out.as_output()),
                        lit_fraction: Some(lit_out.as_output()),
                        ..FrameImages::default()
                    },
                    ..view
                };
                // SAFETY: as in `run_frame`; the images and copies outlive
                // the submission, which the call waits for.
                unsafe {
                    pass.record(cmd, k % 2, &view)?;
                    masks_out.record_copy_out(cmd, &masks_copy);
                    lit_out.record_copy_out(cmd, &lit_copy);
                }
                Ok(())
            };
            // SAFETY: everything recorded outlives the call, which waits.
            unsafe { r.context.submit_and_wait(record) }.unwrap();
            let batch = r
                .render(&scene_at(scene, &view), s, GBufferSource::Gpu)
                .unwrap();
            assert_eq!(batch.masks_high.len(), pixels * (halves - 1));
            let twin = export_images(&batch.masks, &batch.masks_high, &batch.gbuffer, bits as u32);
            let words: Vec<u32> = bytemuck::pod_collect_to_vec(masks_copy.mapped().unwrap());
            assert_eq!(
                words[..pixels * halves],
                twin.masks[..],
                "{mode:?} frame {k}: masks"
            );
            let lit: Vec<u16> = match bits {
                16 => bytemuck::pod_collect_to_vec(&lit_copy.mapped().unwrap()[..pixels * 2]),
                _ => lit_copy.mapped().unwrap()[..pixels]
                    .iter()
                    .map(|&b| u16::from(b))
                    .collect(),
            };
            // UNORM conversion may round a tie (k/64 · 255 never is one,
            // 16/32 · 65535 is) either way: one code at most.
            let off = lit
                .iter()
                .zip(&twin.lit_fraction)
                .filter(|(g, c)| g != c)
                .inspect(|(g, c)| assert!(g.abs_diff(**c) <= 1, "{mode:?}: {g} against {c}"))
                .count();
            let partial = twin
                .lit_fraction
                .iter()
                .filter(|&&c| c != 0 && c != (1 << bits) - 1);
            assert!(partial.count() > 0, "{mode:?}: no penumbra to compare");
            println!("{mode:?} frame {k}: lit codes at a rounding tie {off} of {pixels}");
            checked += 1;
        }
        assert_no_validation_messages(&r, "output images");
    }
    assert_eq!(checked, 2 * cases.len());

    // Bad declarations, refused before any command.
    let scene = &point;
    let config = ShadowPassConfig {
        settings: settings(SampleMode::Lut32),
        frames_in_flight: 1,
        cell_capacity: None,
        edge_slots: None,
        gbuffer: GBufferInput::RayCast,
    };
    let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
    let masks_out = HostTestImage::output(shared, scene.resolution, vk::Format::R32_UINT);
    let good = masks_out.as_output();
    let bad = |change: &dyn Fn(&mut HostImage), lit: bool| {
        let mut image = good;
        change(&mut image);
        let images = if lit {
            FrameImages {
                lit_fraction: Some(image),
                ..FrameImages::default()
            }
        } else {
            FrameImages {
                masks: Some(image),
                ..FrameImages::default()
            }
        };
        FrameView {
            images,
            ..view_at(scene, 0)
        }
    };
    let refusals = [
        (
            bad(&|i| i.format = vk::Format::R32G32_UINT, false),
            "R32_UINT",
        ),
        (
            bad(&|i| i.usage = vk::ImageUsageFlags::SAMPLED, false),
            "lacks STORAGE",
        ),
        (bad(&|i| i.extent = [64, 35], false), "64x35"),
        (bad(&|_| {}, true), "lit fraction image cannot be written"),
    ];
    let mut refused = 0;
    for (view, said) in &refusals {
        assert_refused(&r, &mut pass, 0, view, said);
        refused += 1;
    }
    assert_eq!(refused, refusals.len());
    assert_no_validation_messages(&r, "refused outputs");
}

/// izb's host counters see what the pass does: recording adds no buffer,
/// set, mapping or wait; a read-back is one waited submission through the
/// buffer the pass keeps — made and mapped by the first read-back (or a
/// larger one), reused by the next; the pass's timestamps time the frame.
#[test]
fn recording_adds_nothing_and_read_backs_keep_their_buffer() {
    use izb::gpu::context::HostCounts;
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([64, 36])
        .unwrap();
    let config = ShadowPassConfig {
        settings: settings(SampleMode::Lut32),
        frames_in_flight: 1,
        cell_capacity: None,
        edge_slots: None,
        gbuffer: GBufferInput::RayCast,
    };
    let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
    let counts = || r.context.shared.host_counts();
    let since = |before: HostCounts| {
        let now = counts();
        [
            now.buffers - before.buffers,
            now.descriptor_sets - before.descriptor_sets,
            now.mappings - before.mappings,
            now.waits - before.waits,
        ]
    };
    let view = view_at(&scene, 1);
    let mut in_record = None;
    let record = |cmd| {
        let before = counts();
        // SAFETY: `cmd` is recording on this thread and submitted to the
        // pass's device; no earlier frame of the pass exists.
        let recorded = unsafe { pass.record(cmd, 0, &view) };
        in_record = Some(since(before));
        recorded
    };
    let before = counts();
    // SAFETY: the pass and its buffers outlive the call, which waits.
    unsafe { r.context.submit_and_wait(record) }.unwrap();
    assert_eq!(in_record, Some([0, 0, 0, 0]), "recording made or waited");
    assert_eq!(since(before), [0, 0, 0, 1], "the frame's own submission");
    // SAFETY: the frame was waited for (above), for every call below.
    let millis = unsafe { pass.gpu_millis(0) }.unwrap();
    if r.context.shared.timestamp_period_ns.is_some() {
        let m = millis.expect("the queue has timestamps");
        assert!(m.total > 0.0 && m.evaluate <= m.total, "{m:?}");
    }
    let mut checked = 0;
    // The G-buffer's read-back is the largest: it makes the buffer.
    for (read, made) in [(0, [1, 0, 1, 1]), (1, [0, 0, 0, 1]), (0, [0, 0, 0, 1])] {
        let before = counts();
        match read {
            // SAFETY: as above.
            0 => drop(unsafe { pass.read_back_gbuffer() }.unwrap()),
            // SAFETY: as above.
            _ => drop(unsafe { pass.read_back_frame() }.unwrap()),
        }
        assert_eq!(since(before), made, "read-back {checked}");
        checked += 1;
    }
    assert_eq!(checked, 3);
}

/// A pass fed the CPU twin's G-buffer (`GBufferInput::Uploaded`: the
/// batch `render`'s with an uploaded G-buffer, on the same pass) is that
/// view's: made only through `with_uploaded_gbuffer`, from a G-buffer of
/// its size; its frame's masks are the twin's bit for bit (Exact32), and
/// a moved camera or light and a resize are refused by name.
#[test]
fn an_uploaded_gbuffer_pass_is_one_view_s_and_gives_the_twin_s_masks() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([64, 36])
        .unwrap();
    let s = settings(SampleMode::Exact32);
    let config = ShadowPassConfig {
        settings: s,
        frames_in_flight: 1,
        cell_capacity: None,
        edge_slots: None,
        gbuffer: GBufferInput::Uploaded,
    };
    let refused = ShadowPass::new(&r, scene.clone(), config).err().unwrap();
    assert!(
        refused.to_string().contains("with_uploaded_gbuffer"),
        "{refused}"
    );
    let cpu = izb::cpu::render_cpu(&scene, &izb::bvh::SceneBvh::build(&scene), s);
    let small = scene.clone().with_resolution([32, 18]).unwrap();
    let refused = ShadowPass::with_uploaded_gbuffer(&r, small, config, &cpu.gbuffer)
        .err()
        .unwrap();
    assert!(
        refused.to_string().contains("uploaded G-buffer is 64x36"),
        "{refused}"
    );

    let mut pass =
        ShadowPass::with_uploaded_gbuffer(&r, scene.clone(), config, &cpu.gbuffer).unwrap();
    let own = FrameView {
        camera: scene.camera,
        light: scene.light,
        light_radius: scene.light_radius,
        images: FrameImages::default(),
    };
    run_frame(&r, &mut pass, 0, &own);
    // SAFETY: run_frame waited for the frame.
    let frame = unsafe { pass.read_back_frame() }.unwrap();
    let tested = cpu.visibility.iter().filter(|v| !v.is_nan()).count();
    assert!(tested > 1000, "{tested} shadow-tested pixels");
    assert_eq!(frame.masks, cpu.masks, "the twin's masks bit for bit");

    let moved = view_at(&scene, 1);
    let mut lit_elsewhere = own;
    lit_elsewhere.light = moved.light;
    let mut checked = 0;
    for view in [&moved, &lit_elsewhere] {
        assert_refused(&r, &mut pass, 0, view, "one view's");
        checked += 1;
    }
    assert_eq!(checked, 2);
    let refused = pass.resize([32, 18]).err().unwrap();
    assert!(
        refused.to_string().contains("one image size's"),
        "{refused}"
    );
    // The refusals left the pass as it was.
    run_frame(&r, &mut pass, 1, &own);
    // SAFETY: run_frame waited for the frame.
    let again = unsafe { pass.read_back_frame() }.unwrap();
    assert_eq!(again.masks, cpu.masks);
    assert_no_validation_messages(&r, "an uploaded G-buffer's pass");
}
