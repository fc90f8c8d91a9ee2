//! Exact lit fraction of the `analytic` scene under a disk sun, and the
//! bound the area-light estimator provably meets against it
//! (paper-notes/reference-estimator.md, "Area lights").
//!
//! At a ground point X the light is the disk of radius tan r on the plane
//! one unit from X along c, the unit vector toward the sun (the disk of
//! [`crate::scene::LightDisk`], sampled uniformly by area). A sample is
//! blocked when the ray toward it meets the occluder square, i.e. when it
//! lies in Q, the square projected centrally from X onto that plane: the
//! corner C goes to d/(d·c) − c, d = C − X. In disk units (÷ tan r) the lit
//! fraction is m(X) = 1 − area(unit disk ∩ Q)/π, computed exactly by
//! [`polygon_disk_area`]. The pixel's exact value is the mean of m over the
//! pixel's screen square (the reference integrates screen area, as in the
//! hard case), evaluated by the midpoint rule with a proven allowance.

use super::analytic::{AnalyticShadow, DELTA};
use super::disk_area::{clearance, polygon_disk_area, Clearance};
use super::LIGHT_SAMPLES_PER_RAY;
use crate::scene::procedural::analytic_params::{OCCLUDER_HALF_SIDE, OCCLUDER_HEIGHT};
use crate::scene::{light_disk, CameraFrame, Light, Scene};
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Midpoint-rule cells per side of a pixel (n × n evaluations of m).
pub const QUADRATURE_SIDE: u32 = 64;

/// The exact solution for one camera/light configuration of the analytic
/// scene under a directional light of angular radius r > 0.
pub struct SoftShadow {
    /// The occluder's corners (world).
    corners: [DVec3; 4],
    /// Unit vector toward the light's centre.
    toward: DVec3,
    /// Orthonormal axes of the disk plane (those of [`light_disk`]; any
    /// orthonormal pair ⊥ c gives the same areas).
    axes: [DVec3; 2],
    tan_r: f64,
    eye: DVec3,
    frame: CameraFrame,
    /// The hard solution, for which pixels see the occluder itself.
    hard: AnalyticShadow,
}

/// The exact lit fraction of one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PixelTruth {
    /// m is this constant (0 or 1) over the whole footprint, proven: the
    /// estimator must return it exactly.
    Constant(f64),
    /// The midpoint rule's value `lit`, within `allowance` of the exact
    /// mean of m; `variance` bounds the variance of m over the pixel.
    Integrated {
        lit: f64,
        allowance: f64,
        variance: f64,
    },
    /// Left out: the pixel sees the occluder (some sub-rays stop on it) or
    /// the sky.
    Excluded(Exclusion),
}

/// Why a pixel is not checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exclusion {
    SeesOccluder,
    SeesSky,
}

/// A reference image compared with the exact solution.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SoftCheck {
    /// Checked pixels (constant + integrated).
    pub pixels: usize,
    /// Pixels proven wholly lit or wholly in the umbra.
    pub constant_pixels: usize,
    /// Pixels whose exact value needed the quadrature.
    pub integrated_pixels: usize,
    /// Integrated pixels with 0 < value < 1.
    pub penumbra_pixels: usize,
    pub excluded_occluder: usize,
    pub excluded_sky: usize,
    /// Pixels beyond their per-pixel bound (constant pixels: any error).
    pub violations: usize,
    pub max_abs_error: f64,
    /// Largest |error| − bound over pixels; ≤ 0 when every bound holds.
    pub max_excess_over_bound: f64,
    /// Mean |error| over the integrated pixels, and its bound.
    pub mean_abs_error: f64,
    pub mean_abs_bound: f64,
    /// Mean signed error over the integrated pixels, and its bound.
    pub mean_signed_error: f64,
    pub mean_signed_bound: f64,
    /// Mean and largest quadrature allowance of the integrated pixels.
    pub mean_quadrature_allowance: f64,
    pub max_quadrature_allowance: f64,
}

impl SoftCheck {
    /// Every bound holds.
    pub fn holds(&self) -> bool {
        self.violations == 0
            && self.mean_abs_error <= self.mean_abs_bound
            && self.mean_signed_error.abs() <= self.mean_signed_bound
    }
}

/// Bernstein's inequality solved for the deviation: a sum of independent
/// zero-mean terms, each |·| ≤ `range`, with variances summing to at most
/// `variance`, exceeds the returned t with probability ≤ e^(−`log_term`)
/// (one side; use ln(2/δ) for both).
pub fn bernstein(variance: f64, range: f64, log_term: f64) -> f64 {
    let a = range * log_term / 3.0;
    a + (a * a + 2.0 * variance * log_term).sqrt()
}

