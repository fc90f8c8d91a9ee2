//! The edge pixel's 32 sample rays: each traced against the triangles the
//! probes found first, then the BVH, and grouped by the plane it lands on.

use super::{PixelSamples, Plane, SampleSurface, MAX_SURFACES};
use crate::bvh::SceneBvh;
use crate::gbuffer::{faces_light, facing_normal, microquad_axes, PixelSurface, SurfaceHit};
use crate::scene::{CameraFrame, Light, Scene};
use glam::DVec3;

/// A triangle the sample rays are tested against before the BVH: its
/// camera-space edge normals `Vₐ × V_b` (a ray direction D meets the
/// triangle when the three `e·D` share a sign: the homogeneous
/// rasterisation of Olano & Greer 1997, the eye at the origin) and its
/// plane.
#[derive(Clone, Copy, Default)]
struct ProbedTriangle {
    id: u32,
    edges: [DVec3; 3],
    normal: DVec3,
    offset: f64,
}

impl ProbedTriangle {
    fn new(id: u32, t: &crate::scene::Triangle) -> ProbedTriangle {
        let normal = (t[1] - t[0]).cross(t[2] - t[0]);
        ProbedTriangle {
            id,
            edges: [t[0].cross(t[1]), t[1].cross(t[2]), t[2].cross(t[0])],
            normal,
            offset: normal.dot(t[0]),
        }
    }

    /// The ray parameter where direction `d` meets the triangle, if it does.
    #[inline]
    fn hit(&self, d: DVec3) -> Option<f64> {
        let e = self.edges.map(|e| e.dot(d));
        let inside = (e[0] >= 0.0 && e[1] >= 0.0 && e[2] >= 0.0)
            || (e[0] <= 0.0 && e[1] <= 0.0 && e[2] <= 0.0);
        let t = self.offset / self.normal.dot(d);
        (inside && t.is_finite()).then_some(t)
    }
}

/// The most triangles a pixel's sample rays test before the BVH: the
/// centre's and its eight neighbours'.
const MAX_PROBED: usize = 9;

/// The triangles tested before the BVH.
struct Probed {
    triangles: [ProbedTriangle; MAX_PROBED],
    count: usize,
}

impl Probed {
    /// The centre's triangle and the probes' (at most 9, without repeats).
    fn new(bvh: &SceneBvh, centre: u32, probes: &[Option<SurfaceHit>]) -> Probed {
        let mut probed = Probed {
            triangles: [ProbedTriangle::default(); MAX_PROBED],
            count: 0,
        };
        for id in std::iter::once(centre).chain(probes.iter().flatten().map(|h| h.triangle)) {
            probed.add(id, bvh);
        }
        probed
    }

    fn slice(&self) -> &[ProbedTriangle] {
        &self.triangles[..self.count]
    }

    fn add(&mut self, id: u32, bvh: &SceneBvh) {
        if self.count < MAX_PROBED && self.slice().iter().all(|p| p.id != id) {
            self.triangles[self.count] = ProbedTriangle::new(id, bvh.triangle(id));
            self.count += 1;
        }
    }
}

/// The nearest hit of direction `d` among the probed triangles within
/// (near, far), as (t, triangle).
fn probed_hit(probed: &[ProbedTriangle], d: DVec3, (near, far): (f64, f64)) -> Option<(f64, u32)> {
    let mut best: Option<(f64, u32)> = None;
    for tri in probed {
        if let Some(t) = tri.hit(d) {
            if t > near && t < far && best.is_none_or(|(b, _)| t < b) {
                best = Some((t, tri.id));
            }
        }
    }
    best
}

/// The primary hits of the rays through the image points `points`: the
/// BVH's closest hits within [near, far], found by one packet walk
/// ([`SceneBvh::closest_hits`]) whose rays are each bounded by the nearest
/// probed triangle they meet (every box behind it pruned). Also returns
/// the rays no probed triangle bounded.
fn sample_hits(
    bvh: &SceneBvh,
    frame: &CameraFrame,
    (near, far): (f64, f64),
    probed: &[ProbedTriangle],
    points: &[(f64, f64); 32],
) -> ([Option<SurfaceHit>; 32], u32) {
    let directions = points.map(|(px, py)| frame.direction(px, py));
    let probed_hits = directions.map(|d| probed_hit(probed, d, (near, far)));
    // A nearer triangle that no probe saw (a slat in front of the ground)
    // is still found; the probed hit itself is the fallback the bound's
    // rounding could drop.
    let bounds = probed_hits.map(|best| best.map_or(far, |(t, _)| (t * (1.0 + 1e-9)).min(far)));
    let mut traced = [None; 32];
    bvh.closest_hits(DVec3::ZERO, &directions, near, &bounds, &mut traced);
    let unbounded = probed_hits.iter().filter(|b| b.is_none()).count() as u32;
    let hits = std::array::from_fn(|i| {
        let d = directions[i];
        traced[i]
            .map(|h| (h.t, h.triangle))
            .or(probed_hits[i])
            .map(|(t, triangle)| SurfaceHit {
                triangle,
                t,
                position: d * t,
                normal: facing_normal(bvh.triangle(triangle), d),
            })
    });
    (hits, unbounded)
}

/// A group of sample hits on one plane.
struct PlaneGroup {
    seed: SurfaceHit,
    plane: Plane,
    coverage: u32,
    count: u32,
}

/// The surfaces the sample rays of pixel (`x`, `y`) see (`pattern`, the
/// µQuad's sub-pixel offsets), given its shadow-tested centre surface and
/// its `probes` ([`super::neighbour_probes`]).
#[allow(clippy::too_many_arguments)]
pub fn sample_surfaces(
    bvh: &SceneBvh,
    scene: &Scene,
    frame: &CameraFrame,
    x: u32,
    y: u32,
    centre: &PixelSurface,
    probes: &[Option<SurfaceHit>],
    pattern: &[[f32; 2]; 32],
) -> PixelSamples {
    let light = scene.light.relative_to(scene.camera.eye);
    let depth_range = (scene.camera.near, scene.camera.far);
    let centre_plane = Plane::of(&centre.hit, centre.axis_x, centre.axis_y);
    let probed = Probed::new(bvh, centre.hit.triangle, probes);
    let points = std::array::from_fn(|i| {
        let s = pattern[i];
        (x as f64 + s[0] as f64, y as f64 + s[1] as f64)
    });
    let (hits, unbounded_rays) = sample_hits(bvh, frame, depth_range, probed.slice(), &points);
    let mut out = PixelSamples {
        centre_coverage: 0,
        counted: 0,
        facing_away: 0,
        extra: Vec::new(),
        dropped: 0,
        missed: 0,
        unbounded_rays,
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
            unbounded_rays: out.unbounded_rays,
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
        match extra_surface(frame, x, y, g, pattern, &light) {
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
