//! `rt-soft`: the same-sample reference of soft shadows
//! (paper-notes/soft-shadows.md) — at each pixel's µQuad centre P, exactly
//! the 32 light samples of the light pattern on the light's disk
//! ([`crate::scene::LightDisk`]), traced in `f64` on the real geometry
//! with the BVH.
//!
//! Light sample S is hidden when it lies below the receiver's tangent
//! plane, or when the ray from P toward it (a directional light's sample
//! is a direction; a sphere light's the segment to a point) meets a
//! triangle other than the receiver that passes the soft depth rule
//! ([`crate::frustum::soft::may_shadow_soft`]). That is what the IZB's
//! soft test evaluates with edge functions, so the two agree up to
//! samples within rounding of a boundary ([`soft_decision_margin`]), as
//! `rt32` and the hard IZB do. The area-light ground truth
//! ([`super::reference`]) judges both.

use crate::bvh::SceneBvh;
use crate::frustum::microquad_tolerance;
use crate::frustum::soft::may_shadow_soft;
use crate::gbuffer::{pixel_surface, PixelSurface};
use crate::scene::{Light, LightDisk, Scene};
use glam::DVec3;
use rayon::prelude::*;

/// The light's disk seen from `p` (eye-relative, `f64`), with whether its
/// samples are points at a finite distance. `light` must be eye-relative
/// and `radius` the scene's [`Scene::light_radius`] (> 0).
pub fn disk_from(light: &Light, radius: f64, p: DVec3) -> (LightDisk<DVec3>, bool) {
    let finite = matches!(light, Light::Point { .. });
    (light.disk_from(radius, p), finite)
}

/// The 32-light-sample masks of every pixel (0 where not shadow-tested),
/// bit i = light sample i of `pattern` hidden. With `paired_with` (the
/// µQuad pattern: [`crate::settings::SampleMode::Paired32`]) ray i starts
/// at µQuad sample i instead of P. The scene must have an area light.
pub fn soft_same_sample_masks(
    scene: &Scene,
    bvh: &SceneBvh,
    pattern: &[[f32; 2]; 32],
    paired_with: Option<&[[f32; 2]; 32]>,
) -> Vec<u32> {
    let frame = scene.camera.frame(scene.resolution);
    let light = scene.light.relative_to(scene.camera.eye);
    let [w, h] = scene.resolution;
    (0..h)
        .into_par_iter()
        .flat_map_iter(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| match pixel_surface(bvh, scene, &frame, x, y) {
            Some(px) if px.shadow_tested => {
                pixel_mask(bvh, &px, &light, scene.light_radius, pattern, paired_with)
            }
            _ => 0,
        })
        .collect()
}

fn pixel_mask(
    bvh: &SceneBvh,
    px: &PixelSurface,
    light: &Light,
    radius: f64,
    pattern: &[[f32; 2]; 32],
    paired_with: Option<&[[f32; 2]; 32]>,
) -> u32 {
    let p = px.hit.position;
    let normal = px.hit.normal;
    let size = px.axis_x.length().max(px.axis_y.length());
    let microquad_part = microquad_tolerance::<DVec3>(size);
    let (disk, finite) = disk_from(light, radius, p);
    let occludes_from = |id: u32, delta: DVec3| {
        let t = bvh.triangle(id).map(|v| v - p);
        id != px.hit.triangle
            && may_shadow_soft(&t, normal, microquad_part)
            && same_side_as_p(&t, delta)
    };
    let t_max = if finite { 1.0 } else { f64::INFINITY };
    let mut mask = 0u32;
    for (i, &uv) in pattern.iter().enumerate() {
        let delta = paired_with.map_or(DVec3::ZERO, |pixel| microquad_offset(px, pixel[i]));
        let toward = ray_toward(&disk, finite, uv, delta);
        // A unit direction and the distance as t_max: obvhs's f32 culling
        // dropped a hit 1.2 cm from the origin on the engine with the
        // unnormalised offset (|d| ≈ 629) as the direction, and found it
        // with the unit one.
        let length = toward.length();
        let occludes = |id: u32| occludes_from(id, delta);
        let hidden = normal.dot(toward) <= 0.0
            || bvh.any_hit(p + delta, toward / length, 0.0, t_max * length, occludes);
        if hidden {
            mask |= 1 << i;
        }
    }
    mask
}

