//! The 32 sub-pixel sample positions and the measurement that chose them.
//!
//! Wyman et al. 2015, §4 leaves the sample locations to the developer ("visibility
//! sample locations are developer specified during LUT construction") and
//! the paper used a Halton set. What matters for analytic shadow edges is
//! how well the fraction of samples on one side of a straight edge matches
//! the area on that side, so each candidate below is scored by exactly that
//! ([`coverage_error`]) and [`sample_pattern`] returns the best by RMS; a
//! unit test re-runs the measurement and fails if the choice is stale.

use crate::edge::{inside_area, line_mask, random_crossing_line};
use crate::rng::SplitMix64;
use crate::SAMPLES_PER_PIXEL;
use std::f64::consts::PI;

/// 32 sample positions (u, v) ∈ [0, 1)², (0, 0) the µQuad's top-left
/// corner, v downward (README, Conventions). Sample i is bit i of an occlusion mask.
pub type SamplePattern = [[f32; 2]; SAMPLES_PER_PIXEL];

/// Name of the candidate [`sample_pattern`] returns: the lowest RMS
/// coverage error of [`candidate_patterns`] over [`PATTERN_EVALUATION_LINES`]
/// random edges (see `paper-notes/edge-lut.md` for the numbers).
pub const SAMPLE_PATTERN_NAME: &str = "lattice_g9";

/// Random edges used to rank the candidates.
pub const PATTERN_EVALUATION_LINES: usize = 1_000_000;

/// Seed of the random edges of [`coverage_error`].
const COVERAGE_SEED: u64 = 0x5EED_C0DE_0002_0004;

/// Seed of the randomised candidates (fixed: the pattern is a constant of
/// the renderer, baked into the LUT by `build.rs`).
const JITTER_SEED: u64 = 0x1AB5_0F20_1500_0032;

/// One candidate pattern.
#[derive(Clone, Debug)]
pub struct PatternCandidate {
    /// Short identifier, as in [`SAMPLE_PATTERN_NAME`].
    pub name: &'static str,
    /// How the points are built, in words.
    pub construction: &'static str,
    pub points: SamplePattern,
}

/// The pattern the renderer uses: the candidate named
/// [`SAMPLE_PATTERN_NAME`].
pub fn sample_pattern() -> SamplePattern {
    candidate_patterns()
        .into_iter()
        .find(|c| c.name == SAMPLE_PATTERN_NAME)
        .expect("SAMPLE_PATTERN_NAME names a candidate")
        .points
}

