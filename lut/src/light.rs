//! The 32 light samples of soft shadows and the measurement that chose
//! them: points on the light's disk, in the same (u, v) ∈ [0, 1)² frame as
//! the pixel pattern, inside the disk of radius ½ centred at (½, ½) (the
//! frame [`crate::edge`]'s edge functions use, so the same table generator
//! serves both).
//!
//! A soft-shadow mask is the set of light samples a receiver point cannot
//! see; each occluder edge, projected from the receiver onto the light's
//! disk, is a straight line across it, so what matters is again how well
//! the fraction of samples on one side of a line matches the *disk's*
//! area on that side. Each candidate of [`light_candidates`] is scored by
//! exactly that ([`disk_coverage_error`]) and [`light_pattern`] returns the
//! best by RMS; a unit test re-runs the measurement and fails if the
//! choice is stale (numbers: `paper-notes/light-pattern.md`).

use crate::pattern::{CoverageError, PatternCandidate};
use crate::rng::SplitMix64;
use crate::table::{EdgeLut, LutStats};
use crate::{SamplePattern, SAMPLES_PER_PIXEL};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

mod constructions;

pub use constructions::{
    concentric_map, line_optimised, relaxed_disk, vogel_spiral, OPTIMISED_LLOYD_32,
};
use constructions::{concentric_of_pixel_candidate, random_disk_points, RELAX_SEED};

/// Name of the light pattern the renderer uses: the lowest RMS
/// [`disk_coverage_error`] of [`light_candidates`] over
/// [`LIGHT_EVALUATION_LINES`] random lines.
pub const LIGHT_PATTERN_NAME: &str = "optimised_lloyd";

/// The disk's radius in (u, v): the disk inscribed in the unit square.
pub const LIGHT_DISK_RADIUS: f64 = 0.5;

/// Random lines used to rank the light candidates (about a second for all
/// of them in release).
pub const LIGHT_EVALUATION_LINES: usize = 1_000_000;

/// Seed of the random lines of [`disk_coverage_error`]: not the pixel
/// measurement's seed, so that the two rankings do not share their noise.
const DISK_COVERAGE_SEED: u64 = 0x5EED_D15C_0002_0004;

/// Seed of the random edges of [`light_lut_statistics`].
const LIGHT_STATISTICS_SEED: u64 = 0x0E06_D15C_0002_0004;

/// Every light candidate's name, in a fixed order.
pub const LIGHT_CANDIDATE_NAMES: [&str; 12] = [
    "vogel_spiral",
    "vogel_spiral_rot_90",
    "vogel_spiral_rot_60",
    "vogel_spiral_rot_17",
    "concentric_lattice_g9",
    "concentric_sobol_0_2_centred",
    "concentric_halton_2_3",
    "concentric_multijitter_8x4",
    "lloyd_vogel",
    "lloyd_random",
    "optimised_vogel",
    "optimised_lloyd",
];

/// The light pattern the renderer uses: the candidate named
/// [`LIGHT_PATTERN_NAME`]. Builds that candidate only (`build.rs` calls
/// this unoptimised).
pub fn light_pattern() -> SamplePattern {
    light_candidate(LIGHT_PATTERN_NAME)
        .expect("LIGHT_PATTERN_NAME names a light candidate")
        .points
}

/// Every light candidate, in the order of [`LIGHT_CANDIDATE_NAMES`].
pub fn light_candidates() -> Vec<PatternCandidate> {
    LIGHT_CANDIDATE_NAMES
        .iter()
        .map(|name| light_candidate(name).expect("every listed name builds"))
        .collect()
}

