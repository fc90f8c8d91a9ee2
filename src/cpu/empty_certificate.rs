//! A proof, before any mask is formed, that a triangle's three edges
//! leave no sample of the µQuad inside: the survivor batch's lanes that
//! carry one skip the LUT (or the 32 evaluations) and contribute the mask
//! they would have got, 0.
//!
//! **What a bit needs.** Edge k is f_k(p) = α_k + β_k·x + γ_k·y over the
//! µQuad, x = u − ½, y = v − ½ (`crate::frustum::edge_function`), inside
//! where f_k ≥ 0; r_k = |(β_k, γ_k)|. A sample s gets its bit only if
//! every edge's mask has it, and an edge's mask has it only if
//! f_k(s) ≥ −R·r_k, for R the LUT's proven misclassification bound at the
//! µQuad's corner plus its `f32` allowance
//! ([`izb_lut::EdgeLut::misclassification_bound`] + [`izb_lut::LOOKUP_SLACK`]:
//! about 0.023 µQuad sides at 128 × 128). The exact modes need less (a
//! few ulps of f_k), one sample (the centre) none. So every bit set lies in
//! the grown triangle G = {p : f_k(p) + R·r_k ≥ 0, k = 0, 1, 2}, and the
//! mask is 0 wherever G misses the square S = [−½, ½]² that holds every
//! sample.
//!
//! **The certificate** (Farkas' lemma; Boyd & Vandenberghe 2004, §5.8):
//! for weights λ ≥ 0, every p in G has Σλ_k(f_k(p) + R·r_k) ≥ 0, and the
//! largest value of that affine function over S is
//!
//! ```text
//! V(λ) = Σλ_k(α_k + R·r_k) + ½(|Σλ_k β_k| + |Σλ_k γ_k|).
//! ```
//!
//! So V(λ) < 0 proves G ∩ S = ∅, for any λ ≥ 0. The smallest V over the
//! weight simplex lies at a vertex of its linear pieces: a single edge
//! (λ = e_k: the edge's line misses the square by more than R — the
//! LUT's own saturation is the same test against the square's
//! circumscribed circle) or a pair whose x or y terms cancel
//! (λ_j = |β_k|, λ_k = |β_j|, or the same with γ: the grown triangle's
//! corner between edges j and k lies beyond the square's side, a triangle
//! wholly to one side of the µQuad however thin — no bounding box needs a
//! miter for its sharp corners). Nine candidates in all; the only weights
//! they miss are the interior ones where both sums vanish, which would
//! prove G empty, never the case for a real triangle.
//!
//! **In `f32`.** Each edge is first scaled by its power of two
//! (`crate::frustum::normalised_edge`: exact, the same lines, r_k in
//! [1, 2√2)), and the certificate asks V + M < 0 with the margin
//! M = 2⁻¹⁶·(Σλ_k(|α_k| + R·r_k) + ½(Σλ_k|β_k| + Σλ_k|γ_k|)): the sum of
//! the magnitudes V is formed from, times 2⁻¹⁶, hundreds of times the few
//! roundings of its products and sums (each ≤ 2⁻²⁴ of those magnitudes;
//! Higham 2002, §3.1), of r_k's root and of R. Each edge carries its
//! share of M added to α_k + R·r_k, so a candidate is one weighted sum.
//! An infinite or NaN share, and NaN anywhere, make the comparison false:
//! no certificate. A product that overflows to −∞ does certify, and
//! rightly: it exceeds every finite positive term by more than 2⁻¹⁷ of
//! f32's range, its margin included. Measured in
//! `paper-notes/performance.md` (issue 30, session 21).

use crate::frustum::normalised_edge;

/// The reach R of the certificate for `lut`: the misclassification bound
/// at a corner of the µQuad (the largest over the square, so any sample
/// pattern) plus the lookup's `f32` allowance, 2⁻¹⁰ larger for the
/// rounding of the `f32` constant.
pub fn certificate_reach(lut: &izb_lut::EdgeLut) -> f32 {
    let bound = lut.misclassification_bound([0.0, 0.0]) + izb_lut::LOOKUP_SLACK;
    (bound * (1.0 + 1.0 / 1024.0)) as f32
}

/// One edge scaled by its power of two ([`normalised_edge`]):
/// (α, β, γ, r = |(β, γ)|).
#[inline(always)]
fn scaled(alpha: f32, beta: f32, gamma: f32) -> [f32; 4] {
    let [alpha, beta, gamma] = normalised_edge([alpha, beta, gamma]);
    [alpha, beta, gamma, (beta * beta + gamma * gamma).sqrt()]
}

