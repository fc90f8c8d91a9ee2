//! Tests of the edge LUT: the misclassification bound, lookups, the
//! byte format.

use super::*;
use crate::{exact_mask_f32, sample_pattern};

/// The proof, checked: on 10⁶ random edges per resolution (the default,
/// the paper's 32 × 32, an asymmetric and an odd one), every sample the
/// LUT gets wrong lies within the bound of the exact edge line.
#[test]
fn every_misclassified_sample_lies_within_the_proven_bound() {
    let pattern = sample_pattern();
    for (angles, distances) in [
        (DEFAULT_ANGLES, DEFAULT_DISTANCES),
        (32, 32),
        (256, 64),
        (7, 5),
    ] {
        let lut = EdgeLut::generate(angles, distances, &pattern);
        let stats = lut_statistics(&lut, &pattern, 1_000_000);
        eprintln!(
            "{stats}\n  worst excess over the bound: {:.3e}",
            stats.worst_bound_excess
        );
        assert_eq!(stats.bound_violations, 0, "{angles}x{distances}: {stats}");
        assert!(
            stats.worst_bound_excess <= LOOKUP_SLACK,
            "{angles}x{distances}: excess {:.3e} > slack {LOOKUP_SLACK:.1e}",
            stats.worst_bound_excess
        );
        assert!(
            stats.mismatch_rate > 0.0,
            "{angles}x{distances}: the test must meet mismatches to mean anything"
        );
    }
}

/// Edges placed right on cell boundaries, where f32 rounding may pick
/// either neighbour: the bound still holds within [`LOOKUP_SLACK`].
#[test]
fn edges_on_cell_boundaries_stay_within_the_bound() {
    let pattern = sample_pattern();
    let lut = EdgeLut::generate(DEFAULT_ANGLES, DEFAULT_DISTANCES, &pattern);
    let mut worst_excess = f64::NEG_INFINITY;
    for angle in 0..=lut.angles {
        for distance in 0..=lut.distances {
            let theta_boundary = -PI + f64::from(angle) * lut.angle_step();
            let d_boundary = -HALF_DIAGONAL + f64::from(distance) * lut.distance_step();
            for (dt, dd) in [
                (-1e-7, -1e-7),
                (-1e-7, 1e-7),
                (1e-7, -1e-7),
                (1e-7, 1e-7),
                (0.0, 0.0),
            ] {
                let (theta, d) = (theta_boundary + dt, d_boundary + dd);
                let c = lut.compare_with_exact(d, theta.cos(), theta.sin(), &pattern);
                worst_excess = worst_excess.max(c.worst_excess);
                assert!(
                    c.within_bound(),
                    "θ={theta} d={d}: excess {:.3e} > {LOOKUP_SLACK:.1e}",
                    c.worst_excess
                );
            }
        }
    }
    eprintln!(
        "edges on cell boundaries: worst excess over the exact-arithmetic bound {worst_excess:.3e}"
    );
}

/// Finer tables are better: the measurement behind the default is at
/// least monotone on the diagonal.
#[test]
fn mismatch_rate_falls_with_resolution() {
    let pattern = sample_pattern();
    let rates: Vec<f64> = [16, 32, 64, 128]
        .map(|n| {
            lut_statistics(&EdgeLut::generate(n, n, &pattern), &pattern, 200_000).mismatch_rate
        })
        .to_vec();
    assert!(
        rates.windows(2).all(|w| w[1] < w[0]),
        "mismatch rates 16², 32², 64², 128²: {rates:?}"
    );
}

#[test]
fn cell_centres_look_up_their_own_cell() {
    let pattern = sample_pattern();
    for (angles, distances) in [(DEFAULT_ANGLES, DEFAULT_DISTANCES), (32, 32), (7, 5)] {
        let lut = EdgeLut::generate(angles, distances, &pattern);
        for angle in 0..angles {
            for distance in 0..distances {
                let (theta, d) = lut.cell_centre(angle, distance);
                let scale = 3.0;
                let cell = lut.cell(
                    (scale * d) as f32,
                    (scale * theta.cos()) as f32,
                    (scale * theta.sin()) as f32,
                );
                assert_eq!(
                    cell,
                    LutCell::Cell { angle, distance },
                    "{angles}x{distances}: centre θ={theta} d={d}"
                );
            }
        }
    }
}

#[test]
fn angle_pi_wraps_to_the_first_row() {
    let lut = EdgeLut::generate(32, 32, &sample_pattern());
    // atan2(+0, −1) = π, atan2(−0, −1) = −π: the same line direction.
    let plus = lut.cell(0.0, -1.0, 0.0);
    let minus = lut.cell(0.0, -1.0, -0.0);
    assert_eq!(plus, minus, "θ = ±π must share a row");
    assert!(
        matches!(plus, LutCell::Cell { angle: 0, .. }),
        "θ = π gives {plus:?}"
    );
}

