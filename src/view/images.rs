//! The pictures the viewer paints: each view of a method's frame as an
//! RGBA image, and the sample layout the magnifier draws a mask over.

use super::state::ViewKind;
use super::worker::MethodFrame;
use crate::cpu::SampleMode;
use crate::scene::Scene;

/// Colour of pixels a view has no value for (not shadow-tested, no truth).
const NO_VALUE: [u8; 4] = [40, 44, 60, 255];

/// `frame` as `view` shows it. `candidates` and `truth` are per pixel,
/// when known.
pub fn view_image(
    frame: &MethodFrame,
    view: ViewKind,
    candidates: Option<&[u32]>,
    truth: Option<&[f32]>,
) -> Vec<[u8; 4]> {
    match view {
        ViewKind::Shaded => frame
            .shaded
            .iter()
            .map(|&[r, g, b]| [r, g, b, 255])
            .collect(),
        ViewKind::LitFraction => frame
            .visibility
            .iter()
            .map(|&v| {
                if v.is_nan() {
                    NO_VALUE
                } else {
                    let g = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
                    [g, g, g, 255]
                }
            })
            .collect(),
        ViewKind::Candidates => match candidates {
            Some(c) => {
                let top = c.iter().copied().max().unwrap_or(0).max(1);
                let scale = 1.0 / (1.0 + top as f32).ln();
                c.iter()
                    .map(|&n| {
                        if n == 0 {
                            NO_VALUE
                        } else {
                            heat((1.0 + n as f32).ln() * scale)
                        }
                    })
                    .collect()
            }
            None => vec![NO_VALUE; frame.visibility.len()],
        },
        ViewKind::Error => match truth {
            Some(t) => frame
                .visibility
                .iter()
                .zip(t)
                .map(|(&v, &t)| {
                    if v.is_nan() || t.is_nan() {
                        NO_VALUE
                    } else {
                        // Full scale at an error of 0.5.
                        heat(((v - t).abs() * 2.0).min(1.0))
                    }
                })
                .collect(),
            None => vec![NO_VALUE; frame.visibility.len()],
        },
    }
}

/// Why `view` shows no values at all, when it has nothing to show (an
/// image of one flat colour would otherwise look like a broken view).
pub fn view_notice(view: ViewKind, has_candidates: bool, has_truth: bool) -> Option<&'static str> {
    match view {
        ViewKind::Error if !has_truth => Some(
            "error view: no truth yet — the ray-traced truth starts once the view is still \
             and its frame is shown (scripts: wait-truth SPP)",
        ),
        ViewKind::Candidates if !has_candidates => {
            Some("candidates view: this frame has no per-pixel candidate counts")
        }
        _ => None,
    }
}

/// A black–red–yellow–white ramp over 0–1.
pub fn heat(x: f32) -> [u8; 4] {
    let x = x.clamp(0.0, 1.0);
    let r = (x * 3.0).min(1.0);
    let g = (x * 3.0 - 1.0).clamp(0.0, 1.0);
    let b = (x * 3.0 - 2.0).clamp(0.0, 1.0);
    let [r, g, b] = [r, g, b].map(|c| (c * 255.0).round() as u8);
    [r, g, b, 255]
}

/// Mean absolute error of `visibility` against `truth` over the pixels
/// both have, and their count.
pub fn mean_abs_error(visibility: &[f32], truth: &[f32]) -> Option<(f64, usize)> {
    let (sum, n) = visibility
        .iter()
        .zip(truth)
        .filter(|(v, t)| !v.is_nan() && !t.is_nan())
        .fold((0.0f64, 0usize), |(s, n), (v, t)| {
            (s + f64::from((v - t).abs()), n + 1)
        });
    (n > 0).then(|| (sum / n as f64, n))
}

/// Where a pixel's mask bits lie, for the magnifier: bit i at `points[i]`
/// in [0, 1)², over the µQuad or (`on_light_disk`) the light's disk.
pub struct SampleLayout {
    pub points: Vec<[f32; 2]>,
    pub on_light_disk: bool,
}

/// The layout of `mode`'s masks on `scene`: one centre sample; the
/// µQuad's 32 (or the light's, under an area light); paired rays at
/// their pixel points, 64 when two halves.
pub fn sample_layout(mode: SampleMode, settings_light: bool, halves: usize) -> SampleLayout {
    use crate::lut::{paired_patterns, sample_pattern, tables_for};
    match mode {
        SampleMode::One => SampleLayout {
            points: vec![[0.5, 0.5]],
            on_light_disk: false,
        },
        SampleMode::Paired32 | SampleMode::Paired64 if settings_light => SampleLayout {
            points: (0..halves)
                .flat_map(|h| paired_patterns(h).1.iter().copied())
                .collect(),
            on_light_disk: false,
        },
        SampleMode::Lut32 | SampleMode::Exact32 if settings_light => SampleLayout {
            points: tables_for(true).1.to_vec(),
            on_light_disk: true,
        },
        _ => SampleLayout {
            points: sample_pattern().to_vec(),
            on_light_disk: false,
        },
    }
}

/// The layout of a frame's masks, `None` for methods without masks.
pub fn frame_layout(frame: &MethodFrame, scene: &Scene) -> Option<SampleLayout> {
    let settings = frame.izb?;
    Some(sample_layout(
        settings.mode,
        settings.light_samples(scene),
        settings.mask_halves(scene),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heat_ramp_runs_black_to_white() {
        assert_eq!(heat(0.0), [0, 0, 0, 255]);
        assert_eq!(heat(1.0), [255, 255, 255, 255]);
        assert_eq!(heat(1.0 / 3.0), [255, 0, 0, 255]);
    }

    #[test]
    fn empty_views_say_why() {
        let mut said = 0;
        for view in [ViewKind::Error, ViewKind::Candidates] {
            assert!(view_notice(view, false, false).is_some(), "{}", view.name());
            assert_eq!(view_notice(view, true, true), None);
            said += 1;
        }
        assert_eq!(view_notice(ViewKind::Shaded, false, false), None);
        assert_eq!(said, 2);
    }

    #[test]
    fn error_skips_pixels_without_values() {
        let v = [0.5, f32::NAN, 1.0];
        let t = [0.25, 0.5, f32::NAN];
        assert_eq!(mean_abs_error(&v, &t), Some((0.25, 1)));
        assert_eq!(mean_abs_error(&[f32::NAN], &[0.0]), None);
    }

    #[test]
    fn layouts_have_one_point_per_mask_bit() {
        let cases = [
            (SampleMode::One, false, 1, 1, false),
            (SampleMode::Lut32, false, 1, 32, false),
            (SampleMode::Exact32, true, 1, 32, true),
            (SampleMode::Paired32, true, 1, 32, false),
            (SampleMode::Paired64, true, 2, 64, false),
        ];
        for (mode, light, halves, n, disk) in cases {
            let l = sample_layout(mode, light, halves);
            assert_eq!(l.points.len(), n, "{mode:?}");
            assert_eq!(l.on_light_disk, disk, "{mode:?}");
        }
        assert_eq!(cases.len(), 5);
    }
}
