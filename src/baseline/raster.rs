//! The CPU twin of the hardware rasteriser's depth-only pass
//! (`crate::gpu::shadow_raster`): the rules a Vulkan rasteriser follows
//! when it draws a shadow map, written out so the CPU's map is the map the
//! GPU's fixed-function pipeline draws, up to ties.
//!
//! - **Depth** ([`MapDepth`]): a D32_SFLOAT value. A directional light's map
//!   is orthographic, depth linear in the light distance over the
//!   receivers' range grown by [`MAP_DEPTH_MARGIN`], with depth clamp on:
//!   a caster nearer than the range clamps to 0 and still occludes
//!   ("pancaking"), one beyond it clamps to 1, which reads as empty. A
//!   point light's map is perspective with reversed depth `near / z`
//!   (infinite far plane, compare GREATER), the float format's best
//!   precision (Lapidous & Jiao 1999); it clips at `near`.
//! - **Coverage**: vertices snap to [`SUBPIXEL_BITS`] of sub-texel
//!   precision, a texel is covered when its centre is inside the snapped
//!   triangle, and a centre exactly on an edge belongs to the triangle
//!   only when that edge is a top or a left edge (the tie rule every
//!   desktop rasteriser uses). Edge functions are exact here (`f64` on the
//!   snapped lattice), as they are in hardware's fixed point. Depth, and
//!   the slope of the bias, interpolate over the *unsnapped* triangle:
//!   lavapipe does so (measured: snapping the depth plane too flips
//!   grazing PCF taps against it), and the spec does not say which.
//! - **Depth bias** ([`RasterBias`]): Vulkan's `o = m·slopeFactor +
//!   r·constantFactor`, with `m = max(|∂z/∂x|, |∂z/∂y|)` over the
//!   triangle (the spec also allows the gradient's length; the slope factor
//!   is chosen so either keeps a surface off itself) and `r = 2^(e−23)`,
//!   `e` the exponent of the triangle's largest depth (the spec's rule for
//!   float formats).

use crate::cpu::light_setup::{LightSetup, Projection};
use glam::{DVec2, Vec2, Vec3};

/// Sub-texel precision of vertex positions: 8 bits on the devices we run
/// (lavapipe, NVIDIA, AMD and Intel all report `subPixelPrecisionBits` 8);
/// a device reporting otherwise rounds its edges differently, which the
/// twin test's tie allowance covers.
pub const SUBPIXEL_BITS: u32 = 8;

/// `depthBiasSlopeFactor` of a one-tap map: 1.5 texels of the caster's
/// depth slope. A lookup lands up to half a texel diagonal (0.71 texel)
/// from the centre the depth was taken at, so a surface needs at least
/// 0.71·|∇z| to stay off itself; 1.5·max(|∂z/∂x|, |∂z/∂y|) ≥ 1.06·|∇z|
/// gives that under either of the spec's two slope norms.
pub const ONE_TAP_SLOPE_FACTOR: f32 = 1.5;

/// `depthBiasConstantFactor`: a few units of the float format's
/// resolution, against the interpolation's own rounding.
pub const CONSTANT_FACTOR: f32 = 2.0;

/// Share of the receivers' depth range (plus the first cascade's width)
/// an orthographic map's depth range grows by on each side.
pub const MAP_DEPTH_MARGIN: f32 = izb_contract::tolerance::MAP_DEPTH_MARGIN;

/// The fixed-function depth bias of one map, as `vkCmdSetDepthBias` gets
/// it (no clamp: `depthBiasClamp` would need the depth range on the host,
/// and the range is fitted on the GPU).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RasterBias {
    pub constant_factor: f32,
    pub slope_factor: f32,
}

impl RasterBias {
    /// The bias a map filtered by `filter` is drawn with, toward the far
    /// side of `projection`'s depth (reversed depth: negative). One tap
    /// takes a slope-scaled bias; the filtered lookups bias by the
    /// receiver's plane instead ([Shadow acne notes]), so their maps take
    /// only the constant.
    pub fn for_map(projection: Projection, filter: super::Filter) -> RasterBias {
        let slope = match filter {
            super::Filter::OneTap => ONE_TAP_SLOPE_FACTOR,
            _ => 0.0,
        };
        let sign = match projection {
            Projection::Orthographic => 1.0,
            Projection::Perspective => -1.0,
        };
        RasterBias {
            constant_factor: sign * CONSTANT_FACTOR,
            slope_factor: sign * slope,
        }
    }
}

/// How a light distance maps to the depth a map stores.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapDepth {
    pub projection: Projection,
    /// Orthographic: the distance at depth 0. Perspective: the near plane
    /// (depth 1), a thousandth of the nearest receiver's depth.
    pub near: f32,
    /// Orthographic: the distance from depth 0 to depth 1.
    pub range: f32,
}

