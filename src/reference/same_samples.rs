//! The same-sample reference (paper-notes/frustum-test.md, §8): exactly the 32 µQuad samples
//! of each pixel, traced in `f64` on the real geometry with the BVH.
//!
//! Sample S is shadowed iff some triangle other than the receiver's, lying
//! between the µQuad centre P and the light (the per-pixel depth test of
//! [`crate::frustum::may_shadow`]), meets the *line* through S along
//! the light: for a directional light a ray started far behind S toward the
//! light, for a point light the ray from the light through S, not stopped
//! at S. That is "S lies in the triangle's shadow prism", the rule the IZB
//! evaluates with edge functions — so the two agree by construction, and
//! every disagreement is a bug or a sample within rounding of a boundary.
//!
//! Sharing the depth rule with the IZB is intended: this reference judges
//! the IZB's *visibility* (which samples a triangle's prism covers, found
//! through a BVH instead of the grid, in `f64`), not its choice of which
//! triangles may shadow P; that rule lives once, in [`crate::frustum`],
//! below both. The supersampled ground truth (`super::reference`) uses no
//! such rule and judges both.

use crate::bvh::SceneBvh;
use crate::frustum::{may_shadow, LightRel};
use crate::gbuffer::edge_surfaces::{self, PixelSamples};
use crate::gbuffer::{pixel_surface, trace_primary, PixelSurface};
use crate::scene::{Light, Scene};
use glam::DVec3;
use rayon::prelude::*;

/// A full 32-sample mask.
const FULL: u32 = u32::MAX;

/// Where a directional light's line starts, behind every triangle: 2R
/// from the sample, R the scene's eye-relative radius (the BVH's rounding
/// padding assumes rays start within 3R of the eye).
fn line_start_distance(scene: &Scene) -> f64 {
    let (lo, hi) = scene.bounds();
    2.0 * (lo - scene.camera.eye)
        .abs()
        .max(hi - scene.camera.eye)
        .length()
}

/// The samples of `samples` (bit i: pattern sample i) that the shadow rule
/// darkens on the µQuad of `px`.
fn surface_mask(
    bvh: &SceneBvh,
    light: Light,
    far: f64,
    px: &PixelSurface,
    samples: u32,
    pattern: &[[f32; 2]; 32],
) -> u32 {
    let p = px.hit.position;
    let size = px.axis_x.length().max(px.axis_y.length());
    let rel = match light {
        Light::Directional { direction } => LightRel::Toward(-direction),
        Light::Point { position } => LightRel::At(position - p),
    };
    let occludes = |id: u32| {
        id != px.hit.triangle
            && may_shadow(&bvh.triangle(id).map(|v| v - p), px.hit.normal, size, rel)
    };
    let mut mask = 0u32;
    for (i, s) in pattern.iter().enumerate() {
        if samples & (1 << i) == 0 {
            continue;
        }
        let sample = p + (s[0] as f64 - 0.5) * px.axis_x + (s[1] as f64 - 0.5) * px.axis_y;
        // A line from beyond every triangle to the sample: from the light,
        // or `far` from the sample toward it when the light is farther (the
        // BVH's rounding bound holds for origins within 3R of the eye; a
        // point light 10⁴ radii away made this reference miss and invent
        // occluders, linearly in its distance).
        let (origin, dir): (DVec3, DVec3) = match light {
            Light::Directional { direction } => (sample + direction * far, -direction),
            Light::Point { position } => {
                let to_light = position - sample;
                let distance = to_light.length();
                let origin = if distance > far {
                    sample + to_light * (far / distance)
                } else {
                    position
                };
                (origin, sample - origin)
            }
        };
        if bvh.any_hit(origin, dir, 0.0, f64::INFINITY, occludes) {
            mask |= 1 << i;
        }
    }
    mask
}

