//! Checks of a frame the host waited for, outside the frames it measures:
//! the pass's G-buffer (made from the host's raster) read back and fed to
//! the CPU twin in the frame's mode, and a frame written as `izb render`
//! writes one (`--out DIR`: `visibility.exr` with the masks,
//! `visibility.png`, `shaded.png`, `report.json`), with the host's own
//! lighting of it (`host_shaded.png`).

use glam::Vec3;
use izb::cpu::IzbSettings;
use izb::gpu::gather_draws::{draw_table, FrameGeometry};
use izb::gpu::shadow_pass::{FrameView, PassFrame, ShadowPass};
use izb::scene::Scene;
use std::path::Path;

/// The CPU twin on the pass's G-buffer against the pass's masks.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct TwinComparison {
    /// Pixels whose masks were compared (every pixel).
    pub masks_compared: usize,
    /// Of them, pixels whose masks differ.
    pub mask_mismatches: usize,
    /// Samples (mask bits) that differ, over every pixel's 32.
    pub sample_mismatches: u64,
}

/// The CPU twin's masks on the pass's last G-buffer and triangles, read
/// back, against the pass's own masks.
///
/// # Safety
/// No frame of the pass is executing.
pub unsafe fn twin_on_pass_gbuffer(
    pass: &ShadowPass,
    scene: &Scene,
    view: &FrameView,
    geometry: &FrameGeometry,
    (vertices, indices): (&[Vec3], &[u32]),
    settings: IzbSettings,
) -> Result<TwinComparison, String> {
    // SAFETY: the caller's promise.
    let frame = unsafe { PassInputs::read(pass, scene, view, geometry, (vertices, indices)) }?;
    let twin = izb::cpu::render_cpu_with(&frame.moved, frame.g, &frame.triangles, settings);
    Ok(TwinComparison::of(&twin.masks, &frame.masks))
}

/// What the twin checks read of frame 0: the pass's G-buffer and masks
/// read back, the scene as the frame saw it, and the pass's triangles
/// gathered by the twin from the host's own words.
struct PassInputs {
    g: izb::gbuffer::GBuffer,
    masks: Vec<u32>,
    moved: Scene,
    triangles: Vec<[Vec3; 3]>,
}

impl PassInputs {
    /// # Safety
    /// No frame of the pass is executing.
    unsafe fn read(
        pass: &ShadowPass,
        scene: &Scene,
        view: &FrameView,
        geometry: &FrameGeometry,
        (vertices, indices): (&[Vec3], &[u32]),
    ) -> Result<PassInputs, String> {
        // SAFETY: the caller's promise.
        let (g, images) = unsafe { (pass.read_back_gbuffer(), pass.read_back()) };
        let (g, images) = (
            g.map_err(|e| e.to_string())?,
            images.map_err(|e| e.to_string())?,
        );
        let mut table = Vec::new();
        draw_table(geometry, view.camera.eye, u64::MAX, &mut table).map_err(|e| e.to_string())?;
        let words: [&[u32]; 2] = [bytemuck::cast_slice(vertices), indices];
        let bounds = izb::cpu::gather_draws::eye_relative_bounds(scene.bounds(), view.camera.eye);
        let gathered = izb::cpu::gather_draws::gather_draws(&table, &words, bounds);
        Ok(PassInputs {
            g,
            masks: images.masks,
            moved: seen_as(scene, view, pass.resolution()),
            triangles: gathered.triangles,
        })
    }
}

impl TwinComparison {
    /// The twin's masks against the pass's, pixel by pixel.
    fn of(twin: &[u32], pass: &[u32]) -> TwinComparison {
        let mut c = TwinComparison {
            masks_compared: twin.len(),
            ..Default::default()
        };
        for (a, b) in twin.iter().zip(pass) {
            c.mask_mismatches += usize::from(a != b);
            c.sample_mismatches += u64::from((a ^ b).count_ones());
        }
        c
    }
}

/// What a multisampled frame 0's twin check found beside the masks.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct MultisampledCheck {
    /// Pixels whose centre triangle in the pass's G-buffer differs from
    /// the twin's.
    pub centre_mismatches: usize,
    /// The twin's rejected and uncovered centres (the pass's are in its
    /// status: `PassStatus::visibility_rejected`, `centre_uncovered`).
    pub twin_rejected: usize,
    pub twin_centre_uncovered: usize,
    pub pass_rejected: usize,
    pub pass_centre_uncovered: usize,
}

