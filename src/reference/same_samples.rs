//! The same-sample reference (design §4, §8): exactly the 32 µQuad samples
//! of each pixel, traced in `f64` on the real geometry with the BVH.
//!
//! Sample S is shadowed iff some triangle other than the receiver's, lying
//! between the µQuad centre P and the light (the per-pixel depth test of
//! [`crate::izb::frustum::may_shadow`]), meets the *line* through S along
//! the light: for a directional light a ray started far behind S toward the
//! light, for a point light the ray from the light through S, not stopped
//! at S. That is "S lies in the triangle's shadow prism", the rule the IZB
//! evaluates with edge functions — so the two agree by construction, and
//! every disagreement is a bug or a sample within rounding of a boundary.

use super::bvh::SceneBvh;
use crate::gbuffer::pixel_surface;
use crate::izb::frustum::{may_shadow, LightRel};
use crate::scene::{Light, Scene};
use glam::DVec3;
use rayon::prelude::*;

/// The 32-sample masks of every pixel (0 where not shadow-tested).
pub fn same_sample_masks(scene: &Scene, bvh: &SceneBvh, pattern: &[[f32; 2]; 32]) -> Vec<u32> {
    let frame = scene.camera.frame(scene.resolution);
    let light = scene.light.relative_to(scene.camera.eye);
    // Where a directional light's line starts, behind every triangle: 2R
    // from the sample, R the scene's eye-relative radius (the BVH's
    // rounding padding assumes rays start within 3R of the eye).
    let (lo, hi) = scene.bounds();
    let far = 2.0
        * (lo - scene.camera.eye)
            .abs()
            .max(hi - scene.camera.eye)
            .length();
    let [w, h] = scene.resolution;
    (0..h)
        .into_par_iter()
        .flat_map_iter(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let Some(px) = pixel_surface(bvh, scene, &frame, x, y) else {
                return 0;
            };
            if !px.shadow_tested {
                return 0;
            }
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
                let sample = p + (s[0] as f64 - 0.5) * px.axis_x + (s[1] as f64 - 0.5) * px.axis_y;
                let (origin, dir): (DVec3, DVec3) = match light {
                    Light::Directional { direction } => (sample + direction * far, -direction),
                    Light::Point { position } => (position, sample - position),
                };
                if bvh.any_hit(origin, dir, 0.0, f64::INFINITY, occludes) {
                    mask |= 1 << i;
                }
            }
            mask
        })
        .collect()
}
