//! The shadow pass fed the host's depth and normal images
//! (`izb::gpu::shadow_pass::GBufferInput::DepthNormal`): the test host
//! fills a depth image (`D32_SFLOAT`, `D24_UNORM_S8_UINT`,
//! `D32_SFLOAT_S8_UINT`; standard and reverse Z, finite and infinite far)
//! and an `R32G32B32A32_SFLOAT` normal image with what its raster would
//! hold for each frame's view — the CPU ray cast's view depths, rounded to
//! the format, and its normals — before the pass, in the same command
//! buffer. With `IZB_VALIDATION=1` the device runs the validation layer
//! with synchronization validation, and any message fails the test. No
//! Vulkan device: the test prints that it skipped, unless
//! `IZB_REQUIRE_GPU=1`.

mod common;

use ash::vk;
use common::gpu::assert_no_validation_messages;
use common::shadow_pass::{
    assert_refused, pass_renderer, scene_at, settings, view_at, HostTestImage,
};
use glam::Vec3;
use izb::bvh::SceneBvh;
use izb::cpu::{render_cpu, render_cpu_on, resolve, SampleMode};
use izb::gbuffer::{
    gbuffer, gbuffer_from_depth, DepthConvention, GBuffer, NO_HIT, UNORM24_DEPTH_STEP,
};
use izb::gpu::host_images::{FrameImages, HostImage};
use izb::gpu::resources::GpuBuffer;
use izb::gpu::shadow_pass::{FrameView, GBufferInput, ShadowPass, ShadowPassConfig};
use izb::gpu::{GpuError, GpuRenderer};
use izb::metrics::metrics;
use izb::reference::{reference, ReferenceSettings};
use izb::scene::{self, Scene};

/// A depth format and convention the test host renders with.
#[derive(Clone, Copy, Debug)]
struct DepthCase {
    format: vk::Format,
    convention: DepthConvention,
}

impl DepthCase {
    fn new(format: vk::Format, scene: &Scene, reversed: bool, infinite: bool) -> Self {
        let convention = DepthConvention {
            near: scene.camera.near,
            far: (!infinite).then_some(scene.camera.far),
            reversed,
        };
        DepthCase { format, convention }
    }

    /// 24-bit unorm depth (the combined and packed D24 formats).
    fn is_unorm24(&self) -> bool {
        matches!(
            self.format,
            vk::Format::D24_UNORM_S8_UINT | vk::Format::X8_D24_UNORM_PACK32
        )
    }
}

/// What the test host's raster would write for `scene`'s view: per pixel
/// the depth texel (4 bytes: an `f32`, or a 24-bit unorm in the low
/// bits) and the value a shader reads from it, and the normal texel
/// (RGBA32F; every other pixel's normal facing away, which the pass
/// flips) — from the CPU ray cast's view depth and normal.
struct HostFrame {
    depth_texels: Vec<u32>,
    depth_read: Vec<f32>,
    normal_texels: Vec<[f32; 4]>,
    normals: Vec<Vec3>,
}

fn host_frame(cast: &GBuffer, case: DepthCase) -> HostFrame {
    let c = case.convention;
    let far_value = if c.reversed { 0.0 } else { 1.0 };
    let unorm = f64::from((1u32 << 24) - 1);
    let mut f = HostFrame {
        depth_texels: Vec::new(),
        depth_read: Vec::new(),
        normal_texels: Vec::new(),
        normals: Vec::new(),
    };
    for (i, &z) in cast.depth.iter().enumerate() {
        let d = if cast.triangle_id[i] == NO_HIT {
            far_value
        } else {
            c.depth_at(f64::from(z))
        };
        let (texel, read) = if case.is_unorm24() {
            let k = (d * unorm).round() as u32;
            (k, (f64::from(k) / unorm) as f32)
        } else {
            ((d as f32).to_bits(), d as f32)
        };
        f.depth_texels.push(texel);
        f.depth_read.push(read);
        let n = if i % 2 == 1 {
            -cast.normal[i]
        } else {
            cast.normal[i]
        };
        f.normal_texels.push([n.x, n.y, n.z, 0.0]);
        f.normals.push(n);
    }
    f
}

/// The test host's depth and normal images.
struct HostInputs {
    depth: HostTestImage,
    normal: HostTestImage,
}

