//! The two passes of a shadow map (Williams 1978, Reeves et al. 1987; [Shadow acne notes], [Shadow mapping mechanics], Agenjo 2020: paper-notes/references.md): `shadow_map`
//! rasterises every triangle's distance to the light into one map per
//! cascade, `shadow_lookup` compares each shadow-tested pixel against it.
//!
//! The maps live in the IZB's own light view ([`LightSetup`]): the same
//! rotation, the same receiver-fitted light-NDC bounds per cascade (a
//! sample-distribution fit), so the baselines lose nothing to a looser fit
//! than the IZB gets. A map texel is a square of light NDC; its stored value
//! is the distance to the light (`-z` for a directional light, whose view
//! `+z` points at it; `z` along a point light's axis) of the nearest surface
//! through the texel centre: smaller is nearer the light.

use crate::gbuffer::{flags, GBuffer};
// The GLSL twin's order-preserving float bits (for `fetch_min`).
use crate::cpu::light_setup::{CascadeGrid, LightSetup, Projection};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};

/// How the map is filtered at lookup.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Filter {
    /// One texel, slope-scaled bias ([Shadow mapping mechanics]).
    OneTap,
    /// `k`×`k` bilinear taps (each a Gather-style 2×2 with its own
    /// comparison depth), receiver-plane depth bias ([Shadow acne notes]).
    Pcf(u32),
    /// Percentage-closer soft shadows (Fernando 2005): blocker search,
    /// penumbra estimate, Poisson-disk PCF of that width
    /// ([`super::pcss`]).
    Pcss,
}

impl Filter {
    /// Texels a lookup reaches beyond the one it lands in.
    pub fn reach(self) -> u32 {
        match self {
            Filter::OneTap => 0,
            Filter::Pcf(k) => k / 2 + 1,
            Filter::Pcss => izb_contract::pcss::MAX_RADIUS_TEXELS,
        }
    }
}

/// Slope-scaled bias of the one-tap lookup, in texel widths: the
/// receiver's depth changes by `texel · tanθ` per texel (θ between normal
/// and light), and a lookup lands up to half a texel diagonal (0.71) from
/// the centre the texel's depth was taken at. [Shadow mapping mechanics] scales with
/// `1 − N·L`, which stays bounded where the real error grows without bound;
/// `tanθ` is the slope factor of Vulkan's `depthBiasSlopeFactor`.
pub const SLOPE_BIAS_TEXELS: f32 = 1.0;
/// Largest `tanθ` the slope bias follows (84°): beyond it the bias would
/// detach every shadow from its caster (peter-panning), so grazing
/// receivers keep some acne, as in every engine.
pub const MAX_BIAS_SLOPE: f32 = 10.0;
/// Constant bias, in texel widths, on top of either bias: the
/// quantisation of the stored depth to the texel centre's plane and the
/// curvature of a receiver across one texel.
pub const CONSTANT_BIAS_TEXELS: f32 = 0.1;

/// One cascade's map: `side`² distances, row-major, `+∞` where nothing was
/// drawn.
pub struct CascadeMap {
    pub side: u32,
    /// Light-NDC corner of texel (0, 0) and the NDC size of one texel.
    pub ndc_origin: Vec2,
    pub texel_ndc: Vec2,
    pub distance: Vec<f32>,
}

impl CascadeMap {
    /// Continuous texel coordinates of a light-NDC point.
    #[inline]
    pub fn texel_coords(&self, ndc: Vec2) -> Vec2 {
        (ndc - self.ndc_origin) / self.texel_ndc
    }

    /// Light NDC of the centre of texel (x, y).
    #[inline]
    pub fn texel_centre(&self, x: i32, y: i32) -> Vec2 {
        self.ndc_origin + (Vec2::new(x as f32, y as f32) + 0.5) * self.texel_ndc
    }

    /// The integer texel of floored texel coordinates: clamped to one
    /// texel beyond the map (so any coordinate outside reads as outside),
    /// NaN to (−1, −1). The GPU twin converts exactly so.
    #[inline]
    pub fn texel_of(&self, floored: Vec2) -> (i32, i32) {
        if floored.is_nan() {
            return (-1, -1);
        }
        let c = floored.clamp(Vec2::splat(-1.0), Vec2::splat(self.side as f32));
        (c.x as i32, c.y as i32)
    }

    /// Stored distance of texel (x, y); `+∞` (lit) outside the map.
    #[inline]
    pub fn at(&self, x: i32, y: i32) -> f32 {
        let s = self.side as i32;
        if x < 0 || y < 0 || x >= s || y >= s {
            f32::INFINITY
        } else {
            self.distance[(y * s + x) as usize]
        }
    }
}

