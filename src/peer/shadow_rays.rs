//! `rt32-rays`: the 32 µQuad sample rays of every shadow-tested pixel as
//! plain shadow rays — the ray-tracing peer a user with a GPU but without
//! ray-tracing cores would run (the H100 and H200 have none). The GPU pass
//! is `shaders/shadow_rays.comp` (any-hit BVH traversal with the G-buffer
//! pass's BVH and watertight triangle test, stopping at the first
//! occluder); this is its CPU twin, tracing the same rays with the CPU BVH
//! in `f64` ([`SceneBvh::any_hit`]). Embree traces the same rays
//! (`super::embree`, feature `embree`).
//!
//! A ray starts at sample S = P + (u − ½)·Ex + (v − ½)·Ey of the G-buffer's
//! µQuad, 2⁻⁸ µQuad along its way to the light (the scale of the IZB's own
//! depth tolerance), and for a point light stops as far before it. Unlike
//! `rt32` it does not apply the IZB's per-pixel depth rule: the two differ
//! where a neighbour meets the receiver (the sample mismatch against
//! `rt32` in `izb bench` says how often).

use crate::bvh::SceneBvh;
use crate::frustum::DEPTH_TOLERANCE_MICROQUAD;
use crate::gbuffer::{flags, GBuffer};
use crate::scene::{Light, Scene};
use glam::Vec3;
use rayon::prelude::*;

/// One shadow ray: origin, direction and the parameter interval
/// `(t_near, t_far)` along the direction.
#[derive(Clone, Copy, Debug)]
pub struct ShadowRay {
    pub origin: Vec3,
    pub direction: Vec3,
    pub t_near: f32,
    pub t_far: f32,
}

/// How far along its way to the light a sample's ray starts, for a µQuad
/// with axes `ex`, `ey`: 2⁻⁸ of its longer axis.
pub fn ray_offset(ex: Vec3, ey: Vec3) -> f32 {
    DEPTH_TOLERANCE_MICROQUAD as f32 * ex.length().max(ey.length())
}

/// The 32 shadow rays of a pixel with µQuad centre `p` and axes `ex`, `ey`
/// (eye-relative `f32`) toward `light` (eye-relative), in `pattern` order.
pub fn sample_rays(
    light: &Light,
    p: Vec3,
    ex: Vec3,
    ey: Vec3,
    pattern: &[[f32; 2]; 32],
) -> [ShadowRay; 32] {
    let offset = ray_offset(ex, ey);
    let origin = |s: [f32; 2]| p + (s[0] - 0.5) * ex + (s[1] - 0.5) * ey;
    // The light's case once per pixel, not per sample. This is the
    // definition `rt32-embree`'s packets reproduce lane by lane, bit for
    // bit (`RtcRay16::sample_rays`, feature `embree`).
    match *light {
        Light::Directional { direction } => {
            let direction = -direction.as_vec3();
            pattern.map(|s| ShadowRay {
                origin: origin(s),
                direction,
                t_near: offset,
                t_far: f32::INFINITY,
            })
        }
        Light::Point { position } => {
            let position = position.as_vec3();
            pattern.map(|s| {
                let origin = origin(s);
                // t in units of the sample-to-light vector.
                let to_light = position - origin;
                let reach = offset / to_light.length().max(f32::MIN_POSITIVE);
                ShadowRay {
                    origin,
                    direction: to_light,
                    t_near: reach,
                    t_far: 1.0 - reach,
                }
            })
        }
    }
}

/// The 32-sample masks of every pixel of `g` (0 where not shadow-tested),
/// `trace` turning one pixel's eye-relative light, µQuad centre and axes
/// into its mask (by [`sample_rays`] or lane by lane), pixels in parallel.
pub fn trace_pixels(
    scene: &Scene,
    g: &GBuffer,
    trace: impl Fn(&Light, Vec3, Vec3, Vec3) -> u32 + Sync,
) -> Vec<u32> {
    let light = scene.light.relative_to(scene.camera.eye);
    (0..g.flags.len())
        .into_par_iter()
        .with_min_len(256)
        .map(|i| {
            if g.flags[i] & flags::SHADOW_TESTED == 0 {
                return 0;
            }
            trace(&light, g.position[i], g.axis_x[i], g.axis_y[i])
        })
        .collect()
}

/// The 32-sample masks of every pixel of `g` from plain shadow rays traced
/// with `bvh` (0 where not shadow-tested): the CPU twin of
/// `shaders/shadow_rays.comp`.
pub fn shadow_rays(
    scene: &Scene,
    bvh: &SceneBvh,
    g: &GBuffer,
    pattern: &[[f32; 2]; 32],
) -> Vec<u32> {
    trace_pixels(scene, g, |light, p, ex, ey| {
        sample_rays(light, p, ex, ey, pattern)
            .iter()
            .enumerate()
            .fold(0, |mask, (k, r)| {
                let hit = bvh.any_hit(
                    r.origin.as_dvec3(),
                    r.direction.as_dvec3(),
                    f64::from(r.t_near),
                    f64::from(r.t_far),
                    |_| true,
                );
                mask | (u32::from(hit) << k)
            })
    })
}