/// The 32-sample masks of every pixel (0 where not shadow-tested), every
/// sample on the pixel centre's µQuad.
pub fn same_sample_masks(scene: &Scene, bvh: &SceneBvh, pattern: &[[f32; 2]; 32]) -> Vec<u32> {
    let frame = scene.camera.frame(scene.resolution);
    let light = scene.light.relative_to(scene.camera.eye);
    let far = line_start_distance(scene);
    let [w, h] = scene.resolution;
    (0..h)
        .into_par_iter()
        .flat_map_iter(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| match pixel_surface(bvh, scene, &frame, x, y) {
            Some(px) if px.shadow_tested => surface_mask(bvh, light, far, &px, FULL, pattern),
            _ => 0,
        })
        .collect()
}

/// Same-sample masks with edge pixels' samples each on its own surface
/// ([`crate::gbuffer::edge_surfaces`]), as the IZB tests them.
#[derive(Clone, Debug)]
pub struct EdgeSameSampleMasks {
    /// Shadowed samples per pixel (0 where not shadow-tested).
    pub masks: Vec<u32>,
    /// The samples that count per pixel (all where not shadow-tested).
    pub counted: Vec<u32>,
}

/// [`same_sample_masks`] with per-sample surfaces: the same probes, sample
/// rays and surfaces as the G-buffer ([`crate::gbuffer::gbuffer_with`]),
/// each surface's covered samples traced on its own µQuad, samples on a
/// surface facing away shadowed.
pub fn edge_same_sample_masks(
    scene: &Scene,
    bvh: &SceneBvh,
    pattern: &[[f32; 2]; 32],
) -> EdgeSameSampleMasks {
    let frame = scene.camera.frame(scene.resolution);
    let light = scene.light.relative_to(scene.camera.eye);
    let far = line_start_distance(scene);
    let [w, h] = scene.resolution;
    let (masks, counted) = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let Some((px, samples)) = pixel_samples_at(bvh, scene, &frame, x, y, pattern) else {
                return (0, FULL);
            };
            let mut mask = samples.facing_away
                | surface_mask(bvh, light, far, &px, samples.centre_coverage, pattern);
            for e in &samples.extra {
                mask |= surface_mask(bvh, light, far, &e.surface, e.coverage, pattern);
            }
            (mask, samples.counted)
        })
        .unzip();
    EdgeSameSampleMasks { masks, counted }
}

/// The centre surface of pixel (`x`, `y`) and what its sample rays see
/// ([`edge_surfaces::sample_surfaces`] when its neighbours make it an edge
/// candidate), as the G-buffer finds them; `None` where the pixel is not
/// shadow-tested.
pub fn pixel_samples_at(
    bvh: &SceneBvh,
    scene: &Scene,
    frame: &crate::scene::CameraFrame,
    x: u32,
    y: u32,
    pattern: &[[f32; 2]; 32],
) -> Option<(PixelSurface, PixelSamples)> {
    let px = pixel_surface(bvh, scene, frame, x, y).filter(|p| p.shadow_tested)?;
    let (near, far) = (scene.camera.near, scene.camera.far);
    let (probes, n) = edge_surfaces::neighbour_probes(x, y, scene.resolution, |nx, ny| {
        trace_primary(bvh, frame, near, far, nx as f64 + 0.5, ny as f64 + 0.5)
    });
    let probes = &probes[..n];
    let samples = if edge_surfaces::is_edge_candidate(&px, probes) {
        edge_surfaces::sample_surfaces(bvh, scene, frame, x, y, &px, probes, pattern)
    } else {
        PixelSamples::SMOOTH
    };
    Some((px, samples))
}

/// Relative float tolerance of the IZB's `f32` decisions: a sample whose
/// decision margin (see [`decision_margin`]) is below this fraction of the
/// scale of the quantities involved may be classified either way by an
/// `f32` evaluation (2⁻¹⁶ = 128 ε₃₂: the light-view rotation, the
/// subtraction of P and two cross products each round once or twice).
pub const FLOAT_DECISION_TOLERANCE: f64 = 1.0 / 65536.0;

