//! The shadow pass fed the host's own vertex and index buffers
//! (`ShadowPass::with_host_geometry`, `gather_draws.comp`): the test host
//! keeps `default`'s triangles as three meshes in object space — `u32`
//! indices into interleaved positions (stride 24, offset 16) placed by a
//! turn, `u16` indices at an odd half-word offset into packed positions
//! placed by a mirrored, scaled turn, and unindexed positions placed by
//! the identity — copies them into its buffers in each frame's command
//! buffer, and gives the draws to the pass. With `IZB_VALIDATION=1` the
//! validation layer runs with synchronization validation and any message
//! fails the test. No Vulkan device: the test prints that it skipped,
//! unless `IZB_REQUIRE_GPU=1`.

mod common;

use ash::vk;
use common::gpu::assert_no_validation_messages;
use common::host_geometry::{host_meshes, run_geometry_frame, HostBuffers};
use common::shadow_pass::{pass_renderer, scene_at, settings, view_at, HostTestImage};
use glam::{DVec3, Vec3};
use izb::cpu::gather_draws::{eye_relative_bounds, gather_draws};
use izb::cpu::SampleMode;
use izb::gbuffer::flags;
use izb::gpu::gather_draws::{draw_table, first_triangles, FrameGeometry, HostBuffer, HostDraw};
use izb::gpu::host_images::HostImage;
use izb::gpu::shadow_pass::{
    FrameView, GBufferInput, HostGeometryConfig, ShadowPass, ShadowPassConfig,
};
use izb::gpu::{GBufferSource, GpuRenderer};
use izb::scene::{self, Scene};

fn geometry_config(scene: &Scene, max_triangles: u32, max_draws: u32) -> HostGeometryConfig {
    HostGeometryConfig {
        max_triangles,
        max_draws,
        bounds: scene.bounds(),
    }
}

