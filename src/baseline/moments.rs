//! Filtered shadow maps ([Shadow mapping mechanics]; Donnelly and
//! Lauritzen 2006): the depth map turned into moments of depth and
//! blurred, so a lookup filters once instead of comparing per
//! tap.
//!
//! - `vsm-R`: variance shadow maps (Donnelly & Lauritzen 2006): two
//!   moments, Chebyshev's one-sided bound, light-bleeding reduction
//!   (Lauritzen 2007, GPU Gems 3 ch. 8: bounds below
//!   [`BLEEDING_CUT`] cut to 0, the rest rescaled).
//! - `msm-R`: moment shadow maps (Peters & Klein 2015): four moments,
//!   the Hamburger 4MSM reconstruction (the sharpest lower bound the four
//!   moments allow), moments biased by [`MOMENT_BIAS`].
//! - `esm-R`: exponential shadow maps (Annen et al. 2008): one moment,
//!   `exp(c·(u − 1))` with c = [`ESM_EXPONENT`]; the filtered moment
//!   times `exp(c·(1 − z))` is the lit fraction, clamped to 1 (exact
//!   where every occluder in the filter lies in front of the receiver by
//!   much more than 1/c, bleeding light where they do not).
//!
//! Pass `shadow_blur` (after `shadow_map`) takes every texel's depth to a
//! moment depth `u ∈ [0, 1]` ([`MomentDepth`]), its powers, and blurs
//! them with a separable 9² Gaussian (binomial weights `C(8, i)/256`,
//! the blur of Peters 2017), rows then columns; texels beyond the map
//! read as empty (`u = 1`). Its GPU twin is `shaders/shadow_blur.comp`
//! (`shadow_blur_x`, `shadow_blur_y`), same order of every sum. The
//! lookup filters the moments bilinearly at the receiver and
//! reconstructs.

use super::raster::MapDepth;
use super::shadow_map::{bilinear_taps, texel_world, CascadeMap, ShadowMaps, CONSTANT_BIAS_TEXELS};
use crate::cpu::light_setup::{LightSetup, Projection};
use glam::{Vec2, Vec3};
use izb_contract::filtered::BLUR_RADIUS;
use izb_contract::filtered_params::{BLEEDING_CUT, ESM_EXPONENT, MOMENT_BIAS};
use rayon::prelude::*;

/// Which moments a filtered map keeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MomentKind {
    /// `u`, `u²`.
    Variance,
    /// `u`, `u²`, `u³`, `u⁴`.
    FourMoments,
    /// `exp(c·(u − 1))`.
    Exponential,
}

impl MomentKind {
    pub fn count(self) -> usize {
        match self {
            MomentKind::Exponential => 1,
            MomentKind::Variance => 2,
            MomentKind::FourMoments => 4,
        }
    }
}

/// The moment depth `u` of a stored depth: the light distance over the
/// receivers' range, in [0, 1], 1 for an empty texel. A directional
/// light's stored depth is already that; a point light's reversed depth
/// is not linear, so it goes back to a distance first and onto the same
/// kind of range (grown by the raster's margin) — Chebyshev and the
/// moment bounds want depths whose filtered mean is meaningful.
#[derive(Clone, Copy, Debug)]
pub struct MomentDepth {
    pub map_depth: MapDepth,
    /// Perspective: the distance at `u = 0` and from `u = 0` to `u = 1`.
    pub lo: f32,
    pub range: f32,
}

impl MomentDepth {
    /// The GPU computes the same in `moment_depth_range`
    /// (`shaders/shadow_map.glsl`).
    pub fn new(setup: &LightSetup) -> MomentDepth {
        let map_depth = MapDepth::new(setup);
        let [zmin, zmax] = setup.receiver_z;
        let span = zmax - zmin;
        let mut margin = super::raster::MAP_DEPTH_MARGIN * (span + zmin);
        if !(margin > 0.0 && margin.is_finite()) {
            margin = 1.0;
        }
        match setup.projection {
            Projection::Orthographic => MomentDepth {
                map_depth,
                lo: map_depth.near,
                range: map_depth.range,
            },
            Projection::Perspective => MomentDepth {
                map_depth,
                lo: zmin - margin,
                range: span + margin + margin,
            },
        }
    }

    /// `u` of a light distance.
    #[inline]
    pub fn of_distance(&self, d: f32) -> f32 {
        let u = (d - self.lo) / self.range;
        if u.is_nan() {
            1.0
        } else {
            u.clamp(0.0, 1.0)
        }
    }

    /// `u` of a stored depth.
    #[inline]
    pub fn of_stored(&self, depth: f32) -> f32 {
        match self.map_depth.projection {
            Projection::Orthographic => depth.min(1.0),
            Projection::Perspective => self.of_distance(self.map_depth.distance(depth)),
        }
    }
}

