//! The G-buffer from a host's depth and normal images — the CPU twin of
//! the shadow pass's `gbuffer_from_depth.comp`.
//!
//! A renderer's G-buffer most often holds a hardware depth and a normal,
//! not a triangle id. The pixel's centre ray d (unit component along the
//! view axis) meets the surface at view depth z, so P = z·d; the µQuad
//! follows from P and the normal exactly as the ray-cast G-buffer derives
//! it from its hit's plane (`microquad_axes`). Two things differ from the
//! triangle-id producers (paper-notes/embedding.md, "Depth + normal"):
//! - P carries the depth format's error: the receiver's own triangle is
//!   then one more candidate whose vertices sit off the tangent plane by
//!   that error. With the frustum test's depth tolerance alone (2⁻⁸ of a
//!   µQuad) reverse-Z `D32` stays inside it, but standard Z and `D24` do
//!   not at a distance: their pixels shadowed themselves (courtyard at
//!   480×270: Lut32 MAE 1.33× the ray cast's). So each entry carries its
//!   depth's uncertainty ([`depth_uncertainty`]) and the tolerance grows
//!   by it — a per-pixel bias that is exactly the depth's error, not a
//!   tuned constant.
//! - No triangle id: the entry's id is [`DEPTH_SURFACE`], which no
//!   candidate equals, and its normal is stored per entry
//!   (`B_G_NORMAL` on the GPU, [`GBuffer::normal`] here).

use super::{GBuffer, PixelSurface, SurfaceHit, VisibilityGBuffer};
use crate::scene::Scene;
use glam::{DVec3, Vec3};

/// The id of a G-buffer entry made from depth and a normal: its triangle
/// is not known.
pub const DEPTH_SURFACE: u32 = izb_contract::word::DEPTH_SURFACE;

/// The spacing of a 24-bit unorm depth's values.
pub const UNORM24_DEPTH_STEP: f32 = 1.0 / 16_777_215.0;

/// How far a point at view depth `z` on the centre ray `direction` may
/// lie off its surface of unit normal `normal` when its depth value
/// `depth` is off by [`izb_contract::tolerance::DEPTH_INPUT_SPACINGS`]
/// spacings of its format there (`unorm_step` for a unorm format, 0 for
/// a float one, whose spacing follows D's exponent): |dz/dD| = z²(1 −
/// n/f)/n, along the ray, times |n·d| onto the normal. In `f32` as
/// `gbuffer_from_depth.comp` computes it.
pub fn depth_uncertainty(
    convention: &DepthConvention,
    depth: f32,
    unorm_step: f32,
    z: f32,
    normal: Vec3,
    direction: Vec3,
) -> f32 {
    let float_spacing = f32::from_bits(depth.to_bits() & 0x7F80_0000) * 2f32.powi(-23);
    let spacing = float_spacing.max(unorm_step);
    let span_over_near = (1.0 - convention.near_over_far()) as f32 / convention.near as f32;
    let dz = z * z * span_over_near * (izb_contract::tolerance::DEPTH_INPUT_SPACINGS * spacing);
    dz * normal.dot(direction).abs()
}

/// How the host's depth values map to view depth: its projection's near
/// plane, its far plane (`None`: infinite), and whether depth is reversed
/// (1 at near, 0 at far) or standard (0 at near, 1 at far). A depth at the
/// far plane's value is "no surface".
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthConvention {
    pub near: f64,
    pub far: Option<f64>,
    pub reversed: bool,
}

impl DepthConvention {
    /// A named error for a near plane that is not positive and finite, or
    /// a far plane that is not finite and beyond it.
    pub fn check(&self) -> Result<(), String> {
        if !(self.near > 0.0 && self.near.is_finite()) {
            return Err(format!(
                "the depth convention's near plane is {}: it must be positive and finite",
                self.near
            ));
        }
        match self.far {
            Some(f) if !(f > self.near && f.is_finite()) => Err(format!(
                "the depth convention's far plane is {f}: it must be finite and beyond the near \
                 plane {} (None: infinite)",
                self.near
            )),
            _ => Ok(()),
        }
    }

    /// near / far, 0 for an infinite far plane.
    pub fn near_over_far(&self) -> f64 {
        self.far.map_or(0.0, |f| self.near / f)
    }