#[test]
fn lookup_saturates_like_the_exact_classifier() {
    let pattern = sample_pattern();
    let lut = EdgeLut::generate(DEFAULT_ANGLES, DEFAULT_DISTANCES, &pattern);
    assert_eq!(lut.lookup(1.0, 0.0, 0.0), ALL_SAMPLES);
    assert_eq!(lut.lookup(0.0, 0.0, 0.0), ALL_SAMPLES);
    assert_eq!(lut.lookup(-1.0, 0.0, 0.0), 0);
    assert_eq!(lut.lookup(-1.0, 1e-30, 0.0), 0);
    assert_eq!(lut.lookup(f32::NAN, 1.0, 1.0), 0);
    assert_eq!(lut.lookup(1.0, f32::NAN, 1.0), 0);
    assert_eq!(lut.lookup(1.0, 1.0, f32::NAN), 0);
    assert_eq!(
        exact_mask_f32(1.0, f32::NAN, 1.0, &pattern),
        0,
        "exact mode: NaN is outside too"
    );
    let mut rng = SplitMix64::new(3);
    for _ in 0..100_000 {
        let theta = std::f64::consts::TAU * rng.next_f64();
        let d =
            (HALF_DIAGONAL + 1e-6 + rng.next_f64()) * if rng.next_f64() < 0.5 { -1.0 } else { 1.0 };
        let (alpha, beta, gamma) = (d as f32, theta.cos() as f32, theta.sin() as f32);
        assert_eq!(
            lut.lookup(alpha, beta, gamma),
            exact_mask_f32(alpha, beta, gamma, &pattern),
            "θ={theta} d={d}"
        );
    }
}

#[test]
fn lookup_is_invariant_under_power_of_two_scaling() {
    let pattern = sample_pattern();
    let lut = EdgeLut::generate(DEFAULT_ANGLES, DEFAULT_DISTANCES, &pattern);
    let mut rng = SplitMix64::new(5);
    for _ in 0..100_000 {
        let (theta, d) = random_crossing_line(&mut rng);
        let (alpha, beta, gamma) = (d as f32, theta.cos() as f32, theta.sin() as f32);
        let mask = lut.lookup(alpha, beta, gamma);
        for k in [-40, -7, 3, 50] {
            let s = 2f32.powi(k);
            assert_eq!(
                lut.lookup(s * alpha, s * beta, s * gamma),
                mask,
                "θ={theta} d={d} scale 2^{k}"
            );
        }
    }
}

#[test]
fn exact_f32_and_f64_agree_except_within_rounding_of_the_edge() {
    let pattern = sample_pattern();
    let mut rng = SplitMix64::new(9);
    for _ in 0..200_000 {
        let (theta, d) = random_crossing_line(&mut rng);
        let scale = 10f64.powf(4.0 * rng.next_f64() - 2.0);
        let [alpha, beta, gamma] =
            [scale * d, scale * theta.cos(), scale * theta.sin()].map(|x| x as f32);
        let differ = exact_mask_f32(alpha, beta, gamma, &pattern)
            ^ exact_mask(alpha.into(), beta.into(), gamma.into(), &pattern);
        for i in (0..SAMPLES_PER_PIXEL).filter(|i| differ >> i & 1 == 1) {
            let g = signed_distance(alpha.into(), beta.into(), gamma.into(), pattern[i]);
            // Three roundings of terms of size ≤ |α| + |β|/2 + |γ|/2 ≤ 1.5·r.
            assert!(
                g.abs() < 4.0 * 1.5 * f64::from(f32::EPSILON),
                "sample {i}: g={g:e}"
            );
        }
    }
}

#[test]
fn bytes_round_trip_and_bad_input_is_refused() {
    let lut = EdgeLut::generate(5, 3, &sample_pattern());
    let bytes = lut.to_bytes();
    assert_eq!(bytes.len(), LUT_HEADER_BYTES + 4 * 15);
    assert_eq!(&bytes[..4], b"IZBL");
    assert_eq!(bytes[4..8], 5u32.to_le_bytes());
    assert_eq!(bytes[8..12], 3u32.to_le_bytes());
    assert_eq!(bytes[12..16], lut.masks[0].to_le_bytes());
    assert_eq!(EdgeLut::from_bytes(&bytes), Ok(lut));

    assert_eq!(
        EdgeLut::from_bytes(&bytes[..7]),
        Err(LutDecodeError::TooShort { len: 7 })
    );
    let mut bad = bytes.clone();
    bad[0] = b'X';
    assert!(matches!(
        EdgeLut::from_bytes(&bad),
        Err(LutDecodeError::BadMagic { .. })
    ));
    let mut bad = bytes.clone();
    bad[4..8].copy_from_slice(&0u32.to_le_bytes());
    assert_eq!(
        EdgeLut::from_bytes(&bad),
        Err(LutDecodeError::BadResolution {
            angles: 0,
            distances: 3
        })
    );
    assert_eq!(
        EdgeLut::from_bytes(&bytes[..bytes.len() - 1]),
        Err(LutDecodeError::WrongLength {
            expected: bytes.len(),
            found: bytes.len() - 1
        })
    );
    let message = EdgeLut::from_bytes(&bad).unwrap_err().to_string();
    assert!(message.contains("0x3"), "{message}");
}

#[test]
fn table_rows_sweep_from_none_to_all() {
    // Along the distance axis the inside grows monotonically: each cell's
    // mask contains the previous one's.
    let lut = EdgeLut::generate(64, 64, &sample_pattern());
    for angle in 0..64 {
        let row = &lut.masks[angle * 64..(angle + 1) * 64];
        assert_eq!(row[0], 0, "row {angle} starts with samples inside");
        assert_eq!(
            row[63], ALL_SAMPLES,
            "row {angle} ends with samples outside"
        );
        for w in row.windows(2) {
            assert_eq!(
                w[0] & !w[1],
                0,
                "row {angle}: {:#x} not inside {:#x}",
                w[0],
                w[1]
            );
        }
    }
}
