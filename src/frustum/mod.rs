//! The frustum-triangle test of Wyman et al. 2015, §4 (paper-notes/frustum-test.md): for one pixel's
//! µQuad and one occluder triangle, a per-pixel depth test at the µQuad
//! centre P, then the three shadow-volume side planes as affine edge
//! functions over the µQuad, `f(u, v) = α + β(u − ½) + γ(v − ½) ≥ 0` inside.
//!
//! Written once, generically over `f32` (the IZB, CPU and GPU) and `f64`
//! (the same-sample reference), with every vector *relative to the pixel*
//! ([Compute IZB]: subtract P before any product, never work in NDC). Below
//! both the IZB (`crate::izb`) and the reference (`crate::reference`),
//! which import it; it imports neither.

pub mod soft;

use glam::{DVec3, Vec3};

/// The part of the depth tolerance scaled by the µQuad: a triangle must lie
/// at least 2⁻⁸ of the µQuad's longer axis beyond P toward the light. A
/// coplanar neighbour (distance 0 up to rounding) never passes; a real
/// occluder closer than that to the receiver would shadow less than 1/256
/// of the pixel's width before the edge tests even start.
pub const DEPTH_TOLERANCE_MICROQUAD: f64 =
    izb_contract::tolerance::DEPTH_TOLERANCE_MICROQUAD as f64;

/// The part of the depth tolerance scaled by the triangle's distance from
/// P, covering the rounding of the plane equation in `f32`: 16 ε₃₂.
pub const DEPTH_TOLERANCE_ROUNDING: f64 = izb_contract::tolerance::DEPTH_TOLERANCE_ROUNDING as f64;

/// Where the light is, relative to the pixel.
#[derive(Clone, Copy, Debug)]
pub enum LightRel<V> {
    /// Unit vector toward a directional light.
    Toward(V),
    /// Point light position minus P.
    At(V),
}

/// Vector arithmetic the test needs, for `Vec3` and `DVec3`.
pub trait Vector: Copy + std::ops::Sub<Output = Self> + std::ops::Neg<Output = Self> {
    type Scalar: Copy
        + PartialOrd
        + std::ops::Mul<Output = Self::Scalar>
        + std::ops::Add<Output = Self::Scalar>
        + std::ops::Neg<Output = Self::Scalar>;
    fn dot(self, o: Self) -> Self::Scalar;
    fn cross(self, o: Self) -> Self;
    fn length(self) -> Self::Scalar;
    fn zero() -> Self::Scalar;
    fn from_f64(x: f64) -> Self::Scalar;
    /// The vector scaled by the power of two that brings its largest
    /// component into [1, 2): exact (Goldberg 1991), so a ratio or a sign
    /// taken of it is the unscaled vector's, and its squared length stays
    /// in range whatever the scene's scale. Zero, infinite and NaN vectors
    /// pass as they are.
    fn pow2_normalised(self) -> Self;
}

macro_rules! impl_vector {
    ($v:ty, $s:ty, $exponent:expr, $one_over:expr, $largest:expr) => {
        impl Vector for $v {
            type Scalar = $s;
            #[inline]
            fn dot(self, o: Self) -> $s {
                <$v>::dot(self, o)
            }
            #[inline]
            fn cross(self, o: Self) -> Self {
                <$v>::cross(self, o)
            }
            #[inline]
            fn length(self) -> $s {
                <$v>::length(self)
            }
            #[inline]
            fn zero() -> $s {
                0.0
            }
            #[inline]
            fn from_f64(x: f64) -> $s {
                x as $s
            }
            #[inline]
            fn pow2_normalised(self) -> Self {
                let m = self.abs().max_element();
                let exponent = m.to_bits() & $exponent;
                if m == 0.0 || exponent == $exponent {
                    return self;
                }
                // 2^(bias − E) as bits, at least the smallest normal.
                self * <$s>::from_bits($one_over - exponent.min($largest))
            }
        }
    };
}
impl_vector!(Vec3, f32, 0x7F80_0000, 0x7F00_0000, 0x7E80_0000);
impl_vector!(
    DVec3,
    f64,
    0x7FF0_0000_0000_0000,
    0x7FE0_0000_0000_0000,
    0x7FD0_0000_0000_0000
);