impl MapDepth {
    /// The mapping of `setup`'s light view; the GPU computes the same in
    /// `map_depth_range` (`shaders/shadow_map.glsl`), same order.
    pub fn new(setup: &LightSetup) -> MapDepth {
        let [zmin, zmax] = setup.receiver_z;
        match setup.projection {
            Projection::Orthographic => {
                let span = zmax - zmin;
                let extent = setup
                    .cascades
                    .first()
                    .map_or(0.0, |g| (g.ndc_max - g.ndc_min).max_element());
                let mut margin = MAP_DEPTH_MARGIN * (span + extent);
                // No receiver or a point-sized one: any positive range.
                if !(margin > 0.0 && margin.is_finite()) {
                    margin = 1.0;
                }
                MapDepth {
                    projection: setup.projection,
                    near: -zmax - margin,
                    range: span + margin + margin,
                }
            }
            Projection::Perspective => MapDepth {
                projection: setup.projection,
                near: zmin * izb_contract::tolerance::MAP_NEAR_RATIO,
                range: 0.0,
            },
        }
    }

    /// The depth of a light-view point, before clipping and clamping.
    #[inline]
    pub fn depth(&self, view: Vec3) -> f32 {
        match self.projection {
            Projection::Orthographic => (-view.z - self.near) / self.range,
            Projection::Perspective => self.near / view.z,
        }
    }

    /// The light distance a stored depth stands for; `+∞` for the cleared
    /// value (and, orthographic, for casters clamped to the far end).
    #[inline]
    pub fn distance(&self, depth: f32) -> f32 {
        match self.projection {
            Projection::Orthographic if depth >= 1.0 => f32::INFINITY,
            Projection::Orthographic => self.near + depth * self.range,
            Projection::Perspective if depth <= 0.0 => f32::INFINITY,
            Projection::Perspective => self.near / depth,
        }
    }

    /// The value a map is cleared to: the far end.
    pub fn clear(&self) -> f32 {
        match self.projection {
            Projection::Orthographic => 1.0,
            Projection::Perspective => 0.0,
        }
    }
}

/// One triangle to rasterise: its vertices in framebuffer coordinates
/// (a map's texels, the image's pixels), unsnapped — [`raster_triangle`]
/// snaps them for coverage and interpolates depth over them as they are —
/// and the depth at each vertex.
pub struct RasterTriangle {
    pub position: [Vec2; 3],
    pub depth: [f32; 3],
}

/// Clips a triangle to the half-space `distance(v) ≥ 0`, as the
/// rasteriser clips at a near plane; up to four corners, in order.
pub fn clip_to_plane(face: [Vec3; 3], distance: impl Fn(Vec3) -> f32) -> Vec<Vec3> {
    let mut out = Vec::with_capacity(4);
    for i in 0..3 {
        let (a, b) = (face[i], face[(i + 1) % 3]);
        let (da, db) = (distance(a), distance(b));
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            out.push(a + (b - a) * (da / (da - db)));
        }
    }
    out
}

/// `t` snapped to the sub-texel lattice.
fn snap(t: &[Vec2; 3]) -> [DVec2; 3] {
    let scale = (1u32 << SUBPIXEL_BITS) as f64;
    t.map(|t| DVec2::new((t.x as f64 * scale).round(), (t.y as f64 * scale).round()) / scale)
}

/// Twice the signed area of the snapped triangle, `(s1 − s0) × (s2 − s0)`
/// in framebuffer coordinates (y down): Vulkan's facing is its sign
/// (negative is front-facing for `COUNTER_CLOCKWISE`).
pub fn snapped_area(texel: &[Vec2; 3]) -> f64 {
    let s = snap(texel);
    (s[1] - s[0]).perp_dot(s[2] - s[0])
}

/// Where a triangle lands: its covered texel centres with the biased,
/// clamped depth of each.
pub fn raster_triangle(
    tri: &RasterTriangle,
    [width, height]: [u32; 2],
    projection: Projection,
    bias: RasterBias,
    mut write: impl FnMut(u32, u32, f32),
) -> u64 {
    let s = snap(&tri.position);
    if s.iter().any(|p| !p.is_finite()) {
        return 0;
    }
    let area = (s[1] - s[0]).perp_dot(s[2] - s[0]);
    if area == 0.0 {
        return 0; // edge-on to the light after snapping: covers nothing
    }
    let lo = s[0].min(s[1]).min(s[2]);
    let hi = s[0].max(s[1]).max(s[2]);
    let (w, h) = (width as f64, height as f64);
    if hi.x < 0.0 || hi.y < 0.0 || lo.x > w || lo.y > h {
        return 0;
    }
    let x0 = (lo.x - 0.5).ceil().max(0.0) as u32;
    let y0 = (lo.y - 0.5).ceil().max(0.0) as u32;
    let x1 = (hi.x - 0.5).floor().min(w - 1.0);
    let y1 = (hi.y - 0.5).floor().min(h - 1.0);
    if x1 < x0 as f64 || y1 < y0 as f64 {
        return 0;
    }
    let (x1, y1) = (x1 as u32, y1 as u32);
    let sign = area.signum();
    // Edge e runs from vertex e to e + 1, oriented so the inside is
    // positive; on the edge itself only top and left edges draw.
    let edges: [(DVec2, DVec2, bool); 3] = std::array::from_fn(|e| {
        let (a, b) = (s[e], s[(e + 1) % 3]);
        let d = (b - a) * sign;
        (a, d, d.y < 0.0 || (d.y == 0.0 && d.x > 0.0))
    });
    let z = tri.depth.map(f64::from);
    // Depth interpolates over the unsnapped triangle, as lavapipe does
    // (the spec leaves it open; see the module note).
    let u = tri.position.map(|t| DVec2::new(t.x as f64, t.y as f64));
    let u_area = (u[1] - u[0]).perp_dot(u[2] - u[0]);
    let offset = depth_bias(&u, z, u_area, bias);
    let clamp_unit = projection == Projection::Orthographic;
    let mut written = 0;
    for y in y0..=y1 {
        for x in x0..=x1 {
            let c = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            let inside = edges.iter().all(|(a, d, top_left)| {
                let f = d.perp_dot(c - *a);
                f > 0.0 || (f == 0.0 && *top_left)
            });
            if !inside {
                continue;
            }
            let b1 = (c - u[0]).perp_dot(u[2] - u[0]) / u_area;
            let b2 = (u[1] - u[0]).perp_dot(c - u[0]) / u_area;
            let depth = z[0] + b1 * (z[1] - z[0]) + b2 * (z[2] - z[0]) + offset;
            let depth = if clamp_unit {
                depth.clamp(0.0, 1.0)
            } else {
                depth.max(0.0)
            };
            write(x, y, depth as f32);
            written += 1;
        }
    }
    written
}

