//! Exact area of a convex polygon intersected with a disk, and the
//! polygon's clearance from the disk: the closed-form building blocks of
//! the area-light check ([`super::analytic_soft`]).
//!
//! The area is the sum over the polygon's edges of the *signed* area of
//! the disk intersected with the triangle (centre, pᵢ, pᵢ₊₁): the
//! triangles fan out from the centre, their signs cancel outside the
//! polygon (the same decomposition as the shoelace formula). Each triangle splits where its far edge crosses the
//! circle: pieces inside contribute their triangle area, pieces outside
//! the sector ½ r² θ they subtend. Every term is a cross product, a dot
//! product or an `atan2` of them, so the result is accurate to a few ulps
//! of r² in `f64`.

use glam::DVec2;

/// Area of the intersection of the disk of radius `radius` centred at the
/// origin with the convex (or any simple) polygon `polygon`, whose vertices
/// may wind either way.
pub fn polygon_disk_area(polygon: &[DVec2], radius: f64) -> f64 {
    if polygon.len() < 3 {
        return 0.0;
    }
    let mut signed = 0.0;
    for i in 0..polygon.len() {
        signed += triangle_disk_area(polygon[i], polygon[(i + 1) % polygon.len()], radius);
    }
    signed.abs()
}

/// Signed area of the disk of radius `r` at the origin intersected with
/// the triangle (origin, `a`, `b`); positive when a → b turns
/// counter-clockwise about the origin.
fn triangle_disk_area(a: DVec2, b: DVec2, r: f64) -> f64 {
    let d = b - a;
    let dd = d.length_squared();
    if dd == 0.0 {
        return 0.0;
    }
    // |a + t d|² = r²: t² dd + 2 t (a·d) + (a·a − r²) = 0.
    let half_b = a.dot(d);
    let c = a.length_squared() - r * r;
    let disc = half_b * half_b - dd * c;
    let mut points = [a; 4];
    let mut n = 1;
    if disc > 0.0 {
        let root = disc.sqrt();
        for t in [(-half_b - root) / dd, (-half_b + root) / dd] {
            if t > 0.0 && t < 1.0 {
                points[n] = a + d * t;
                n += 1;
            }
        }
    }
    points[n] = b;
    n += 1;
    let mut area = 0.0;
    for w in points[..n].windows(2) {
        let (p, q) = (w[0], w[1]);
        let cross = p.perp_dot(q);
        // Between consecutive breakpoints the segment is wholly inside or
        // wholly outside the circle: its midpoint tells which.
        if ((p + q) * 0.5).length_squared() <= r * r {
            area += 0.5 * cross;
        } else {
            area += 0.5 * r * r * cross.atan2(p.dot(q));
        }
    }
    area
}

/// Where a convex polygon stands relative to the disk of radius `radius`
/// at the origin, with the margin by which it does: every vertex may move
/// by less than `margin` without changing the overlap's area from 0 (for
/// [`Clearance::Outside`]) or from the whole disk ([`Clearance::Covers`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Clearance {
    /// The polygon misses the disk by `margin` (distance from the disk to
    /// the polygon).
    Outside(f64),
    /// The polygon holds the disk with `margin` to spare (distance from
    /// the disk to the polygon's boundary).
    Covers(f64),
    /// Neither: the boundary crosses the disk.
    Crosses,
}

impl Clearance {
    /// The margin of an `Outside` or `Covers` clearance, 0 for `Crosses`.
    pub fn margin(&self) -> f64 {
        match *self {
            Clearance::Outside(m) | Clearance::Covers(m) => m,
            Clearance::Crosses => 0.0,
        }
    }
}

/// The [`Clearance`] of the convex `polygon` (either winding) from the
/// disk of radius `radius` at the origin. If every vertex moves by at most
/// δ < margin, the moved polygon lies within δ of the old one and the old
/// within δ of the new (convex hulls of displaced vertices), so the overlap
/// stays empty, or stays the whole disk.
pub fn clearance(polygon: &[DVec2], radius: f64) -> Clearance {
    if polygon.len() < 3 {
        return Clearance::Outside(f64::INFINITY);
    }
    let (mut min_dist, mut pos, mut neg) = (f64::INFINITY, false, false);
    for i in 0..polygon.len() {
        let (a, b) = (polygon[i], polygon[(i + 1) % polygon.len()]);
        let side = a.perp_dot(b - a);
        pos |= side > 0.0;
        neg |= side < 0.0;
        min_dist = min_dist.min(segment_distance(a, b));
    }
    let inside = !(pos && neg);
    let margin = min_dist - radius;
    match (inside, margin > 0.0) {
        (false, true) => Clearance::Outside(margin),
        (true, true) => Clearance::Covers(margin),
        _ => Clearance::Crosses,
    }
}