/// The host's three meshes give the pass triangles equal to the twin's
/// gather bit for bit every frame while the eye, view and light move; its
/// normals within a few ulps (a GPU's square root and division may round
/// otherwise); its masks equal the CPU twin's on the pass's own G-buffer
/// (exact ones bit for bit, LUT ones within `LUT_SAMPLE_MISMATCH`) and `render`'s of the scene — whose vertices are the
/// `f64` ones the meshes were made from — at ≥ 99.9 % of the
/// shadow-tested pixels; nothing is allocated while recording, and the
/// validation layer with synchronization validation stays silent.
#[test]
fn the_host_s_meshes_give_the_twin_s_triangles_and_render_s_masks() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    let meshes = host_meshes(&scene);
    let buffers = HostBuffers::new(&r, &meshes);
    let n = scene.triangles.len() as u32;
    assert_eq!(first_triangles(&meshes.draws), [0, n / 3, 2 * n / 3]);
    let (mut compared, mut tested, mut differ) = (0, 0usize, 0usize);
    for mode in [SampleMode::Exact32, SampleMode::Lut32] {
        let s = settings(mode);
        let config = ShadowPassConfig {
            settings: s,
            frames_in_flight: 2,
            cell_capacity: None,
            edge_slots: None,
            gbuffer: GBufferInput::Visibility,
        };
        let limits = geometry_config(&scene, n, 4);
        let mut pass = ShadowPass::with_host_geometry(&r, scene.clone(), config, limits).unwrap();
        let mut image = HostTestImage::visibility(&r.context.shared, scene.resolution);
        for k in 0..FRAMES {
            let mut view = view_at(&scene, 3 * k);
            view.camera.eye += DVec3::new(0.013, 0.004, -0.009) * 30.0 * k as f64;
            view.camera.target += DVec3::new(0.013, 0.004, -0.009) * 30.0 * k as f64;
            let moved = scene_at(&scene, &view);
            let batch = r.render(&moved, s, GBufferSource::Gpu).unwrap();
            let ids = &batch.gbuffer.triangle_id;
            let made = run_geometry_frame(
                &r,
                &mut pass,
                &mut image,
                &buffers,
                k,
                &view,
                ids,
                &meshes.draws,
            )
            .unwrap();
            assert_eq!(
                made,
                [0, 0],
                "{mode:?} frame {k}: allocations while recording"
            );
            // SAFETY: the frame was waited for; nothing is executing.
            let (status, images, vertices, normals, g) = unsafe {
                (
                    pass.status(k % 2).unwrap(),
                    pass.read_back().unwrap(),
                    pass.read_back_vertices().unwrap(),
                    pass.read_back_triangle_normals().unwrap(),
                    pass.read_back_gbuffer().unwrap(),
                )
            };
            assert_eq!(
                (
                    status.visibility_rejected,
                    status.index_out_of_range,
                    status.outside_bounds
                ),
                (0, 0, 0),
                "{status:?}"
            );
            assert!(status.geometry_error().is_none());
            let mut table = Vec::new();
            let declared =
                buffers.declared((vk::PipelineStageFlags::empty(), vk::AccessFlags::empty()));
            let geometry = FrameGeometry {
                buffers: &declared,
                draws: &meshes.draws,
            };
            assert_eq!(
                draw_table(&geometry, view.camera.eye, u64::MAX, &mut table).unwrap(),
                n
            );
            let slots: Vec<&[u32]> = meshes.words.iter().map(|w| &w[..]).collect();
            let twin = gather_draws(
                &table,
                &slots,
                eye_relative_bounds(scene.bounds(), view.camera.eye),
            );
            assert_eq!((twin.index_out_of_range, twin.outside_bounds), (0, 0));
            let twin_vertices: Vec<Vec3> = twin.triangles.iter().flatten().copied().collect();
            let bits = |v: &[Vec3]| -> Vec<[u32; 3]> {
                v.iter().map(|v| v.to_array().map(f32::to_bits)).collect()
            };
            assert_eq!(
                bits(&vertices[..3 * n as usize]),
                bits(&twin_vertices),
                "{mode:?} frame {k}: vertices"
            );
            for (t, (gpu, cpu)) in normals.iter().zip(&twin.normals).enumerate() {
                assert!(
                    (*gpu - *cpu).abs().max_element() <= 4.0 * f32::EPSILON,
                    "triangle {t}: {gpu} {cpu}"
                );
            }
            let on_twin = izb::cpu::render_cpu_with(&moved, g, &twin.triangles, s);
            // Exact masks bit for bit; LUT masks within rounding of a cell
            // boundary (the LUT cell's division and square root; the same
            // pixel differs with the resident pass: not the gather's).
            let samples: Vec<u32> = (0..images.masks.len())
                .map(|i| (images.masks[i] ^ on_twin.masks[i]).count_ones())
                .collect();
            let differing: u32 = samples.iter().sum();
            let allowed = match mode {
                SampleMode::Exact32 => 0.0,
                _ => LUT_SAMPLE_MISMATCH * 32.0 * samples.len() as f64,
            };
            assert!(
                f64::from(differing) <= allowed,
                "{mode:?} frame {k}: the twin on the pass's G-buffer differs at {differing} samples"
            );
            for (i, f) in batch.gbuffer.flags.iter().enumerate() {
                if f & flags::SHADOW_TESTED != 0 {
                    tested += 1;
                    differ += usize::from(images.masks[i] != batch.masks[i]);
                }
            }
            compared += 1;
        }
        assert_no_validation_messages(&r, "host geometry");
    }
    assert_eq!(compared, 2 * FRAMES);
    assert!(tested > 1000, "{tested} shadow-tested pixels");
    assert!(
        differ * 1000 <= tested,
        "{differ} of {tested} shadow-tested pixels differ from render's"
    );
    println!("host geometry: {differ} of {tested} shadow-tested pixels differ from render's masks");
}

/// Frames of the geometry test per mode.
const FRAMES: usize = 3;