impl SoftShadow {
    /// The exact solution for `scene`: the `analytic` procedural scene (or a
    /// copy with another camera or resolution) under a directional light of
    /// `light_radius` > 0.
    pub fn new(scene: &Scene) -> Result<Self, String> {
        let Light::Directional { direction } = scene.light else {
            return Err("the analytic solution needs a directional light".into());
        };
        if !scene.has_area_light() {
            return Err("the soft solution needs a light of angular radius > 0".into());
        }
        let toward = -direction.normalize();
        let disk = light_disk(toward, 1.0);
        let s = OCCLUDER_HALF_SIDE;
        Ok(SoftShadow {
            corners: [(-s, -s), (s, -s), (s, s), (-s, s)]
                .map(|(x, z)| DVec3::new(x, OCCLUDER_HEIGHT, z)),
            toward,
            axes: [disk.axis_u.normalize(), disk.axis_v.normalize()],
            tan_r: scene.light_radius.tan(),
            eye: scene.camera.eye,
            frame: scene.camera.frame(scene.resolution),
            hard: AnalyticShadow::new(scene)?,
        })
    }

    /// Q seen from the ground point `x`, in disk units. The square is first
    /// clipped to d·c ≥ 10⁻⁶ h (h its height over X, so |d| ≥ h): what that
    /// removes is seen at cos < 10⁻⁶ from c, far outside any disk the scene
    /// accepts (≤ 30°), and what stays projects to finite points.
    fn disk_polygon(&self, x: DVec3) -> Vec<DVec2> {
        let c = self.toward;
        let eps = 1e-6 * (OCCLUDER_HEIGHT - x.y);
        let d: Vec<DVec3> = self.corners.iter().map(|&k| k - x).collect();
        let mut kept = Vec::with_capacity(6);
        for i in 0..d.len() {
            let (a, b) = (d[i], d[(i + 1) % d.len()]);
            let (sa, sb) = (a.dot(c) - eps, b.dot(c) - eps);
            if sa >= 0.0 {
                kept.push(a);
            }
            if (sa >= 0.0) != (sb >= 0.0) {
                kept.push(a + (b - a) * (sa / (sa - sb)));
            }
        }
        kept.iter()
            .map(|&d| {
                let p = d / d.dot(c) - c;
                DVec2::new(p.dot(self.axes[0]), p.dot(self.axes[1])) / self.tan_r
            })
            .collect()
    }

    /// The lit fraction m(X) of the ground point `x` (y = 0) below the
    /// occluder's plane.
    pub fn lit_fraction_at(&self, x: DVec3) -> f64 {
        1.0 - polygon_disk_area(&self.disk_polygon(x), 1.0) / PI
    }

    /// The ground point (y = 0) seen through pixel coordinates (`px`, `py`),
    /// `None` above the horizon.
    fn ground(&self, px: f64, py: f64) -> Option<DVec3> {
        let dir = self.frame.direction(px, py);
        (dir.y < 0.0).then(|| self.eye + dir * (-self.eye.y / dir.y))
    }

    /// How fast, in disk units per ground unit, a point of ∂Q that lies
    /// within `reach` disk units of the disk's centre can move as X slides
    /// on the ground.
    ///
    /// Such a point is p = d/(d·c) − c for a point Y of the square's
    /// boundary, d = Y − X, seen at an angle θ ≤ r' = atan(reach · tan r)
    /// from c, so d·c = |d| cos θ, and |d| ≥ h / sin(elevation of c + r')
    /// (h the occluder's height). Since dp = −dX/(d·c) + d (dX·c)/(d·c)²,
    /// |dp| ≤ (1/cos r' + 1/cos² r') |dX| / |d|.
    fn boundary_speed(&self, reach: f64) -> f64 {
        let r = (reach * self.tan_r).atan();
        let (cos, elevation) = (r.cos(), self.toward.y.asin());
        let sin_max = (elevation + r).min(std::f64::consts::FRAC_PI_2).sin();
        (1.0 / cos + 1.0 / (cos * cos)) * sin_max / (OCCLUDER_HEIGHT * self.tan_r)
    }

