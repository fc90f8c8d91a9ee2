//! The frustum-triangle test for a light of finite size (paper-notes/soft-shadows.md):
//! per receiver point P, a mask over the 32 samples of the light's disk
//! ([`crate::scene::LightDisk`]) instead of the µQuad's.
//!
//! Kalbertodt's tiled per-triangle soft shadow volumes ([Compute IZB]'s
//! next step) rasterise each occluder's projection onto the light into a
//! per-pixel bitmask; here that projection is formed with Wyman et al.
//! 2015's edge functions. Seen from P, each triangle edge (A, B) spans the
//! plane through P, A and B; where that plane cuts the light's disk is a
//! line, and the samples on the triangle's side of all three lines are
//! exactly the light directions (points) whose ray from P passes through
//! the triangle. With the vertices relative to P (t = A − P, …), the
//! plane's normal is `t_k × t_{k+1}`, and over the disk's (u, v) frame
//! the edge function is `f = n·c + (u − ½) n·a_u + (v − ½) n·a_v` — the
//! pixel's form, so the same LUT machinery and the same saturation test
//! apply, with the light pattern's own table.
//!
//! Every decision uses only vectors relative to P, and none depends on the
//! light but through the disk: the same floats frame after frame while
//! the light turns (see [`super`] on temporal stability).

use super::{above_full_tolerance, above_tangent_plane, Vector};
use crate::scene::LightDisk;

/// The per-pixel depth rule for an area light: triangle `t` (vertices
/// minus P) may shadow some light sample seen from P only if
///
/// 1. some vertex lies above the receiver's tangent plane by more than the
///    tolerance (as for a point light: a ray to a light sample above the
///    horizon climbs into that side; samples below the horizon are
///    occluded by the receiver itself, [`below_horizon_function`]), and
/// 2. P lies off the triangle's plane by more than the tolerance, on
///    either side: a ray from P through the triangle then crosses it at a
///    positive distance. (The point-light rule's "beyond the plane seen
///    from the light" is decided per light sample by the cone itself for a
///    directional light, and by [`beyond_plane_function`] for a sphere.)
///
/// The tolerance is the point-light rule's: `microquad_part` plus
/// [`super::DEPTH_TOLERANCE_ROUNDING`] × the triangle's distance from P. Coplanar
/// neighbours of the receiver fail condition 2; the triangles below its
/// tangent plane fail condition 1.
#[inline]
pub fn may_shadow_soft<V: Vector>(t: &[V; 3], normal: V, microquad_part: V::Scalar) -> bool {
    above_tangent_plane(t, normal, microquad_part)
        .is_some_and(|height| off_triangle_plane(t, height, microquad_part))
}

/// Condition 2 of [`may_shadow_soft`] (and condition 1 against the full
/// tolerance) for a triangle [`above_tangent_plane`] let through with
/// `height`.
#[inline]
pub fn off_triangle_plane<V: Vector>(
    t: &[V; 3],
    height: V::Scalar,
    microquad_part: V::Scalar,
) -> bool {
    let Some(tolerance) = above_full_tolerance(t, height, microquad_part) else {
        return false;
    };
    // Power-of-two normalised as in `beyond_triangle_plane`.
    let n = (t[1] - t[0]).cross(t[2] - t[0]).pow2_normalised();
    let distance = n.dot(t[0]);
    let distance = if distance < V::zero() {
        -distance
    } else {
        distance
    };
    distance > tolerance * n.length()
}

/// The orientation of the cone from P through triangle `t`: the triple
/// product (t₀ × t₁)·t₂. A ray d = Σ λᵢ tᵢ (λ ≥ 0) through the triangle
/// has `(t_k × t_{k+1})·d = λ_{k+2} · this`, so with the sign of this
/// number the three edge functions are ≥ 0 exactly on the cone toward
/// the triangle (and ≤ 0 on the opposite cone). Zero or NaN: P lies in
/// the triangle's plane (the depth rule has already refused it).
#[inline]
pub fn cone_orientation<V: Vector>(t: &[V; 3]) -> V::Scalar {
    t[0].cross(t[1]).dot(t[2])
}

/// Edge function `k` (edge from vertex k to k + 1) of triangle `t` over
/// the light disk's (u, v): ≥ 0 on the triangle's side. `flip` is
/// `cone_orientation(t) < 0`.
#[inline]
pub fn light_edge_function<V: Vector>(
    t: &[V; 3],
    k: usize,
    disk: &LightDisk<V>,
    flip: bool,
) -> [V::Scalar; 3] {
    let n = t[k].cross(t[(k + 1) % 3]);
    let n = if flip { -n } else { n };
    [n.dot(disk.centre), n.dot(disk.axis_u), n.dot(disk.axis_v)]
}

/// For a sphere light, whose samples are points at a finite distance: ≥ 0
/// where the light sample lies beyond the triangle's plane seen from P, so
/// that the segment from P to it meets the triangle's cone *after* the
/// triangle. ANDed with the three edges: the segment hits the triangle.
/// (A directional light's samples are at infinity, always beyond.)
#[inline]
pub fn beyond_plane_function<V: Vector>(t: &[V; 3], disk: &LightDisk<V>) -> [V::Scalar; 3] {
    let m = (t[1] - t[0]).cross(t[2] - t[0]);
    // Orient m away from P: P − A = −t₀ must have m·(−t₀) < 0.
    let m = if m.dot(t[0]) < V::zero() { -m } else { m };
    [
        m.dot(disk.centre - t[0]),
        m.dot(disk.axis_u),
        m.dot(disk.axis_v),
    ]
}

/// ≥ 0 where the light sample lies on or below the receiver's tangent
/// plane (normal `normal`, the camera-facing side): the receiver itself
/// hides that part of the light. A pixel's soft mask starts from this.
#[inline]
pub fn below_horizon_function<V: Vector>(normal: V, disk: &LightDisk<V>) -> [V::Scalar; 3] {
    [
        -normal.dot(disk.centre),
        -normal.dot(disk.axis_u),
        -normal.dot(disk.axis_v),
    ]
}
