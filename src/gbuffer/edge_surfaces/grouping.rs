//! An edge pixel's 32 sample hits grouped by the plane they land on, and
//! each group a µQuad of its own: the half of the edge surfaces that does
//! not depend on how the hits were found (the BVH's sample rays in
//! `sample_rays.rs`, a multisampled visibility buffer's candidates in
//! `crate::gbuffer::multisampled`).

use super::{PixelSamples, Plane, SampleSurface, MAX_SURFACES};
use crate::gbuffer::{faces_light, microquad_axes, PixelSurface, SurfaceHit};
use crate::scene::{CameraFrame, Light};

/// The image points of pixel (`x`, `y`)'s samples under `pattern`.
pub fn sample_points(x: u32, y: u32, pattern: &[[f32; 2]; 32]) -> [(f64, f64); 32] {
    std::array::from_fn(|i| {
        let s = pattern[i];
        (x as f64 + s[0] as f64, y as f64 + s[1] as f64)
    })
}

/// A group of sample hits on one plane.
struct PlaneGroup {
    seed: SurfaceHit,
    plane: Plane,
    coverage: u32,
    count: u32,
}

/// What pixel (`x`, `y`)'s samples see (`pattern`, the µQuad's
/// sub-pixel offsets), from the primary `hits` of its 32 sample rays and
/// its shadow-tested `centre` surface: a hit on the centre's plane is the
/// centre's, the rest are grouped by plane, the centre and the groups with
/// most samples kept ([`MAX_SURFACES`]), each kept group facing the light
/// a µQuad of its own. `unbounded_rays` is left 0 for the caller.
pub fn group_sample_hits(
    frame: &CameraFrame,
    light: &Light,
    (x, y): (u32, u32),
    centre: &PixelSurface,
    hits: &[Option<SurfaceHit>; 32],
    pattern: &[[f32; 2]; 32],
) -> PixelSamples {
    let centre_plane = Plane::of(&centre.hit, centre.axis_x, centre.axis_y);
    let points = sample_points(x, y, pattern);
    let mut out = PixelSamples {
        centre_coverage: 0,
        counted: 0,
        facing_away: 0,
        extra: Vec::new(),
        dropped: 0,
        missed: 0,
        unbounded_rays: 0,
    };
    let mut groups: Vec<PlaneGroup> = Vec::new();
    for (i, (hit, &(px, py))) in hits.iter().zip(&points).enumerate() {
        let bit = 1u32 << i;
        let Some(hit) = *hit else {
            out.missed |= bit;
            continue;
        };
        if centre_plane.holds(hit.position) {
            out.centre_coverage |= bit;
            continue;
        }
        match groups.iter_mut().find(|g| g.plane.holds(hit.position)) {
            Some(g) => {
                g.coverage |= bit;
                g.count += 1;
            }
            None => {
                let (ax, ay, _) = microquad_axes(frame, px, py, &hit);
                groups.push(PlaneGroup {
                    seed: hit,
                    plane: Plane::of(&hit, ax, ay),
                    coverage: bit,
                    count: 1,
                });
            }
        }
    }
    if out.centre_coverage == 0 && groups.is_empty() {
        // Every sample ray slipped past a sub-pixel sliver the centre ray
        // hit (or missed everything): the centre's surface stands for the
        // whole pixel, as in the ground truth's fallback.
        return PixelSamples {
            missed: out.missed,
            ..PixelSamples::SMOOTH
        };
    }
    out.counted = out.centre_coverage;
    // Most samples first; ties by the first sample, so the order is a pure
    // function of the hits.
    groups.sort_by_key(|g| (std::cmp::Reverse(g.count), g.coverage.trailing_zeros()));
    for (k, g) in groups.iter().enumerate() {
        if k + 1 >= MAX_SURFACES {
            out.dropped |= g.coverage;
            continue;
        }
        out.counted |= g.coverage;
        match extra_surface(frame, x, y, g, pattern, light) {
            Some(surface) => out.extra.push(SampleSurface {
                surface,
                coverage: g.coverage,
            }),
            None => out.facing_away |= g.coverage,
        }
    }
    out
}

/// The µQuad of a group's plane, or `None` when the plane faces away from
/// the light (its samples are shadowed).
fn extra_surface(
    frame: &CameraFrame,
    x: u32,
    y: u32,
    group: &PlaneGroup,
    pattern: &[[f32; 2]; 32],
    light: &Light,
) -> Option<PixelSurface> {
    let normal = group.seed.normal;
    // The centroid of the group's sample offsets: a convex combination of
    // points whose rays meet the plane in front of the eye, so its own
    // ray does too (the directions meeting a plane in front form a half
    // plane of the image).
    let (mut su, mut sv) = (0.0, 0.0);
    for i in (0..32).filter(|i| group.coverage & (1 << i) != 0) {
        su += pattern[i][0] as f64;
        sv += pattern[i][1] as f64;
    }
    let n = group.count as f64;
    let (mut u, mut v) = (su / n, sv / n);
    let mut d = frame.direction(x as f64 + u, y as f64 + v);
    let mut t = normal.dot(group.seed.position) / normal.dot(d);
    if !(t > 0.0 && t.is_finite()) {
        // Rounding at a plane seen edge-on: anchor at the seed's own ray.
        let s = pattern[group.coverage.trailing_zeros() as usize];
        (u, v) = (s[0] as f64, s[1] as f64);
        d = frame.direction(x as f64 + u, y as f64 + v);
        t = group.seed.t;
    }
    let anchor = SurfaceHit {
        triangle: group.seed.triangle,
        t,
        position: d * t,
        normal,
    };
    if !faces_light(light, anchor.position, normal) {
        return None;
    }
    let (axis_x, axis_y, axes_clamped) = microquad_axes(frame, x as f64 + u, y as f64 + v, &anchor);
    // The same tangent frame, centred where the pixel centre's offsets
    // (½, ½) put it: the µQuad coordinates of every sample stay the
    // pattern's own, as for the centre's surface.
    let position = anchor.position + (0.5 - u) * axis_x + (0.5 - v) * axis_y;
    Some(PixelSurface {
        hit: SurfaceHit {
            triangle: group.seed.triangle,
            t: frame.view_depth(position),
            position,
            normal,
        },
        axis_x,
        axis_y,
        axes_clamped,
        shadow_tested: true,
    })
}