    /// Whether the clearance of Q at a ground point proves m constant on
    /// every ground point within `rho` of it: `Some(m)` if so. While the
    /// gap between ∂Q and the disk is below μ ≤ the margin, the nearest
    /// points of ∂Q lie within 1 + μ of the centre and so move at most
    /// `boundary_speed(1 + μ)` per ground unit: the gap cannot
    /// close over a distance shorter than μ / that speed.
    fn constant_within(&self, clearance: Clearance, rho: f64) -> Option<f64> {
        let mu = clearance.margin().min(1.0);
        if mu <= 0.0 || self.boundary_speed(1.0 + mu) * rho >= mu {
            return None;
        }
        match clearance {
            Clearance::Outside(_) => Some(1.0),
            Clearance::Covers(_) => Some(0.0),
            Clearance::Crosses => None,
        }
    }

    /// The exact value of pixel (`x`, `y`), the midpoint rule on `n × n`
    /// cells where no certificate proves it constant.
    ///
    /// Why the midpoint rule's allowance holds: as X moves, the area of
    /// disk ∩ Q changes at the normal speed of ∂Q integrated over ∂Q ∩ disk,
    /// whose length is at most the disk's perimeter 2π (it bounds part of
    /// the convex set Q ∩ disk), so |dm| ≤ (2π/π) · speed · |dX| with the
    /// speed of `boundary_speed(1)`. A cell whose ground footprint
    /// lies within ρ of its centre's ground point is thus off by at most
    /// min(1, 2 · speed · ρ); the footprint of a screen square is a convex
    /// quadrilateral (a homography), so ρ is attained at its corners.
    pub fn pixel(&self, x: u32, y: u32, n: u32) -> PixelTruth {
        if self.hard.sees_occluder(x, y) {
            return PixelTruth::Excluded(Exclusion::SeesOccluder);
        }
        let (x0, y0) = (x as f64, y as f64);
        let footprint: Option<Vec<DVec3>> = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
            .iter()
            .map(|&(i, j)| self.ground(x0 + i, y0 + j))
            .collect();
        let Some(footprint) = footprint else {
            return PixelTruth::Excluded(Exclusion::SeesSky);
        };
        let speed = self.boundary_speed(1.0);
        // Whole-pixel certificate first: most pixels are far from the shadow.
        let centre = self
            .ground(x0 + 0.5, y0 + 0.5)
            .expect("inside the footprint");
        let rho = footprint
            .iter()
            .map(|g| (*g - centre).length())
            .fold(0.0, f64::max);
        if let Some(v) = self.constant_within(clearance(&self.disk_polygon(centre), 1.0), rho) {
            return PixelTruth::Constant(v);
        }
        let step = 1.0 / n as f64;
        let corner_row = |j: u32| -> Vec<DVec3> {
            (0..=n)
                .map(|i| {
                    self.ground(x0 + i as f64 * step, y0 + j as f64 * step)
                        .expect("inside the footprint")
                })
                .collect()
        };
        let (mut values, mut allowance) = (Vec::with_capacity((n * n) as usize), 0.0);
        let (mut all_lit, mut all_umbra) = (true, true);
        let mut upper = corner_row(0);
        for j in 0..n {
            let lower = corner_row(j + 1);
            for i in 0..n {
                let (u, v) = ((i as f64 + 0.5) * step, (j as f64 + 0.5) * step);
                let g = self.ground(x0 + u, y0 + v).expect("inside the footprint");
                let cell = [upper[i as usize], upper[i as usize + 1]];
                let cell = [cell[0], cell[1], lower[i as usize], lower[i as usize + 1]];
                let rho = cell.iter().map(|c| (*c - g).length()).fold(0.0, f64::max);
                let q = self.disk_polygon(g);
                match self.constant_within(clearance(&q, 1.0), rho) {
                    Some(1.0) => all_umbra = false,
                    Some(_) => all_lit = false,
                    None => (all_lit, all_umbra) = (false, false),
                }
                values.push(1.0 - polygon_disk_area(&q, 1.0) / PI);
                allowance += (2.0 * speed * rho).min(1.0);
            }
            upper = lower;
        }
        if all_lit || all_umbra {
            return PixelTruth::Constant(all_lit as u32 as f64);
        }
        let cells = (n * n) as f64;
        let lit = values.iter().sum::<f64>() / cells;
        let allowance = allowance / cells;
        // Var m ≤ E(m − lit)², and |(m − a)² − (m_c − a)²| ≤ 2|m − m_c| on
        // [0, 1], so the cell means of (m_c − lit)² are off by ≤ 2 allowance.
        let spread = values.iter().map(|m| (m - lit).powi(2)).sum::<f64>() / cells;
        PixelTruth::Integrated {
            lit,
            allowance,
            variance: (spread + 2.0 * allowance).min(0.25),
        }
    }

