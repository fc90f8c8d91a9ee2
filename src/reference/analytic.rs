//! Closed-form lit fraction of the `analytic` procedural scene, and the
//! bound the stratified estimator provably meets against it.
//!
//! Scene: ground plane y = 0 (large enough to fill the view) and a square
//! occluder parallel to it, under a directional light. The shadow on the
//! ground is the occluder translated along the light, a square; the camera
//! maps the ground plane to the image by a homography, so the shadow's
//! image is the quadrilateral through the projected corners. The exact
//! shadowed fraction of a pixel is the area of that quadrilateral clipped
//! to the pixel square. Pixels whose square meets the occluder's own image
//! are excluded (some of their sub-rays hit the occluder, not the ground).
//!
//! The bound (see `paper-notes/reference-estimator.md`): with one uniform
//! sample in each of the N = k² strata, a stratum lying wholly inside or
//! outside the shadow contributes no error, and one cut by the boundary
//! contributes a term X_i − f_i in [−f_i, 1 − f_i] with mean 0 and variance
//! f_i(1 − f_i), f_i its shadowed fraction. Hence, with c the number of cut
//! strata, per pixel |error| ≤ c / N always; E|error| ≤ σ =
//! √(Σ f_i(1 − f_i)) / N; and over many pixels Hoeffding's inequality bounds
//! the mean absolute and mean signed error with failure probability δ.

use crate::scene::procedural::analytic_params::{OCCLUDER_HALF_SIDE, OCCLUDER_HEIGHT};
use crate::scene::{Light, Scene};
use glam::{DVec2, DVec3};

/// Failure probability of the statistical (mean) bounds.
pub const DELTA: f64 = 1e-9;

/// The exact solution for one camera/light configuration of the scene.
pub struct AnalyticShadow {
    /// The shadow square's image, in pixel coordinates.
    shadow: Vec<DVec2>,
    /// The occluder's own image, in pixel coordinates.
    occluder: Vec<DVec2>,
}

/// Per-pixel comparison of a reference image with the exact solution.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct AnalyticCheck {
    /// Shadow-tested pixels not touching the occluder's image.
    pub pixels: usize,
    /// Of those, pixels cut by the shadow boundary (0 < exact < 1).
    pub penumbra_pixels: usize,
    /// Pixels whose error exceeds the deterministic bound c/N.
    pub violations: usize,
    pub max_abs_error: f64,
    /// Largest (|error| − c/N) over pixels; ≤ 0 when the bound holds.
    pub max_excess_over_bound: f64,
    pub mean_abs_error: f64,
    /// Bound on the mean absolute error: mean σ + Hoeffding slack.
    pub mean_abs_bound: f64,
    pub mean_signed_error: f64,
    pub mean_signed_bound: f64,
}

impl AnalyticCheck {
    /// All three bounds hold.
    pub fn holds(&self) -> bool {
        self.violations == 0
            && self.mean_abs_error <= self.mean_abs_bound
            && self.mean_signed_error.abs() <= self.mean_signed_bound
    }
}

impl AnalyticShadow {
    /// The exact solution for `scene` (the `analytic` procedural scene or a
    /// copy with another camera, light or resolution).
    pub fn new(scene: &Scene) -> Result<Self, String> {
        Self::translated(scene, DVec3::ZERO)
    }

    /// The exact solution for the analytic scene moved by `offset` (with
    /// [`Scene::translated`]).
    pub fn translated(scene: &Scene, offset: DVec3) -> Result<Self, String> {
        let Light::Directional { direction } = scene.light else {
            return Err("the analytic solution needs a directional light".into());
        };
        let s = OCCLUDER_HALF_SIDE;
        let h = OCCLUDER_HEIGHT;
        let corners = [(-s, -s), (s, -s), (s, s), (-s, s)].map(|(x, z)| DVec3::new(x, h, z));
        // Follow the light from each corner down to y = 0.
        let shadow = corners.map(|c| c + direction * (c.y / -direction.y) + offset);
        let corners = corners.map(|c| c + offset);
        let project = |p: &DVec3| {
            project_to_pixels(scene, *p)
                .ok_or_else(|| format!("corner {p} of the shadow or occluder is behind the camera"))
        };
        Ok(AnalyticShadow {
            shadow: shadow.iter().map(project).collect::<Result<_, _>>()?,
            occluder: corners.iter().map(project).collect::<Result<_, _>>()?,
        })
    }

