//! The second half of the 64 paired rays (`izb64-paired`,
//! `paper-notes/soft-shadows.md`): 32 more (µQuad sample, light sample)
//! pairs, made from the first 32 by turning each pattern about the
//! centre of its domain. Turned copies keep each half as good as the
//! original on its own (the same score: a half is one 32-bit mask, formed
//! exactly as `izb32-paired` forms its own), and the turn angles make the
//! 64-point unions cover their domains well:
//!
//! - pixel: a quarter turn, (u, v) → (v, 1 − u). It maps the square onto
//!   itself, and no turned lattice point lands on an original one. Both
//!   quarter turns score the same on the union (RMS 0.0139 against the
//!   half's 0.0196); they differ only in which light sample each µQuad
//!   sample meets, and this one had the lower smooth-penumbra error on
//!   the bench scenes (`soft-shadows.md`).
//! - light: [`SECOND_LIGHT_TURN_DEG`], the angle whose 64-point union has
//!   the lowest disk coverage RMS over a sweep of turns (0.0131 against a
//!   half's 0.0190; a unit test re-runs the sweep).

use crate::SamplePattern;

/// The turn of the light pattern's second half, in degrees.
pub const SECOND_LIGHT_TURN_DEG: f64 = 54.0;

/// The µQuad pattern of the second half: `pixel` turned a quarter turn.
pub fn second_half_pixel_pattern(pixel: &SamplePattern) -> SamplePattern {
    pixel.map(|[u, v]| [v, 1.0 - u])
}

/// The light pattern of the second half: `light` turned by
/// [`SECOND_LIGHT_TURN_DEG`] about the disk's centre (½, ½), in `f64`
/// then rounded (the GPU receives these `f32`s).
pub fn second_half_light_pattern(light: &SamplePattern) -> SamplePattern {
    turned(light, SECOND_LIGHT_TURN_DEG)
}

fn turned(points: &SamplePattern, degrees: f64) -> SamplePattern {
    let (sin, cos) = degrees.to_radians().sin_cos();
    points.map(|[u, v]| {
        let (x, y) = (f64::from(u) - 0.5, f64::from(v) - 0.5);
        [
            (0.5 + cos * x - sin * y) as f32,
            (0.5 + sin * x + cos * y) as f32,
        ]
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{disk_coverage_error_of, light_pattern, sample_pattern};

    fn union(a: &SamplePattern, b: &SamplePattern) -> Vec<[f32; 2]> {
        a.iter().chain(b).copied().collect()
    }

    #[test]
    fn the_second_halves_stay_in_their_domains_and_apart() {
        let (pixel, light) = (sample_pattern(), light_pattern());
        let (pixel2, light2) = (
            second_half_pixel_pattern(&pixel),
            second_half_light_pattern(&light),
        );
        for [u, v] in pixel2 {
            assert!(
                (0.0..1.0).contains(&u) && (0.0..1.0).contains(&v),
                "{u} {v}"
            );
        }
        for [u, v] in light2 {
            let r = (f64::from(u) - 0.5).hypot(f64::from(v) - 0.5);
            assert!(r < 0.5, "light sample ({u}, {v}) outside the disk");
        }
        // No point of a second half repeats one of its first half.
        for (first, second) in [(&pixel, &pixel2), (&light, &light2)] {
            for a in second {
                let nearest = first
                    .iter()
                    .map(|b| (a[0] - b[0]).hypot(a[1] - b[1]))
                    .fold(f32::INFINITY, f32::min);
                assert!(nearest > 1.0 / 256.0, "{a:?} repeats a first-half point");
            }
        }
    }

    #[test]
    fn the_light_turn_is_the_best_of_a_sweep() {
        const LINES: usize = 100_000;
        let light = light_pattern();
        let score = |degrees: f64| {
            disk_coverage_error_of(&union(&light, &turned(&light, degrees)), LINES).rms
        };
        let chosen = score(SECOND_LIGHT_TURN_DEG);
        let single = disk_coverage_error_of(&light, LINES).rms;
        assert!(
            chosen < 0.75 * single,
            "64 samples {chosen} against 32: {single}"
        );
        let mut checked = 0;
        for step in 0..180 {
            let degrees = f64::from(step);
            let other = score(degrees);
            // 1 %: the score's noise at this many lines.
            assert!(
                chosen <= other * 1.01,
                "a turn of {degrees}° scores {other}, below the chosen {chosen}"
            );
            checked += 1;
        }
        assert_eq!(checked, 180);
    }
}
