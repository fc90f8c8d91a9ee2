//! The screenshot: what `izb render` writes for the left (or only)
//! method — `visibility.exr` (lit fraction and masks), `visibility.png`,
//! `shaded.png`, `report.json` — plus `window.png`, the window as
//! presented, and the right method's images when the screen is split.

use super::state::ViewState;
use super::truth::TruthUpdate;
use super::ui::Shown;
use crate::output::{write_json, write_mask_outputs, write_png};
use anyhow::{Context, Result};
use std::path::Path;

/// Writes the screenshot into `dir` (created if needed).
pub fn write(
    dir: &Path,
    window: &image::RgbaImage,
    image_rect_px: Option<[f32; 4]>,
    shown: &Shown,
    state: &ViewState,
    truth: Option<&TruthUpdate>,
) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let scene = &shown.result.scene;
    let [w, h] = scene.resolution;
    let mut methods = Vec::new();
    for (k, frame) in shown.result.frames.iter().enumerate() {
        // The left method's files carry `render`'s names in `dir`, the
        // right one's the same names in `dir/right`.
        let sub = if k == 0 {
            dir.to_path_buf()
        } else {
            dir.join("right")
        };
        std::fs::create_dir_all(&sub)?;
        write_mask_outputs(
            &sub,
            scene,
            &frame.visibility,
            &frame.masks,
            &frame.masks_high,
            &[],
        )?;
        let shaded =
            image::RgbImage::from_raw(w, h, frame.shaded.concat()).context("shaded image size")?;
        write_png(&sub.join("shaded.png"), &shaded)?;
        let mae = truth.and_then(|t| {
            super::images::mean_abs_error(&frame.visibility, &t.visibility)
                .map(|(mae, pixels)| serde_json::json!({"mae": mae, "pixels": pixels, "truth_spp": t.spp}))
        });
        methods.push(serde_json::json!({
            "method": frame.name,
            "backend": frame.backend,
            "pass_milliseconds": frame.pass_millis,
            "tests_per_pixel": frame.tests_per_pixel,
            "memory_bytes": frame.memory_bytes,
            "error_against_truth": mae,
            "render": frame.report,
        }));
    }
    // A frame whose methods all failed still gets its window and errors.
    let left = methods.first().cloned().unwrap_or_default();
    let report = serde_json::json!({
        "command": "view",
        "backend": left["backend"],
        "scene": scene.summary(),
        "render": left["render"],
        "methods": methods,
        "view": {
            "method": state.method,
            "split": state.split,
            "divider": state.divider,
            "view": state.view.name(),
            "orbit_deg_deg_factor": state.orbit,
            "light_turn_deg": state.light_turn,
            "light_size": state.light_size,
            "overlay": state.overlay,
            // Why the view is empty, as the window says over the image.
            "notice": super::images::view_notice(
                state.view,
                shown.result.candidates.is_some(),
                truth.is_some(),
            ),
        },
        "window": {
            "size": [window.width(), window.height()],
            "image_rect_px": image_rect_px,
        },
        "errors": shown.result.errors,
    });
    write_json(&dir.join("report.json"), &report)?;
    let png = image::DynamicImage::ImageRgba8(window.clone()).to_rgb8();
    write_png(&dir.join("window.png"), &png)
}