/// How close sample `uv` of the pixel `px` is to flipping: over every
/// triangle other than the receiver, the smallest relative margin among the
/// conditions of the shadow rule — the two per-pixel depth conditions of
/// [`may_shadow`] (distance above the tangent plane and beyond the triangle
/// plane, minus the tolerance; the latter divided by the plane's condition,
/// reach over the triangle's smallest height) and, for triangles passing
/// them, the signed distance of the sample to each side plane — each
/// divided by the scale of its inputs (the triangle's distance from P plus
/// the µQuad size).
/// A sample with a margin below [`FLOAT_DECISION_TOLERANCE`] lies within
/// float rounding of a shadow boundary. `f64`, brute force: meant for the
/// few samples where the IZB and this reference disagree.
pub fn decision_margin(
    eye_relative_triangles: &[crate::scene::Triangle],
    px: &crate::gbuffer::PixelSurface,
    light: &Light,
    uv: [f32; 2],
) -> f64 {
    sample_margins(eye_relative_triangles, px, light, uv).decision
}

/// How far sample `uv` of the pixel `px` lies from the nearest edge of a
/// triangle that passes the per-pixel depth test, in µQuad side lengths
/// (the unit of the LUT's misclassification bound,
/// [`crate::lut::EdgeLut::misclassification_bound`]): a sample LUT mode
/// gets wrong must lie within that bound of some such edge (Wyman et al.
/// 2015, §4). Infinite when no triangle passes. `f64`, brute force.
pub fn nearest_edge_distance(
    eye_relative_triangles: &[crate::scene::Triangle],
    px: &crate::gbuffer::PixelSurface,
    light: &Light,
    uv: [f32; 2],
) -> f64 {
    sample_margins(eye_relative_triangles, px, light, uv).nearest_edge
}

/// What [`decision_margin`] and [`nearest_edge_distance`] report.
struct SampleMargins {
    decision: f64,
    nearest_edge: f64,
}