/// Distance from the origin to the segment [a, b].
fn segment_distance(a: DVec2, b: DVec2) -> f64 {
    let d = b - a;
    let dd = d.length_squared();
    let t = if dd > 0.0 {
        (-a.dot(d) / dd).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + d * t).length()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn square(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<DVec2> {
        vec![
            DVec2::new(x0, y0),
            DVec2::new(x1, y0),
            DVec2::new(x1, y1),
            DVec2::new(x0, y1),
        ]
    }

    #[test]
    fn polygon_inside_the_disk_keeps_its_area() {
        let tri = vec![
            DVec2::new(-0.3, -0.2),
            DVec2::new(0.4, -0.1),
            DVec2::new(0.0, 0.5),
        ];
        let shoelace = 0.5 * (0.7 * 0.7 - 0.1 * 0.3);
        assert!((polygon_disk_area(&tri, 1.0) - shoelace).abs() < 1e-15);
        // Either winding.
        let rev: Vec<_> = tri.iter().rev().copied().collect();
        assert!((polygon_disk_area(&rev, 1.0) - shoelace).abs() < 1e-15);
        assert!(matches!(clearance(&tri, 1.0), Clearance::Crosses));
    }

    #[test]
    fn disk_inside_the_polygon_is_the_whole_disk() {
        let big = square(-3.0, -2.0, 5.0, 4.0);
        assert!((polygon_disk_area(&big, 1.0) - PI).abs() < 1e-14);
        assert!((polygon_disk_area(&big, 0.5) - PI / 4.0).abs() < 1e-14);
        assert_eq!(clearance(&big, 1.0), Clearance::Covers(1.0));
    }

    #[test]
    fn half_plane_cuts_leave_circular_segments() {
        let mut checked = 0;
        for i in -9..=9 {
            let h = i as f64 / 10.0;
            // x ≥ h inside the unit disk: acos h − h √(1 − h²).
            let segment = h.acos() - h * (1.0 - h * h).sqrt();
            let cut = square(h, -10.0, 10.0, 10.0);
            let area = polygon_disk_area(&cut, 1.0);
            assert!(
                (area - segment).abs() < 1e-14,
                "h = {h}: {area} vs {segment}"
            );
            checked += 1;
        }
        assert_eq!(checked, 19);
    }

    #[test]
    fn square_corners_take_their_quarter() {
        // The quadrant x, y ≥ 0: a quarter disk.
        let quadrant = square(0.0, 0.0, 10.0, 10.0);
        assert!((polygon_disk_area(&quadrant, 1.0) - PI / 4.0).abs() < 1e-15);
        // The corner at (a, a): ∫ over x from a to √(1 − a²) of (√(1 − x²) − a),
        // in closed form with F(x) = ½ (x √(1 − x²) + asin x).
        let a: f64 = 0.3;
        let f = |x: f64| 0.5 * (x * (1.0 - x * x).sqrt() + x.asin());
        let b = (1.0 - a * a).sqrt();
        let exact = f(b) - f(a) - a * (b - a);
        let corner = square(a, a, 10.0, 10.0);
        assert!((polygon_disk_area(&corner, 1.0) - exact).abs() < 1e-14);
    }

    #[test]
    fn a_polygon_overlapping_the_disk_matches_a_fine_grid_count() {
        // A skewed quadrilateral: no symmetry to hide a sign error.
        let quad = vec![
            DVec2::new(-1.4, -0.3),
            DVec2::new(0.6, -1.2),
            DVec2::new(1.1, 0.9),
            DVec2::new(-0.2, 0.7),
        ];
        let n = 2000;
        let mut inside = 0u64;
        for j in 0..n {
            for i in 0..n {
                let p = DVec2::new(
                    -1.0 + 2.0 * (i as f64 + 0.5) / n as f64,
                    -1.0 + 2.0 * (j as f64 + 0.5) / n as f64,
                );
                let in_quad = (0..4).all(|e| {
                    let (a, b) = (quad[e], quad[(e + 1) % 4]);
                    (b - a).perp_dot(p - a) >= 0.0
                });
                inside += (p.length_squared() <= 1.0 && in_quad) as u64;
            }
        }
        let counted = inside as f64 * 4.0 / (n * n) as f64;
        let area = polygon_disk_area(&quad, 1.0);
        // The grid's error is about perimeter × cell side: ~6 × 1e-3.
        assert!((area - counted).abs() < 3e-3, "{area} vs {counted}");
        assert!(area > 1.0 && area < PI);
    }

    #[test]
    fn clearance_measures_the_gap() {
        let away = square(1.5, -1.0, 3.0, 1.0);
        assert_eq!(clearance(&away, 1.0), Clearance::Outside(0.5));
        let cover = square(-1.25, -2.0, 2.0, 2.0);
        assert_eq!(clearance(&cover, 1.0), Clearance::Covers(0.25));
        let cut = square(0.5, -2.0, 2.0, 2.0);
        assert_eq!(clearance(&cut, 1.0), Clearance::Crosses);
        assert_eq!(clearance(&cut, 1.0).margin(), 0.0);
    }
}
