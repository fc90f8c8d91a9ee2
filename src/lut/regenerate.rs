//! `izb lut`: the tables regenerated at any resolution, written with a
//! picture of each and measured against the exact classifier.

use super::{
    light_lut_statistics, light_pattern, lut_statistics, sample_pattern, EdgeLut, LutStats,
    MAX_RESOLUTION,
};
use crate::output::{write_atomically, write_png};
use anyhow::{ensure, Result};
use std::path::Path;

/// Random edges behind each table's statistics [`regenerate_tables`]
/// returns.
pub const REGENERATE_STATISTICS_LINES: usize = 1_000_000;

/// Shortest side, in pixels, of `edge_lut.png` and `light_lut.png`: small tables are scaled up
/// by a whole factor until their longer side reaches it.
const PICTURE_MIN_SIDE: u32 = 512;

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