fn sample_margins(
    eye_relative_triangles: &[crate::scene::Triangle],
    px: &crate::gbuffer::PixelSurface,
    light: &Light,
    uv: [f32; 2],
) -> SampleMargins {
    use crate::frustum::{edge_functions, DEPTH_TOLERANCE_MICROQUAD, DEPTH_TOLERANCE_ROUNDING};
    let p = px.hit.position;
    let size = px.axis_x.length().max(px.axis_y.length());
    let rel = match *light {
        Light::Directional { direction } => LightRel::Toward(-direction),
        Light::Point { position } => LightRel::At(position - p),
    };
    let (du, dv) = (uv[0] as f64 - 0.5, uv[1] as f64 - 0.5);
    let mut margins = SampleMargins {
        decision: f64::INFINITY,
        nearest_edge: f64::INFINITY,
    };
    for (id, tri) in eye_relative_triangles.iter().enumerate() {
        if id as u32 == px.hit.triangle {
            continue;
        }
        let t = tri.map(|v| v - p);
        let reach = t.iter().map(|v| v.length()).fold(0.0, f64::max);
        let scale = reach + size;
        let tolerance = DEPTH_TOLERANCE_MICROQUAD * size + DEPTH_TOLERANCE_ROUNDING * reach;
        let height = t
            .iter()
            .map(|v| px.hit.normal.dot(*v))
            .fold(f64::NEG_INFINITY, f64::max);
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        let facing = match rel {
            LightRel::Toward(w) => n.dot(w),
            LightRel::At(l) => n.dot(l - t[0]),
        };
        let beyond = if facing == 0.0 {
            f64::NEG_INFINITY
        } else {
            n.dot(t[0]) * facing.signum() / n.length() - tolerance
        };
        let depth = (height - tolerance).min(beyond);
        // The plane's orientation is only as good as its vertices: moving
        // one by δ turns the normal by δ / h, h the triangle's smallest
        // height, so P's distance to the plane moves by reach · δ / h. A
        // sliver (h → 0) makes the `f32` plane test a coin toss however far
        // P lies from its plane (fuzz_extremes seed 1796324431 case 42492:
        // a 1.6e-6 sliver, P 0.035 on the lit side in `f64`, beyond it in
        // `f32`, the sample's shadow ray within 10⁻⁷ of the sliver).
        let longest = (0..3)
            .map(|k| (t[(k + 1) % 3] - t[k]).length())
            .fold(0.0, f64::max);
        let plane_condition = (longest * reach / n.length()).max(1.0);
        let beyond_margin = if plane_condition.is_finite() {
            beyond.abs() / plane_condition
        } else {
            0.0
        };
        let depth_margin = (height - tolerance).abs().min(beyond_margin) / scale;
        margins.decision = margins.decision.min(depth_margin);
        if depth > 0.0 {
            for e in edge_functions(&t, px.axis_x, px.axis_y, rel) {
                let len = (e[1] * e[1] + e[2] * e[2]).sqrt().max(f64::MIN_POSITIVE);
                // The side plane's normal scales with the edge length and
                // the light vector: normalised by its component in the
                // µQuad plane, f / len is a distance in µQuad sides.
                let g = (e[0] + e[1] * du + e[2] * dv) / len;
                margins.decision = margins.decision.min((g * size).abs() / scale);
                margins.nearest_edge = margins.nearest_edge.min(g.abs());
            }
        }
    }
    margins
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gbuffer::{PixelSurface, SurfaceHit};
    use glam::DVec3;

    /// The receiver and light of fuzz_extremes seed 1796324431 case 42492
    /// (eye-relative): a ground pixel under a nearby point light.
    fn receiver() -> (PixelSurface, Light) {
        let surface = PixelSurface {
            hit: SurfaceHit {
                triangle: 0,
                t: 14.73,
                position: DVec3::new(-6.531249043503523, -9.688767545307696, -8.989857112544167),
                normal: DVec3::new(
                    0.062352163717679335,
                    0.9962227848399421,
                    -0.06043484628485583,
                ),
            },
            axis_x: DVec3::new(
                0.7168240245463586,
                -0.08048706386948644,
                -0.5872029161636574,
            ),
            axis_y: DVec3::new(0.8194609165493408, 0.019846873303613722, 1.1726193244173757),
            axes_clamped: false,
            shadow_tested: true,
        };
        let position = DVec3::new(-4.280338887881931, -7.036175447205654, -12.155432424403351);
        (surface, Light::Point { position })
    }

    /// The case's sliver (smallest height 1.6e-6 of its longest edge): P
    /// lies 0.035 on its lit side in `f64`, but the plane of its `f32`
    /// vertices may put P beyond it, and sample 31's shadow ray passes
    /// within 10⁻⁷ of it. Its depth decision is within rounding; a
    /// well-shaped triangle in the same place keeps a decisive margin.
    #[test]
    fn a_slivers_plane_test_is_within_rounding_a_solid_triangles_is_not() {
        let (surface, light) = receiver();
        let sliver = [
            DVec3::new(-5.626588715247192, -9.510462705746166, -9.41483580391088),
            DVec3::new(-6.07053075572526, -9.307626701385644, -9.240222410082115),
            DVec3::new(-5.880698220307198, -9.394359870257654, -9.31488839045719),
        ];
        let sample_31 = [0.984375, 0.734375];
        let margin = decision_margin(&[sliver, sliver], &surface, &light, sample_31);
        assert!(
            margin < FLOAT_DECISION_TOLERANCE,
            "sliver margin {margin:e}"
        );
        // The same triangle with its third vertex 0.2 off the line, moved
        // 0.3 aside so that no edge passes near the sample's ray.
        let mut solid = sliver.map(|v| v + DVec3::new(0.0, 0.0, 0.3));
        solid[2] += DVec3::new(0.2, 0.0, 0.0);
        let margin = decision_margin(&[solid, solid], &surface, &light, sample_31);
        assert!(
            margin > 100.0 * FLOAT_DECISION_TOLERANCE,
            "solid margin {margin:e}"
        );
    }
}
