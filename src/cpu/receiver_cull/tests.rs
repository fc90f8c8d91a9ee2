//! Tests of the `behind_receivers` cull's arithmetic: the corner it
//! selects and the bounds that stand in for its margins.

use super::*;

/// The selected corner's height is the four corners' highest, bit for
/// bit: random upward normals (a third with a zero x or y), planes
/// and boxes at scales 2⁻¹² to 2²⁰, and normals near `f32::MAX`, where
/// the products overflow.
#[test]
fn the_selected_corner_is_the_highest() {
    let mut random = crate::cpu::test_random::XorShift::new(0x9E37_79B9_7F4A_7C15);
    let mut next = move || random.unit_f32() - 0.5;
    let (mut checked, mut overflowing) = (0, 0);
    for i in 0..400_000 {
        let scale = 2f32.powi((next() * 32.0) as i32 + 4);
        let mut n = Vec3::new(next(), next(), next().abs() + 1e-3);
        match i % 6 {
            0 => n.x = 0.0,
            1 => n.y = -0.0,
            2 if i % 12 == 2 => n *= 3e37,
            _ => {}
        }
        let a = Vec3::new(next(), next(), next()) * scale;
        let lo = Vec2::new(next(), next()) * scale;
        let hi = lo + Vec2::new(next() + 0.5, next() + 0.5) * scale * 0.1;
        let (one, four) = (
            highest_plane_height(n, a, lo, hi),
            highest_corner_height(n, a, lo, hi),
        );
        assert!(
            one.to_bits() == four.to_bits() || one == four,
            "n {n} a {a} box {lo}..{hi}: {one} against {four}"
        );
        checked += 1;
        overflowing += !plane_height(n, a, lo).is_finite() as usize;
    }
    assert_eq!(checked, 400_000);
    assert!(overflowing > 1_000, "{overflowing} overflowing planes");
}

/// The margins' bounds ([`length_bound`]) never fall below the margins
/// they stand in for, as `f32` rounds both: wherever a value clears the
/// bound it clears the margin, so the cull's verdicts are the ones the
/// margins alone give. Box sides from 2⁻⁴⁰ to 2⁷⁰ (zeros, one side only,
/// and past the squares' overflow), lengths and slopes over as wide a
/// range, and infinite ones.
#[test]
fn the_margin_bounds_are_never_below_the_margins() {
    let mut random = crate::cpu::test_random::XorShift::new(0x2545_F491_4F6C_DD1D);
    let mut next = move || random.unit_f32();
    let wide = |r: f32| 2f32.powi((r * 110.0) as i32 - 40) * (1.0 + r);
    let (mut bounded, mut unbounded) = (0, 0);
    for i in 0..300_000 {
        let mut size = Vec3::new(wide(next()), wide(next()), wide(next()));
        match i % 5 {
            0 => size.y = 0.0,
            1 => (size.x, size.z) = (0.0, 0.0),
            _ => {}
        }
        let length = match i % 97 {
            0 => f32::INFINITY,
            1 => 0.0,
            _ => wide(next()),
        };
        let Some(bound) = length_bound(size) else {
            unbounded += 1;
            continue;
        };
        bounded += 1;
        // `plane_beyond_pyramid`'s margin.
        let (by_bound, margin) = (
            BEHIND_MARGIN * bound * length,
            BEHIND_MARGIN * size.length() * length,
        );
        assert!(
            by_bound >= margin || (by_bound.is_nan() && margin.is_nan()) || by_bound.is_nan(),
            "sides {size} length {length}: {by_bound} below {margin}"
        );
        assert!(
            !margin.is_nan() || by_bound.is_nan(),
            "sides {size} length {length}"
        );
        // `plane_below_box`'s: a box's xy sides and a z extent, z_min above.
        let (xy, dz, z_min) = (size.truncate(), size.z, wide(next()) - wide(next()));
        let Some(bound) = length_bound(xy.extend(0.0)) else {
            continue;
        };
        let (by_bound, exact) = (
            z_min - BEHIND_MARGIN * (bound + dz) * length,
            z_min - BEHIND_MARGIN * (xy.length() + dz) * length,
        );
        assert!(
            by_bound <= exact || by_bound.is_nan(),
            "sides {xy}, {dz} slope {length}: {by_bound} above {exact}"
        );
    }
    assert_eq!(bounded + unbounded, 300_000);
    assert!(
        bounded > 200_000 && unbounded > 10_000,
        "{bounded} {unbounded}"
    );
}

