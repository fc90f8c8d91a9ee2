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
use izb_contract::{tolerance, BvhNode};

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

/// A BVH node built over the vertices' anchor-relative high parts, made
/// relative to `eye` and widened so that it holds every vertex
/// [`difference`] makes from a double-single inside it: the low part
/// (≤ ½ ulp of the reach), the bound's own rounding (≤ 1 ulp) and the
/// vertex's (≤ 1½ ulp) make at most 3 ulps ≤ 3·2⁻²³ of the reach, and the
/// widening is 2⁻²⁰ of it (`NODE_WIDENING`), plus a floor for a box at the
/// eye. A wider box costs a few more box tests, never a hit: the closest
/// hit does not depend on the boxes' bounds or the traversal's order
/// (`bvh_closest_hit.glsl` breaks ties by id).
pub fn translate_node(node: BvhNode, eye: [Vec3; 2]) -> BvhNode {
    let (lo_anchor, hi_anchor) = (Vec3::from(node.lo), Vec3::from(node.hi));
    let lo = difference([lo_anchor, Vec3::ZERO], eye);
    let hi = difference([hi_anchor, Vec3::ZERO], eye);
    let reach = lo_anchor
        .abs()
        .max(hi_anchor.abs())
        .max(lo.abs().max(hi.abs()));
    let margin = reach * tolerance::NODE_WIDENING + Vec3::splat(tolerance::NODE_WIDENING_FLOOR);
    BvhNode {
        lo: (lo - margin).to_array(),
        hi: (hi + margin).to_array(),
        ..node
    }
}

/// Every node of an anchor-space BVH made relative to `eye`
/// ([`translate_node`]).
pub fn translate_nodes(nodes: &[BvhNode], eye: [Vec3; 2]) -> Vec<BvhNode> {
    nodes.iter().map(|&n| translate_node(n, eye)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform numbers in [−1, 1) from a xorshift generator seeded by `seed`.
    fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut random = crate::cpu::test_random::XorShift::new(seed);
        move || random.unit_f64() * 2.0 - 1.0
    }

    /// The two-sum difference is `f32(v − eye)` but within 2⁻⁴⁸ of the
    /// radius of a midpoint, and within one ulp of it always, over
    /// vertices and eyes spread across a scene 10⁴ from its anchor's
    /// origin at scales from 10⁻³ to 10⁶.
    #[test]
    fn differences_round_as_f64_does_but_at_near_ties() {
        let mut next = uniform(0x2545_f491_4f6c_dd1d);
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

    /// A node boxing a few vertices' high parts, translated, holds every
    /// one of them translated — over boxes from a point to the whole
    /// scale, near and far from the eye, at scales from 10⁻³ to 10⁶, and
    /// boxes touching the eye.
    #[test]
    fn translated_boxes_hold_their_translated_vertices() {
        let mut next = uniform(0x9e37_79b9_7f4a_7c15);
        let mut checked = 0;
        for scale in [1e-3, 1.0, 1e3, 1e6] {
            for case in 0..5_000 {
                let centre = DVec3::new(next(), next(), next()) * scale;
                let size = scale * 10f64.powi(-(case % 8));
                let points: Vec<[Vec3; 2]> = (0..4)
                    .map(|_| split(centre + DVec3::new(next(), next(), next()) * size))
                    .collect();
                // Every fourth eye sits inside the box.
                let eye = match case % 4 {
                    0 => centre,
                    _ => DVec3::new(next(), next(), next()) * scale,
                };
                let eye = split(eye);
                let his = points.iter().map(|p| p[0]);
                let lo = his.clone().fold(Vec3::INFINITY, Vec3::min);
                let hi = his.fold(Vec3::NEG_INFINITY, Vec3::max);
                let node = BvhNode {
                    lo: lo.to_array(),
                    prim_count: 1,
                    hi: hi.to_array(),
                    first: 0,
                };
                let moved = translate_node(node, eye);
                for &p in &points {
                    let v = difference(p, eye);
                    for k in 0..3 {
                        assert!(
                            moved.lo[k] <= v[k] && v[k] <= moved.hi[k],
                            "{v} outside {moved:?} (eye {eye:?})"
                        );
                    }
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 4 * 5_000 * 4);
    }
}