/// The edge functions (α, β, γ) of the three side planes.
pub type EdgeFunctions<S> = [[S; 3]; 3];

/// Normal of the side plane through edge (x, y) (pixel-relative vertices).
/// For a point light at `l`, (x − l) × (y − x): equal to (x − l) × (y − l)
/// in exact arithmetic, but without its cancellation — two vectors of
/// length ~|l| that differ by the edge, whose rounding (ulp(|l|) each)
/// swamped the edge once the light was far: a light 10⁴ scene radii away
/// put 0.8 % of `default`'s samples on the wrong side (issue 28).
#[inline]
fn side_plane_normal<V: Vector>(x: V, y: V, light: LightRel<V>) -> V {
    match light {
        LightRel::Toward(w) => (y - x).cross(w),
        LightRel::At(l) => (x - l).cross(y - x),
    }
}

/// The per-pixel depth test at P (paper-notes/frustum-test.md): whether triangle `t`
/// (vertices minus P) may shadow the µQuad of a receiver with camera-facing
/// normal `normal`. Two conditions, both evaluated once per pixel:
///
/// 1. **Above the tangent plane.** Some vertex lies more than the tolerance
///    above the receiver's tangent plane (on the side of `normal`). The
///    receiver faces the light, so every ray from a point of its tangent
///    plane toward the light climbs into that side: a triangle wholly
///    below the plane cannot shadow *any* point of the µQuad. Without this
///    test the convex neighbours of the receiver (the next facet of a
///    sphere, the side of a box) pass the plane test below — P lies behind
///    their plane — and their infinite side-plane prism darkens every
///    convex edge (measured on `default`: edge-pixel MAE 0.127 with it
///    missing, against 0.011 for 1 spp).
/// 2. **Between P and the light.** P lies beyond the triangle's plane, seen
///    from the light, by more than the tolerance. Coplanar neighbours
///    (distance 0 up to rounding) fail; so do triangles seen edge-on from
///    the light (no shadow area).
///
/// The tolerance is [`DEPTH_TOLERANCE_MICROQUAD`] × `microquad_size` plus
/// [`DEPTH_TOLERANCE_ROUNDING`] × the triangle's distance from P.
#[inline]
pub fn may_shadow<V: Vector>(
    t: &[V; 3],
    normal: V,
    microquad_size: V::Scalar,
    light: LightRel<V>,
) -> bool {
    let microquad_part = microquad_tolerance::<V>(microquad_size);
    above_tangent_plane(t, normal, microquad_part)
        .is_some_and(|height| beyond_triangle_plane(t, height, microquad_part, light))
}

/// The part of the depth tolerance scaled by the µQuad
/// ([`DEPTH_TOLERANCE_MICROQUAD`] × `microquad_size`): the same for every
/// triangle a pixel tests, so callers may compute it once per pixel.
#[inline]
pub fn microquad_tolerance<V: Vector>(microquad_size: V::Scalar) -> V::Scalar {
    V::from_f64(DEPTH_TOLERANCE_MICROQUAD) * microquad_size
}

/// Condition 1 of [`may_shadow`] against the µQuad part of the tolerance
/// alone: the height of the highest vertex of `t` above the tangent plane
/// when it exceeds `microquad_part`, else `None`. The full tolerance is
/// this part plus a non-negative term and rounding is monotone, so a
/// height at or under it fails the full comparison too: the three lengths
/// [`beyond_triangle_plane`] needs are only computed for triangles that
/// may pass. Most candidates end here (measured on courtyard at 1080p:
/// about 30 M of 47 M tests), so it is kept small enough to inline.
#[inline]
pub fn above_tangent_plane<V: Vector>(
    t: &[V; 3],
    normal: V,
    microquad_part: V::Scalar,
) -> Option<V::Scalar> {
    let height = max3(normal.dot(t[0]), normal.dot(t[1]), normal.dot(t[2]));
    matches!(
        height.partial_cmp(&microquad_part),
        Some(std::cmp::Ordering::Greater)
    )
    .then_some(height)
}

