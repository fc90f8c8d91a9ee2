//! A minimal visibility-buffer pass (Burns and Hunt 2013) for a host that
//! has none, and the one the host example and its tests draw: the
//! shaders (`visibility_raster.vert` / `.frag`) and their push constants
//! ([`VisibilityView`]) from a [`Camera`]. The host builds the pipeline
//! in its own render pass (vertex input: location 0, three `f32`s;
//! colour attachment 0: `R32_UINT`, cleared to `0xFFFFFFFF`; a depth
//! attachment cleared to 0 and tested with `GREATER`: reverse Z; push
//! constants: one [`VisibilityView`] for the vertex and fragment stages;
//! the `geometryShader` feature, for `gl_PrimitiveID`; a viewport of the
//! whole image, `minDepth` 0, `maxDepth` 1, positive height, no depth
//! bias or clamp), and draws the scene's triangles in the scene's order —
//! the image it leaves is what
//! [`super::shadow_pass::GBufferInput::Visibility`] reads. A surface
//! exactly at the far plane gets depth 0, the clear value, and is not
//! drawn: the ray cast's `[near, far)`.
//!
//! Why the projection is built here and not by the host: the pass derives
//! each pixel's surface from the ray through its centre
//! ([`crate::scene::CameraFrame::direction`]); a projection made from the
//! same frame puts the rasteriser's sample on that ray, so the triangle
//! covering the sample is the one the ray meets first (up to the
//! rasteriser's edge rules and depth rounding).

pub use super::shared::VisibilityView;
use crate::gbuffer::DepthConvention;
use crate::scene::Camera;
use glam::DVec3;

/// The vertex shader's SPIR-V.
pub const VERTEX_SPIRV: &[u8] =
    include_bytes!(concat!(env!("OUT_DIR"), "/visibility_raster_vert.spv"));
/// The fragment shader's SPIR-V.
pub const FRAGMENT_SPIRV: &[u8] =
    include_bytes!(concat!(env!("OUT_DIR"), "/visibility_raster_frag.spv"));
/// The depth + normal G-buffer's vertex shader's SPIR-V: the same, with
/// the eye-relative position passed on for the normal.
pub const DEPTH_NORMAL_VERTEX_SPIRV: &[u8] =
    include_bytes!(concat!(env!("OUT_DIR"), "/depth_normal_raster_vert.spv"));
/// The depth + normal G-buffer's fragment shader's SPIR-V: the id into
/// attachment 0 and the geometric normal (`R32G32B32A32_SFLOAT`, xyz,
/// from the position's screen derivatives) into attachment 1; the depth
/// attachment under [`raster_view`]'s convention.
pub const DEPTH_NORMAL_FRAGMENT_SPIRV: &[u8] =
    include_bytes!(concat!(env!("OUT_DIR"), "/depth_normal_raster_frag.spv"));

/// The push constants that draw `camera`'s view of an image of
/// `resolution` pixels, for vertices relative to `origin` (subtracted in
/// f64 before the rounding to f32, so a far origin costs no precision),
/// with triangle ids from `first_triangle` on.
pub fn visibility_view(
    camera: &Camera,
    resolution: [u32; 2],
    origin: DVec3,
    first_triangle: u32,
) -> VisibilityView {
    let reverse_z = DepthConvention {
        near: camera.near,
        far: Some(camera.far),
        reversed: true,
    };
    raster_view(camera, resolution, origin, first_triangle, &reverse_z)
}

/// [`visibility_view`] with the depth written under `depth`: the clip z
/// whose z / w is [`DepthConvention::depth_at`] of the view depth w.
/// A host draws with depth test `GREATER` and clears to 0 under reverse
/// Z, `LESS` and 1 under standard Z.
pub fn raster_view(
    camera: &Camera,
    resolution: [u32; 2],
    origin: DVec3,
    first_triangle: u32,
    depth: &DepthConvention,
) -> VisibilityView {
    let frame = camera.frame(resolution);
    let f32s = |v: DVec3| v.as_vec3().to_array();
    // The reversed value is u = (n/w − n/f) / (1 − n/f): offset n/(1 − r)
    // over w, scale −r/(1 − r); standard Z is 1 − u.
    let (n, r) = (depth.near, depth.near_over_far());
    let (offset, scale) = (n / (1.0 - r), -r / (1.0 - r));
    let (offset, scale) = if depth.reversed {
        (offset, scale)
    } else {
        (-offset, 1.0 - scale)
    };
    VisibilityView {
        eye: f32s(camera.eye - origin),
        depth_offset: offset as f32,
        right: f32s(frame.right / (frame.tan_half_fov * frame.aspect)),
        first_triangle,
        down: f32s(-frame.up / frame.tan_half_fov),
        depth_scale: scale as f32,
        forward: f32s(frame.forward),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point on the ray through a pixel's centre projects onto that
    /// centre, at depth 1 on the near plane and 0 on the far.
    #[test]
    fn pixel_centre_rays_project_onto_their_pixels() {
        let camera = Camera {
            eye: DVec3::new(1.0, 2.0, 3.0),
            target: DVec3::new(-4.0, 0.5, 7.0),
            up: DVec3::Y,
            fov_y_deg: 50.0,
            near: 0.1,
            far: 300.0,
        };
        let resolution = [64, 36];
        let frame = camera.frame(resolution);
        let origin = DVec3::new(0.5, -1.0, 2.0);
        let view = visibility_view(&camera, resolution, origin, 0);
        let d = |v: [f32; 3]| DVec3::from(v.map(f64::from));
        let mut checked = 0;
        for (x, y) in [(0, 0), (63, 35), (17, 30), (40, 3)] {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let dir = frame.direction(px, py);
            for t in [camera.near, 5.0, camera.far] {
                let q = dir * t;
                let w = q.dot(d(view.forward));
                let sx = (q.dot(d(view.right)) / w + 1.0) * 0.5 * resolution[0] as f64;
                let sy = (q.dot(d(view.down)) / w + 1.0) * 0.5 * resolution[1] as f64;
                let z = (view.depth_offset as f64 + view.depth_scale as f64 * w) / w;
                assert!((sx - px).abs() < 1e-4 && (sy - py).abs() < 1e-4, "{x},{y}");
                // Reverse Z: near / far ↦ 1 / 0, and 1/d in between.
                let (n, f) = (camera.near, camera.far);
                let want = n * (f - t) / ((f - n) * t);
                assert!(
                    (z - want).abs() < 1e-5,
                    "{x},{y} at {t}: depth {z}, want {want}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 12);
    }

    /// Every convention's clip z over w is its `depth_at` of the view
    /// depth, from the near plane to far past the far one.
    #[test]
    fn raster_depth_follows_the_convention() {
        let camera = Camera {
            eye: DVec3::ZERO,
            target: DVec3::Z,
            up: DVec3::Y,
            fov_y_deg: 60.0,
            near: 0.1,
            far: 500.0,
        };
        let mut checked = 0;
        for reversed in [true, false] {
            for far in [Some(camera.far), None] {
                let c = DepthConvention {
                    near: camera.near,
                    far,
                    reversed,
                };
                let view = raster_view(&camera, [64, 36], DVec3::ZERO, 0, &c);
                for w in [0.1, 2.0, 77.0, 500.0, 4000.0] {
                    let z = (f64::from(view.depth_offset) + f64::from(view.depth_scale) * w) / w;
                    let want = c.depth_at(w);
                    assert!((z - want).abs() < 1e-6, "{c:?} at {w}: {z}, want {want}");
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 20);
    }
}
