//! The 32-sample pattern and the edge-visibility LUT as the renderer uses
//! them (Wyman et al. 2015, §4, paper-notes/frustum-test.md).
//!
//! `build.rs` runs [`izb_lut`] at compile time and this module embeds what
//! it wrote: [`edge_lut`] is the `DEFAULT_ANGLES × DEFAULT_DISTANCES` table
//! for [`sample_pattern`], and [`light_lut`] the same-size table for the
//! soft shadows' [`light_pattern`]. [`regenerate_tables`] (the `izb lut`
//! command) runs the same generator at any resolution, writes both tables
//! and a picture of each, and measures them against the exact classifier.
//! Why these patterns and this resolution: `paper-notes/edge-lut.md`,
//! `paper-notes/light-pattern.md`.

use std::sync::OnceLock;

// Regenerating the tables writes files (PNG pictures among them): not
// part of the pass alone (`--no-default-features`).
#[cfg(feature = "cli")]
mod regenerate;
#[cfg(feature = "cli")]
pub use regenerate::{
    lut_picture, regenerate, regenerate_tables, RegeneratedTables, REGENERATE_STATISTICS_LINES,
};

pub use izb_lut::{
    candidate_patterns, coverage_error, disk_coverage_error, disk_inside_area, edge_line,
    exact_mask, exact_mask_f32, inside_area, light_candidates, light_lut_statistics,
    lut_statistics, signed_distance, CoverageError, EdgeComparison, EdgeLine, EdgeLut, LutCell,
    LutDecodeError, LutStats, PatternCandidate, SamplePattern, ALL_SAMPLES, DEFAULT_ANGLES,
    DEFAULT_DISTANCES, HALF_DIAGONAL, LIGHT_DISK_RADIUS, LIGHT_PATTERN_NAME, LOOKUP_SLACK,
    LUT_HEADER_BYTES, LUT_MAGIC, MAX_RESOLUTION, SAMPLE_PATTERN_NAME,
};

/// The default table, as `build.rs` serialised it.
static EMBEDDED_EDGE_LUT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/edge_lut.bin"));

/// The pattern the embedded table was built for.
static EMBEDDED_SAMPLE_PATTERN: SamplePattern =
    include!(concat!(env!("OUT_DIR"), "/sample_pattern.rs"));

/// The light-sample table, as `build.rs` serialised it.
static EMBEDDED_LIGHT_LUT: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/light_lut.bin"));

/// The light pattern the embedded light table was built for.
static EMBEDDED_LIGHT_PATTERN: SamplePattern =
    include!(concat!(env!("OUT_DIR"), "/light_pattern.rs"));

/// The embedded light-sample LUT (soft shadows; decoded once): the same
/// generator as [`edge_lut`], for [`light_pattern`].
pub fn light_lut() -> &'static EdgeLut {
    static LUT: OnceLock<EdgeLut> = OnceLock::new();
    LUT.get_or_init(|| {
        EdgeLut::from_bytes(EMBEDDED_LIGHT_LUT)
            .unwrap_or_else(|e| panic!("build.rs wrote an invalid light LUT: {e}"))
    })
}

/// The 32 light samples (u, v) in the disk inscribed in [0, 1)², bit i =
/// sample i of a soft-shadow mask ([`crate::scene::LightDisk`]).
pub fn light_pattern() -> &'static SamplePattern {
    &EMBEDDED_LIGHT_PATTERN
}

/// The table and the 32 samples a mask is over: the light's
/// ([`light_lut`], [`light_pattern`]) for soft shadows, else the µQuad's.
pub fn tables_for(light_samples: bool) -> (&'static EdgeLut, &'static SamplePattern) {
    if light_samples {
        (light_lut(), light_pattern())
    } else {
        (edge_lut(), sample_pattern())
    }
}

/// The (light, µQuad) patterns of one half of the paired rays: half 0 is
/// ([`light_pattern`], [`sample_pattern`]), pair i joining sample i of
/// each; half 1 (`izb64-paired`'s samples 32–63) both turned
/// ([`izb_lut::pairs`]).
pub fn paired_patterns(half: usize) -> (&'static SamplePattern, &'static SamplePattern) {
    static SECOND: OnceLock<(SamplePattern, SamplePattern)> = OnceLock::new();
    if half == 0 {
        return (light_pattern(), sample_pattern());
    }
    let (light, pixel) = SECOND.get_or_init(|| {
        (
            izb_lut::second_half_light_pattern(light_pattern()),
            izb_lut::second_half_pixel_pattern(sample_pattern()),
        )
    });
    (light, pixel)
}

/// The embedded default edge LUT (decoded once).
pub fn edge_lut() -> &'static EdgeLut {
    static LUT: OnceLock<EdgeLut> = OnceLock::new();
    LUT.get_or_init(|| {
        EdgeLut::from_bytes(EMBEDDED_EDGE_LUT)
            .unwrap_or_else(|e| panic!("build.rs wrote an invalid edge LUT: {e}"))
    })
}

/// The renderer's 32 sample positions (u, v) ∈ [0, 1)², bit i = sample i:
/// the ones the embedded table was generated for.
pub fn sample_pattern() -> &'static SamplePattern {
    &EMBEDDED_SAMPLE_PATTERN
}