impl HostInputs {
    fn new(r: &GpuRenderer, extent: [u32; 2], format: vk::Format) -> Self {
        let shared = &r.context.shared;
        HostInputs {
            depth: HostTestImage::input(shared, extent, format),
            normal: HostTestImage::input(shared, extent, vk::Format::R32G32B32A32_SFLOAT),
        }
    }
}

/// Frame `k`: the host's depth and normal copied into its images and the
/// pass recorded after them, in one command buffer; returns the buffers
/// and sets made while recording.
fn run_depth_frame(
    r: &GpuRenderer,
    pass: &mut ShadowPass,
    inputs: &mut HostInputs,
    k: usize,
    view: &FrameView,
    frame: &HostFrame,
) -> Result<[u64; 2], GpuError> {
    let shared = &r.context.shared;
    let depth_staging = GpuBuffer::staging(shared, bytemuck::cast_slice(&frame.depth_texels))?;
    let normal_staging = GpuBuffer::staging(shared, bytemuck::cast_slice(&frame.normal_texels))?;
    let slot = k % pass.frames_in_flight();
    let mut made = [0; 2];
    let record = |cmd| {
        // SAFETY: `cmd` is recording; the staging buffers outlive the
        // submission, which the call waits for.
        let (depth, normal) = unsafe {
            (
                inputs.depth.record_fill(cmd, &depth_staging),
                inputs.normal.record_fill(cmd, &normal_staging),
            )
        };
        let view = FrameView {
            images: FrameImages {
                depth: Some(depth),
                normal: Some(normal),
                ..view.images
            },
            ..*view
        };
        let before = shared.allocations();
        // SAFETY: as in `common::shadow_pass::run_frame`; the images live
        // until the wait.
        let recorded = unsafe { pass.record(cmd, slot, &view) };
        let after = shared.allocations();
        made = [after[0] - before[0], after[1] - before[1]];
        recorded
    };
    // SAFETY: the pass, the images and the staging buffers outlive the
    // call, which waits.
    unsafe { r.context.submit_and_wait(record) }?;
    Ok(made)
}

fn pass_for<'r>(
    r: &'r GpuRenderer,
    scene: &Scene,
    mode: SampleMode,
    case: DepthCase,
) -> ShadowPass<'r> {
    let config = ShadowPassConfig {
        settings: settings(mode),
        frames_in_flight: 2,
        cell_capacity: None,
        edge_slots: None,
        gbuffer: GBufferInput::DepthNormal(case.convention),
    };
    ShadowPass::new(r, scene.clone(), config).unwrap()
}

