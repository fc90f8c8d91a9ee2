//! One occluder edge seen from one pixel: the affine edge function on the
//! µQuad, its normalised (angle, distance) form, and the exact per-sample
//! classification the LUT is measured against.
//!
//! Wyman et al. 2015, §4 (Wyman et al., "frustum-triangle tests"): each triangle edge
//! and the light span a *shadow quad*; projected onto the receiver's tangent
//! plane it is a line, and one side of it is shadowed. Design §4 writes the
//! side test in µQuad coordinates as the affine function
//!
//! ```text
//! f(u, v) = α + β (u − ½) + γ (v − ½),    sample inside (occluded) ⇔ f ≥ 0,
//! ```
//!
//! with (u, v) ∈ [0, 1)², (0, 0) the pixel's top-left corner, v downward.

use crate::rng::SplitMix64;
use crate::{SamplePattern, SAMPLES_PER_PIXEL};
use std::f64::consts::PI;

/// Distance from the µQuad centre to its corners, √2/2, in units of the
/// µQuad side: the largest |cos θ·(u−½) + sin θ·(v−½)| over the unit square.
/// A line at |d| ≥ this from the centre cannot cut the square (paper-notes/frustum-test.md).
pub const HALF_DIAGONAL: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// Mask with every sample inside.
pub const ALL_SAMPLES: u32 = u32::MAX;

const _: () = assert!(SAMPLES_PER_PIXEL == u32::BITS as usize);

/// The normalised form of an edge function (paper-notes/frustum-test.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EdgeLine {
    /// The line misses the µQuad, or (β, γ) vanishes: every sample gets the
    /// same answer; the mask is [`ALL_SAMPLES`] or 0.
    Constant(u32),
    /// g(u, v) = `distance` + cos `theta`·(u−½) + sin `theta`·(v−½) = f/|(β, γ)|,
    /// `theta` = atan2(γ, β) ∈ [−π, π], |`distance`| < √2/2. `distance` > 0
    /// means the µQuad centre is inside.
    Line { theta: f64, distance: f64 },
}

/// Normalises (α, β, γ) to an [`EdgeLine`], in f64.
///
/// With r = |(β, γ)|, the signed distance of the line from the µQuad centre
/// is d = α/r. When |α| ≥ (√2/2)·r every point of the unit square lies on
/// the side of sign(α) (|cos θ·x + sin θ·y| ≤ √2/2 there), so the mask is
/// constant; this one comparison also catches r = 0 and an r so small
/// against |α| that d would be huge, without dividing by it. α = 0 = r is
/// "inside" (f = 0 ≥ 0), and any NaN gives "none", both as [`exact_mask`].
pub fn edge_line(alpha: f64, beta: f64, gamma: f64) -> EdgeLine {
    let r = beta.hypot(gamma);
    // False for NaN too, which then takes the constant branch.
    let line_may_cut_the_square = alpha.abs() < HALF_DIAGONAL * r;
    if !line_may_cut_the_square {
        let inside = alpha >= 0.0 && r >= 0.0;
        return EdgeLine::Constant(if inside { ALL_SAMPLES } else { 0 });
    }
    EdgeLine::Line {
        theta: gamma.atan2(beta),
        distance: alpha / r,
    }
}

/// Exact signed distance g(s) = f(s)/|(β, γ)| of sample `sample` from the
/// edge line, in µQuad side lengths (positive inside). Infinite or NaN when
/// β = γ = 0.
pub fn signed_distance(alpha: f64, beta: f64, gamma: f64, sample: [f32; 2]) -> f64 {
    let f = alpha + beta * (f64::from(sample[0]) - 0.5) + gamma * (f64::from(sample[1]) - 0.5);
    f / beta.hypot(gamma)
}

/// g(s) = d + cos θ·(u−½) + sin θ·(v−½) for a line given by angle and
/// signed distance.
pub fn line_signed_distance(theta: f64, distance: f64, sample: [f32; 2]) -> f64 {
    distance
        + theta.cos() * (f64::from(sample[0]) - 0.5)
        + theta.sin() * (f64::from(sample[1]) - 0.5)
}