/// An edge as the certificate reads it: β, γ, and α + R·r with the
/// margin's share 2⁻¹⁶·(|α| + R·r + ½(|β| + |γ|)) added (the module's
/// documentation: Σλ_k times it is the margin M).
struct Grown {
    guarded: f32,
    beta: f32,
    gamma: f32,
}

#[inline(always)]
fn grown(e: [f32; 4], reach: f32) -> Grown {
    let grown = reach * e[3];
    let magnitude = (e[0].abs() + grown) + 0.5 * (e[1].abs() + e[2].abs());
    Grown {
        guarded: (e[0] + grown) + magnitude * (1.0 / 65536.0),
        beta: e[1],
        gamma: e[2],
    }
}

/// Whether weights (`wa`, `wb`) ≥ 0 on edges `a`, `b` certify that no
/// sample is inside: V + M < 0 (the module's documentation). An infinite
/// magnitude makes its edge's `guarded` +∞ or NaN, so V + M is too and
/// nothing is certified.
#[inline(always)]
fn certifies(wa: f32, a: &Grown, wb: f32, b: &Grown) -> bool {
    let beyond = (wa * a.guarded + wb * b.guarded)
        + 0.5 * ((wa * a.beta + wb * b.beta).abs() + (wa * a.gamma + wb * b.gamma).abs());
    beyond < 0.0
}

/// Edge `a` alone, or the pair (`a`, `b`) with its x terms and then its y
/// terms cancelled.
#[inline(always)]
fn certified_by(a: &Grown, b: &Grown) -> bool {
    let alone = a.guarded + 0.5 * (a.beta.abs() + a.gamma.abs()) < 0.0;
    alone
        | certifies(b.beta.abs(), a, a.beta.abs(), b)
        | certifies(b.gamma.abs(), a, a.gamma.abs(), b)
}

/// Whether edges `e` (α, β, γ each, inside where f ≥ 0) provably leave
/// no sample inside, every edge's mask allowed to err by `reach` (see the
/// module's documentation). Straight-line code: callers run it over a
/// batch's lanes in one vectorised loop.
#[inline(always)]
pub fn no_sample_inside(e: [[f32; 3]; 3], reach: f32) -> bool {
    let e0 = grown(scaled(e[0][0], e[0][1], e[0][2]), reach);
    let e1 = grown(scaled(e[1][0], e[1][1], e[1][2]), reach);
    let e2 = grown(scaled(e[2][0], e[2][1], e[2][2]), reach);
    certified_by(&e0, &e1) | certified_by(&e1, &e2) | certified_by(&e2, &e0)
}