/// Samples a LUT mask may differ on between the pass and its CPU twin on
/// the same G-buffer and triangles: `tests/gpu_backend.rs`'s allowance (a
/// LUT cell within rounding of its boundary), which `default`'s second
/// frame here meets at 3 samples of one pixel with the resident pass too.
const LUT_SAMPLE_MISMATCH: f64 = 1e-4;

/// Records `geometry` (or, with `None`, a plain `record`) expecting a
/// refusal before any command whose message says `said`.
fn assert_geometry_refused(
    r: &GpuRenderer,
    pass: &mut ShadowPass,
    view: &FrameView,
    geometry: Option<&FrameGeometry>,
    said: &str,
) {
    let mut error = None;
    let record = |cmd| {
        // SAFETY: `cmd` is recording on this thread after every earlier
        // frame; the wait below ends it; the declared buffers are live.
        error = unsafe {
            match geometry {
                Some(g) => pass.record_host_geometry(cmd, 0, view, g),
                None => pass.record(cmd, 0, view),
            }
        }
        .err();
        Ok(())
    };
    // SAFETY: the pass outlives the call, which waits.
    unsafe { r.context.submit_and_wait(record) }.unwrap();
    let e = error.unwrap_or_else(|| panic!("{said}: recorded"));
    assert!(e.to_string().contains(said), "{said}: {e}");
}

