//! Reproduces the measurements of `paper-notes/edge-lut.md`: the coverage
//! error of every candidate sample pattern, and the accuracy of edge LUTs of
//! several resolutions against the exact classifier.
//!
//! `cargo run --release -p izb-lut --example lut_compare [LINES]`

use izb_lut::{
    candidate_patterns, coverage_error, lut_statistics, sample_pattern, EdgeLut, DEFAULT_ANGLES,
    DEFAULT_DISTANCES, PATTERN_EVALUATION_LINES, SAMPLE_PATTERN_NAME,
};
use std::time::Instant;

/// Resolutions compared (angles, distances).
const RESOLUTIONS: [(u32, u32); 12] = [
    (32, 32),
    (64, 32),
    (64, 64),
    (128, 32),
    (128, 64),
    (128, 128),
    (256, 64),
    (256, 128),
    (256, 256),
    (512, 256),
    (512, 512),
    (1024, 1024),
];

fn main() {
    let lines: usize = std::env::args()
        .nth(1)
        .map_or(1_000_000, |a| a.parse().expect("LINES is a number"));

    println!("## Sample patterns ({PATTERN_EVALUATION_LINES} random edges)\n");
    println!("| pattern | RMS coverage error | max | mean abs | RMS, worst orientation |");
    println!("|---|---|---|---|---|");
    let mut scores: Vec<_> = candidate_patterns()
        .into_iter()
        .map(|c| (coverage_error(&c.points, PATTERN_EVALUATION_LINES), c))
        .collect();
    scores.sort_by(|a, b| a.0.rms.total_cmp(&b.0.rms));
    for (e, c) in &scores {
        let chosen = if c.name == SAMPLE_PATTERN_NAME {
            " (chosen)"
        } else {
            ""
        };
        println!(
            "| `{}`{chosen} | {:.5} | {:.5} | {:.5} | {:.5} |",
            c.name, e.rms, e.max, e.mean_abs, e.worst_orientation_rms
        );
    }

    let pattern = sample_pattern();
    println!("\n## Resolutions ({lines} random edges, pattern `{SAMPLE_PATTERN_NAME}`)\n");
    println!("| A x D | bytes | mismatch rate | edges with a mismatch | coverage RMS, LUT vs exact | coverage RMS vs area (exact: {:.5}) | worst distance | max bound | worst / bound | beyond bound | generate + measure |", izb_lut::coverage_error(&pattern, PATTERN_EVALUATION_LINES).rms);
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for (angles, distances) in RESOLUTIONS {
        let start = Instant::now();
        let lut = EdgeLut::generate(angles, distances, &pattern);
        let s = lut_statistics(&lut, &pattern, lines);
        let default = if (angles, distances) == (DEFAULT_ANGLES, DEFAULT_DISTANCES) {
            " (default)"
        } else {
            ""
        };
        println!(
            "| {angles} x {distances}{default} | {} | {:.3e} | {:.4} | {:.3e} | {:.5} ({:+.1} %) | {:.4} | {:.4} | {:.3} | {} | {:.2} s |",
            s.table_bytes,
            s.mismatch_rate,
            s.lines_with_mismatch,
            s.coverage_rms_error,
            s.lut_coverage_rms,
            100.0 * (s.lut_coverage_rms / s.exact_coverage_rms - 1.0),
            s.worst_misclassified_distance,
            s.max_bound,
            s.worst_bound_ratio,
            s.bound_violations,
            start.elapsed().as_secs_f64()
        );
    }
}