/// [`no_sample_inside`] of the first `lanes` lanes of a batch's edges
/// (`edges[k][component][lane]`): 1 where certified, else 0.
#[inline(always)]
pub fn no_sample_inside_lanes<const LANES: usize>(
    edges: &[[[f32; LANES]; 3]; 3],
    reach: f32,
    out: &mut [u32; LANES],
    lanes: usize,
) {
    for l in 0..lanes {
        let e = |k: usize| [edges[k][0][l], edges[k][1][l], edges[k][2][l]];
        out[l] = u32::from(no_sample_inside([e(0), e(1), e(2)], reach));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frustum::{exact_edge_mask, normalised_edge};

    /// On random triangles around and near the µQuad (thin ones pointing
    /// at its corners included), every certified lane's LUT masks and
    /// exact masks AND to 0, and the certificate fires on most triangles
    /// wholly outside the grown square.
    #[test]
    fn a_certified_triangle_sets_no_bit() {
        let lut = crate::lut::edge_lut();
        let pattern = crate::lut::sample_pattern();
        let reach = certificate_reach(lut);
        let mut random = crate::cpu::test_random::XorShift::new(0x9E37_79B9_7F4A_7C15);
        let mut next = move || random.unit_f32();
        let (mut certified, mut outside, mut checked) = (0, 0, 0);
        // Triangles whose LUT masks set bits no sample's exact test does:
        // the cases a certificate with too small a reach would lose.
        let mut lut_only = 0;
        for i in 0..400_000 {
            // Vertices in a box of half-size 0.6 to 3 around the centre,
            // a third of the triangles slivers from one vertex.
            let spread = 0.6 + 2.4 * next();
            let mut v = [[0.0f32; 2]; 3];
            for p in &mut v {
                *p = [(next() - 0.5) * 2.0 * spread, (next() - 0.5) * 2.0 * spread];
            }
            if i % 3 == 0 {
                let t = 1e-3 * next();
                v[2] = [
                    v[1][0] + t * (v[0][0] - v[1][0]) + 1e-3,
                    v[1][1] + t * (v[0][1] - v[1][1]),
                ];
            }
            let area = (v[1][0] - v[0][0]) * (v[2][1] - v[0][1])
                - (v[1][1] - v[0][1]) * (v[2][0] - v[0][0]);
            if area == 0.0 {
                continue;
            }
            // Edge k from v[k] to v[k+1], inside on the triangle's side,
            // at a random scale.
            let scale = 2f32.powi(i % 40 - 20);
            let edges = [0, 1, 2].map(|k| {
                let (a, b) = (v[k], v[(k + 1) % 3]);
                let n = [
                    -(b[1] - a[1]) * area.signum(),
                    (b[0] - a[0]) * area.signum(),
                ];
                [
                    -(n[0] * a[0] + n[1] * a[1]) * scale,
                    n[0] * scale,
                    n[1] * scale,
                ]
            });
            let lut_and = edges
                .iter()
                .map(|e| {
                    let e = normalised_edge(*e);
                    lut.lookup(e[0], e[1], e[2])
                })
                .fold(u32::MAX, |m, x| m & x);
            let exact_and = edges
                .iter()
                .map(|e| exact_edge_mask(normalised_edge(*e), pattern))
                .fold(u32::MAX, |m, x| m & x);
            let centre = edges.iter().all(|e| e[0] >= 0.0);
            // The grown triangle's corners in f64: where it lies wholly
            // beyond a side of the square by 10⁻³, a triangle that is not
            // thin must be certified.
            let lines = edges.map(|e| {
                let r = f64::from(e[1]).hypot(f64::from(e[2]));
                [
                    f64::from(e[0]) / r + f64::from(reach),
                    f64::from(e[1]) / r,
                    f64::from(e[2]) / r,
                ]
            });
            let corner = |j: usize, k: usize| {
                let (a, b) = (lines[j], lines[k]);
                let det = a[1] * b[2] - a[2] * b[1];
                [
                    (-a[0] * b[2] + b[0] * a[2]) / det,
                    (-a[1] * b[0] + b[1] * a[0]) / det,
                ]
            };
            let corners = [corner(0, 1), corner(1, 2), corner(2, 0)];
            let beyond = (0..2).any(|axis| {
                corners.iter().all(|c| c[axis] > 0.501) || corners.iter().all(|c| c[axis] < -0.501)
            });
            let longest = (0..3)
                .map(|k| {
                    let (a, b) = (v[k], v[(k + 1) % 3]);
                    (b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)
                })
                .fold(0.0, f32::max);
            let fat = area.abs() > 0.4 * longest;
            checked += 1;
            outside += (fat && beyond) as usize;
            lut_only += (exact_and == 0 && lut_and != 0) as usize;
            if no_sample_inside(edges, reach) {
                assert_eq!(lut_and, 0, "LUT bits under a certificate: {v:?}");
                assert_eq!(exact_and, 0, "exact bits under a certificate: {v:?}");
                assert!(!centre, "the centre under a certificate: {v:?}");
                certified += 1;
            } else {
                assert!(!(fat && beyond), "beyond the square, no certificate: {v:?}");
            }
        }
        println!(
            "{checked} triangles, {certified} certified, {outside} fat ones beyond the grown \
             square, {lut_only} with LUT bits and no exact ones"
        );
        assert!(checked > 390_000 && lut_only > 1_000);
        assert!(outside > 2_000 && certified > outside);
    }

    /// NaN, infinite and zero edges never certify; an edge whose whole
    /// half-plane lies off the square does, at any scale.
    #[test]
    fn degenerate_edges() {
        let reach = certificate_reach(crate::lut::edge_lut());
        let open = [1.0, 0.0, 0.0];
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert!(!no_sample_inside([[bad, 1.0, 0.0], open, open], reach));
            assert!(!no_sample_inside([[-1.0, bad, 0.0], open, open], reach));
        }
        assert!(!no_sample_inside([[0.0; 3], open, open], reach));
        for scale in [1e-30f32, 1.0, 1e30] {
            // x ≤ −0.6: off the square by 0.1 > reach.
            let off = [-0.6 * scale, -scale, 0.0];
            assert!(no_sample_inside([off, open, open], reach));
            let near = [-0.51 * scale, -scale, 0.0];
            assert!(!no_sample_inside([near, open, open], reach));
        }
        assert!(no_sample_inside([[-1e38, 0.0, 0.0], open, open], reach));
    }
}