/// Every cascade's map of one frame.
pub struct ShadowMaps {
    pub maps: Vec<CascadeMap>,
    /// Triangles drawn (after clipping to a point light's near plane) and
    /// texels written.
    pub triangles_drawn: usize,
    pub texels_written: u64,
}

impl ShadowMaps {
    /// Bytes of map storage (4 per texel).
    pub fn bytes(&self) -> u64 {
        self.maps.iter().map(|m| m.distance.len() as u64 * 4).sum()
    }
}

/// Distance to the light of a light-view point: smaller is nearer.
#[inline]
pub(super) fn light_distance(projection: Projection, p: Vec3) -> f32 {
    match projection {
        Projection::Orthographic => -p.z,
        Projection::Perspective => p.z,
    }
}

/// Light-view direction of the light ray through light NDC `n`, scaled so
/// that the distance along it is [`light_distance`].
#[inline]
fn ray_direction(projection: Projection, n: Vec2) -> (Vec3, Vec3) {
    match projection {
        // Origin on the z = 0 plane, travelling away from the light.
        Projection::Orthographic => (Vec3::new(n.x, n.y, 0.0), Vec3::NEG_Z),
        Projection::Perspective => (Vec3::ZERO, Vec3::new(n.x, n.y, 1.0)),
    }
}

/// Distance to the light where the light ray through `n` meets the plane
/// through `point` with normal `normal` (light view); `None` when the ray
/// runs along the plane.
#[inline]
pub(super) fn plane_distance(
    projection: Projection,
    n: Vec2,
    point: Vec3,
    normal: Vec3,
) -> Option<f32> {
    let (origin, dir) = ray_direction(projection, n);
    let denom = normal.dot(dir);
    let t = normal.dot(point - origin) / denom;
    t.is_finite().then_some(t)
}

/// The square map of `grid` at `side`² texels, grown by `reach` texels on
/// every side so a filtered lookup at the fitted bounds still reads drawn
/// texels.
fn cascade_frame(grid: &CascadeGrid, side: u32, reach: u32) -> CascadeMap {
    let extent = grid.ndc_max - grid.ndc_min;
    let inner = (side as f32 - 2.0 * reach as f32).max(1.0);
    let texel_ndc = extent / inner;
    CascadeMap {
        side,
        ndc_origin: grid.ndc_min - texel_ndc * reach as f32,
        texel_ndc,
        distance: Vec::new(),
    }
}

/// Clips a light-view triangle to `z >= near` (point lights: only what is
/// in front of the light projects); up to four vertices.
fn clip_to_near(tri: [Vec3; 3], near: f32) -> Vec<Vec3> {
    let mut out = Vec::with_capacity(4);
    for i in 0..3 {
        let (a, b) = (tri[i], tri[(i + 1) % 3]);
        let (da, db) = (a.z - near, b.z - near);
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            out.push(a + (b - a) * (da / (da - db)));
        }
    }
    out
}

