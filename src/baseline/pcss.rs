//! Percentage-closer soft shadows (Fernando 2005), the soft-shadow peer of
//! the IZB under an area light: the `pcss-R` lookup on the same single map
//! the other filters read ([`super::shadow_map::shadow_map`]).
//!
//! Per shadow-tested pixel, in the map's light NDC (a directional light's
//! NDC is light-view units; a point light's is `x/z`, the image plane at
//! depth 1):
//!
//! 1. **Blocker search** over a disk whose radius is the light's size
//!    projected from the receiver toward the near end of the map's depth
//!    range: `tan r · (d_r − d_near)` for a directional light of angular
//!    radius `r` (`d_near` the highest scene vertex toward the light), and
//!    Fernando's similar triangles `R · (z_r − z_n) / (z_r · z_n)` for a
//!    sphere light of radius `R`, `z_n` the map's near plane (the
//!    rasteriser's clip, a thousandth of the nearest receiver's depth).
//!    [`BLOCKER_DISK`]'s 16 taps; a tap is a blocker when its texel is
//!    nearer than the receiver plane there by more than the PCF filters'
//!    constant bias (the receiver-plane depth bias of `pcf`). No blocker:
//!    fully lit.
//! 2. **Penumbra**: with `d_b` the blockers' mean distance, the penumbra
//!    is `2 tan r · (d_r − d_b)` wide (directional) or `2R · (d_r − d_b) /
//!    d_b` (point, in world units at the receiver; divided by `d_r` in
//!    NDC); the filter radius is half of it.
//! 3. **Filter**: [`FILTER_DISK`]'s 32 taps scaled to that radius, the
//!    lit fraction the share of taps whose texel does not shadow the
//!    receiver plane.
//!
//! Both radii are clamped to `[1, MAX_RADIUS_TEXELS]` texels of the map's
//! finer axis. The floor keeps the filter a filter: with `light_radius ==
//! 0` (a hard light) the penumbra is 0 and PCSS degrades to a 32-tap PCF
//! of one texel's radius, a smoothed one-tap lookup, not a refusal. The cap
//! is explained at [`izb_contract::pcss::MAX_RADIUS_TEXELS`]: 32 fixed
//! taps over a wider disk step over whole occluders, and the map keeps that
//! many texels of margin ([`super::Filter::reach`]). The tap pattern is
//! the same for every pixel (no per-pixel rotation): the result is
//! deterministic and the GPU twin (`shaders/pcss.glsl`) repeats it
//! operation for operation; the price is some banding in wide penumbrae.

use super::shadow_map::{
    light_distance, plane_distance, texel_world, CascadeMap, CONSTANT_BIAS_TEXELS,
};
use crate::cpu::light_setup::{directional_rotation, LightSetup, Projection};
use crate::scene::{Light, Scene};
use glam::{Vec2, Vec3};
use izb_contract::pcss::{FILTER_TAPS, MAX_RADIUS_TEXELS};
pub use izb_contract::pcss_taps::{BLOCKER_DISK, FILTER_DISK};

/// The light as PCSS needs it, computed once per frame on the host for
/// both twins (the GPU gets it in `FrameParams::map_light_size` and
/// `map_near`), so both use the same bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct PcssLight {
    /// tan r for a directional light of angular radius r, the radius of a
    /// point light; 0 for a hard light.
    pub size: f32,
    /// Directional light: the largest `z · v` over the scene's
    /// eye-relative vertices `v`, `z` the light view's unit axis toward
    /// the light (the near end of the map's depth range; a receiver at
    /// `position` lies `near − z · position` below it). 0 for a point
    /// light.
    pub near: f32,
}

impl PcssLight {
    /// The light of `scene` over its eye-relative `f32` vertices.
    pub fn new(scene: &Scene, vertices: impl IntoIterator<Item = Vec3>) -> PcssLight {
        match scene.light {
            Light::Directional { direction } => {
                let toward = directional_rotation(direction).row(2);
                let near = vertices
                    .into_iter()
                    .map(|v| toward.dot(v))
                    .fold(f32::NEG_INFINITY, f32::max);
                PcssLight {
                    size: scene.light.disk_radius(scene.light_radius) as f32,
                    near: if near.is_finite() { near } else { 0.0 },
                }
            }
            Light::Point { .. } => PcssLight {
                size: scene.light_radius as f32,
                near: 0.0,
            },
        }
    }
}

/// The receiver plane's distance at texel (x, y)'s centre, never beyond the
/// receiver itself (the `pcf` filter's receiver-plane bias).
#[inline]
fn receiver_at(
    map: &CascadeMap,
    projection: Projection,
    (x, y): (i32, i32),
    p: Vec3,
    n: Vec3,
) -> f32 {
    let own = light_distance(projection, p);
    plane_distance(projection, map.texel_centre(x, y), p, n).map_or(own, |d| d.min(own))
}

/// PCSS lit fraction of the receiver at eye-relative `position` (light
/// view `p`, light-view normal `n`, light NDC `ndc`) in `map`.
pub(super) fn pcss(
    setup: &LightSetup,
    light: &PcssLight,
    map: &CascadeMap,
    position: Vec3,
    p: Vec3,
    n: Vec3,
    ndc: Vec2,
) -> f32 {
    let projection = setup.projection;
    let own = light_distance(projection, p);
    let bias = texel_world(map, projection, p) * CONSTANT_BIAS_TEXELS;
    let t = map.texel_coords(ndc);
    let finer = map.texel_ndc.min_element();
    let cap = finer * MAX_RADIUS_TEXELS as f32;
    // 1. Blocker search: the light projected from the receiver onto the
    // near end of the depth range (Fernando 2005, eq. 1's similar
    // triangles).
    let search = match projection {
        Projection::Orthographic => {
            let span = light.near - setup.rotation.row(2).dot(position);
            light.size * span.max(0.0)
        }
        Projection::Perspective => {
            let zn = setup.receiver_z[0] * izb_contract::tolerance::MAP_NEAR_RATIO;
            light.size * (p.z - zn) / (p.z * zn)
        }
    };
    let search = search.max(finer).min(cap);
    let scale = Vec2::splat(search) / map.texel_ndc;
    let (mut sum, mut count) = (0.0f32, 0u32);
    for tap in BLOCKER_DISK {
        let s = t + Vec2::from(tap) * scale;
        let texel = map.texel_of(s.floor());
        let stored = map.at(texel.0, texel.1);
        if stored == f32::INFINITY {
            continue;
        }
        let receiver = receiver_at(map, projection, texel, p, n);
        if stored + bias < receiver {
            sum += stored;
            count += 1;
        }
    }
    if count == 0 {
        return 1.0;
    }
    let blocker = sum / count as f32;
    // 2. Penumbra half-width (Fernando 2005, eq. 2), in light NDC.
    let radius = match projection {
        Projection::Orthographic => light.size * (own - blocker),
        Projection::Perspective => light.size * (own - blocker) / (blocker * own),
    };
    let radius = radius.max(finer).min(cap);
    // 3. Percentage-closer filter over that disk.
    let scale = Vec2::splat(radius) / map.texel_ndc;
    let mut lit = 0u32;
    for tap in FILTER_DISK {
        let s = t + Vec2::from(tap) * scale;
        let texel = map.texel_of(s.floor());
        let stored = map.at(texel.0, texel.1);
        if stored == f32::INFINITY {
            lit += 1;
            continue;
        }
        let receiver = receiver_at(map, projection, texel, p, n);
        lit += (receiver <= stored + bias) as u32;
    }
    lit as f32 / FILTER_TAPS as f32
}
