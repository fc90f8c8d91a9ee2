//! `izb-lut`: the 32-sample sub-pixel pattern, the normalised edge-line
//! parameterisation and the edge-visibility lookup table of `izb`
//! (Wyman et al. 2015, §4, paper-notes/frustum-test.md). Pure Rust, no I/O, no dependencies: `build.rs`
//! of the `izb` crate, the `izb lut` command and the tests all call this
//! same code.
//!
//! - [`pattern`]: candidate 32-point patterns, their coverage error on
//!   straight edges, and the chosen [`sample_pattern`].
//! - [`edge`]: f(u,v) = α + β(u−½) + γ(v−½) ≥ 0 per sample, exactly
//!   ([`exact_mask`], [`exact_mask_f32`]), and its normalised form
//!   (θ, d) ([`edge_line`]).
//! - [`table`]: the (θ, d) table [`EdgeLut`], its lookup, its proven
//!   misclassification bound and [`lut_statistics`].
//! - [`light`]: the 32 light samples of soft shadows on the light's disk,
//!   their coverage error on lines across the disk
//!   ([`disk_coverage_error`]), the chosen [`light_pattern`] and
//!   [`light_lut_statistics`] for its table.
//! - [`pairs`]: the second half of the 64 paired rays (pixel and light
//!   patterns turned).

pub mod edge;
pub mod light;
pub mod pairs;
pub mod pattern;
mod rng;
pub mod table;

pub use edge::{
    edge_line, exact_mask, exact_mask_f32, inside_area, line_mask, line_signed_distance,
    signed_distance, EdgeLine, ALL_SAMPLES, HALF_DIAGONAL,
};
pub use light::{
    concentric_map, disk_coverage_error, disk_coverage_error_of, disk_inside_area, light_candidate,
    light_candidates, light_lut_statistics, light_pattern, line_optimised, relaxed_disk,
    vogel_spiral, LIGHT_CANDIDATE_NAMES, LIGHT_DISK_RADIUS, LIGHT_EVALUATION_LINES,
    LIGHT_PATTERN_NAME, OPTIMISED_LLOYD_32,
};
pub use pairs::{second_half_light_pattern, second_half_pixel_pattern, SECOND_LIGHT_TURN_DEG};
pub use pattern::{
    candidate_patterns, coverage_error, sample_pattern, CoverageError, PatternCandidate,
    SamplePattern, PATTERN_EVALUATION_LINES, SAMPLE_PATTERN_NAME,
};
pub use table::{
    lut_statistics, EdgeComparison, EdgeLut, LutCell, LutDecodeError, LutStats, DEFAULT_ANGLES,
    DEFAULT_DISTANCES, LOOKUP_SLACK, LUT_HEADER_BYTES, LUT_MAGIC, MAX_RESOLUTION,
};

/// Number of visibility samples per pixel: one bit each in a `u32` mask.
pub const SAMPLES_PER_PIXEL: usize = 32;