    /// Exact shadowed fraction of the axis-aligned rectangle \[x0, x1\] × \[y0, y1\].
    pub fn shadowed_fraction(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> f64 {
        clipped_area(&self.shadow, x0, y0, x1, y1) / ((x1 - x0) * (y1 - y0))
    }

    /// Whether the pixel's square meets the occluder's image.
    pub fn sees_occluder(&self, x: u32, y: u32) -> bool {
        let (x0, y0) = (x as f64, y as f64);
        clipped_area(&self.occluder, x0, y0, x0 + 1.0, y0 + 1.0) > 0.0
    }

    /// Checks a reference image (traced with `k × k` strata) against the
    /// exact solution.
    pub fn check(&self, visibility: &[f32], width: u32, k: u32) -> AnalyticCheck {
        let n = (k * k) as f64;
        let mut c = AnalyticCheck::default();
        let (mut sum_abs, mut sum_signed, mut sum_sigma) = (0.0, 0.0, 0.0);
        let (mut sum_range_sq, mut cut_strata_total) = (0.0, 0.0);
        for (i, &v) in visibility.iter().enumerate() {
            let (x, y) = ((i as u32 % width), (i as u32 / width));
            if v.is_nan() || self.sees_occluder(x, y) {
                continue;
            }
            c.pixels += 1;
            let (x0, y0) = (x as f64, y as f64);
            let exact_lit = 1.0 - self.shadowed_fraction(x0, y0, x0 + 1.0, y0 + 1.0);
            let error = v as f64 - exact_lit;
            let (mut cut, mut variance) = (0.0, 0.0);
            if exact_lit > 0.0 && exact_lit < 1.0 {
                c.penumbra_pixels += 1;
            }
            // Only a pixel cut by the boundary can hold cut strata.
            if exact_lit > 0.0 && exact_lit < 1.0 {
                for j in 0..k {
                    for i in 0..k {
                        let sx = x0 + i as f64 / k as f64;
                        let sy = y0 + j as f64 / k as f64;
                        let f = self.shadowed_fraction(
                            sx,
                            sy,
                            sx + 1.0 / k as f64,
                            sy + 1.0 / k as f64,
                        );
                        if f > 0.0 && f < 1.0 {
                            cut += 1.0;
                            variance += f * (1.0 - f);
                        }
                    }
                }
            }
            // The stored value is f32: allow its rounding.
            let bound = cut / n + f32::EPSILON as f64;
            if error.abs() > bound {
                c.violations += 1;
            }
            c.max_abs_error = c.max_abs_error.max(error.abs());
            c.max_excess_over_bound = if c.pixels == 1 {
                error.abs() - bound
            } else {
                c.max_excess_over_bound.max(error.abs() - bound)
            };
            sum_abs += error.abs();
            sum_signed += error;
            sum_sigma += variance.sqrt() / n;
            sum_range_sq += (cut / n).powi(2);
            cut_strata_total += cut;
        }
        let p = c.pixels.max(1) as f64;
        c.mean_abs_error = sum_abs / p;
        c.mean_signed_error = sum_signed / p;
        // Hoeffding: the |e_p| are independent, each in [0, c_p/N].
        c.mean_abs_bound = sum_sigma / p
            + (sum_range_sq * (1.0 / DELTA).ln() / 2.0).sqrt() / p
            + f32::EPSILON as f64;
        // Hoeffding over all cut strata, each term with range 1/N.
        c.mean_signed_bound =
            (cut_strata_total * (2.0 / DELTA).ln() / 2.0).sqrt() / n / p + f32::EPSILON as f64;
        c
    }
}

/// Pixel coordinates of a world point, `None` if it is not in front of the
/// camera.
pub fn project_to_pixels(scene: &Scene, world: DVec3) -> Option<DVec2> {
    let frame = scene.camera.frame(scene.resolution);
    let q = world - scene.camera.eye;
    let z = q.dot(frame.forward);
    if z <= 0.0 {
        return None;
    }
    let ndc_x = q.dot(frame.right) / (z * frame.tan_half_fov * frame.aspect);
    let ndc_y = q.dot(frame.up) / (z * frame.tan_half_fov);
    Some(DVec2::new(
        (ndc_x + 1.0) * 0.5 * frame.width as f64,
        (1.0 - ndc_y) * 0.5 * frame.height as f64,
    ))
}

/// Area of a convex polygon clipped to an axis-aligned rectangle
/// (Sutherland–Hodgman against the four sides, then the shoelace formula).
pub fn clipped_area(polygon: &[DVec2], x0: f64, y0: f64, x1: f64, y1: f64) -> f64 {
    let mut poly = polygon.to_vec();
    // Each clip keeps the side where `inside(p) >= 0`.
    let sides: [&dyn Fn(DVec2) -> f64; 4] =
        [&|p| p.x - x0, &|p| x1 - p.x, &|p| p.y - y0, &|p| y1 - p.y];
    for inside in sides {
        if poly.is_empty() {
            break;
        }
        let mut out = Vec::with_capacity(poly.len() + 2);
        for i in 0..poly.len() {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            let (da, db) = (inside(a), inside(b));
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                out.push(a + (b - a) * (da / (da - db)));
            }
        }
        poly = out;
    }
    let mut twice = 0.0;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        twice += a.x * b.y - a.y * b.x;
    }
    (twice * 0.5).abs()
}