/// The moments of `kind` a texel at moment depth `u` stores (the first
/// `kind.count()` of the four): `u`'s powers `u`, `u·u`, `u²·u`, `u²·u²`,
/// or ESM's exponential.
#[inline]
fn moments_of(kind: MomentKind, u: f32) -> [f32; 4] {
    if kind == MomentKind::Exponential {
        return [(ESM_EXPONENT * (u - 1.0)).exp(), 0.0, 0.0, 0.0];
    }
    let u2 = u * u;
    [u, u2, u2 * u, u2 * u2]
}

/// The blur's weights, `C(8, i) / 256`, built by the recurrence the
/// shader runs (every step exact in `f32`).
fn blur_weights() -> [f32; 2 * BLUR_RADIUS as usize + 1] {
    let n = 2 * BLUR_RADIUS;
    let mut w = [0.0f32; 2 * BLUR_RADIUS as usize + 1];
    let mut c = 1.0f32;
    for (i, wi) in w.iter_mut().enumerate() {
        *wi = c / (1u32 << n) as f32;
        c = c * (n - i as u32) as f32 / (i as u32 + 1) as f32;
    }
    w
}

/// Pass `shadow_blur`: the blurred moments of every cascade's map,
/// `side²·count` floats each, texel-major.
pub fn shadow_blur(setup: &LightSetup, maps: &ShadowMaps, kind: MomentKind) -> Vec<Vec<f32>> {
    let depth = MomentDepth::new(setup);
    let n = kind.count();
    let w = blur_weights();
    let r = BLUR_RADIUS as i32;
    maps.maps
        .iter()
        .map(|map| {
            let side = map.side as i32;
            let u_at = |x: i32, y: i32| {
                if x < 0 || x >= side {
                    1.0
                } else {
                    depth.of_stored(map.depth[(y * side + x) as usize])
                }
            };
            // Rows: the moments of each texel's horizontal neighbours.
            let rows: Vec<f32> = (0..side * side)
                .into_par_iter()
                .flat_map_iter(|i| {
                    let (x, y) = (i % side, i / side);
                    let mut sum = [0.0f32; 4];
                    for (j, wj) in w.iter().enumerate() {
                        let m = moments_of(kind, u_at(x + j as i32 - r, y));
                        for c in 0..4 {
                            sum[c] += wj * m[c];
                        }
                    }
                    sum.into_iter().take(n)
                })
                .collect();
            // Columns of the rows; beyond the map every moment is 1.
            (0..side * side)
                .into_par_iter()
                .flat_map_iter(|i| {
                    let (x, y) = (i % side, i / side);
                    let mut sum = [0.0f32; 4];
                    for (j, wj) in w.iter().enumerate() {
                        let yy = y + j as i32 - r;
                        for (c, s) in sum.iter_mut().enumerate().take(n) {
                            let m = if yy < 0 || yy >= side {
                                1.0
                            } else {
                                rows[((yy * side + x) as usize) * n + c]
                            };
                            *s += wj * m;
                        }
                    }
                    sum.into_iter().take(n)
                })
                .collect()
        })
        .collect()
}

/// The lit fraction of a receiver at light-view `p` (light NDC `ndc`) from
/// cascade map `map` and its blurred `moments`.
pub fn moments_lookup(
    depth: &MomentDepth,
    kind: MomentKind,
    map: &CascadeMap,
    moments: &[f32],
    p: Vec3,
    ndc: Vec2,
) -> f32 {
    let n = kind.count();
    let side = map.side as i32;
    // Bilinear: texel centres sit at integer + ½.
    let t = map.texel_coords(ndc) - 0.5;
    let base = t.floor();
    let f = t - base;
    let (bx, by) = map.texel_of(base);
    let mut b = [0.0f32; 4];
    for (dx, dy, wt) in bilinear_taps(f) {
        let (x, y) = (bx + dx, by + dy);
        let inside = x >= 0 && y >= 0 && x < side && y < side;
        for (c, bc) in b.iter_mut().enumerate().take(n) {
            let m = if inside {
                moments[((y * side + x) as usize) * n + c]
            } else {
                1.0
            };
            *bc += wt * m;
        }
    }
    let projection = depth.map_depth.projection;
    let own = depth.of_distance(super::shadow_map::light_distance(projection, p));
    let bias = texel_world(map, projection, p) * CONSTANT_BIAS_TEXELS / depth.range;
    let z = own - bias;
    match kind {
        MomentKind::Exponential => exponential(b[0], z),
        MomentKind::Variance => chebyshev(b[0], b[1], z, bias),
        MomentKind::FourMoments => 1.0 - hamburger(b, z),
    }
}

/// ESM: the filtered `exp(c·(u − 1))` times `exp(c·(1 − z))`, clamped to
/// [0, 1]. A receiver in front of the range (`z < 0`) is taken at 0, which
/// keeps the factor within `f32` (≤ e⁷²) and reads lit, as it is.
fn exponential(mean: f32, z: f32) -> f32 {
    let lit = mean * (ESM_EXPONENT * (1.0 - z.max(0.0))).exp();
    lit.clamp(0.0, 1.0)
}

