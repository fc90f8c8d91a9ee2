//! Tests of the footprint's cell tests: the selected corner against
//! every corner, and the row spans against the cells one by one.

use super::*;

/// The level-0 footprint of vertices `v` (cells) over the box of its
/// vertices clamped to `[lo, hi]` and rounded out to whole cells,
/// oriented `degenerate` where its winding is 0; with its winding.
fn test_footprint(
    v: [Vec2; 3],
    (lo, hi): (f32, f32),
    degenerate: f32,
    pad: Vec2,
) -> (Footprint, f32) {
    let (d1, d2) = (v[1] - v[0], v[2] - v[0]);
    let winding = d1.x * d2.y - d1.y * d2.x;
    let clamp = |p: Vec2| p.clamp(Vec2::splat(lo), Vec2::splat(hi));
    let (box_lo, box_hi) = (
        clamp(v[0].min(v[1]).min(v[2])),
        clamp(v[0].max(v[1]).max(v[2])),
    );
    let orientation = if winding == 0.0 {
        degenerate
    } else {
        winding.signum()
    };
    let rect = [
        box_lo.x as u32,
        box_lo.y as u32,
        box_hi.x as u32 + 1,
        box_hi.y as u32 + 1,
    ];
    (
        Footprint {
            level: 0,
            rect,
            v,
            orientation,
            pad,
            tame: v.iter().all(|p| p.abs().max_element() < TAME_COORDINATE),
        },
        winding,
    )
}

/// The selected corner gives every verdict the four corners give: on
/// random triangles (a third slivers, some with exactly axis-aligned
/// edges) at scales 2⁻¹⁰ to 2²⁰ cells, against every cell of their
/// rectangle grown by one, under random growths, and on triangles with
/// coordinates near `f32::MAX`, where products overflow; and
/// [`FootprintRow`] gives them too.
#[test]
fn the_selected_corner_decides_like_every_corner() {
    let mut random = crate::cpu::test_random::XorShift::new(0x2545_F491_4F6C_DD1D);
    let mut next = move || random.unit_f32();
    let (mut checked, mut touched, mut overflowing) = (0, 0, 0);
    for i in 0..20_000 {
        let scale = 2f32.powi((next() * 30.0) as i32 - 10);
        let centre = Vec2::new(next() * 64.0, next() * 64.0);
        let mut v = [0; 3].map(|_| centre + (Vec2::new(next(), next()) - 0.5) * scale);
        match i % 6 {
            0 => v[2] = v[1] + (v[0] - v[1]) * 1e-3 * next() + Vec2::new(1e-4 * scale, 0.0),
            1 => v[1].y = v[0].y, // a horizontal edge: dy = 0
            2 => v[2].x = v[1].x, // a vertical edge: dx = 0
            3 if i % 12 == 3 => v = v.map(|p| p * 1e37),
            _ => {}
        }
        let (f, winding) = test_footprint(v, (-1.0, 70.0), 1.0, Vec2::ZERO);
        overflowing += !winding.is_finite() as usize;
        let grow = Vec2::new(next(), next()) * [0.0, 1.0 / 64.0, 2.0][i % 3];
        let [x0, y0, x1, y1] = f.rect.map(i64::from);
        for y in y0 - 1..=y1 + 1 {
            for x in x0 - 1..=x1 + 1 {
                let expected = f.touches_grown_by_corners(x, y, grow);
                assert_eq!(f.touches_grown(x, y, grow), expected, "{f:?} cell {x}, {y}");
                let by_row = f.row_grown(y, grow).touches(x);
                assert_eq!(by_row, expected, "{f:?} cell {x}, {y} along its row");
                checked += 1;
                touched += expected as usize;
            }
        }
    }
    assert!(checked > 500_000, "{checked} cells checked");
    assert!(
        touched > checked / 10 && touched < checked * 9 / 10,
        "{touched} touched"
    );
    assert!(overflowing > 100, "{overflowing} overflowing triangles");
}

/// Every cell a row's span leaves out is untouched: random triangles
/// (a fifth long and thin, some with axis-aligned edges, some near
/// `f32::MAX`) over rectangles up to 160 cells wide, under random pads.
#[test]
fn a_row_span_leaves_out_only_untouched_cells() {
    let mut random = crate::cpu::test_random::XorShift::new(0x6A09_E667_F3BC_C908);
    let mut next = move || random.unit_f32();
    let (mut checked, mut left_out, mut touched, mut rows) = (0usize, 0usize, 0usize, 0usize);
    for i in 0..6_000 {
        let scale = 2f32.powi((next() * 10.0) as i32 - 2);
        let centre = Vec2::new(next() * 80.0, next() * 80.0);
        let mut v = [0; 3].map(|_| centre + (Vec2::new(next(), next()) - 0.5) * scale);
        match i % 10 {
            0 | 5 => v[2] = v[1] + (v[0] - v[1]) * 0.97 + Vec2::new(0.3, -0.2) * next(),
            1 => v[1].y = v[0].y,
            2 => v[2].x = v[1].x,
            3 if i % 20 == 3 => v = v.map(|p| p * 1e37),
            _ => {}
        }
        let pad = Vec2::new(next(), next()) * [0.0, 0.5, 3.0][i % 3];
        let (f, _) = test_footprint(v, (0.0, 160.0), 0.0, pad);
        let [x0, y0, x1, y1] = f.rect.map(i64::from);
        for y in y0..=y1 {
            let (a, b) = f.row_span(y);
            assert!(a >= x0 && b <= x1, "{f:?} row {y}: span {a}..={b}");
            rows += 1;
            for x in x0..=x1 {
                let is_touched = f.touches(x, y);
                if x < a || x > b {
                    assert!(
                        !is_touched,
                        "{f:?} cell {x}, {y} outside the span {a}..={b}"
                    );
                    left_out += 1;
                }
                touched += is_touched as usize;
                checked += 1;
            }
        }
    }
    assert!(checked > 1_000_000, "{checked} cells checked");
    assert!(left_out > checked / 4, "{left_out} of {checked} left out");
    assert!(touched > checked / 20, "{touched} touched");
    assert!(rows > 50_000, "{rows} rows");
}

/// `as_u32` is `as u32` on special values, near every power of two and
/// on random bit patterns (every class of `f32`).
#[test]
fn as_u32_is_the_saturating_cast() {
    let mut values = vec![
        f32::NAN,
        -f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        0.0,
        -0.0,
        f32::MIN_POSITIVE,
        f32::MAX,
        f32::MIN,
        0.999_999_94,
        4_294_967_040.0,
        4_294_967_296.0,
    ];
    for e in 0..40 {
        let p = (2.0f64).powi(e) as f32;
        for v in [p, -p] {
            values.extend([
                v,
                f32::from_bits(v.to_bits() - 1),
                f32::from_bits(v.to_bits() + 1),
            ]);
        }
    }
    let mut rng = crate::cpu::test_random::XorShift::new(0xa5_u32 as u64);
    values.extend((0..1_000_000).map(|_| f32::from_bits(rng.next_u64() as u32)));
    for &v in &values {
        assert_eq!(as_u32(v), v as u32, "{v:e} ({:#010x})", v.to_bits());
    }
    assert!(values.len() > 1_000_000, "{} values", values.len());
}
