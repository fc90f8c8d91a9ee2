//! The `behind-receivers` cull itself (Wyman et al. 2015, §5.4, exact):
//! the test that drops a triangle from a cell when its plane lies beyond
//! no receiver able to test it there, so the per-pixel depth test would
//! fail for all of them. What it tests against (each cell's farthest
//! receiver, its reach and its grown box) is registered in
//! [`super::receivers`]; the bin asks it per (triangle, cell) pair. The GPU
//! twin is `behind_receivers` in `shaders/bin.comp`.

use super::light_setup::{CascadeGrid, Projection};
use super::receivers::{cull_box, CellReceivers};
use glam::{Vec2, Vec3};

/// Relative margin of [`behind_receivers`] (2⁻¹⁰), about 10⁴ times the
/// `f32` rounding of the depth test it must agree with.
pub const BEHIND_MARGIN: f32 = izb_contract::tolerance::BEHIND_MARGIN;

/// Whether triangle `tri` (light view) is behind every receiver that can
/// test it in cell (`x`, `y`) of level `level` of `grid` (index `c` in the
/// cell arrays): no µQuad centre P
/// of those receivers can lie beyond its plane, seen from the light. Then
/// the per-pixel depth test ([`crate::frustum::may_shadow`]: P beyond the
/// plane, away from the light, by more than a tolerance) fails for each of
/// them and the cell need not list the triangle. A cell no receiver
/// touches never needs a list. Where the P can be: over the cell grown by
/// their reach (light NDC), no farther from the light than the farthest.
/// - Directional light (+z toward it): a box with z ≥ the lowest z; the
///   plane's height is linear in x, y, so it is below the box's floor when
///   it is below at the four corners.
/// - Point light (at the origin, z its depth): the pyramid from the light
///   through the grown cell down to the largest depth; the light is on its
///   own side of the plane, so the pyramid is when its four base corners
///   are.
pub fn behind_receivers(
    grid: &CascadeGrid,
    receivers: &CellReceivers,
    tri: &[Vec3; 3],
    level: u32,
    c: usize,
    (x, y): (u32, u32),
    light_radius: f32,
) -> bool {
    TriangleCull::new(tri, receivers.projection, light_radius).behind(
        grid,
        receivers,
        level,
        c,
        (x, y),
    )
}

/// What [`behind_receivers`] computes of the triangle alone, once for
/// every cell of its rectangle (the same values, so the same verdicts).
pub struct TriangleCull<'a> {
    tri: &'a [Vec3; 3],
    projection: Projection,
    /// Under an area light: every light sample on the receivers' side of
    /// the plane ([`beyond_every_light_sample`]); else `true`.
    light_side: bool,
    plane: PlaneParts,
}

/// The plane's parts of [`plane_below_box`] and [`plane_beyond_pyramid`].
enum PlaneParts {
    /// Directional; `None`: seen edge-on.
    Below(Option<UpwardPlane>),
    /// Point light.
    Beyond(PointPlane),
}

/// A directional light's triangle: its upward normal, |n| / n_z, and its
/// xy and z bounds.
#[derive(Clone, Copy)]
struct UpwardPlane {
    n: Vec3,
    slope: f32,
    xy: (Vec2, Vec2),
    z: (f32, f32),
}

/// A point light's triangle: its normal, the light's side (`None`: the
/// light in the plane, or NaN), |n|, and the bounds of the triangle and
/// the light (the origin).
#[derive(Clone, Copy)]
struct PointPlane {
    n: Vec3,
    side: Option<f32>,
    length: f32,
    bounds: (Vec3, Vec3),
}

impl<'a> TriangleCull<'a> {
    /// The triangle's parts of the test, under a light of `light_radius`.
    pub fn new(tri: &'a [Vec3; 3], projection: Projection, light_radius: f32) -> Self {
        let light_side = if light_radius > 0.0 {
            beyond_every_light_sample(tri, projection, light_radius)
        } else {
            true // a point-like light (or NaN, as before: not checked)
        };
        let plane = match projection {
            Projection::Orthographic => PlaneParts::Below(upward_normal(tri).map(|n| {
                let xy = [tri[1], tri[2]]
                    .iter()
                    .fold((tri[0].truncate(), tri[0].truncate()), |(lo, hi), v| {
                        (lo.min(v.truncate()), hi.max(v.truncate()))
                    });
                let z = (
                    tri[0].z.min(tri[1].z).min(tri[2].z),
                    tri[0].z.max(tri[1].z).max(tri[2].z),
                );
                UpwardPlane {
                    n,
                    slope: n.length() / n.z,
                    xy,
                    z,
                }
            })),
            Projection::Perspective => {
                let a = tri[0];
                let n = (tri[1] - a).cross(tri[2] - a);
                // The light's side: sign of n · (light − a), the light at
                // the origin.
                let light_side = -n.dot(a);
                let side = (light_side != 0.0).then(|| light_side.signum());
                let bounds = tri.iter().fold((Vec3::ZERO, Vec3::ZERO), |(lo, hi), p| {
                    (lo.min(*p), hi.max(*p))
                });
                PlaneParts::Beyond(PointPlane {
                    n,
                    side,
                    length: n.length(),
                    bounds,
                })
            }
        };
        TriangleCull {
            tri,
            projection,
            light_side,
            plane,
        }
    }

