//! Temporal stability (issue 6): the light turns by a tiny angle each
//! frame; a method's flicker is the mean per-pixel |Δ visibility| between
//! consecutive frames, over pixels shadow-tested in both. Divided by the
//! ground truth's own, it says how much of a method's frame-to-frame change
//! is shimmer rather than the shadow really moving (1 = none). The ground
//! truth keeps its sub-pixel positions from frame to frame (seeded per
//! pixel), so its own change is the real motion of the shadow.

use super::{Method, MethodKind, SceneTruth};
use crate::baseline::render_shadow_map;
use crate::cpu::{render_cpu, resolve};
use crate::gbuffer::gbuffer;
use crate::reference::reference;
use crate::reference::same_samples::{edge_same_sample_masks, same_sample_masks};
use crate::reference::ReferenceSettings;
use crate::scene::{Light, Scene};
use glam::{DQuat, DVec3};

/// How the light moves.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct FlickerOptions {
    pub frames: usize,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub step_degrees: f64,
    #[serde(skip)]
    pub reference: ReferenceSettings,
}

/// One method's flicker.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct FlickerRow {
    pub method: String,
    pub family: String,
    /// Mean |Δ visibility| per pixel per frame step.
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub mean_abs_delta: f64,
    /// `mean_abs_delta` over the ground truth's.
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub ratio_to_truth: f64,
    /// 95 % interval of `ratio_to_truth`: a moving-block bootstrap over
    /// frame steps ([`ratio_interval`]).
    #[serde(deserialize_with = "crate::output::nan_pair_if_null")]
    pub ratio_ci95: [f64; 2],
    /// The same over smooth pixels (every sub-pixel hit on the centre's
    /// plane in both frames) and over edge pixels.
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub smooth_ratio_to_truth: f64,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
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
/// not: paper-notes/reference-estimator.md).
#[derive(Default)]
struct Delta {
    previous: Option<Vec<f32>>,
    sum: [f64; 3],
    pixels: [u64; 3],
    /// Per frame step, the sum and the pixel count over all pixels.
    steps: Vec<(f64, u64)>,
}

/// Index of the sums: all, smooth, edge.
const ALL: usize = 0;
const SMOOTH: usize = 1;
const EDGE: usize = 2;

impl Delta {
    /// `smooth[i]`: whether pixel i is smooth in this frame and the last.
    fn push(&mut self, visibility: Vec<f32>, smooth: &[bool]) {
        if let Some(prev) = &self.previous {
            let before = (self.sum[ALL], self.pixels[ALL]);
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
            self.steps
                .push((self.sum[ALL] - before.0, self.pixels[ALL] - before.1));
        }
        self.previous = Some(visibility);
    }

    fn mean(&self, class: usize) -> f64 {
        self.sum[class] / self.pixels[class].max(1) as f64
    }
}

impl FlickerOptions {
    /// The most the light may turn over a run, in degrees: past a half
    /// turn the sweep only repeats itself.
    pub const MAX_SWEEP_DEGREES: f64 = 180.0;

