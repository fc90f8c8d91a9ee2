//! Temporal stability (issue 6): the light turns by a tiny angle each
//! frame; a method's flicker is the mean per-pixel |Δ visibility| between
//! consecutive frames, over pixels shadow-tested in both. Divided by the
//! ground truth's own, it says how much of a method's frame-to-frame change
//! is shimmer rather than the shadow really moving (1 = none). The ground
//! truth keeps its sub-pixel positions from frame to frame (seeded per
//! pixel), so its own change is the real motion of the shadow.

use super::{Method, MethodKind, SceneTruth};
use crate::baseline::render_shadow_map;
use crate::gbuffer::gbuffer;
use crate::izb::{render_cpu, resolve};
use crate::reference::reference;
use crate::reference::same_samples::same_sample_masks;
use crate::reference::ReferenceSettings;
use crate::scene::{Light, Scene};
use glam::{DQuat, DVec3};

/// How the light moves.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct FlickerOptions {
    pub frames: usize,
    pub step_degrees: f64,
    #[serde(skip)]
    pub reference: ReferenceSettings,
}

/// One method's flicker.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FlickerRow {
    pub method: String,
    pub family: &'static str,
    /// Mean |Δ visibility| per pixel per frame step.
    pub mean_abs_delta: f64,
    /// `mean_abs_delta` over the ground truth's.
    pub ratio_to_truth: f64,
    /// The same over smooth pixels (every sub-pixel hit on the centre's
    /// plane in both frames) and over edge pixels.
    pub smooth_ratio_to_truth: f64,
    pub edge_ratio_to_truth: f64,
    pub frames: usize,
    pub step_degrees: f64,
}

/// `scene`'s light turned by `degrees`: a directional light tilts about
/// the horizontal axis across it; a point light circles the vertical axis
/// through the camera's target.
pub fn rotated_light(scene: &Scene, degrees: f64) -> Light {
    let angle = degrees.to_radians();
    match scene.light {
        Light::Directional { direction } => {
            let mut axis = direction.cross(DVec3::Y);
            if axis.length_squared() < 1e-12 {
                axis = DVec3::X;
            }
            Light::directional(DQuat::from_axis_angle(axis.normalize(), angle) * direction)
        }
        Light::Point { position } => {
            let pivot = scene.camera.target;
            Light::Point {
                position: pivot + DQuat::from_rotation_y(angle) * (position - pivot),
            }
        }
    }
}

/// Running sums of |Δ| between consecutive frames, over all pixels and
/// split by the ground truth's pixel class (smooth in both frames, or
/// not: design §8).
#[derive(Default)]
struct Delta {
    previous: Option<Vec<f32>>,
    sum: [f64; 3],
    pixels: [u64; 3],
}

/// Index of the sums: all, smooth, edge.
const ALL: usize = 0;
const SMOOTH: usize = 1;
const EDGE: usize = 2;

impl Delta {
    /// `smooth[i]`: whether pixel i is smooth in this frame and the last.
    fn push(&mut self, visibility: Vec<f32>, smooth: &[bool]) {
        if let Some(prev) = &self.previous {
            for (i, (a, b)) in prev.iter().zip(&visibility).enumerate() {
                if !a.is_nan() && !b.is_nan() {
                    let d = (a - b).abs() as f64;
                    let class = if smooth[i] { SMOOTH } else { EDGE };
                    for k in [ALL, class] {
                        self.sum[k] += d;
                        self.pixels[k] += 1;
                    }
                }
            }
        }
        self.previous = Some(visibility);
    }

    fn mean(&self, class: usize) -> f64 {
        self.sum[class] / self.pixels[class].max(1) as f64
    }
}

/// Runs every method and the ground truth on `options.frames` frames;
/// `progress` is called once per frame. Methods a frame refuses are
/// left out of the result.
pub fn flicker(
    scene: &Scene,
    shared: &SceneTruth,
    methods: &[Method],
    options: &FlickerOptions,
    progress: &dyn Fn(),
) -> Vec<FlickerRow> {
    let mut truth = Delta::default();
    let mut deltas: Vec<Option<Delta>> = methods.iter().map(|_| Some(Delta::default())).collect();
    let bvh = &shared.bvh;
    let mut last_smooth: Option<Vec<f32>> = None;
    for f in 0..options.frames {
        let mut frame = scene.clone();
        frame.light = rotated_light(scene, f as f64 * options.step_degrees);
        let g = gbuffer(&frame, bvh);
        let t = reference(&frame, bvh, options.reference, &|_| {});
        let smooth: Vec<bool> = match &last_smooth {
            Some(prev) => prev
                .iter()
                .zip(&t.smooth)
                .map(|(a, b)| *a == 1.0 && *b == 1.0)
                .collect(),
            None => vec![false; t.smooth.len()],
        };
        truth.push(t.visibility, &smooth);
        last_smooth = Some(t.smooth);
        for (m, d) in methods.iter().zip(deltas.iter_mut()) {
            let Some(delta) = d else { continue };
            let visibility = match &m.kind {
                MethodKind::Izb(s) => render_cpu(&frame, bvh, *s).visibility,
                MethodKind::RayTraced32 => resolve(
                    &same_sample_masks(&frame, bvh, crate::lut::sample_pattern()),
                    &g,
                ),
                MethodKind::ShadowMap(s) => match render_shadow_map(&frame, &g, *s) {
                    Ok(r) => r.visibility,
                    Err(_) => {
                        *d = None;
                        continue;
                    }
                },
            };
            delta.push(visibility, &smooth);
        }
        progress();
    }
    let base = [truth.mean(ALL), truth.mean(SMOOTH), truth.mean(EDGE)];
    let row = |method: String, family: &'static str, d: &Delta| FlickerRow {
        method,
        family,
        mean_abs_delta: d.mean(ALL),
        ratio_to_truth: d.mean(ALL) / base[ALL],
        smooth_ratio_to_truth: d.mean(SMOOTH) / base[SMOOTH],
        edge_ratio_to_truth: d.mean(EDGE) / base[EDGE],
        frames: options.frames,
        step_degrees: options.step_degrees,
    };
    let mut rows = vec![row("truth".into(), "reference", &truth)];
    for (m, d) in methods.iter().zip(deltas) {
        if let Some(d) = d {
            rows.push(row(m.name.clone(), m.kind.family(), &d));
        }
    }
    rows
}