/// The rest of [`may_shadow`] for a triangle [`above_tangent_plane`] let
/// through with `height`: condition 1 against the full tolerance, then
/// condition 2.
#[inline]
pub fn beyond_triangle_plane<V: Vector>(
    t: &[V; 3],
    height: V::Scalar,
    microquad_part: V::Scalar,
    light: LightRel<V>,
) -> bool {
    let Some(tolerance) = above_full_tolerance(t, height, microquad_part) else {
        return false;
    };
    // Normalised by a power of two: its length is taken through its
    // square, the fourth power of the scene's scale, which left `f32`'s
    // range below 10⁻⁹ units (the numeric-extremes run: a canopy's small
    // triangles at 2⁻³²) and above 10⁹.
    let n = (t[1] - t[0]).cross(t[2] - t[0]).pow2_normalised();
    // Orient n toward the light.
    let facing = match light {
        LightRel::Toward(w) => n.dot(w),
        LightRel::At(l) => n.dot(l - t[0]),
    };
    let zero = V::zero();
    if facing == zero {
        return false;
    }
    let n = if facing > zero { n } else { -n };
    // P − A = −A: P is beyond the plane (away from the light) when n·A > 0.
    n.dot(t[0]) > tolerance * n.length()
}

/// Condition 1 against the full tolerance (the µQuad part plus
/// [`DEPTH_TOLERANCE_ROUNDING`] × the triangle's distance from P): the
/// tolerance when `height` exceeds it, else `None`. Shared by the point
/// light's rule and the area light's ([`soft::off_triangle_plane`]).
#[inline]
pub(crate) fn above_full_tolerance<V: Vector>(
    t: &[V; 3],
    height: V::Scalar,
    microquad_part: V::Scalar,
) -> Option<V::Scalar> {
    let reach = max3(t[0].length(), t[1].length(), t[2].length());
    let tolerance = microquad_part + V::from_f64(DEPTH_TOLERANCE_ROUNDING) * reach;
    matches!(
        height.partial_cmp(&tolerance),
        Some(std::cmp::Ordering::Greater)
    )
    .then_some(tolerance)
}

#[inline]
pub(crate) fn max3<S: PartialOrd>(a: S, b: S, c: S) -> S {
    let m = if a > b { a } else { b };
    if m > c {
        m
    } else {
        c
    }
}

/// The winding of triangle `t` as seen from the light: the side of edge
/// 0's side plane the third vertex lies on. All three edges take their
/// orientation from this one number. (Orienting each edge by its own
/// third vertex, as this crate first did, fails on a sliver seen almost
/// edge-on from the light: the third vertex then lies on the side plane up
/// to rounding, one edge can flip alone, and the three half-planes meet in
/// a wedge reaching far beyond the sliver. Measured: a 1 mm wire triangle
/// at N·L = 1.6e-4 shadowed 2 045 lit pixels of `wires` at one light angle
/// of `izb bench --flicker`. With one shared orientation a wrong sign
/// flips all three edges, whose outer half-planes meet nowhere near the
/// pixel.) Zero (or NaN) means the triangle is edge-on: no shadow.
#[inline]
pub fn winding<V: Vector>(t: &[V; 3], light: LightRel<V>) -> V::Scalar {
    side_plane_normal(t[0], t[1], light).dot(t[2] - t[0])
}

/// The three edge functions of triangle `t` (vertices minus P) over the
/// µQuad with axes `ex`, `ey`: edge plane normals oriented by the
/// triangle's [`winding`] so the triangle is inside, α = n·(P − A) = −n·A,
/// β = n·Ex, γ = n·Ey.
#[inline]
pub fn edge_functions<V: Vector>(
    t: &[V; 3],
    ex: V,
    ey: V,
    light: LightRel<V>,
) -> EdgeFunctions<V::Scalar> {
    let flip = winding(t, light) < V::zero();
    [0, 1, 2].map(|k| edge_function(t, k, ex, ey, light, flip))
}

/// Edge function `k` of [`edge_functions`] alone (edge from vertex k to
/// k + 1), the same arithmetic, so a caller may stop after one edge;
/// `flip` is `winding(t, light) < 0`.
#[inline]
pub fn edge_function<V: Vector>(
    t: &[V; 3],
    k: usize,
    ex: V,
    ey: V,
    light: LightRel<V>,
    flip: bool,
) -> [V::Scalar; 3] {
    let (x, y) = (t[k], t[(k + 1) % 3]);
    let n = side_plane_normal(x, y, light);
    let n = if flip { -n } else { n };
    [-(n.dot(x)), n.dot(ex), n.dot(ey)]
}