    /// The depth value a rasteriser writes (before its format rounds it)
    /// at view depth `z`: u = (n/z − n/f) / (1 − n/f), the reversed value,
    /// and 1 − u with standard Z.
    pub fn depth_at(&self, z: f64) -> f64 {
        let r = self.near_over_far();
        let u = (self.near / z - r) / (1.0 - r);
        if self.reversed {
            u
        } else {
            1.0 - u
        }
    }

    /// The view depth of depth value `depth`, `None` at or beyond the far
    /// plane (u ≤ 0) or where it is not finite. Standard Z's 1 − D is
    /// exact for D ≥ ½ (Sterbenz 1974), so no cancellation hides in
    /// n·f / (f − D(f − n)), which loses log₂(f/n) bits near the far plane.
    pub fn view_depth(&self, depth: f64) -> Option<f64> {
        let u = if self.reversed { depth } else { 1.0 - depth };
        let r = self.near_over_far();
        let z = self.near / (r + u * (1.0 - r));
        (u > 0.0 && z.is_finite() && z > 0.0).then_some(z)
    }
}

/// The G-buffer of `scene`'s view from the host's `depth` (per pixel the
/// value a shader reads from its depth image, row-major) and `normals`
/// (per pixel the geometric normal, world axes, either facing; normalised
/// here), under `convention`. Pixels whose depth gives no view depth in
/// front of the eye, or whose normal is zero or not finite, are misses,
/// counted in `rejected` unless the depth is the far plane's (no surface).
/// `unorm_step` is the depth format's spacing if it is a unorm format
/// ([`UNORM24_DEPTH_STEP`]), 0 for a float one. An error names buffers of
/// the wrong size or a bad convention.
pub fn gbuffer_from_depth(
    scene: &Scene,
    depth: &[f32],
    normals: &[Vec3],
    convention: DepthConvention,
    unorm_step: f32,
) -> Result<VisibilityGBuffer, String> {
    convention.check()?;
    let [w, h] = scene.resolution;
    for (what, len) in [("depth", depth.len()), ("normal", normals.len())] {
        if len != scene.pixel_count() {
            return Err(format!(
                "the {what} buffer holds {len} pixels; the view is {w}x{h}"
            ));
        }
    }
    let frame = scene.camera.frame(scene.resolution);
    let light = scene.light.relative_to(scene.camera.eye);
    let far_value = if convention.reversed { 0.0 } else { 1.0 };
    let mut g = GBuffer::with_capacity(w, h);
    let mut uncertainty = Vec::with_capacity(depth.len());
    let mut rejected = 0;
    for (i, (&d, &n)) in depth.iter().zip(normals).enumerate() {
        let (px, py) = ((i % w as usize) as f64 + 0.5, (i / w as usize) as f64 + 0.5);
        let surface = (d != far_value).then(|| {
            let z = convention.view_depth(f64::from(d))?;
            let n: DVec3 = n.as_dvec3();
            let length = n.length();
            if !(length > 0.0 && length.is_finite()) {
                return None;
            }
            let direction = frame.direction(px, py);
            let mut normal = n / length;
            if normal.dot(direction) > 0.0 {
                normal = -normal;
            }
            let hit = SurfaceHit {
                triangle: DEPTH_SURFACE,
                t: z,
                position: direction * z,
                normal,
            };
            Some(PixelSurface::of_hit(&frame, (px, py), hit, &light))
        });
        rejected += usize::from(matches!(surface, Some(None)));
        let surface = surface.flatten();
        uncertainty.push(surface.as_ref().map_or(0.0, |s| {
            let (z, n) = (s.hit.t as f32, s.hit.normal.as_vec3());
            let direction = frame.direction(px, py).as_vec3();
            depth_uncertainty(&convention, d, unorm_step, z, n, direction)
        }));
        g.push(surface.as_ref());
    }
    g.depth_uncertainty = Some(uncertainty);
    Ok(VisibilityGBuffer {
        gbuffer: g,
        rejected,
        centre_uncovered: 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    #[cfg(feature = "cli")]
    use crate::bvh::SceneBvh;

    /// Each convention maps view depth to depth and back within a few
    /// ulps of z, misses exactly at the far plane, and refuses bad planes.
    #[test]
    fn conventions_round_trip_view_depth() {
        let mut checked = 0;
        for reversed in [false, true] {
            for far in [Some(1000.0), None] {
                let c = DepthConvention {
                    near: 0.1,
                    far,
                    reversed,
                };
                for z in [0.1, 0.37, 5.0, 123.0, 999.0] {
                    let back = c.view_depth(c.depth_at(z)).unwrap();
                    assert!((back - z).abs() <= 1e-12 * z, "{c:?} {z} {back}");
                    checked += 1;
                }
                let far_value = if reversed { 0.0 } else { 1.0 };
                assert_eq!(c.view_depth(far_value), None, "{c:?}");
            }
        }
        assert_eq!(checked, 20);
        let bad = |near, far| DepthConvention {
            near,
            far,
            reversed: true,
        };
        assert!(bad(0.0, None)
            .check()
            .unwrap_err()
            .contains("near plane is 0"));
        assert!(bad(1.0, Some(0.5))
            .check()
            .unwrap_err()
            .contains("far plane is 0.5"));
    }

    /// The ray cast's view depths and normals, as a `D32` depth image
    /// would hold them, give the ray cast's G-buffer: every hit a hit
    /// with the same flags but for pixels within rounding of N·L = 0,
    /// every entry's id `DEPTH_SURFACE`, and the points off by no more
    /// than the depth's rounding moves them (half an `f32` ulp of D, times
    /// dz/dD = z²(1 − n/f)/n, twice over) plus 2⁻¹⁶ of the µQuad. Reverse
    /// Z stays within 2⁻¹² of a µQuad (16 times inside the frustum test's
    /// depth tolerance); standard Z does not at a distance: the reason
    /// for a per-format note (paper-notes/embedding.md).
    #[test]
    #[cfg(feature = "cli")]
    fn ray_cast_depths_and_normals_give_the_ray_cast_g_buffer() {
        let mut checked = 0;
        for reversed in [true, false] {
            let scene = crate::scene::load("default")
                .unwrap()
                .with_resolution([64, 36])
                .unwrap();
            let bvh = SceneBvh::build(&scene);
            let cast = super::super::gbuffer(&scene, &bvh);
            let c = DepthConvention {
                near: scene.camera.near,
                far: Some(scene.camera.far),
                reversed,
            };
            let far_value = if reversed { 0.0 } else { 1.0 };
            let depth: Vec<f32> = cast
                .depth
                .iter()
                .map(|&z| {
                    if z.is_finite() {
                        c.depth_at(f64::from(z)) as f32
                    } else {
                        far_value
                    }
                })
                .collect();
            let from = gbuffer_from_depth(&scene, &depth, &cast.normal, c, 0.0).unwrap();
            assert_eq!(from.rejected, 0);
            let g = &from.gbuffer;
            let frame = scene.camera.frame(scene.resolution);
            let [w, _] = scene.resolution;
            let (mut flags_differ, mut worst) = (0, 0.0f64);
            for (i, &d) in depth.iter().enumerate() {
                let hit = cast.triangle_id[i] != crate::gbuffer::NO_HIT;
                let id = if hit {
                    DEPTH_SURFACE
                } else {
                    cast.triangle_id[i]
                };
                assert_eq!(g.triangle_id[i], id, "pixel {i}");
                flags_differ += usize::from(g.flags[i] != cast.flags[i]);
                if hit {
                    let size = f64::from(cast.axis_x[i].length().max(cast.axis_y[i].length()));
                    let z = f64::from(cast.depth[i]);
                    let (x, y) = ((i % w as usize) as f64 + 0.5, (i / w as usize) as f64 + 0.5);
                    let ray = frame.direction(x, y).length();
                    // 2⁻²⁴·D: at least half an ulp of D.
                    let half_ulp = f64::from(d) * 2f64.powi(-24);
                    let moved = 2.0 * ray * z * z * (1.0 - c.near_over_far()) / c.near * half_ulp;
                    let off = f64::from((g.position[i] - cast.position[i]).length());
                    assert!(
                        off <= moved + size / 65536.0,
                        "pixel {i}: {off} > {moved} + 2^-16 of {size}"
                    );
                    worst = worst.max(off / size);
                    checked += 1;
                }
            }
            assert!(flags_differ * 1000 <= scene.pixel_count(), "{flags_differ}");
            eprintln!("reversed {reversed}: P off by {worst:e} of the µQuad at most");
            if reversed {
                assert!(worst <= 1.0 / 4096.0, "{worst}");
            }
        }
        assert!(checked > 2000, "{checked}");
    }
}