/// VSM: Chebyshev's upper bound on the lit fraction, the variance kept
/// at least `min_sigma²`, then light-bleeding reduction.
fn chebyshev(mean: f32, square: f32, z: f32, min_sigma: f32) -> f32 {
    if z <= mean {
        return 1.0;
    }
    let variance = (square - mean * mean).max(min_sigma * min_sigma);
    let d = z - mean;
    let p = variance / (variance + d * d);
    ((p - BLEEDING_CUT) / (1.0 - BLEEDING_CUT)).clamp(0.0, 1.0)
}

/// MSM: the Hamburger 4MSM shadow intensity (Peters & Klein 2015,
/// Algorithm 2) of a receiver at moment depth `z` behind the filtered
/// moments `m`: a Cholesky factorisation of the biased Hankel matrix,
/// the two other support points as the roots of a quadratic, and the
/// weight of those in front of `z`.
fn hamburger(m: [f32; 4], z: f32) -> f32 {
    let a = MOMENT_BIAS;
    let b = m.map(|v| (1.0 - a) * v + a * 0.5);
    let l32_d22 = -b[0] * b[1] + b[2];
    let d22 = -b[0] * b[0] + b[1];
    let squared_variance = -b[1] * b[1] + b[3];
    let d33_d22 = squared_variance * d22 - l32_d22 * l32_d22;
    let inv_d22 = 1.0 / d22;
    let l32 = l32_d22 * inv_d22;
    // Solve B·c = (1, z, z²) by substitution.
    let mut c = [1.0, z, z * z];
    c[1] -= b[0];
    c[2] -= b[1] + l32 * c[1];
    c[1] *= inv_d22;
    c[2] *= d22 / d33_d22;
    c[1] -= l32 * c[2];
    c[0] -= c[1] * b[0] + c[2] * b[1];
    // Roots of c0 + c1·x + c2·x².
    let p = c[1] / c[2];
    let q = c[0] / c[2];
    let r = (p * p * 0.25 - q).max(0.0).sqrt();
    let (z1, z2) = (-p * 0.5 - r, -p * 0.5 + r);
    let (s0, s1, s2, s3) = if z2 < z {
        (z1, z, 1.0, 1.0)
    } else if z1 < z {
        (z, z1, 0.0, 1.0)
    } else {
        return 0.0;
    };
    let quotient = (s0 * z2 - b[0] * (s0 + z2) + b[1]) / ((z2 - s1) * (z - z1));
    let shadow = s2 + s3 * quotient;
    if shadow.is_nan() {
        0.0
    } else {
        shadow.clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blur_weights_are_the_binomial_row() {
        let w = blur_weights();
        let expect = [1.0, 8.0, 28.0, 56.0, 70.0, 56.0, 28.0, 8.0, 1.0].map(|c: f32| c / 256.0);
        assert_eq!(w, expect);
        assert_eq!(w.iter().sum::<f32>(), 1.0);
    }

    /// Two depths with weights: the occluded share behind both is 1, in
    /// front of both 0, and between them a bound the true share (the
    /// front depth's weight) lies within for VSM and near for MSM; ESM's
    /// lit fraction there never falls below the true one.
    #[test]
    fn reconstructions_bound_a_two_depth_distribution() {
        let (front, back, share) = (0.3f32, 0.7f32, 0.4f32);
        let m: [f32; 4] = std::array::from_fn(|k| {
            share * front.powi(k as i32 + 1) + (1.0 - share) * back.powi(k as i32 + 1)
        });
        assert_eq!(hamburger(m, 0.2), 0.0);
        assert!(hamburger(m, 0.9) > 0.99, "{}", hamburger(m, 0.9));
        let between = hamburger(m, 0.5);
        assert!((between - share).abs() < 0.05, "MSM {between}");
        // Chebyshev's bound on the lit share is ≥ the true 0.6 before
        // the bleeding cut.
        let lit = chebyshev(m[0], m[1], 0.5, 0.0);
        let uncut = lit * (1.0 - BLEEDING_CUT) + BLEEDING_CUT;
        assert!(uncut >= 1.0 - share - 1e-6, "VSM {lit}");
        assert_eq!(chebyshev(m[0], m[1], 0.2, 0.0), 1.0);
        // ESM: lit in front of both depths, dark well behind both, and
        // between them never darker than the truth (its light leak).
        let e = share * moments_of(MomentKind::Exponential, front)[0]
            + (1.0 - share) * moments_of(MomentKind::Exponential, back)[0];
        assert_eq!(exponential(e, 0.2), 1.0);
        assert!(exponential(e, 0.9) < 1e-4, "ESM {}", exponential(e, 0.9));
        assert!(
            exponential(e, 0.5) >= 1.0 - share,
            "ESM {}",
            exponential(e, 0.5)
        );
        // A receiver in front of the range reads lit without overflow.
        assert_eq!(exponential(e, -5.0), 1.0);
    }
}