/// Whether the ray origin P + `delta` lies strictly on P's side of the
/// plane of `t` (vertices minus P): a paired ray from beyond it starts, as
/// far as the µQuad can tell, inside that occluder, which does not shadow
/// it (the IZB's `paired_occluded_samples`). Always true from P.
fn same_side_as_p(t: &[DVec3; 3], delta: DVec3) -> bool {
    if delta == DVec3::ZERO {
        return true;
    }
    let m = (t[1] - t[0]).cross(t[2] - t[0]);
    let o = m.dot(t[0]);
    (o - delta.dot(m)) * o > 0.0
}

/// The offset from P of the µQuad sample at `uv`.
fn microquad_offset(px: &PixelSurface, uv: [f32; 2]) -> DVec3 {
    (uv[0] as f64 - 0.5) * px.axis_x + (uv[1] as f64 - 0.5) * px.axis_y
}

/// The ray from P + `delta` toward light sample `uv`: a direction for a
/// sun, the offset to the point for a sphere (t = 1 at the light).
fn ray_toward(disk: &LightDisk<DVec3>, finite: bool, uv: [f32; 2], delta: DVec3) -> DVec3 {
    let c = disk.sample(uv);
    if finite {
        c - delta
    } else {
        c
    }
}

/// How close light sample `uv` of pixel `px` is to flipping, relative to
/// the scale of its inputs: the smallest, over every triangle other than
/// the receiver, of the soft depth rule's margins (height above the
/// tangent plane and distance off the triangle's plane, minus the
/// tolerance, over the triangle's distance plus the µQuad size) and, for
/// triangles passing it, the sine of the angle between the ray's
/// direction and each edge plane through its origin (P, or µQuad sample
/// `paired_uv`) (and for a sphere light the
/// sample's distance to the triangle's plane over the scale); and the
/// sample's elevation above the horizon. Compare with
/// [`super::same_samples::FLOAT_DECISION_TOLERANCE`]. `f64`, brute force:
/// for the few samples where the IZB and [`soft_same_sample_masks`]
/// disagree.
pub fn soft_decision_margin(
    eye_relative_triangles: &[crate::scene::Triangle],
    px: &PixelSurface,
    light: &Light,
    radius: f64,
    uv: [f32; 2],
    paired_uv: Option<[f32; 2]>,
) -> f64 {
    use crate::frustum::{DEPTH_TOLERANCE_MICROQUAD, DEPTH_TOLERANCE_ROUNDING};
    let p = px.hit.position;
    let size = px.axis_x.length().max(px.axis_y.length());
    let (disk, finite) = disk_from(light, radius, p);
    let delta = paired_uv.map_or(DVec3::ZERO, |pixel| microquad_offset(px, pixel));
    let s = ray_toward(&disk, finite, uv, delta);
    let s_len = s.length();
    let mut margin = (px.hit.normal.dot(s) / s_len).abs();
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
        let off = (n.dot(t[0]) / n.length()).abs();
        margin = margin.min((height - tolerance).abs().min((off - tolerance).abs()) / scale);
        if paired_uv.is_some() {
            // The paired rule's side of the plane: S_i's distance to it.
            margin = margin.min((n.dot(t[0] - delta) / n.length()).abs() / scale);
        }
        if height > tolerance && off > tolerance {
            for k in 0..3 {
                let e = (t[k] - delta).cross(t[(k + 1) % 3] - delta);
                let len = e.length().max(f64::MIN_POSITIVE);
                margin = margin.min((e.dot(s) / (len * s_len)).abs());
            }
            if finite {
                margin = margin.min((n.dot(disk.sample(uv) - t[0]) / n.length()).abs() / scale);
            }
        }
    }
    margin
}
