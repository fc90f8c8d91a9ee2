//! The two passes of a shadow map (Williams 1978, Reeves et al. 1987; [Shadow acne notes], [Shadow mapping mechanics], Agenjo 2020: paper-notes/references.md): `shadow_map`
//! rasterises every triangle's depth into one map per cascade as the
//! hardware rasteriser does ([`super::raster`]; on the GPU a depth-only
//! render pass, `crate::gpu::shadow_raster`), `shadow_lookup` compares
//! each shadow-tested pixel against it.
//!
//! The maps live in the IZB's own light view ([`LightSetup`]): the same
//! rotation, the same receiver-fitted light-NDC bounds per cascade (a
//! sample-distribution fit), so the baselines lose nothing to a looser fit
//! than the IZB gets. A map texel is a square of light NDC; its stored value
//! is the depth ([`MapDepth`]) of the nearest surface through the texel
//! centre, which [`CascadeMap::at`] turns back into the distance to the
//! light (`-z` for a directional light, whose view `+z` points at it; `z`
//! along a point light's axis): smaller is nearer the light.

use super::moments::{moments_lookup, MomentDepth, MomentKind};
use super::raster::{clip_to_plane, raster_triangle, MapDepth, RasterBias, RasterTriangle};
use crate::cpu::light_setup::{CascadeGrid, LightSetup, Projection};
use crate::gbuffer::{flags, GBuffer};
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
    /// Variance shadow map, blurred, light-bleeding reduction
    /// ([`super::moments`]).
    Vsm,
    /// Moment shadow map, four moments, blurred, Hamburger
    /// reconstruction ([`super::moments`]).
    Msm,
    /// Exponential shadow map, blurred ([`super::moments`]).
    Esm,
}

impl Filter {
    /// Texels a lookup reaches beyond the one it lands in.
    pub fn reach(self) -> u32 {
        match self {
            Filter::OneTap => 0,
            Filter::Pcf(k) => k / 2 + 1,
            Filter::Pcss => izb_contract::pcss::MAX_RADIUS_TEXELS,
            // The blur's taps and the bilinear lookup's second texel.
            Filter::Vsm | Filter::Msm | Filter::Esm => izb_contract::filtered::BLUR_RADIUS + 1,
        }
    }

    /// The moments a filtered map keeps, `None` for the others.
    pub fn moments(self) -> Option<MomentKind> {
        match self {
            Filter::Vsm => Some(MomentKind::Variance),
            Filter::Msm => Some(MomentKind::FourMoments),
            Filter::Esm => Some(MomentKind::Exponential),
            _ => None,
        }
    }
}

pub use izb_contract::tolerance::CONSTANT_BIAS_TEXELS;

/// One cascade's map: `side`² depths, row-major, as the D32_SFLOAT
/// attachment holds them ([`MapDepth`]).
pub struct CascadeMap {
    pub side: u32,
    /// Light-NDC corner of texel (0, 0) and the NDC size of one texel.
    pub ndc_origin: Vec2,
    pub texel_ndc: Vec2,
    pub map_depth: MapDepth,
    pub depth: Vec<f32>,
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
            self.map_depth.distance(self.depth[(y * s + x) as usize])
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
    /// A filtered map's blurred moments per cascade (pass
    /// [`super::moments::shadow_blur`]); empty for the others.
    pub moments: Vec<Vec<f32>>,
}

impl ShadowMaps {
    /// Bytes of map storage (4 per texel, and 4 per moment).
    pub fn bytes(&self) -> u64 {
        let depths: u64 = self.maps.iter().map(|m| m.depth.len() as u64 * 4).sum();
        depths + self.moments.iter().map(|m| m.len() as u64 * 4).sum::<u64>()
    }
}

