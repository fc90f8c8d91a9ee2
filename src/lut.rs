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

use crate::output::{write_atomically, write_png};
use anyhow::{ensure, Result};
use std::path::Path;
use std::sync::OnceLock;

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

/// Random edges behind each table's statistics [`regenerate_tables`]
/// returns.
pub const REGENERATE_STATISTICS_LINES: usize = 1_000_000;

/// Shortest side, in pixels, of `edge_lut.png` and `light_lut.png`: small tables are scaled up
/// by a whole factor until their longer side reaches it.
const PICTURE_MIN_SIDE: u32 = 512;

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

/// Both tables [`regenerate_tables`] wrote, measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegeneratedTables {
    /// The pixel table ([`sample_pattern`]): [`lut_statistics`], random
    /// edges crossing the pixel, distances in pixels.
    pub edge: LutStats,
    /// The light table ([`light_pattern`]): [`light_lut_statistics`],
    /// random edges crossing the light disk, coverage against the disk's
    /// area, distances in light-disk diameters.
    pub light: LutStats,
}

/// Generates the `angles × distances` tables for [`sample_pattern`] and
/// [`light_pattern`] with the code `build.rs` uses, writes `edge_lut.bin`,
/// `light_lut.bin` ([`EdgeLut::to_bytes`]) and `edge_lut.png`,
/// `light_lut.png` ([`lut_picture`]) into `out_dir` (atomically), and
/// returns both tables' statistics over [`REGENERATE_STATISTICS_LINES`]
/// random edges each. A resolution outside 1..=[`MAX_RESOLUTION`] is
/// refused before anything is written.
pub fn regenerate_tables(angles: u32, distances: u32, out_dir: &Path) -> Result<RegeneratedTables> {
    let valid = 1..=MAX_RESOLUTION;
    ensure!(
        valid.contains(&angles) && valid.contains(&distances),
        "edge LUT resolution {angles}x{distances}: both must lie in 1..={MAX_RESOLUTION}"
    );
    let write_table = |name: &str, lut: &EdgeLut| -> Result<()> {
        let bytes = lut.to_bytes();
        write_atomically(&out_dir.join(format!("{name}.bin")), |tmp| {
            Ok(std::fs::write(tmp, &bytes)?)
        })?;
        write_png(&out_dir.join(format!("{name}.png")), &lut_picture(lut))
    };
    let edge = EdgeLut::generate(angles, distances, sample_pattern());
    write_table("edge_lut", &edge)?;
    let light = EdgeLut::generate(angles, distances, light_pattern());
    write_table("light_lut", &light)?;
    Ok(RegeneratedTables {
        edge: lut_statistics(&edge, sample_pattern(), REGENERATE_STATISTICS_LINES),
        light: light_lut_statistics(&light, light_pattern(), REGENERATE_STATISTICS_LINES),
    })
}

/// [`regenerate_tables`], returning the pixel table's statistics only:
/// writes the same four files. Kept for callers that predate the light
/// table (`examples/regenerate_lut.rs`).
pub fn regenerate(angles: u32, distances: u32, out_dir: &Path) -> Result<LutStats> {
    Ok(regenerate_tables(angles, distances, out_dir)?.edge)
}

/// A picture of the table: one block per cell, A rows (θ from −π at the
/// top to π at the bottom) × D columns (d from −√2/2 at the left to √2/2
/// at the right). Brightness is the fraction of samples inside, so each row
/// (one edge direction swept across the pixel) runs from black to white;
/// a faint tint, a hash of the mask, tells neighbouring distinct masks
/// apart, so the curves d = −(cos θ·x_i + sin θ·y_i) along which sample i
/// changes sides show as the borders between tinted regions. Scaled up by
/// a whole factor to at least `PICTURE_MIN_SIDE` pixels on the longer
/// side.
pub fn lut_picture(lut: &EdgeLut) -> image::RgbImage {
    const TINT: f64 = 0.3;
    let scale = PICTURE_MIN_SIDE
        .div_ceil(lut.angles.max(lut.distances))
        .max(1);
    image::RgbImage::from_fn(lut.distances * scale, lut.angles * scale, |x, y| {
        let mask = lut.masks[((y / scale) * lut.distances + x / scale) as usize];
        let coverage = f64::from(mask.count_ones()) / f64::from(u32::BITS);
        // Fibonacci hashing spreads masks that differ in one bit apart.
        let hash = mask.wrapping_mul(0x9E37_79B9).to_le_bytes();
        image::Rgb(std::array::from_fn(|c| {
            let tint = f64::from(hash[c + 1]) / 255.0;
            (((1.0 - TINT) * coverage + TINT * tint) * 255.0).round() as u8
        }))
    })
}