/// Pass `shadow_map`: every triangle (eye-relative `f32`) drawn into every
/// cascade's `side`² map (texel centres inside the projected triangle take
/// the triangle plane's distance there, clamped to its vertices' range:
/// nearest wins).
pub fn shadow_map(
    setup: &LightSetup,
    triangles: &[[Vec3; 3]],
    side: u32,
    filter: Filter,
) -> ShadowMaps {
    let texels = side as usize * side as usize;
    let mut maps: Vec<CascadeMap> = setup
        .cascades
        .iter()
        .map(|g| cascade_frame(g, side, filter.reach()))
        .collect();
    let atomic: Vec<Vec<AtomicU32>> = maps
        .iter()
        .map(|_| {
            (0..texels)
                .into_par_iter()
                .map(|_| AtomicU32::new(u32::MAX))
                .collect()
        })
        .collect();
    let projection = setup.projection;
    // Point lights: geometry nearer than a thousandth of the nearest
    // receiver's depth cannot project into a finite map.
    let near = setup.receiver_z[0] * 1e-3;
    let counts = triangles
        .par_iter()
        .map(|tri| {
            let view = tri.map(|v| setup.to_light_view(v));
            let polygon = match projection {
                Projection::Orthographic => view.to_vec(),
                Projection::Perspective => clip_to_near(view, near),
            };
            if polygon.len() < 3 {
                return (0usize, 0u64);
            }
            let normal = (view[1] - view[0]).cross(view[2] - view[0]);
            let (dmin, dmax) = view
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |a, &p| {
                    let d = light_distance(projection, p);
                    (a.0.min(d), a.1.max(d))
                });
            let mut written = 0u64;
            for (map, depth) in maps.iter().zip(&atomic) {
                for k in 1..polygon.len() - 1 {
                    let fan = [polygon[0], polygon[k], polygon[k + 1]];
                    written +=
                        draw_triangle(map, depth, projection, fan, view[0], normal, (dmin, dmax));
                }
            }
            (1, written)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    for (map, depth) in maps.iter_mut().zip(atomic) {
        map.distance = depth
            .into_par_iter()
            .map(|a| {
                let o = a.into_inner();
                if o == u32::MAX {
                    f32::INFINITY
                } else {
                    from_ordered_bits(o)
                }
            })
            .collect();
    }
    ShadowMaps {
        maps,
        triangles_drawn: counts.0,
        texels_written: counts.1,
    }
}

/// Draws one (clipped) light-view triangle into `map`; returns texels
/// written.
fn draw_triangle(
    map: &CascadeMap,
    depth: &[AtomicU32],
    projection: Projection,
    fan: [Vec3; 3],
    plane_point: Vec3,
    plane_normal: Vec3,
    (dmin, dmax): (f32, f32),
) -> u64 {
    let ndc = |p: Vec3| match projection {
        Projection::Orthographic => Vec2::new(p.x, p.y),
        Projection::Perspective => Vec2::new(p.x / p.z, p.y / p.z),
    };
    let t = fan.map(|p| map.texel_coords(ndc(p)));
    let area = (t[1] - t[0]).perp_dot(t[2] - t[0]);
    if !area.is_finite() || area == 0.0 {
        return 0; // edge-on to the light: covers no texel centre
    }
    let lo = t[0].min(t[1]).min(t[2]);
    let hi = t[0].max(t[1]).max(t[2]);
    let side = map.side as f32;
    if hi.x < 0.0 || hi.y < 0.0 || lo.x > side || lo.y > side {
        return 0;
    }
    // Texel centres (x + 0.5) inside [lo, hi].
    let x0 = (lo.x - 0.5).ceil().max(0.0) as i32;
    let y0 = (lo.y - 0.5).ceil().max(0.0) as i32;
    let x1 = (hi.x - 0.5).floor().min(side - 1.0) as i32;
    let y1 = (hi.y - 0.5).floor().min(side - 1.0) as i32;
    let sign = area.signum();
    let mut written = 0;
    for y in y0..=y1 {
        for x in x0..=x1 {
            let c = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let inside = (0..3).all(|e| {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                sign * (b - a).perp_dot(c - a) >= 0.0
            });
            if !inside {
                continue;
            }
            let n = map.texel_centre(x, y);
            let d = plane_distance(projection, n, plane_point, plane_normal)
                .unwrap_or(dmin)
                .clamp(dmin, dmax);
            depth[(y as u32 * map.side + x as u32) as usize]
                .fetch_min(ordered_bits(d), Ordering::Relaxed);
            written += 1;
        }
    }
    written
}

/// World size of one texel of `map` at light-view point `p` (the larger
/// axis: texels follow the fitted bounds' aspect).
#[inline]
pub(super) fn texel_world(map: &CascadeMap, projection: Projection, p: Vec3) -> f32 {
    let s = map.texel_ndc.max_element();
    match projection {
        Projection::Orthographic => s,
        Projection::Perspective => s * p.z,
    }
}

/// Pass `shadow_lookup`: lit fraction of every shadow-tested pixel (NaN
/// elsewhere), looked up at the pixel centre in its cascade's map. `light`
/// is read by [`Filter::Pcss`] only.
pub fn shadow_lookup(
    setup: &LightSetup,
    maps: &ShadowMaps,
    g: &GBuffer,
    filter: Filter,
    light: &super::pcss::PcssLight,
) -> Vec<f32> {
    (0..g.flags.len())
        .into_par_iter()
        .map(|i| {
            if g.flags[i] & flags::SHADOW_TESTED == 0 {
                return f32::NAN;
            }
            let p = setup.to_light_view(g.position[i]);
            let n = setup.rotate(g.normal[i]);
            let map = &maps.maps[setup.cascade_of(g.position[i])];
            let Some(ndc) = setup.ndc(p) else {
                return 1.0;
            };
            match filter {
                Filter::OneTap => one_tap(setup.projection, map, p, n, ndc),
                Filter::Pcf(k) => pcf(setup.projection, map, p, n, ndc, k),
                Filter::Pcss => super::pcss::pcss(setup, light, map, g.position[i], p, n, ndc),
            }
        })
        .collect()
}

/// tanθ between the receiver normal `n` and the direction to the light.
#[inline]
fn tan_to_light(projection: Projection, p: Vec3, n: Vec3) -> f32 {
    let to_light = match projection {
        Projection::Orthographic => Vec3::Z,
        Projection::Perspective => -p.normalize(),
    };
    let cos = n.dot(to_light).clamp(1e-6, 1.0);
    (1.0 - cos * cos).sqrt() / cos
}

/// One texel, slope-scaled bias ([Shadow mapping mechanics]).
fn one_tap(projection: Projection, map: &CascadeMap, p: Vec3, n: Vec3, ndc: Vec2) -> f32 {
    let (x, y) = map.texel_of(map.texel_coords(ndc).floor());
    let stored = map.at(x, y);
    let slope = tan_to_light(projection, p, n).min(MAX_BIAS_SLOPE);
    let bias = texel_world(map, projection, p) * (SLOPE_BIAS_TEXELS * slope + CONSTANT_BIAS_TEXELS);
    let lit = light_distance(projection, p) <= stored + bias;
    lit as u32 as f32
}

/// `k`×`k` bilinear PCF, receiver-plane depth bias ([Shadow acne notes]): each of
/// the 2×2 texels behind every tap is compared against the receiver
/// plane's own distance at that texel's centre, computed geometrically
/// from the G-buffer normal ([Shadow acne notes] recommends this over screen-space
/// derivatives, which break at every silhouette). The plane is only
/// allowed to move the comparison toward the light ([Shadow acne notes]'s
/// `min(0, …)`: a bias may remove shadow, never add it).
fn pcf(projection: Projection, map: &CascadeMap, p: Vec3, n: Vec3, ndc: Vec2, k: u32) -> f32 {
    let own = light_distance(projection, p);
    let bias = texel_world(map, projection, p) * CONSTANT_BIAS_TEXELS;
    let t = map.texel_coords(ndc);
    let r = (k / 2) as i32;
    let mut lit = 0.0f32;
    for oy in -r..=r {
        for ox in -r..=r {
            let s = t + Vec2::new(ox as f32, oy as f32) - 0.5;
            let base = s.floor();
            let f = s - base;
            let (bx, by) = map.texel_of(base);
            for (dx, dy, w) in [
                (0, 0, (1.0 - f.x) * (1.0 - f.y)),
                (1, 0, f.x * (1.0 - f.y)),
                (0, 1, (1.0 - f.x) * f.y),
                (1, 1, f.x * f.y),
            ] {
                let (x, y) = (bx + dx, by + dy);
                let stored = map.at(x, y);
                if stored == f32::INFINITY {
                    lit += w;
                    continue;
                }
                let centre = map.texel_centre(x, y);
                let receiver = plane_distance(projection, centre, p, n).map_or(own, |d| d.min(own));
                lit += w * (receiver <= stored + bias) as u32 as f32;
            }
        }
    }
    lit / (k * k) as f32
}

/// The float ↔ ordered-uint map both shadow-map twins store depths with
/// (`ordered_bits` in the shaders): unsigned order of the words is the
/// order of the floats, so an atomic minimum keeps the nearest depth.
pub fn ordered_bits(f: f32) -> u32 {
    let u = f.to_bits();
    if u & 0x8000_0000 != 0 {
        !u
    } else {
        u | 0x8000_0000
    }
}

/// Inverse of [`ordered_bits`].
pub fn from_ordered_bits(u: u32) -> f32 {
    f32::from_bits(if u & 0x8000_0000 != 0 {
        u & 0x7FFF_FFFF
    } else {
        !u
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ordered_bits_preserve_order() {
        let values = [
            -1e30f32,
            -2.5,
            -1e-30,
            -0.0,
            0.0,
            1e-30,
            3.0,
            1e30,
            f32::INFINITY,
        ];
        for w in values.windows(2) {
            assert!(
                ordered_bits(w[0]) <= ordered_bits(w[1]),
                "{} vs {}",
                w[0],
                w[1]
            );
            assert_eq!(from_ordered_bits(ordered_bits(w[1])), w[1]);
        }
    }

    #[test]
    fn near_clip_keeps_the_part_in_front() {
        let tri = [
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        let poly = clip_to_near(tri, 0.5);
        assert_eq!(poly.len(), 4);
        assert!(poly.iter().all(|p| p.z >= 0.5 - 1e-6), "{poly:?}");
    }
}