/// Every candidate, in a fixed order.
pub fn candidate_patterns() -> Vec<PatternCandidate> {
    let mut rng = SplitMix64::new(JITTER_SEED);
    vec![
        PatternCandidate {
            name: "halton_2_3",
            construction: "Halton, bases 2 and 3, indices 1..=32 (index 0 would put a sample on the corner)",
            points: from_fn(|i| [radical_inverse(i as u32 + 1, 2), radical_inverse(i as u32 + 1, 3)]),
        },
        PatternCandidate {
            name: "sobol_0_2",
            construction: "Sobol' dimensions 1-2 (van der Corput base 2, then Sobol's second dimension), indices 0..32: a (0,5,2)-net, every 1/32-area elementary box holds one point; points on the 1/32 grid, (0,0) included",
            points: from_fn(|i| [radical_inverse(i as u32, 2), sobol_second_dimension(i as u32)]),
        },
        PatternCandidate {
            name: "sobol_0_2_centred",
            construction: "sobol_0_2 shifted by (1/64, 1/64): each point moves to the centre of its 1/32 x 1/32 grid cell, still a (0,5,2)-net, no longer biased toward the top-left corner",
            points: from_fn(|i| {
                let half_cell = 1.0 / 64.0;
                [
                    radical_inverse(i as u32, 2) + half_cell,
                    sobol_second_dimension(i as u32) + half_cell,
                ]
            }),
        },
        lattice("lattice_g7", 7, "rank-1 lattice ((i+1/2)/32, frac((7i+1/2)/32)), a grid rotated and wrapped onto the torus"),
        lattice("lattice_g9", 9, "rank-1 lattice ((i+1/2)/32, frac((9i+1/2)/32)), a grid rotated and wrapped onto the torus"),
        lattice("lattice_g13", 13, "rank-1 lattice ((i+1/2)/32, frac((13i+1/2)/32)), a grid rotated and wrapped onto the torus"),
        PatternCandidate {
            name: "regular_8x4",
            construction: "8 x 4 grid of cell centres (baseline: the worst case for axis-aligned edges)",
            points: from_fn(|i| [((i % 8) as f64 + 0.5) / 8.0, ((i / 8) as f64 + 0.5) / 4.0]),
        },
        PatternCandidate {
            name: "jittered_8x4",
            construction: "one uniform random point per cell of an 8 x 4 grid (SplitMix64, fixed seed)",
            points: {
                let jitter: Vec<[f64; 2]> = (0..SAMPLES_PER_PIXEL).map(|_| [rng.next_f64(), rng.next_f64()]).collect();
                from_fn(|i| [((i % 8) as f64 + jitter[i][0]) / 8.0, ((i / 8) as f64 + jitter[i][1]) / 4.0])
            },
        },
        PatternCandidate {
            name: "multijitter_8x4",
            construction: "multi-jittered (Chiu, Shirley and Wang 1994): jittered on the 8 x 4 grid and N-rooks on 32 columns and 32 rows, shuffles from SplitMix64 with a fixed seed",
            points: multi_jittered(8, 4, &mut rng),
        },
    ]
}

/// Coverage error of a pattern over random straight edges.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoverageError {
    /// Number of random edges.
    pub lines: usize,
    /// RMS over the edges of (samples inside / 32 − area inside).
    pub rms: f64,
    /// Largest |samples inside / 32 − area inside| met.
    pub max: f64,
    /// Mean |samples inside / 32 − area inside|.
    pub mean_abs: f64,
    /// RMS within the worst of [`ORIENTATION_BINS`] equal bins of edge
    /// orientation (θ mod π): a pattern with a good average can still fail
    /// for one family of edges, which then shows as banding along every
    /// shadow edge of that orientation.
    pub worst_orientation_rms: f64,
}

/// Orientation bins of [`CoverageError::worst_orientation_rms`] (over θ mod
/// π, 64 bins of 2.8°).
pub const ORIENTATION_BINS: usize = 64;

/// Measures how well `pattern` estimates the covered area of straight
/// edges: for `lines` random lines crossing the unit square (uniform angle,
/// uniform offset over the offsets that cross it), compares the fraction of
/// samples on the inside with the exact inside area ([`inside_area`]).
/// Deterministic: the same lines for every pattern.
pub fn coverage_error(pattern: &SamplePattern, lines: usize) -> CoverageError {
    coverage_error_over(
        lines,
        COVERAGE_SEED,
        random_crossing_line,
        |theta, distance| {
            f64::from(line_mask(theta, distance, pattern).count_ones()) / SAMPLES_PER_PIXEL as f64
        },
        inside_area,
    )
}