/// One light candidate by name (`None` for an unknown name).
pub fn light_candidate(name: &str) -> Option<PatternCandidate> {
    let n = SAMPLES_PER_PIXEL;
    let (name, construction, points): (&'static str, &'static str, Vec<[f32; 2]>) = match name {
        "vogel_spiral" => (
            "vogel_spiral",
            "Vogel 1979 golden-angle spiral: sample i at radius ½·√((i+½)/32), angle i·π(3−√5)",
            vogel_spiral(n, 0.0),
        ),
        // Uniform line angles make every rotation of a set score the same
        // in expectation: these three measure the Monte Carlo noise.
        "vogel_spiral_rot_90" => (
            "vogel_spiral_rot_90",
            "vogel_spiral rotated by 90° about the centre (a noise gauge)",
            vogel_spiral(n, FRAC_PI_2),
        ),
        "vogel_spiral_rot_60" => (
            "vogel_spiral_rot_60",
            "vogel_spiral rotated by 60° (a noise gauge)",
            vogel_spiral(n, PI / 3.0),
        ),
        "vogel_spiral_rot_17" => (
            "vogel_spiral_rot_17",
            "vogel_spiral rotated by 17° (a noise gauge)",
            vogel_spiral(n, 17f64.to_radians()),
        ),
        "concentric_lattice_g9" => (
            "concentric_lattice_g9",
            "Shirley–Chiu 1997 concentric map of the pixel pattern lattice_g9",
            concentric_of_pixel_candidate("lattice_g9"),
        ),
        "concentric_sobol_0_2_centred" => (
            "concentric_sobol_0_2_centred",
            "concentric map of sobol_0_2_centred (a (0,5,2)-net)",
            concentric_of_pixel_candidate("sobol_0_2_centred"),
        ),
        "concentric_halton_2_3" => (
            "concentric_halton_2_3",
            "concentric map of halton_2_3 (the paper's pixel points)",
            concentric_of_pixel_candidate("halton_2_3"),
        ),
        "concentric_multijitter_8x4" => (
            "concentric_multijitter_8x4",
            "concentric map of multijitter_8x4 (fixed seed)",
            concentric_of_pixel_candidate("multijitter_8x4"),
        ),
        "lloyd_vogel" => (
            "lloyd_vogel",
            "vogel_spiral relaxed by 64 Lloyd steps toward a centroidal Voronoi set of the disk",
            relaxed_disk(vogel_spiral(n, 0.0)),
        ),
        "lloyd_random" => (
            "lloyd_random",
            "32 uniform random points of the disk (SplitMix64, fixed seed), 64 Lloyd steps",
            relaxed_disk(random_disk_points(n, RELAX_SEED)),
        ),
        "optimised_vogel" => (
            "optimised_vogel",
            "vogel_spiral moved by 400 gradient steps on the mean squared disk coverage error itself (512 angles, d integrated exactly)",
            line_optimised(vogel_spiral(n, 0.0)),
        ),
        "optimised_lloyd" => (
            "optimised_lloyd",
            "lloyd_vogel, then the same 400 gradient steps (baked: OPTIMISED_LLOYD_32)",
            OPTIMISED_LLOYD_32.to_vec(),
        ),
        _ => return None,
    };
    Some(PatternCandidate {
        name,
        construction,
        points: points.try_into().expect("32 points per light candidate"),
    })
}

/// Fraction of the light disk's area with d + cos θ·(u−½) + sin θ·(v−½)
/// ≥ 0, in closed form: with t = d/R clamped to [−1, 1], the circular
/// segment gives ½ + (t·√(1 − t²) + asin t)/π. Independent of θ (the disk
/// is round).
pub fn disk_inside_area(distance: f64) -> f64 {
    let t = (distance / LIGHT_DISK_RADIUS).clamp(-1.0, 1.0);
    0.5 + (t * (1.0 - t * t).sqrt() + t.asin()) / PI
}

/// A random line that crosses the light disk: θ uniform in [−π, π), d
/// uniform in (−R, R) (every offset at which the line meets the disk).
fn random_disk_crossing_line(rng: &mut SplitMix64) -> (f64, f64) {
    let theta = -PI + TAU * rng.next_f64();
    let distance = LIGHT_DISK_RADIUS * (2.0 * rng.next_f64() - 1.0);
    (theta, distance)
}

/// [`disk_coverage_error_of`] for a 32-sample pattern.
pub fn disk_coverage_error(pattern: &SamplePattern, lines: usize) -> CoverageError {
    disk_coverage_error_of(pattern, lines)
}

/// Measures how well `points` (any number) estimate the covered area of
/// the light disk: for `lines` random lines crossing the disk (uniform
/// angle, uniform offset over the offsets that cross it), compares the
/// fraction of points on the inside with the fraction of the disk's area
/// there ([`disk_inside_area`]). Deterministic: the same lines for every
/// pattern. The fields mean what they mean for the pixel's
/// [`crate::coverage_error`], with the disk for the square.
pub fn disk_coverage_error_of(points: &[[f32; 2]], lines: usize) -> CoverageError {
    let centred: Vec<[f64; 2]> = points
        .iter()
        .map(|p| [f64::from(p[0]) - 0.5, f64::from(p[1]) - 0.5])
        .collect();
    crate::pattern::coverage_error_over(
        lines,
        DISK_COVERAGE_SEED,
        random_disk_crossing_line,
        |theta, distance| {
            let (sin, cos) = theta.sin_cos();
            let inside = centred
                .iter()
                .filter(|p| distance + cos * p[0] + sin * p[1] >= 0.0)
                .count();
            inside as f64 / points.len().max(1) as f64
        },
        |_, distance| disk_inside_area(distance),
    )
}

/// [`crate::lut_statistics`] for a light table: the same measurement of
/// `lut` against [`crate::exact_mask`], but on `lines` random edges crossing the
/// light *disk* (a subset of those crossing the square: the others cannot
/// split the samples) and with coverage judged against the disk's area
/// ([`disk_inside_area`]). Every edge gets a random scale |(β, γ)|
/// log-uniform in [10⁻³, 10³] and is rounded to f32 before both
/// classifiers see it. Distances are in (u, v) units, i.e. light-disk
/// diameters. Deterministic.
pub fn light_lut_statistics(lut: &EdgeLut, pattern: &SamplePattern, lines: usize) -> LutStats {
    crate::table::lut_statistics_over(
        lut,
        pattern,
        lines,
        LIGHT_STATISTICS_SEED,
        random_disk_crossing_line,
        |_, distance| disk_inside_area(distance),
    )
}

#[cfg(test)]
mod tests;