/// The cull's verdicts with the bounds are those of the margins alone
/// (the tests as they were before the bounds): random triangles against
/// random cells and receiver depths, under a point light and a
/// directional one, both verdicts common.
#[test]
fn the_verdicts_are_the_margins_verdicts() {
    fn beyond_by_margin(tri: &[Vec3; 3], p: &PointPlane, lo: Vec2, hi: Vec2, depth: f32) -> bool {
        let Some(side) = p.side else { return false };
        let corners = [
            Vec3::new(lo.x * depth, lo.y * depth, depth),
            Vec3::new(hi.x * depth, lo.y * depth, depth),
            Vec3::new(hi.x * depth, hi.y * depth, depth),
            Vec3::new(lo.x * depth, hi.y * depth, depth),
        ];
        let (mut box_lo, mut box_hi) = p.bounds;
        for q in &corners {
            (box_lo, box_hi) = (box_lo.min(*q), box_hi.max(*q));
        }
        let margin = BEHIND_MARGIN * (box_hi - box_lo).length() * p.length;
        corners.iter().all(|&q| side * p.n.dot(q - tri[0]) > margin)
    }
    fn below_by_margin(
        tri: &[Vec3; 3],
        u: &Option<UpwardPlane>,
        lo: Vec2,
        hi: Vec2,
        z_min: f32,
    ) -> bool {
        let Some(u) = *u else { return false };
        let plane_max = highest_plane_height(u.n, tri[0], lo, hi);
        let (box_lo, box_hi) = (lo.min(u.xy.0), hi.max(u.xy.1));
        let (z_lo, z_hi) = (z_min.min(u.z.0), z_min.max(u.z.1));
        let size = (box_hi - box_lo).length() + (z_hi - z_lo);
        plane_max < z_min - BEHIND_MARGIN * size * u.slope
    }
    let mut random = crate::cpu::test_random::XorShift::new(0x9E37_79B9_7F4A_7C15 ^ 0xABCD);
    let mut next = move || random.unit_f32() - 0.5;
    let mut counts = [[0usize; 2]; 2];
    for i in 0..200_000 {
        let scale = 2f32.powi((next() * 24.0) as i32);
        let tri = [0; 3].map(|_| Vec3::new(next(), next(), next() + 1.5) * scale);
        let lo = Vec2::new(next(), next()) * 0.5;
        let hi = lo + Vec2::new(next() + 0.5, next() + 0.5) * 0.01 * (1.0 + (i % 7) as f32);
        let depth = (next() + 1.6) * scale * 1.2;
        let (point, directional) = (
            TriangleCull::new(&tri, Projection::Perspective, 0.0),
            TriangleCull::new(&tri, Projection::Orthographic, 0.0),
        );
        let (PlaneParts::Beyond(p), PlaneParts::Below(u)) = (&point.plane, &directional.plane)
        else {
            unreachable!("each projection's own parts");
        };
        let beyond = plane_beyond_pyramid(&tri, p, lo, hi, depth);
        assert_eq!(
            beyond,
            beyond_by_margin(&tri, p, lo, hi, depth),
            "{tri:?} {lo} {hi} {depth}"
        );
        counts[0][beyond as usize] += 1;
        let z_min = depth;
        let below = plane_below_box(&tri, u, lo * scale, hi * scale, z_min);
        assert_eq!(
            below,
            below_by_margin(&tri, u, lo * scale, hi * scale, z_min),
            "{tri:?}"
        );
        counts[1][below as usize] += 1;
    }
    assert_eq!(counts.iter().flatten().sum::<usize>(), 400_000);
    assert!(counts.iter().flatten().all(|&c| c > 10_000), "{counts:?}");
}