/// [`coverage_error`] over a family of lines: `random_line` draws (θ, d)
/// from the seeded generator, `estimate(θ, d)` is the share of samples
/// inside and `area(θ, d)` the share of the domain (the pixel's square,
/// or the light's disk: `crate::light::disk_coverage_error_of`).
pub(crate) fn coverage_error_over(
    lines: usize,
    seed: u64,
    mut random_line: impl FnMut(&mut SplitMix64) -> (f64, f64),
    estimate: impl Fn(f64, f64) -> f64,
    area: impl Fn(f64, f64) -> f64,
) -> CoverageError {
    let mut rng = SplitMix64::new(seed);
    let (mut sum_sq, mut sum_abs, mut max) = (0.0f64, 0.0f64, 0.0f64);
    let mut bins = [(0.0f64, 0usize); ORIENTATION_BINS];
    for _ in 0..lines {
        let (theta, distance) = random_line(&mut rng);
        let error = (estimate(theta, distance) - area(theta, distance)).abs();
        sum_sq += error * error;
        sum_abs += error;
        max = max.max(error);
        let bin = ((theta.rem_euclid(PI) / PI * ORIENTATION_BINS as f64) as usize)
            .min(ORIENTATION_BINS - 1);
        bins[bin].0 += error * error;
        bins[bin].1 += 1;
    }
    let n = lines.max(1) as f64;
    CoverageError {
        lines,
        rms: (sum_sq / n).sqrt(),
        max,
        mean_abs: sum_abs / n,
        worst_orientation_rms: bins
            .iter()
            .filter(|b| b.1 > 0)
            .map(|b| (b.0 / b.1 as f64).sqrt())
            .fold(0.0, f64::max),
    }
}

/// Builds a pattern from f64 positions, rounding each to the nearest f32
/// but never up to 1.0 (the square is half-open).
fn from_fn(point: impl Fn(usize) -> [f64; 2]) -> SamplePattern {
    const BELOW_ONE: f32 = 1.0 - f32::EPSILON / 2.0;
    std::array::from_fn(|i| point(i).map(|c| (c as f32).min(BELOW_ONE)))
}

/// Radical inverse of `index` in `base`: its digits mirrored about the
/// radix point (van der Corput for base 2, Halton per dimension).
fn radical_inverse(mut index: u32, base: u32) -> f64 {
    let (mut numerator, mut denominator) = (0u64, 1u64);
    while index > 0 {
        numerator = numerator * u64::from(base) + u64::from(index % base);
        denominator *= u64::from(base);
        index /= base;
    }
    numerator as f64 / denominator as f64
}

/// Second dimension of the Sobol' sequence (primitive polynomial x + 1,
/// direction numbers m_k = 1, 3, 5, 15, 17, …): XOR of the direction
/// numbers of the set bits of `index`. Kollig and Keller's compact form:
/// the direction number of bit k+1 is v ⊕ (v >> 1) of bit k's.
fn sobol_second_dimension(mut index: u32) -> f64 {
    let (mut bits, mut direction) = (0u32, 1u32 << 31);
    while index != 0 {
        if index & 1 == 1 {
            bits ^= direction;
        }
        index >>= 1;
        direction ^= direction >> 1;
    }
    f64::from(bits) / 4_294_967_296.0
}

/// Rank-1 lattice with generator (1, g): x_i = (i+½)/32,
/// y_i = ((g·i mod 32) + ½)/32. For odd g both coordinates are
/// permutations of the 32 cell centres (N-rooks), and the points form a
/// sheared, i.e. rotated and wrapped, grid.
fn lattice(name: &'static str, generator: usize, construction: &'static str) -> PatternCandidate {
    PatternCandidate {
        name,
        construction,
        points: from_fn(|i| {
            let n = SAMPLES_PER_PIXEL;
            [
                (i as f64 + 0.5) / n as f64,
                ((generator * i % n) as f64 + 0.5) / n as f64,
            ]
        }),
    }
}