    /// [`behind_receivers`] in cell (`x`, `y`) of level `level` (index `c`).
    #[inline]
    pub fn behind(
        &self,
        grid: &CascadeGrid,
        receivers: &CellReceivers,
        level: u32,
        c: usize,
        (x, y): (u32, u32),
    ) -> bool {
        let z_min = receivers.z_min[c];
        if z_min == f32::INFINITY {
            return true;
        }
        if !self.light_side {
            return false;
        }
        let [lo, hi] = receivers.cull_box[c];
        debug_assert_eq!([lo, hi], cull_box(grid, level, (x, y), receivers.reach[c]));
        debug_assert_eq!(self.projection, receivers.projection);
        match &self.plane {
            PlaneParts::Below(parts) => plane_below_box(self.tri, parts, lo, hi, z_min),
            PlaneParts::Beyond(parts) => plane_beyond_pyramid(self.tri, parts, lo, hi, -z_min),
        }
    }
}

/// Under an area light the cull also needs every light sample on the
/// receivers' side of the plane, seen along every ray: a receiver above
/// a steep plane can still see part of the light's disk through it.
/// - Directional light of angular radius r (`light_radius` = tan r): a
///   ray toward any sample never descends toward the plane when the
///   plane's upward unit normal has n̂_z ≥ sin r.
/// - Sphere light of radius R at the origin: every sample lies on the
///   light's (and the receivers') side when the plane is farther than R
///   from the centre; a segment between two points of one half-space
///   stays in it.
///
/// With a margin of [`BEHIND_MARGIN`], far above the `f32` rounding.
fn beyond_every_light_sample(tri: &[Vec3; 3], projection: Projection, light_radius: f32) -> bool {
    let grow = 1.0 + BEHIND_MARGIN;
    match projection {
        Projection::Orthographic => upward_normal(tri).is_some_and(|n| {
            let sin_r = light_radius / (1.0 + light_radius * light_radius).sqrt();
            n.z > sin_r * grow * n.length()
        }),
        Projection::Perspective => {
            let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
            n.dot(tri[0]).abs() > light_radius * grow * n.length()
        }
    }
}

/// Directional [`behind_receivers`]: the plane of `tri` below the box
/// `[lo, hi]` × [`z_min`, ∞) by a margin.
fn plane_below_box(
    tri: &[Vec3; 3],
    parts: &Option<UpwardPlane>,
    lo: Vec2,
    hi: Vec2,
    z_min: f32,
) -> bool {
    let Some(UpwardPlane {
        n,
        slope,
        xy: (xy_lo, xy_hi),
        z: (tri_z_lo, tri_z_hi),
    }) = *parts
    else {
        return false;
    };
    let plane_max = highest_plane_height(n, tri[0], lo, hi);
    if plane_max.partial_cmp(&z_min) != Some(std::cmp::Ordering::Less) {
        // Not below the floor (or NaN): the margin is never negative, so
        // the answer is no without it, the usual one (most triangles rise
        // above their cells' floor).
        return false;
    }
    // Size of the whole configuration, for the margin.
    let (box_lo, box_hi) = (lo.min(xy_lo), hi.max(xy_hi));
    let (z_lo, z_hi) = (z_min.min(tri_z_lo), z_min.max(tri_z_hi));
    // Against a bound of the margin without the square root first
    // ([`length_bound`]; a larger sum, a larger product, a lower
    // difference), the same verdict where the plane clears it.
    if let Some(bound) = length_bound((box_hi - box_lo).extend(0.0)) {
        if plane_max < z_min - BEHIND_MARGIN * (bound + (z_hi - z_lo)) * slope {
            return true;
        }
    }
    let size = (box_hi - box_lo).length() + (z_hi - z_lo);
    let margin = BEHIND_MARGIN * size * slope;
    plane_max < z_min - margin
}