/// Edge `e` = (α, β, γ) scaled by the power of two that brings
/// max(|β|, |γ|) into [1, 2). A power-of-two scale is exact in binary
/// floating point (Goldberg 1991), so every sample's sign, the saturation
/// test and the LUT cell of an edge in range are unchanged bit for bit;
/// what it removes is the range problem: the side planes' coefficients
/// grow as the square (directional light) or the cube (point light) of
/// the scene's scale, and β² + γ² in the LUT's and the saturation test's
/// normalisation overflowed `f32` at 10⁷ units under a point light (found
/// by the numeric-extremes run, `examples/fuzz_extremes`). Zero, infinite
/// and NaN edges pass as they are. The GPU's `normalised_edge`
/// (`pixel_frustum.glsl`) is the twin.
///
/// Straight-line code, so that loops over SIMD lanes (the LUT kernel, the
/// empty certificate) vectorise: an edge left as it is (zero, infinite or
/// NaN largest term) is scaled by 1, which is exact.
#[inline(always)]
pub fn normalised_edge(e: [f32; 3]) -> [f32; 3] {
    const EXPONENT: u32 = 0x7F80_0000;
    let m = e[1].abs().max(e[2].abs());
    let exponent = m.to_bits() & EXPONENT;
    let unscaled = m == 0.0 || exponent == EXPONENT;
    // 2^(127 − E) as bits: biased exponent 254 − E, at least 1 (a normal
    // number) for the largest finite m.
    let scale = f32::from_bits(0x7F00_0000 - exponent.min(0x7E80_0000));
    let scale = if unscaled { 1.0 } else { scale };
    e.map(|x| x * scale)
}

/// Whether edge `e` = (α, β, γ) keeps every sample of the pattern on one
/// side, and which: `Some(FULL)` all inside, `Some(0)` all outside, `None`
/// when the line may cross a sample (then the LUT or the 32 evaluations
/// decide). `radius` is the pattern's largest distance from the µQuad
/// centre. Exact against [`exact_edge_mask`]: |β(u−½) + γ(v−½)| ≤ r·radius,
/// and the 2⁻¹⁰ relative margin is ~10³ times the f32 rounding of r and of
/// the sample sums, so every sample then has the sign of α. NaN → `None`.
#[inline]
pub fn saturated_edge(e: [f32; 3], radius: f32) -> Option<u32> {
    let r = (e[1] * e[1] + e[2] * e[2]).sqrt();
    let reach = r * radius * (1.0 + SATURATION_MARGIN);
    if e[0] > reach {
        Some(u32::MAX)
    } else if -e[0] > reach {
        Some(0)
    } else {
        None
    }
}

/// Relative margin of [`saturated_edge`] (2⁻¹⁰).
pub const SATURATION_MARGIN: f32 = izb_contract::tolerance::SATURATION_MARGIN;

/// Largest distance of a pattern sample from the µQuad centre, in µQuad
/// sides (below √2/2: samples lie strictly inside the square).
pub fn pattern_radius(pattern: &[[f32; 2]; 32]) -> f32 {
    pattern
        .iter()
        .map(|s| (s[0] - 0.5).hypot(s[1] - 0.5))
        .fold(0.0, f32::max)
}

/// Occluded samples of one edge, evaluated exactly at every sample of the
/// pattern (`f32`, the expression order a shader uses).
#[inline]
pub fn exact_edge_mask(e: [f32; 3], pattern: &[[f32; 2]; 32]) -> u32 {
    let mut mask = 0u32;
    for (i, s) in pattern.iter().enumerate() {
        let f = e[0] + e[1] * (s[0] - 0.5) + e[2] * (s[1] - 0.5);
        mask |= ((f >= 0.0) as u32) << i;
    }
    mask
}

/// The same in `f64` (the same-sample reference).
#[inline]
pub fn exact_edge_mask_f64(e: [f64; 3], pattern: &[[f32; 2]; 32]) -> u32 {
    let mut mask = 0u32;
    for (i, s) in pattern.iter().enumerate() {
        let f = e[0] + e[1] * (s[0] as f64 - 0.5) + e[2] * (s[1] as f64 - 0.5);
        mask |= ((f >= 0.0) as u32) << i;
    }
    mask
}