/// Mask of the samples with d + cos θ·(u−½) + sin θ·(v−½) ≥ 0: what one LUT
/// cell stores for its centre (θ_c, d_c).
pub fn line_mask(theta: f64, distance: f64, pattern: &SamplePattern) -> u32 {
    let (sin, cos) = theta.sin_cos();
    let mut mask = 0;
    for (i, &[u, v]) in pattern.iter().enumerate() {
        let g = distance + cos * (f64::from(u) - 0.5) + sin * (f64::from(v) - 0.5);
        mask |= u32::from(g >= 0.0) << i;
    }
    mask
}

/// Exact classification in f64: bit i set iff
/// α + β·(u_i − ½) + γ·(v_i − ½) ≥ 0. The reference the LUT is judged by.
pub fn exact_mask(alpha: f64, beta: f64, gamma: f64, pattern: &SamplePattern) -> u32 {
    let mut mask = 0;
    for (i, &[u, v]) in pattern.iter().enumerate() {
        let f = alpha + beta * (f64::from(u) - 0.5) + gamma * (f64::from(v) - 0.5);
        mask |= u32::from(f >= 0.0) << i;
    }
    mask
}

/// Exact classification in f32, the renderer's "exact" mode.
///
/// Evaluated as `(alpha + beta * (u - 0.5)) + gamma * (v - 0.5)`, left to
/// right, every operation rounded once and none fused. IEEE-754 (and Vulkan,
/// for +, − and ×) round these operations correctly, so a GLSL shader that
/// writes the same expression and declares the result `precise` (which
/// forbids contraction into FMA; README, Precision: lavapipe fuses otherwise) gets
/// the same bits for f, hence the same mask, even for samples exactly on an
/// edge. Rust never contracts floating-point expressions on its own.
pub fn exact_mask_f32(alpha: f32, beta: f32, gamma: f32, pattern: &SamplePattern) -> u32 {
    let mut mask = 0;
    for (i, &[u, v]) in pattern.iter().enumerate() {
        let f = alpha + beta * (u - 0.5) + gamma * (v - 0.5);
        mask |= u32::from(f >= 0.0) << i;
    }
    mask
}

/// Exact area of the part of the unit square with
/// d + cos θ·(u−½) + sin θ·(v−½) ≥ 0: the square clipped by the half-plane
/// (one Sutherland–Hodgman step), then the shoelace formula.
pub fn inside_area(theta: f64, distance: f64) -> f64 {
    let (sin, cos) = theta.sin_cos();
    let g = |p: [f64; 2]| distance + cos * p[0] + sin * p[1];
    let square = [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]];
    // A convex quadrilateral cut by one line keeps at most 5 vertices.
    let mut clipped = [[0.0; 2]; 5];
    let mut n = 0;
    for k in 0..4 {
        let (a, b) = (square[k], square[(k + 1) % 4]);
        let (ga, gb) = (g(a), g(b));
        if ga >= 0.0 {
            clipped[n] = a;
            n += 1;
        }
        if (ga >= 0.0) != (gb >= 0.0) {
            let t = ga / (ga - gb);
            clipped[n] = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
            n += 1;
        }
    }
    let twice_area: f64 = (0..n)
        .map(|k| {
            let (p, q) = (clipped[k], clipped[(k + 1) % n]);
            p[0] * q[1] - q[0] * p[1]
        })
        .sum();
    0.5 * twice_area.abs()
}

/// A random line that crosses the unit square: θ uniform in [−π, π), then
/// d uniform over the offsets at which the line meets the square,
/// |d| < (|cos θ| + |sin θ|)/2 (the square's support half-width along the
/// normal). The distribution of every measurement in this crate.
pub(crate) fn random_crossing_line(rng: &mut SplitMix64) -> (f64, f64) {
    let theta = -PI + 2.0 * PI * rng.next_f64();
    let half_width = 0.5 * (theta.cos().abs() + theta.sin().abs());
    let distance = half_width * (2.0 * rng.next_f64() - 1.0);
    (theta, distance)
}

#[cfg(test)]
mod tests {
    use super::*;