/// The height over `q` of the plane through `a` with upward normal `n`.
#[inline]
pub(super) fn plane_height(n: Vec3, a: Vec3, q: Vec2) -> f32 {
    a.z - (n.x * (q.x - a.x) + n.y * (q.y - a.y)) / n.z
}

/// [`highest_corner_height`] at one corner. With n_z > 0 and every
/// rounded step monotone, the corner against the normal's x and y is the
/// highest of the four rounded heights, bit for bit. A non-finite height
/// there (an overflow, which a NaN at another corner would carry there)
/// asks all four. (`shaders/bin_placement.glsl` takes the four corners'
/// largest, the same value.)
#[inline]
fn highest_plane_height(n: Vec3, a: Vec3, lo: Vec2, hi: Vec2) -> f32 {
    let highest = Vec2::new(
        if n.x >= 0.0 { lo.x } else { hi.x },
        if n.y >= 0.0 { lo.y } else { hi.y },
    );
    match plane_height(n, a, highest) {
        h if h.is_finite() => h,
        _ => highest_corner_height(n, a, lo, hi),
    }
}

/// The highest [`plane_height`] at the four corners of `[lo, hi]`: how
/// [`plane_below_box`] is defined.
fn highest_corner_height(n: Vec3, a: Vec3, lo: Vec2, hi: Vec2) -> f32 {
    let height = |q: Vec2| plane_height(n, a, q);
    height(lo)
        .max(height(Vec2::new(hi.x, lo.y)))
        .max(height(hi))
        .max(height(Vec2::new(lo.x, hi.y)))
}

/// Point-light [`behind_receivers`]: the four corners at depth `depth` of
/// the pyramid from the light (the origin) through the NDC rectangle
/// `[lo, hi]` lie on the light's side of `tri`'s plane by a margin.
fn plane_beyond_pyramid(
    tri: &[Vec3; 3],
    parts: &PointPlane,
    lo: Vec2,
    hi: Vec2,
    depth: f32,
) -> bool {
    let PointPlane {
        n,
        side,
        length,
        bounds: (tri_lo, tri_hi),
    } = *parts;
    let Some(side) = side else {
        return false; // the light in the plane (or NaN): no side to keep
    };
    let a = tri[0];
    let corners = [
        Vec3::new(lo.x * depth, lo.y * depth, depth),
        Vec3::new(hi.x * depth, lo.y * depth, depth),
        Vec3::new(hi.x * depth, hi.y * depth, depth),
        Vec3::new(lo.x * depth, hi.y * depth, depth),
    ];
    let beyond = corners.map(|q| side * n.dot(q - a));
    // The margin is never negative (or it is NaN, which no value exceeds):
    // a corner on the plane or behind it answers no without it, the usual
    // answer where the cull does not drop the triangle.
    if !beyond.iter().all(|&b| b > 0.0) {
        return false;
    }
    // Size of the whole configuration (light, corners, triangle).
    let (mut box_lo, mut box_hi) = (tri_lo, tri_hi);
    for p in &corners {
        box_lo = box_lo.min(*p);
        box_hi = box_hi.max(*p);
    }
    let size = box_hi - box_lo;
    // Most corners clear the margin by far: against a bound of it without
    // the square root first, the same verdict.
    if let Some(bound) = length_bound(size) {
        if beyond.iter().all(|&b| b > BEHIND_MARGIN * bound * length) {
            return true;
        }
    }
    let margin = BEHIND_MARGIN * size.length() * length;
    beyond.iter().all(|&b| b > margin)
}

/// A bound on `size.length()` as `f32` rounds it, never below it, for a
/// box of sides `size` (non-negative), without the square root: |size|₁
/// grown by 2⁻¹⁰ (|·|₂ ≤ |·|₁, and the roundings of the two differ by a
/// few ulps). A margin computed from it by the same products is never
/// below the one computed from the length: each rounded product is
/// monotone. `None` where the squares could overflow (sides near 10¹⁹),
/// or for NaN.
#[inline]
fn length_bound(size: Vec3) -> Option<f32> {
    let l1 = (size.x + size.y + size.z) * (1.0 + 1.0 / 1024.0);
    (l1 < 1.0e18).then_some(l1)
}

/// The normal of light-view triangle `tri` turned toward the light (+z),
/// or `None` when the light sees it edge-on (or it is NaN): then it has no
/// height function z(x, y).
pub(super) fn upward_normal(tri: &[Vec3; 3]) -> Option<Vec3> {
    let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
    let n = if n.z < 0.0 { -n } else { n };
    (n.z > 0.0).then_some(n)
}

#[cfg(test)]
mod tests;
