//! The edge pixel's 32 sample rays: each traced against the triangles the
//! probes found first, then the BVH, and grouped by the plane it lands on.

use super::PixelSamples;
use crate::bvh::SceneBvh;
use crate::gbuffer::{facing_normal, PixelSurface, SurfaceHit};
use crate::scene::{CameraFrame, Scene};
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

/// The surfaces the sample rays of pixel (`x`, `y`) see (`pattern`, the
/// µQuad's sub-pixel offsets), given its shadow-tested centre surface and
/// its `probes` ([`super::neighbour_probes`]): the BVH's closest hits,
/// grouped by plane ([`super::group_sample_hits`]).
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
    let depth_range = (scene.camera.near, scene.camera.far);
    let probed = Probed::new(bvh, centre.hit.triangle, probes);
    let points = super::sample_points(x, y, pattern);
    let (hits, unbounded_rays) = sample_hits(bvh, frame, depth_range, probed.slice(), &points);
    let light = scene.light.relative_to(scene.camera.eye);
    let mut samples = super::group_sample_hits(frame, &light, (x, y), centre, &hits, pattern);
    samples.unbounded_rays = unbounded_rays;
    samples
}