/// Distance to the light of a light-view point: smaller is nearer.
#[inline]
pub(crate) fn light_distance(projection: Projection, p: Vec3) -> f32 {
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
fn cascade_frame(grid: &CascadeGrid, side: u32, reach: u32, map_depth: MapDepth) -> CascadeMap {
    let extent = grid.ndc_max - grid.ndc_min;
    let inner = (side as f32 - 2.0 * reach as f32).max(1.0);
    let texel_ndc = extent / inner;
    CascadeMap {
        side,
        ndc_origin: grid.ndc_min - texel_ndc * reach as f32,
        texel_ndc,
        map_depth,
        depth: Vec::new(),
    }
}

/// Clips a light-view triangle to `z >= near` (point lights: only what is
/// in front of the light projects, as the rasteriser clips at its near
/// plane); up to four vertices.
fn clip_to_near(tri: [Vec3; 3], near: f32) -> Vec<Vec3> {
    clip_to_plane(tri, |v| v.z - near)
}

/// Where the rasteriser puts light-view point `q` in `map`, in texel
/// coordinates: `shadow_map.vert`'s clip position, the division by `w`
/// and the viewport transform, each rounded as the GPU rounds it (the
/// texel coordinates computed directly differ in the last bits, which
/// the sub-texel snap turns into whole steps now and then).
fn framebuffer_position(projection: Projection, map: &CascadeMap, q: Vec3) -> Vec2 {
    let half = map.side as f32 * 0.5;
    let to_clip = 2.0 / map.side as f32;
    let ndc = match projection {
        Projection::Orthographic => map.texel_coords(Vec2::new(q.x, q.y)) * to_clip - 1.0,
        Projection::Perspective => {
            let tz = (Vec2::new(q.x, q.y) - map.ndc_origin * q.z) / map.texel_ndc;
            (tz * to_clip - q.z) / q.z
        }
    };
    ndc * half + half
}

/// Pass `shadow_map`: every triangle (eye-relative `f32`) drawn into every
/// cascade's `side`² map by the rules of the hardware rasteriser
/// ([`super::raster`]): the nearest depth of each texel centre, biased as
/// `filter`'s map is on the GPU.
pub fn shadow_map(
    setup: &LightSetup,
    triangles: &[[Vec3; 3]],
    side: u32,
    filter: Filter,
) -> ShadowMaps {
    let texels = side as usize * side as usize;
    let map_depth = MapDepth::new(setup);
    let mut maps: Vec<CascadeMap> = setup
        .cascades
        .iter()
        .map(|g| cascade_frame(g, side, filter.reach(), map_depth))
        .collect();
    let projection = setup.projection;
    let bias = RasterBias::for_map(projection, filter);
    // Depths are non-negative, so their bits order as they do: the depth
    // test is an atomic minimum (orthographic, LESS) or maximum (reversed
    // perspective, GREATER) on the bits.
    let clear = map_depth.clear().to_bits();
    let atomic: Vec<Vec<AtomicU32>> = maps
        .iter()
        .map(|_| {
            (0..texels)
                .into_par_iter()
                .map(|_| AtomicU32::new(clear))
                .collect()
        })
        .collect();
    let counts = triangles
        .par_iter()
        .map(|tri| {
            let view = tri.map(|v| setup.to_light_view(v));
            let polygon = match projection {
                Projection::Orthographic => view.to_vec(),
                Projection::Perspective => clip_to_near(view, map_depth.near),
            };
            if polygon.len() < 3 {
                return (0usize, 0u64);
            }
            let depth: Vec<f32> = polygon.iter().map(|&p| map_depth.depth(p)).collect();
            let mut written = 0u64;
            for (map, texels) in maps.iter().zip(&atomic) {
                let texel: Vec<Vec2> = polygon
                    .iter()
                    .map(|&q| framebuffer_position(projection, map, q))
                    .collect();
                for k in 1..polygon.len() - 1 {
                    let fan = RasterTriangle {
                        position: [texel[0], texel[k], texel[k + 1]],
                        depth: [depth[0], depth[k], depth[k + 1]],
                    };
                    written += raster_triangle(&fan, [side, side], projection, bias, |x, y, d| {
                        let cell = &texels[(y * side + x) as usize];
                        match projection {
                            Projection::Orthographic => {
                                cell.fetch_min(d.to_bits(), Ordering::Relaxed)
                            }
                            Projection::Perspective => {
                                cell.fetch_max(d.to_bits(), Ordering::Relaxed)
                            }
                        };
                    });
                }
            }
            (1, written)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    for (map, depth) in maps.iter_mut().zip(atomic) {
        map.depth = depth
            .into_par_iter()
            .map(|a| f32::from_bits(a.into_inner()))
            .collect();
    }
    ShadowMaps {
        maps,
        triangles_drawn: counts.0,
        texels_written: counts.1,
        moments: Vec::new(),
    }
}

/// World size of one texel of `map` at light-view point `p` (the larger
/// axis: texels follow the fitted bounds' aspect).
#[inline]
pub(crate) fn texel_world(map: &CascadeMap, projection: Projection, p: Vec3) -> f32 {
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
    let moment_depth = MomentDepth::new(setup);
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
                Filter::OneTap => one_tap(setup.projection, map, p, ndc),
                Filter::Pcf(k) => pcf(setup.projection, map, p, n, ndc, k),
                Filter::Pcss => super::pcss::pcss(setup, light, map, g.position[i], p, n, ndc),
                Filter::Vsm | Filter::Msm | Filter::Esm => {
                    let k = setup.cascade_of(g.position[i]);
                    let kind = filter.moments().expect("a filtered map");
                    moments_lookup(&moment_depth, kind, map, &maps.moments[k], p, ndc)
                }
            }
        })
        .collect()
}

/// One texel; the map carries the slope-scaled bias
/// ([`RasterBias::for_map`], [Shadow mapping mechanics]).
fn one_tap(projection: Projection, map: &CascadeMap, p: Vec3, ndc: Vec2) -> f32 {
    let (x, y) = map.texel_of(map.texel_coords(ndc).floor());
    let stored = map.at(x, y);
    let bias = texel_world(map, projection, p) * CONSTANT_BIAS_TEXELS;
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
            for (dx, dy, w) in bilinear_taps(f) {
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

/// The 2×2 texels of a bilinear lookup at fraction `f` past texel
/// (0, 0): their offsets and weights, in the order the shaders sum them.
pub(crate) fn bilinear_taps(f: Vec2) -> [(i32, i32, f32); 4] {
    [
        (0, 0, (1.0 - f.x) * (1.0 - f.y)),
        (1, 0, f.x * (1.0 - f.y)),
        (0, 1, (1.0 - f.x) * f.y),
        (1, 1, f.x * f.y),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

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