    /// Refuses settings that measure nothing: fewer than two frames (no
    /// frame step to compare), a step that is not a positive finite angle,
    /// or a sweep past [`Self::MAX_SWEEP_DEGREES`].
    pub fn check(&self) -> Result<(), String> {
        if self.frames < 2 {
            return Err(format!(
                "--flicker-frames {}: flicker compares consecutive frames, so it needs at least 2",
                self.frames
            ));
        }
        if !(self.step_degrees.is_finite() && self.step_degrees > 0.0) {
            return Err(format!(
                "--flicker-step {}: the light's turn per frame must be a positive number of degrees",
                self.step_degrees
            ));
        }
        let sweep = self.step_degrees * (self.frames - 1) as f64;
        if sweep > Self::MAX_SWEEP_DEGREES {
            return Err(format!(
                "--flicker-step {} over --flicker-frames {} turns the light {sweep}°, more than {}°",
                self.step_degrees,
                self.frames,
                Self::MAX_SWEEP_DEGREES
            ));
        }
        Ok(())
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
    // One copy whose light each frame replaces (not a copy per frame: on
    // courtyard that is 60 MB of triangles a frame).
    let mut frame = scene.clone();
    for f in 0..options.frames {
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
                MethodKind::RayTraced32 {
                    edge_surfaces: false,
                } => resolve(
                    &same_sample_masks(&frame, bvh, crate::lut::sample_pattern()),
                    &g,
                ),
                MethodKind::RayTraced32 {
                    edge_surfaces: true,
                } => {
                    let m = edge_same_sample_masks(&frame, bvh, crate::lut::sample_pattern());
                    crate::cpu::resolve_counted(&m.masks, &m.counted, &g)
                }
                // Plain shadow rays of the same samples: their flicker is
                // rt32's up to the rule's contacts, not measured again.
                MethodKind::Embree32 | MethodKind::ShadowRays32 => {
                    *d = None;
                    continue;
                }
                MethodKind::ShadowVolumes => {
                    crate::baseline::volumes::shadow_volumes(&frame, &g).visibility
                }
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
        family: family.to_string(),
        mean_abs_delta: d.mean(ALL),
        ratio_to_truth: d.mean(ALL) / base[ALL],
        ratio_ci95: ratio_interval(&d.steps, &truth.steps),
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

/// Resamples of [`ratio_interval`].
const BOOTSTRAP_RESAMPLES: usize = 2000;

/// 95 % interval of the flicker ratio `Σ method / Σ truth` (each a mean
/// over pixels) by a paired moving-block bootstrap over frame steps:
/// blocks of ⌈√n⌉ consecutive steps, drawn with replacement (circularly)
/// until n steps are drawn, the same steps for the method and the truth.
/// Blocks, not single steps, because a shadow edge crossing a sample row
/// toggles samples in several consecutive frames; the interval then
/// counts such a burst as one event, not as many independent ones. With
/// fewer than 3 steps the interval is the point value.
pub fn ratio_interval(method: &[(f64, u64)], truth: &[(f64, u64)]) -> [f64; 2] {
    use rand::{Rng, SeedableRng};
    let n = method.len().min(truth.len());
    let ratio = |idx: &mut dyn Iterator<Item = usize>| {
        let (mut ms, mut mp, mut ts, mut tp) = (0.0, 0u64, 0.0, 0u64);
        for i in idx {
            ms += method[i].0;
            mp += method[i].1;
            ts += truth[i].0;
            tp += truth[i].1;
        }
        (ms / mp.max(1) as f64) / (ts / tp.max(1) as f64)
    };
    let point = ratio(&mut (0..n));
    if n < 3 {
        return [point, point];
    }
    let block = (n as f64).sqrt().ceil() as usize;
    let mut rng = rand_pcg::Pcg32::seed_from_u64(0x5eed);
    let mut ratios: Vec<f64> = (0..BOOTSTRAP_RESAMPLES)
        .map(|_| {
            let starts: Vec<usize> = (0..n.div_ceil(block))
                .map(|_| rng.random_range(0..n))
                .collect();
            ratio(
                &mut starts
                    .iter()
                    .flat_map(|&s| (s..s + block).map(|i| i % n))
                    .take(n),
            )
        })
        .collect();
    ratios.sort_by(f64::total_cmp);
    let at = |q: f64| ratios[((q * (BOOTSTRAP_RESAMPLES - 1) as f64).round()) as usize];
    [at(0.025), at(0.975)]
}

#[cfg(test)]
mod tests {
    use super::ratio_interval;

    #[test]
    fn interval_holds_the_ratio_and_shrinks_with_agreement() {
        // A method that always changes twice as much as the truth: every
        // resample gives exactly 2.
        let truth: Vec<(f64, u64)> = (0..50).map(|i| (1.0 + (i % 7) as f64, 100)).collect();
        let twice: Vec<(f64, u64)> = truth.iter().map(|&(s, p)| (2.0 * s, p)).collect();
        let [lo, hi] = ratio_interval(&twice, &truth);
        assert!(
            (lo - 2.0).abs() < 1e-12 && (hi - 2.0).abs() < 1e-12,
            "[{lo}, {hi}]"
        );
        // One burst frame: the interval is wide and holds the point value.
        let mut burst = truth.clone();
        burst[10].0 += 100.0;
        let [lo, hi] = ratio_interval(&burst, &truth);
        let point = burst.iter().map(|s| s.0).sum::<f64>() / truth.iter().map(|s| s.0).sum::<f64>();
        assert!(
            lo < point && point < hi && lo < 1.05 && hi > 1.5,
            "{point} in [{lo}, {hi}]"
        );
    }
}