/// Multi-jittered sampling on a `columns` × `rows` grid: canonical
/// arrangement, then the x coordinates shuffled among the points of each
/// column and the y coordinates among the points of each row, which keeps
/// both the coarse grid stratification and the N-rooks property.
fn multi_jittered(columns: usize, rows: usize, rng: &mut SplitMix64) -> SamplePattern {
    let n = columns * rows;
    let mut points = vec![[0.0f64; 2]; n];
    for j in 0..rows {
        for i in 0..columns {
            points[j * columns + i] = [
                (i as f64 + (j as f64 + rng.next_f64()) / rows as f64) / columns as f64,
                (j as f64 + (i as f64 + rng.next_f64()) / columns as f64) / rows as f64,
            ];
        }
    }
    for i in 0..columns {
        for j in 0..rows {
            let k = j + rng.below(rows - j);
            let (a, b) = (points[j * columns + i][0], points[k * columns + i][0]);
            points[j * columns + i][0] = b;
            points[k * columns + i][0] = a;
        }
    }
    for j in 0..rows {
        for i in 0..columns {
            let k = i + rng.below(columns - i);
            let (a, b) = (points[j * columns + i][1], points[j * columns + k][1]);
            points[j * columns + i][1] = b;
            points[j * columns + k][1] = a;
        }
    }
    from_fn(|i| points[i])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candidates_lie_in_the_half_open_square_and_are_distinct() {
        for c in candidate_patterns() {
            for (i, p) in c.points.iter().enumerate() {
                assert!(
                    p.iter().all(|&x| (0.0..1.0).contains(&x)),
                    "{} sample {i} = {p:?}",
                    c.name
                );
                for q in &c.points[..i] {
                    assert_ne!(p, q, "{}: repeated sample", c.name);
                }
            }
        }
    }

    #[test]
    fn nets_and_rooks_are_stratified() {
        let candidates = candidate_patterns();
        let get = |name: &str| candidates.iter().find(|c| c.name == name).unwrap().points;
        // (0,5,2)-net: every elementary box 2^-a × 2^-(5-a) holds one point.
        for name in ["sobol_0_2", "sobol_0_2_centred"] {
            let p = get(name);
            for a in 0..=5 {
                let (nx, ny) = (1usize << a, 1usize << (5 - a));
                let mut count = vec![0; 32];
                for [u, v] in p {
                    count[(u * nx as f32) as usize * ny + (v * ny as f32) as usize] += 1;
                }
                assert!(
                    count.iter().all(|&c| c == 1),
                    "{name}: boxes {nx}x{ny}: {count:?}"
                );
            }
        }
        for name in ["multijitter_8x4", "lattice_g7", "lattice_g9", "lattice_g13"] {
            let p = get(name);
            for axis in 0..2 {
                let mut seen = [false; 32];
                for q in p {
                    seen[(q[axis] * 32.0) as usize] = true;
                }
                assert!(seen.iter().all(|&s| s), "{name}: axis {axis} not N-rooks");
            }
        }
        let sobol = get("sobol_0_2");
        assert_eq!(sobol[1], [0.5, 0.5]);
        assert_eq!(sobol[2], [0.25, 0.75]);
        assert_eq!(sobol[3], [0.75, 0.25]);
        let halton = get("halton_2_3");
        assert_eq!(halton[0], [0.5, 1.0 / 3.0]);
    }

    /// The chosen pattern is the measured best, not a hard-coded opinion.
    #[test]
    fn chosen_pattern_has_the_lowest_rms_coverage_error() {
        let mut scores: Vec<(&str, CoverageError)> = candidate_patterns()
            .iter()
            .map(|c| (c.name, coverage_error(&c.points, PATTERN_EVALUATION_LINES)))
            .collect();
        scores.sort_by(|a, b| a.1.rms.total_cmp(&b.1.rms));
        for (name, e) in &scores {
            eprintln!(
                "{name:>20}: rms {:.5} max {:.5} mean {:.5} worst orientation rms {:.5}",
                e.rms, e.max, e.mean_abs, e.worst_orientation_rms
            );
        }
        assert_eq!(
            scores[0].0, SAMPLE_PATTERN_NAME,
            "best by RMS is {} ({:.5}), SAMPLE_PATTERN_NAME is {}",
            scores[0].0, scores[0].1.rms, SAMPLE_PATTERN_NAME
        );
        assert_eq!(
            sample_pattern(),
            candidate_patterns()
                .into_iter()
                .find(|c| c.name == SAMPLE_PATTERN_NAME)
                .unwrap()
                .points
        );
    }
}