    /// The exact values of every pixel (row-major).
    pub fn truth(&self, n: u32) -> Vec<PixelTruth> {
        let [w, h] = [self.frame.width, self.frame.height];
        (0..w * h)
            .into_par_iter()
            .map(|i| self.pixel(i % w, i / w, n))
            .collect()
    }

    /// Checks a reference image traced with `k × k` sub-pixel rays and
    /// [`LIGHT_SAMPLES_PER_RAY`] light samples per hit against `truth`
    /// (from [`SoftShadow::truth`]). Failure probability ≤ 3δ when the
    /// estimator is right (δ = [`DELTA`] for each of the three tests).
    pub fn check(truth: &[PixelTruth], visibility: &[f32], k: u32) -> SoftCheck {
        let l = LIGHT_SAMPLES_PER_RAY as f64;
        let k2 = (k * k) as f64;
        let eps32 = f32::EPSILON as f64;
        let mut c = SoftCheck::default();
        for t in truth {
            match t {
                PixelTruth::Constant(_) => c.constant_pixels += 1,
                PixelTruth::Integrated { .. } => c.integrated_pixels += 1,
                PixelTruth::Excluded(Exclusion::SeesOccluder) => c.excluded_occluder += 1,
                PixelTruth::Excluded(Exclusion::SeesSky) => c.excluded_sky += 1,
            }
        }
        // Union bound over the pixels with a random error.
        let log_pixel = (2.0 * c.integrated_pixels.max(1) as f64 / DELTA).ln();
        let (mut sum_abs, mut sum_signed, mut sum_sigma, mut sum_var) = (0.0, 0.0, 0.0, 0.0);
        let (mut sum_allow, mut max_range) = (0.0, 0.0f64);
        c.max_excess_over_bound = f64::NEG_INFINITY;
        for (t, &v) in truth.iter().zip(visibility) {
            let (exact, bound) = match *t {
                PixelTruth::Excluded(_) => continue,
                PixelTruth::Constant(f) => (f, eps32),
                PixelTruth::Integrated {
                    lit,
                    allowance,
                    variance,
                } => {
                    // f(1 − f) at its largest over [lit ± allowance].
                    let f = (lit - allowance)
                        .max(0.5)
                        .min(lit + allowance)
                        .clamp(0.0, 1.0);
                    let var = f * (1.0 - f) / (k2 * l) + (1.0 - 1.0 / l) * variance / k2;
                    let statistical = bernstein(var, 1.0 / k2, log_pixel);
                    sum_sigma += var.sqrt();
                    sum_var += var;
                    sum_allow += allowance;
                    max_range = max_range.max(statistical);
                    c.max_quadrature_allowance = c.max_quadrature_allowance.max(allowance);
                    if lit > 0.0 && lit < 1.0 {
                        c.penumbra_pixels += 1;
                    }
                    (lit, statistical + allowance + eps32)
                }
            };
            if v.is_nan() {
                // A checked ground pixel must be shadow-tested.
                c.violations += 1;
                continue;
            }
            c.pixels += 1;
            let error = v as f64 - exact;
            if error.abs() > bound {
                c.violations += 1;
            }
            c.max_abs_error = c.max_abs_error.max(error.abs());
            c.max_excess_over_bound = c.max_excess_over_bound.max(error.abs() - bound);
            if matches!(t, PixelTruth::Integrated { .. }) {
                sum_abs += error.abs();
                sum_signed += error;
            }
        }
        let p = c.integrated_pixels.max(1) as f64;
        c.mean_abs_error = sum_abs / p;
        c.mean_signed_error = sum_signed / p;
        c.mean_quadrature_allowance = sum_allow / p;
        // Mean |e|: E|e_p| ≤ σ_p; on the event that every pixel is within
        // its bound the |e_p| are in [0, t_p] with variance ≤ σ_p², and
        // Bernstein (one-sided) bounds their mean's excess.
        c.mean_abs_bound = sum_sigma / p
            + bernstein(sum_var, max_range, (1.0 / DELTA).ln()) / p
            + c.mean_quadrature_allowance
            + eps32;
        // Mean signed error: all k²·(pixels) sub-ray terms are independent,
        // each |·| ≤ 1/k², variances summing to ≤ Σ σ_p².
        c.mean_signed_bound = bernstein(sum_var, 1.0 / k2, (2.0 / DELTA).ln()) / p
            + c.mean_quadrature_allowance
            + eps32;
        if c.pixels == 0 {
            c.max_excess_over_bound = 0.0;
        }
        c
    }
}
