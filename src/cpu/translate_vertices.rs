//! Eye-relative `f32` vertices for a moving eye — the CPU twin of the
//! shadow pass's `translate_vertices.comp`.
//!
//! Every `f32` path is exact inside the precision envelope because the
//! vertices it reads are eye-relative, rounded once from `f64`. A pass
//! that stays resident while the eye moves cannot round from `f64` on the
//! host each frame, so it keeps each vertex relative to a fixed anchor
//! (the scene's bounds centre) as a double-single `hi + lo` (Dekker 1971:
//! an unevaluated sum of two floats carrying about 48 bits), and
//! subtracts the eye, also anchor-relative and double-single, with
//! Knuth's two-sum (Knuth 1997, TAOCP vol. 2, §4.2.2): the difference is
//! the `f64` one to within 2⁻⁴⁸ of the scene's radius before its one
//! rounding to `f32`, so it equals `f32(v − eye)` except within that of a
//! rounding midpoint, and is within one ulp of it always.
//!
//! Both sides run the same IEEE `f32` operations in the same order (the
//! shader's are `precise`: no reassociation, no fused multiply-add), so
//! the GPU's vertices equal this twin's bit for bit.

use glam::{DVec3, Vec3};

/// `v` as a double-single: `hi = f32(v)`, `lo = f32(v − hi)`.
pub fn split(v: DVec3) -> [Vec3; 2] {
    let hi = v.as_vec3();
    [hi, (v - hi.as_dvec3()).as_vec3()]
}

/// `a − b` of two double-singles, rounded to `f32`: two-sum of the high
/// parts, then the low parts' difference added to its error.
pub fn difference(a: [Vec3; 2], b: [Vec3; 2]) -> Vec3 {
    let s = a[0] - b[0];
    let a_part = s + b[0];
    let b_part = s - a_part;
    let error = (a[0] - a_part) - (b[0] + b_part);
    s + (error + (a[1] - b[1]))
}

/// Every vertex of `world` (anchor-relative double-singles) relative to
/// `eye` (anchor-relative double-single), in `f32`.
pub fn translate_vertices(world: &[[Vec3; 2]], eye: [Vec3; 2]) -> Vec<Vec3> {
    world.iter().map(|&v| difference(v, eye)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The two-sum difference is `f32(v − eye)` but within 2⁻⁴⁸ of the
    /// radius of a midpoint, and within one ulp of it always, over
    /// vertices and eyes spread across a scene 10⁴ from its anchor's
    /// origin at scales from 10⁻³ to 10⁶.
    #[test]
    fn differences_round_as_f64_does_but_at_near_ties() {
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let (mut checked, mut off_by_one) = (0, 0);
        for scale in [1e-3, 1.0, 1e3, 1e6] {
            for _ in 0..20_000 {
                let v = DVec3::new(next(), next(), next()) * scale;
                let eye = DVec3::new(next(), next(), next()) * scale;
                let got = difference(split(v), split(eye));
                let want = (v - eye).as_vec3();
                for k in 0..3 {
                    let ulps = (got[k].to_bits() as i64 - want[k].to_bits() as i64).abs();
                    assert!(ulps <= 1, "{v} − {eye}: {got} against {want}");
                    off_by_one += usize::from(ulps == 1);
                }
                checked += 1;
            }
        }
        assert_eq!(checked, 80_000);
        // A midpoint within 2⁻⁴⁸ relative: about 2⁻²³ of the cases.
        assert!(off_by_one <= 10, "{off_by_one} coordinates one ulp off");
    }
}