/// Bad host geometry is refused by name — at creation (a ray-cast
/// G-buffer, no room), or at record time before any command (more
/// triangles or draws than the pass was made for, a buffer without
/// storage usage, a range past its buffer, a misaligned stride or index
/// offset, another position format, draws to a resident pass or none to
/// a host-geometry pass) — and an index past its draw's vertices is
/// counted on the device, named by the status, never read out of bounds;
/// `reserve_host_geometry` makes room, after which the refused frame
/// records.
#[test]
fn bad_host_geometry_is_refused_or_counted() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([64, 36])
        .unwrap();
    let meshes = host_meshes(&scene);
    let buffers = HostBuffers::new(&r, &meshes);
    let n = scene.triangles.len() as u32;
    let config = ShadowPassConfig {
        settings: settings(SampleMode::Lut32),
        frames_in_flight: 2,
        cell_capacity: None,
        edge_slots: None,
        gbuffer: GBufferInput::Visibility,
    };
    let ray_cast = ShadowPassConfig {
        gbuffer: GBufferInput::RayCast,
        ..config
    };
    let refused =
        ShadowPass::with_host_geometry(&r, scene.clone(), ray_cast, geometry_config(&scene, n, 3));
    assert!(refused
        .err()
        .unwrap()
        .to_string()
        .contains("ray-cast G-buffer"));
    let refused =
        ShadowPass::with_host_geometry(&r, scene.clone(), config, geometry_config(&scene, 0, 3));
    assert!(refused.err().unwrap().to_string().contains("at least 1"));

    let mut pass = ShadowPass::with_host_geometry(
        &r,
        scene.clone(),
        config,
        geometry_config(&scene, n - 1, 2),
    )
    .unwrap();
    let mut image = HostTestImage::visibility(&r.context.shared, scene.resolution);
    // Refused before any command: the image's declared state is never used.
    let visibility = HostImage {
        image: image.image,
        view: image.view,
        format: vk::Format::R32_UINT,
        extent: scene.resolution,
        usage: HostTestImage::USAGE,
        samples: vk::SampleCountFlags::TYPE_1,
        layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        written_by: (vk::PipelineStageFlags::empty(), vk::AccessFlags::empty()),
    };
    let mut view = view_at(&scene, 0);
    view.images.visibility = Some(visibility);
    let declared = buffers.declared((vk::PipelineStageFlags::empty(), vk::AccessFlags::empty()));
    let with = |d: &[HostDraw], b: &[HostBuffer], said: &str, pass: &mut ShadowPass| {
        assert_geometry_refused(
            &r,
            pass,
            &view,
            Some(&FrameGeometry {
                buffers: b,
                draws: d,
            }),
            said,
        );
    };
    let mut checked = 0;
    with(&meshes.draws, &declared, "3 draws", &mut pass);
    let two = &meshes.draws[..2];
    let changed = |change: &dyn Fn(&mut HostDraw)| {
        let mut d = two.to_vec();
        change(&mut d[0]);
        d
    };
    let mut no_storage = declared.clone();
    no_storage[1].usage = vk::BufferUsageFlags::TRANSFER_DST;
    let cases: Vec<(Vec<HostDraw>, Vec<HostBuffer>, &str)> = vec![
        (two.to_vec(), no_storage, "lacks STORAGE_BUFFER"),
        (
            changed(&|d| d.vertex_stride = 22),
            declared.clone(),
            "multiples of 4",
        ),
        (
            changed(&|d| d.vertex_count += 1),
            declared.clone(),
            "past buffer 0",
        ),
        (
            changed(&|d| d.indices.as_mut().unwrap().offset = 2),
            declared.clone(),
            "a multiple of 4",
        ),
        (
            changed(&|d| d.vertex_format = vk::Format::R16G16B16A16_SFLOAT),
            declared.clone(),
            "R32G32B32_SFLOAT",
        ),
        (
            changed(&|d| d.vertex_buffer = 5),
            declared.clone(),
            "buffer 5, of 3 given",
        ),
        (
            changed(&|d| d.transform.translation.x = f64::MAX),
            declared.clone(),
            "finite f32",
        ),
    ];
    for (draws, b, said) in &cases {
        with(draws, b, said, &mut pass);
        checked += 1;
    }
    assert_eq!(checked, cases.len());
    assert_geometry_refused(&r, &mut pass, &view, None, "record_host_geometry");
    let mut resident = ShadowPass::new(&r, scene.clone(), config).unwrap();
    let g = FrameGeometry {
        buffers: &declared,
        draws: two,
    };
    assert_geometry_refused(&r, &mut resident, &view, Some(&g), "with_host_geometry");
    drop(resident);
    // Two draws fit; the three need room.
    let batch = r
        .render(&scene, config.settings, GBufferSource::Gpu)
        .unwrap();
    let ids = &batch.gbuffer.triangle_id;
    let mut all = meshes.draws.clone();
    assert!(pass.reserve_host_geometry(n, 3).unwrap());
    // An index past its draw's vertices: mesh 0's last vertex dropped.
    all[0].vertex_count -= 1;
    let uses_last = |t: usize| -> bool {
        let last = all[0].vertex_count;
        (0..3).any(|k| meshes.words[2][3 * t + k] == last)
    };
    let past = (0..all[0].triangle_count as usize)
        .filter(|&t| uses_last(t))
        .count() as u32;
    assert!(past > 0);
    run_geometry_frame(&r, &mut pass, &mut image, &buffers, 0, &view, ids, &all).unwrap();
    // SAFETY: the frame was waited for.
    let status = unsafe { pass.status(0) }.unwrap();
    assert_eq!(status.index_out_of_range, past, "{status:?}");
    let named = status.geometry_error().unwrap().to_string();
    assert!(named.contains("indexed past"), "{named}");
    // A draw moved far outside the bounds the pass was made for.
    all[0].vertex_count += 1;
    all[1].transform.translation += DVec3::new(1e3, 0.0, 0.0);
    run_geometry_frame(&r, &mut pass, &mut image, &buffers, 1, &view, ids, &all).unwrap();
    // SAFETY: the frame was waited for.
    let status = unsafe { pass.status(1) }.unwrap();
    assert_eq!(
        (status.index_out_of_range, status.outside_bounds),
        (0, meshes.draws[1].triangle_count),
        "{status:?}"
    );
    assert_no_validation_messages(&r, "bad host geometry");
}