/// Vulkan's depth bias of a triangle (texel-space vertices `s`,
/// vertex depths `z`, twice its signed area `area`).
fn depth_bias(s: &[DVec2; 3], z: [f64; 3], area: f64, bias: RasterBias) -> f64 {
    let (e1, e2) = (s[1] - s[0], s[2] - s[0]);
    let (dz1, dz2) = (z[1] - z[0], z[2] - z[0]);
    let dzdx = (dz1 * e2.y - dz2 * e1.y) / area;
    let dzdy = (dz2 * e1.x - dz1 * e2.x) / area;
    let m = dzdx.abs().max(dzdy.abs());
    let largest = z.iter().fold(0.0f64, |a, v| a.max(v.abs())) as f32;
    let r = if largest > 0.0 {
        // 2^(e − 23): one unit in the last place of the largest depth.
        let e = ((largest.to_bits() >> 23) & 0xFF) as i32 - 127;
        2f64.powi(e - 23)
    } else {
        0.0
    };
    m * bias.slope_factor as f64 + r * bias.constant_factor as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn draw(texel: [Vec2; 3]) -> Vec<(u32, u32)> {
        let tri = RasterTriangle {
            position: texel,
            depth: [0.5; 3],
        };
        let no_bias = RasterBias {
            constant_factor: 0.0,
            slope_factor: 0.0,
        };
        let mut out = Vec::new();
        raster_triangle(
            &tri,
            [8, 8],
            Projection::Orthographic,
            no_bias,
            |x, y, _| out.push((x, y)),
        );
        out.sort();
        out
    }

    #[test]
    fn a_shared_edge_through_texel_centres_draws_each_texel_once() {
        // Two triangles of the square (0.5, 0.5)–(3.5, 3.5) split along its
        // diagonal, which runs through texel centres; both windings.
        let (a, b, c, d) = (
            Vec2::new(0.5, 0.5),
            Vec2::new(3.5, 0.5),
            Vec2::new(3.5, 3.5),
            Vec2::new(0.5, 3.5),
        );
        for flip in [false, true] {
            let (t1, t2) = if flip {
                ([a, c, b], [a, d, c])
            } else {
                ([a, b, c], [a, c, d])
            };
            let mut all = draw(t1);
            all.extend(draw(t2));
            let n = all.len();
            all.sort();
            all.dedup();
            assert_eq!(all.len(), n, "a texel drawn twice");
            // Top-left: the square's top row (y = 0) and left column
            // (x = 0) are in, its right and bottom edges out: 3 × 3.
            assert_eq!(n, 9, "{all:?}");
            assert!(all.contains(&(0, 0)) && !all.contains(&(3, 3)));
        }
    }

    #[test]
    fn vertices_snap_to_the_subpixel_grid() {
        // An edge 2⁻¹² texels right of a centre snaps onto it; as a right
        // edge it then leaves the centre out.
        let eps = 1.0 / 4096.0;
        let t = [
            Vec2::new(0.0, 0.0),
            Vec2::new(0.5 + eps, 0.0),
            Vec2::new(0.5 + eps, 2.0),
        ];
        assert!(!draw(t).contains(&(0, 0)));
    }

    #[test]
    fn stored_depth_maps_back_to_the_distance() {
        for projection in [Projection::Orthographic, Projection::Perspective] {
            let m = MapDepth {
                projection,
                near: 0.25,
                range: 10.0,
            };
            let p = Vec3::new(
                0.3,
                -0.2,
                if projection == Projection::Perspective {
                    4.0
                } else {
                    -4.0
                },
            );
            let d = m.distance(m.depth(p));
            assert!((d - 4.0).abs() < 1e-5, "{projection:?}: {d}");
            assert_eq!(m.distance(m.clear()), f32::INFINITY);
        }
    }
}