    const CORNERS_AND_CENTRE: SamplePattern = {
        let mut p = [[0.5f32, 0.5]; SAMPLES_PER_PIXEL];
        p[0] = [0.0, 0.0];
        p[1] = [0.75, 0.25];
        p
    };

    #[test]
    fn inside_area_matches_closed_forms() {
        // Axis-aligned: d + (u − ½) ≥ 0 keeps u ≥ ½ − d.
        for d in [-0.4, -0.1, 0.0, 0.3] {
            let area = inside_area(0.0, d);
            assert!((area - (0.5 + d)).abs() < 1e-12, "d={d}: area {area}");
        }
        // Diagonal through the centre halves the square; a corner cut at
        // distance t from the corner along the diagonal keeps t²·… = 2t²·½.
        let half = inside_area(PI / 4.0, 0.0);
        assert!((half - 0.5).abs() < 1e-12, "diagonal: {half}");
        let t = 0.1;
        let corner = inside_area(PI / 4.0, t - HALF_DIAGONAL);
        assert!(
            (corner - t * t).abs() < 1e-12,
            "corner: {corner} vs {}",
            t * t
        );
        assert_eq!(inside_area(1.0, 0.8), 1.0);
        assert_eq!(inside_area(1.0, -0.8), 0.0);
    }

    #[test]
    fn edge_line_saturates_and_normalises() {
        assert_eq!(edge_line(1.0, 0.0, 0.0), EdgeLine::Constant(ALL_SAMPLES));
        assert_eq!(edge_line(0.0, 0.0, 0.0), EdgeLine::Constant(ALL_SAMPLES));
        assert_eq!(edge_line(-1e-30, 0.0, 0.0), EdgeLine::Constant(0));
        assert_eq!(edge_line(f64::NAN, 1.0, 0.0), EdgeLine::Constant(0));
        assert_eq!(edge_line(1.0, f64::NAN, 0.0), EdgeLine::Constant(0));
        assert_eq!(edge_line(0.8, 1.0, 0.0), EdgeLine::Constant(ALL_SAMPLES));
        match edge_line(0.6, 0.0, 2.0) {
            EdgeLine::Line { theta, distance } => {
                assert!((theta - PI / 2.0).abs() < 1e-15, "theta {theta}");
                assert!((distance - 0.3).abs() < 1e-15, "distance {distance}");
            }
            other => panic!("expected a line, got {other:?}"),
        }
    }

    #[test]
    fn saturation_agrees_with_exact_masks() {
        // |d| ≥ √2/2 must give the same mask as testing every sample, even
        // with a sample on the corner (0, 0).
        let mut rng = SplitMix64::new(7);
        for _ in 0..10_000 {
            let theta = -PI + 2.0 * PI * rng.next_f64();
            let d = (HALF_DIAGONAL + 1e-9 + rng.next_f64())
                * if rng.next_f64() < 0.5 { -1.0 } else { 1.0 };
            let (beta, gamma) = (3.0 * theta.cos(), 3.0 * theta.sin());
            let alpha = 3.0 * d;
            let EdgeLine::Constant(mask) = edge_line(alpha, beta, gamma) else {
                panic!("d={d} did not saturate");
            };
            assert_eq!(
                mask,
                exact_mask(alpha, beta, gamma, &CORNERS_AND_CENTRE),
                "θ={theta} d={d}"
            );
        }
    }

    #[test]
    fn exact_masks_agree_between_forms() {
        let mut rng = SplitMix64::new(11);
        for _ in 0..10_000 {
            let (theta, d) = random_crossing_line(&mut rng);
            let scale = 0.37;
            let (alpha, beta, gamma) = (scale * d, scale * theta.cos(), scale * theta.sin());
            let by_line = line_mask(theta, d, &CORNERS_AND_CENTRE);
            let by_edge = exact_mask(alpha, beta, gamma, &CORNERS_AND_CENTRE);
            // They may differ only on a sample within rounding of the line.
            for (i, &sample) in CORNERS_AND_CENTRE.iter().enumerate() {
                if (by_line ^ by_edge) >> i & 1 == 1 {
                    let g = line_signed_distance(theta, d, sample);
                    assert!(g.abs() < 1e-12, "sample {i}: g={g}");
                }
            }
        }
    }
}