/// The CPU twin fed the host's multisampled visibility buffer — `ids`,
/// every sample of frame 0's, read back — on the pass's triangles
/// (`gbuffer_from_multisampled_visibility_on`, its sample rays in `f64`),
/// against the pass's masks; and the centres' triangles and counts
/// against the pass's G-buffer (the pass's counts left 0 for the caller,
/// who reads its status).
///
/// # Safety
/// No frame of the pass is executing.
#[allow(clippy::too_many_arguments)]
pub unsafe fn twin_on_multisampled_ids(
    pass: &ShadowPass,
    scene: &Scene,
    view: &FrameView,
    geometry: &FrameGeometry,
    (vertices, indices): (&[Vec3], &[u32]),
    settings: IzbSettings,
    (ids, samples): (&[u32], usize),
) -> Result<(TwinComparison, MultisampledCheck), String> {
    // SAFETY: the caller's promise.
    let frame = unsafe { PassInputs::read(pass, scene, view, geometry, (vertices, indices)) }?;
    let triangles: Vec<izb::scene::Triangle> = frame
        .triangles
        .iter()
        .map(|t| t.map(|v| v.as_dvec3()))
        .collect();
    let halves = settings.edge_halves(&frame.moved);
    let twin = izb::gbuffer::gbuffer_from_multisampled_visibility_on(
        &frame.moved,
        &triangles,
        ids,
        samples,
        halves,
    )?;
    let check = MultisampledCheck {
        centre_mismatches: (0..frame.g.triangle_id.len())
            .filter(|&i| frame.g.triangle_id[i] != twin.gbuffer.triangle_id[i])
            .count(),
        twin_rejected: twin.rejected,
        twin_centre_uncovered: twin.centre_uncovered,
        ..Default::default()
    };
    let render = izb::cpu::render_cpu_with(&frame.moved, twin.gbuffer, &frame.triangles, settings);
    Ok((TwinComparison::of(&render.masks, &frame.masks), check))
}

/// Writes the host's lighting of a frame (RGBA8 words, `resolution`) as
/// `dir/host_shaded.png`.
pub fn write_host_shaded(words: &[u32], [w, h]: [u32; 2], dir: &Path) -> Result<(), String> {
    let rgb: Vec<u8> = words
        .iter()
        .flat_map(|word| {
            let [r, g, b, _] = word.to_le_bytes();
            [r, g, b]
        })
        .collect();
    let path = dir.join("host_shaded.png");
    let error = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let image = image::RgbImage::from_raw(w, h, rgb).ok_or_else(|| error(&"its size"))?;
    izb::output::write_png(&path, &image).map_err(|e| error(&e))
}

/// `scene` seen from `view` at `resolution`.
pub fn seen_as(scene: &Scene, view: &FrameView, resolution: [u32; 2]) -> Scene {
    let mut moved = scene.clone();
    (moved.camera, moved.light, moved.light_radius) = (view.camera, view.light, view.light_radius);
    moved.resolution = resolution;
    moved
}

/// Writes `frame` (of `seen`: the scene as that frame saw it) into `dir`
/// as `izb render` writes one: the lit fraction and masks
/// (`visibility.exr`, `visibility.png`), izb's shaded image
/// (`shaded.png`) and `report.json` (`extra`'s fields added).
pub fn write_frame(
    frame: &PassFrame,
    seen: &Scene,
    dir: &Path,
    extra: serde_json::Value,
) -> Result<(), String> {
    let error = |e: &dyn std::fmt::Display| format!("{}: {e}", dir.display());
    std::fs::create_dir_all(dir).map_err(|e| error(&e))?;
    izb::output::write_mask_outputs(
        dir,
        seen,
        &frame.visibility,
        &frame.masks,
        &frame.masks_high,
        &[],
    )
    .map_err(|e| error(&e))?;
    let [w, h] = seen.resolution;
    let shaded = image::RgbImage::from_raw(w, h, frame.shaded.concat())
        .ok_or_else(|| error(&"the shaded image's size"))?;
    izb::output::write_png(&dir.join("shaded.png"), &shaded).map_err(|e| error(&e))?;
    let mut report = serde_json::json!({
        "command": "embed_host",
        "scene": seen.summary(),
    });
    if let (Some(r), serde_json::Value::Object(more)) = (report.as_object_mut(), extra) {
        r.extend(more);
    }
    izb::output::write_json(&dir.join("report.json"), &report).map_err(|e| error(&e))
}