/// Per depth format and convention, over frames whose camera and light
/// move: the pass's G-buffer matches its CPU twin (`gbuffer_from_depth`
/// on the values the shader reads) entry by entry; the CPU twin's later
/// passes fed that G-buffer read back give the pass's Exact32 masks bit
/// for bit; nothing is allocated while recording; and the validation
/// layer with synchronization validation is silent. Printed: how many
/// shadow-tested pixels equal `render`'s masks (its own ray cast), per
/// format — the depth's precision at work.
#[test]
fn host_depth_and_normals_give_the_twin_s_masks_bit_for_bit() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    let cases = [
        DepthCase::new(vk::Format::D32_SFLOAT, &scene, true, false),
        DepthCase::new(vk::Format::D32_SFLOAT, &scene, true, true),
        DepthCase::new(vk::Format::D32_SFLOAT, &scene, false, false),
        DepthCase::new(vk::Format::D32_SFLOAT_S8_UINT, &scene, true, false),
        DepthCase::new(vk::Format::D24_UNORM_S8_UINT, &scene, true, false),
        DepthCase::new(vk::Format::D24_UNORM_S8_UINT, &scene, false, false),
    ];
    let mut compared = 0;
    for case in cases {
        let mode = SampleMode::Exact32;
        let mut pass = pass_for(&r, &scene, mode, case);
        let mut inputs = HostInputs::new(&r, scene.resolution, case.format);
        let (mut equal, mut tested) = (0, 0);
        for k in 0..DEPTH_FRAMES {
            let view = view_at(&scene, 3 * k);
            let moved = scene_at(&scene, &view);
            let bvh = SceneBvh::build(&moved);
            let cast = gbuffer(&moved, &bvh);
            let frame = host_frame(&cast, case);
            let made = run_depth_frame(&r, &mut pass, &mut inputs, k, &view, &frame).unwrap();
            assert_eq!(
                made,
                [0, 0],
                "{case:?} frame {k}: allocations while recording"
            );
            // SAFETY: the frame was waited for; nothing is executing.
            let (status, images, g) = unsafe {
                (
                    pass.status(k % 2).unwrap(),
                    pass.read_back().unwrap(),
                    pass.read_back_gbuffer().unwrap(),
                )
            };
            assert_eq!(status.visibility_rejected, 0, "{case:?}: {status:?}");
            let step = if case.is_unorm24() {
                UNORM24_DEPTH_STEP
            } else {
                0.0
            };
            let twin = gbuffer_from_depth(
                &moved,
                &frame.depth_read,
                &frame.normals,
                case.convention,
                step,
            )
            .unwrap();
            assert_eq!(twin.rejected, 0);
            assert_g_buffers_agree(
                &g,
                &twin.gbuffer,
                &frame,
                case,
                &format!("{case:?} frame {k}"),
            );
            let cpu = render_cpu_on(&moved, g, settings(mode));
            assert_eq!(images.masks, cpu.masks, "{case:?} frame {k}: masks");
            let truth = render_cpu(&moved, &bvh, settings(mode));
            for i in 0..moved.pixel_count() {
                if truth.gbuffer.flags[i] & izb::gbuffer::flags::SHADOW_TESTED != 0 {
                    tested += 1;
                    equal += usize::from(images.masks[i] == truth.masks[i]);
                }
            }
            compared += 1;
        }
        println!(
            "{:?} reversed {} far {:?}: masks equal to render's at {equal} of {tested} shadow-tested pixels",
            case.format, case.convention.reversed, case.convention.far
        );
        assert_no_validation_messages(&r, "depth input");
    }
    assert_eq!(compared, cases.len() * DEPTH_FRAMES);
}

/// Frames per depth case.
const DEPTH_FRAMES: usize = 2;

/// The GPU's G-buffer against its CPU twin's (`f32` against `f64`):
/// the same ids everywhere, flags equal but for pixels within rounding
/// of N·L = 0, normals within 2⁻²⁰, and points within 2⁻¹² of the µQuad
/// plus what one ulp of the depth value read moves them (the device's
/// unorm-to-float conversion may round the other way: |dz| =
/// z²(1 − n/f)/n · |dD|, with standard Z's u = 1 − D small far away).
fn assert_g_buffers_agree(
    gpu: &GBuffer,
    twin: &GBuffer,
    frame: &HostFrame,
    case: DepthCase,
    what: &str,
) {
    assert_eq!(gpu.triangle_id, twin.triangle_id, "{what}: ids");
    let c = case.convention;
    let mut differ = 0;
    for i in 0..twin.triangle_id.len() {
        differ += usize::from(gpu.flags[i] != twin.flags[i]);
        if twin.triangle_id[i] == NO_HIT {
            continue;
        }
        let size = f64::from(twin.axis_x[i].length().max(twin.axis_y[i].length()));
        let (z, p) = (
            f64::from(twin.depth[i]),
            f64::from(twin.position[i].length()),
        );
        let ulp = f64::from(frame.depth_read[i].abs().max(f32::MIN_POSITIVE)) * 2f64.powi(-23);
        let moved = p * z * (1.0 - c.near_over_far()) / c.near * ulp;
        let off = f64::from((gpu.position[i] - twin.position[i]).length());
        assert!(
            off <= moved + size / 4096.0,
            "{what} pixel {i}: P off by {off} of {size} (+{moved})"
        );
        let turned = (gpu.normal[i] - twin.normal[i]).length();
        assert!(
            turned <= 1.0 / 1048576.0,
            "{what} pixel {i}: normal off by {turned}"
        );
        let (a, b) = (
            gpu.depth_uncertainty.as_ref().unwrap()[i],
            twin.depth_uncertainty.as_ref().unwrap()[i],
        );
        assert!(
            (a - b).abs() <= b / 256.0,
            "{what} pixel {i}: depth uncertainty {a} against {b}"
        );
    }
    let pixels = twin.triangle_id.len();
    assert!(
        differ * 1000 <= pixels,
        "{what}: {differ} of {pixels} flags differ"
    );
}

/// Bad depth and normal inputs are refused by name at create or record
/// time, before any command — a wrong format, size or usage, a missing
/// normal, a visibility buffer or nothing in their place, a bad depth
/// convention — and pixels whose normal is zero are stored as misses and
/// counted, never used.
#[test]
fn bad_depth_inputs_are_refused_or_counted() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([64, 36])
        .unwrap();
    let case = DepthCase::new(vk::Format::D32_SFLOAT, &scene, true, false);
    let mut bad_convention = case.convention;
    bad_convention.near = 0.0;
    let config = ShadowPassConfig {
        settings: settings(SampleMode::Lut32),
        frames_in_flight: 2,
        cell_capacity: None,
        edge_slots: None,
        gbuffer: GBufferInput::DepthNormal(bad_convention),
    };
    let refused = ShadowPass::new(&r, scene.clone(), config).err().unwrap();
    assert!(refused.to_string().contains("near plane is 0"), "{refused}");

    let mut pass = pass_for(&r, &scene, SampleMode::Lut32, case);
    let mut inputs = HostInputs::new(&r, scene.resolution, case.format);
    let view = view_at(&scene, 0);
    let cast = gbuffer(&scene, &SceneBvh::build(&scene));
    let mut frame = host_frame(&cast, case);
    let hits: Vec<usize> = (0..cast.triangle_id.len())
        .filter(|&i| cast.triangle_id[i] != NO_HIT)
        .collect();
    for &i in hits.iter().step_by(5) {
        frame.normal_texels[i] = [0.0; 4];
    }
    let zeroed = hits.iter().step_by(5).count() as u32;
    run_depth_frame(&r, &mut pass, &mut inputs, 0, &view, &frame).unwrap();
    // SAFETY: the frame was waited for.
    let status = unsafe { pass.status(0) }.unwrap();
    assert_eq!(status.visibility_rejected, zeroed);
    assert!(zeroed > 10);
    assert_no_validation_messages(&r, "zero normals");

    let declared = |image: &HostTestImage, format| HostImage {
        image: image.image,
        view: image.view,
        format,
        extent: scene.resolution,
        usage: HostTestImage::USAGE,
        samples: vk::SampleCountFlags::TYPE_1,
        layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        written_by: (vk::PipelineStageFlags::empty(), vk::AccessFlags::empty()),
    };
    let (depth, normal) = (
        declared(&inputs.depth, case.format),
        declared(&inputs.normal, vk::Format::R32G32B32A32_SFLOAT),
    );
    let with = |images: FrameImages| FrameView { images, ..view };
    let both = |d: &dyn Fn(&mut HostImage), n: &dyn Fn(&mut HostImage)| {
        let (mut d2, mut n2) = (depth, normal);
        d(&mut d2);
        n(&mut n2);
        with(FrameImages {
            depth: Some(d2),
            normal: Some(n2),
            ..FrameImages::default()
        })
    };
    let keep = |_: &mut HostImage| {};
    let cases: [(FrameView, &str); 7] = [
        (
            both(&|d| d.format = vk::Format::R32_SFLOAT, &keep),
            "its format is R32_SFLOAT",
        ),
        (
            both(&keep, &|n| n.format = vk::Format::R8G8B8A8_UNORM),
            "its format is R8G8B8A8_UNORM",
        ),
        (both(&|d| d.extent = [32, 36], &keep), "32x36"),
        (
            both(&keep, &|n| n.usage = vk::ImageUsageFlags::STORAGE),
            "lacks SAMPLED",
        ),
        (
            both(&|d| d.layout = vk::ImageLayout::UNDEFINED, &keep),
            "UNDEFINED",
        ),
        (
            with(FrameImages {
                depth: Some(depth),
                ..FrameImages::default()
            }),
            "lacks a normal image",
        ),
        (
            with(FrameImages {
                visibility: Some(declared(&inputs.depth, vk::Format::R32_UINT)),
                ..FrameImages::default()
            }),
            "gives a visibility buffer",
        ),
    ];
    let mut checked = 0;
    for (view, said) in &cases {
        assert_refused(&r, &mut pass, 1, view, said);
        checked += 1;
    }
    assert_eq!(checked, cases.len());
    assert_no_validation_messages(&r, "refused depth inputs");
}

/// Accuracy with the host's depth and normal: the Lut32 lit fraction's
/// MAE against the 64-spp ray-traced reference is within 10 % of
/// `render`'s (its own ray cast) on the same view, per depth format and
/// convention, `D24` and standard Z included: each pixel's depth error
/// joins the depth test's tolerance. Printed with the pixels whose masks
/// equal `render`'s: what depth precision costs (paper-notes/embedding.md).
/// `IZB_DEPTH_SCENES` (comma-separated names, default `default`) and
/// `IZB_DEPTH_RESOLUTION` (default 240x135) measure other views.
#[test]
fn host_depth_accuracy_against_the_reference_per_format() {
    let Some(r) = pass_renderer() else { return };
    let names = std::env::var("IZB_DEPTH_SCENES").unwrap_or_else(|_| "default".into());
    let resolution = std::env::var("IZB_DEPTH_RESOLUTION").map_or([240, 135], |v| {
        let (w, h) = v.split_once('x').expect("IZB_DEPTH_RESOLUTION: WxH");
        [w.parse().unwrap(), h.parse().unwrap()]
    });
    let mut checked = 0;
    for name in names.split(',') {
        let scene = match scene::load(name) {
            Ok(s) => s,
            Err(_) => match common::shared_scene(name) {
                Some(s) => s,
                None => continue,
            },
        };
        checked += accuracy_per_format(&r, &scene.with_resolution(resolution).unwrap());
    }
    assert!(checked >= 5, "{checked}");
    assert_no_validation_messages(&r, "depth accuracy");
}

/// The per-format MAE of one view against render's; returns the cases
/// checked.
fn accuracy_per_format(r: &GpuRenderer, scene: &Scene) -> usize {
    let bvh = SceneBvh::build(scene);
    let truth = reference(
        scene,
        &bvh,
        ReferenceSettings::from_spp(64, 1).unwrap(),
        &|_| {},
    );
    let mode = SampleMode::Lut32;
    let rendered = render_cpu(scene, &bvh, settings(mode));
    let render_mae = metrics(&rendered.visibility, &truth.visibility, &truth.smooth).mae;
    let [w, h] = scene.resolution;
    println!(
        "{} at {w}x{h}, render (its own ray cast): Lut32 MAE {render_mae:.5}",
        scene.name
    );
    let cast = gbuffer(scene, &bvh);
    let cases = [
        DepthCase::new(vk::Format::D32_SFLOAT, scene, true, false),
        DepthCase::new(vk::Format::D32_SFLOAT, scene, false, false),
        DepthCase::new(vk::Format::D32_SFLOAT_S8_UINT, scene, true, true),
        DepthCase::new(vk::Format::D24_UNORM_S8_UINT, scene, true, false),
        DepthCase::new(vk::Format::D24_UNORM_S8_UINT, scene, false, false),
    ];
    let (mut checked, mut failed) = (0, Vec::new());
    for case in cases {
        let mut pass = pass_for(r, scene, mode, case);
        let mut inputs = HostInputs::new(r, scene.resolution, case.format);
        let frame = host_frame(&cast, case);
        let view = view_at(scene, 0);
        run_depth_frame(r, &mut pass, &mut inputs, 0, &view, &frame).unwrap();
        // SAFETY: the frame was waited for; nothing is executing.
        let (images, g) = unsafe { (pass.read_back().unwrap(), pass.read_back_gbuffer().unwrap()) };
        let visibility = resolve(&images.masks, &g);
        let mae = metrics(&visibility, &truth.visibility, &truth.smooth).mae;
        let ratio = mae / render_mae;
        let (mut equal, mut tested) = (0, 0);
        for i in 0..scene.pixel_count() {
            if rendered.gbuffer.flags[i] & izb::gbuffer::flags::SHADOW_TESTED != 0 {
                tested += 1;
                equal += usize::from(images.masks[i] == rendered.masks[i]);
            }
        }
        println!(
            "  {:?} reversed {} far {:?}: Lut32 MAE {mae:.5} ({ratio:.3}x render's); masks equal \
             to render's at {equal} of {tested} shadow-tested pixels",
            case.format, case.convention.reversed, case.convention.far
        );
        if ratio > 1.1 {
            failed.push(format!("{case:?}: MAE {mae} against render's {render_mae}"));
        }
        checked += 1;
    }
    assert!(failed.is_empty(), "{}: {failed:#?}", scene.name);
    checked
}
