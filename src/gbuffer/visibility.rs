//! The G-buffer from a host's visibility buffer — per pixel the id of the
//! triangle its raster saw (Burns and Hunt 2013) — the CPU twin of the
//! shadow pass's `gbuffer_from_visibility.comp`.
//!
//! A visibility buffer names the surface but not where on it the pixel's
//! centre lies; that follows exactly from the centre ray and the
//! triangle's plane, t = (n·A)/(n·D) — the same refinement the ray-cast
//! G-buffer applies to its hit — so a raster that sees the triangle the ray
//! cast sees gives the same entry, with no depth-buffer quantisation.

use super::{facing_normal, GBuffer, PixelSurface, SurfaceHit, NO_HIT};
use crate::scene::{CameraFrame, Light, Scene, Triangle};

/// [`gbuffer_from_visibility`]'s G-buffer, and how many pixels it stored
/// as misses because their id (with a multisampled buffer: any of their
/// samples' ids, and such a pixel nominates nothing for its neighbours)
/// named no triangle (other than [`NO_HIT`]) or a triangle whose plane
/// the centre ray does not cross in front of the eye.
pub struct VisibilityGBuffer {
    pub gbuffer: GBuffer,
    pub rejected: usize,
    /// With a multisampled buffer ([`super::gbuffer_from_multisampled_visibility`]):
    /// pixels some of whose samples saw a triangle but whose centre ray
    /// meets none that the samples of the pixel and its neighbours saw —
    /// the background between a silhouette's samples, or a triangle no
    /// sample saw — stored as misses.
    pub centre_uncovered: usize,
}

/// The G-buffer of `scene`'s view from `visibility`, row-major, one
/// triangle id per pixel (the scene's triangle order; [`NO_HIT`] for
/// none). An error names a buffer of the wrong size.
pub fn gbuffer_from_visibility(
    scene: &Scene,
    visibility: &[u32],
) -> Result<VisibilityGBuffer, String> {
    let [w, h] = scene.resolution;
    if visibility.len() != scene.pixel_count() {
        return Err(format!(
            "the visibility buffer holds {} ids; the view is {w}x{h}",
            visibility.len()
        ));
    }
    let triangles = scene.eye_relative_triangles();
    let frame = scene.camera.frame(scene.resolution);
    let light = scene.light.relative_to(scene.camera.eye);
    let mut g = GBuffer::with_capacity(w, h);
    let mut rejected = 0;
    for (i, &id) in visibility.iter().enumerate() {
        let pixel = ((i % w as usize) as u32, (i / w as usize) as u32);
        let surface = (id != NO_HIT).then(|| surface_of(&triangles, &frame, &light, pixel, id));
        rejected += usize::from(matches!(surface, Some(None)));
        g.push(surface.flatten().as_ref());
    }
    Ok(VisibilityGBuffer {
        gbuffer: g,
        rejected,
        centre_uncovered: 0,
    })
}

/// The entry of pixel (`x`, `y`) whose centre ray sees triangle `id` of
/// the eye-relative `triangles`: the point where the ray meets its plane;
/// `None` when `id` names no triangle or the ray does not cross the plane
/// in front of the eye.
pub(super) fn surface_of(
    triangles: &[Triangle],
    frame: &CameraFrame,
    light: &Light,
    (x, y): (u32, u32),
    id: u32,
) -> Option<PixelSurface> {
    let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
    let tri = triangles.get(id as usize)?;
    let d = frame.direction(px, py);
    let normal = facing_normal(tri, d);
    let t = normal.dot(tri[0]) / normal.dot(d);
    if !(t > 0.0 && t.is_finite()) {
        return None;
    }
    let hit = SurfaceHit {
        triangle: id,
        t,
        position: d * t,
        normal,
    };
    Some(PixelSurface::of_hit(frame, (px, py), hit, light))
}

#[cfg(test)]
mod tests {
    use super::*;
    #[cfg(feature = "cli")]
    use crate::bvh::SceneBvh;

    /// The longer µQuad axis of entry `i` (tolerances scale with it).
    #[cfg(feature = "cli")]
    fn footprint(g: &GBuffer, i: usize) -> f64 {
        let [x, y] = [g.axis_x[i], g.axis_y[i]].map(|a| f64::from(a.length()));
        x.max(y)
    }

    /// The ray-cast G-buffer's ids fed back as a visibility buffer give
    /// the ray cast's entries: the same ids and flags everywhere, points
    /// within a few ulps of the µQuad (the ray cast's t comes from its
    /// hit test, this one's from the plane), and the same stats.
    #[test]
    #[cfg(feature = "cli")]
    fn the_ray_cast_ids_give_the_ray_cast_g_buffer() {
        let mut checked = 0;
        for name in ["default", "city"] {
            let scene = crate::scene::load(name)
                .unwrap()
                .with_resolution([64, 36])
                .unwrap();
            let bvh = SceneBvh::build(&scene);
            let cast = super::super::gbuffer(&scene, &bvh);
            let v = gbuffer_from_visibility(&scene, &cast.triangle_id).unwrap();
            assert_eq!(v.rejected, 0, "{name}");
            let g = &v.gbuffer;
            assert_eq!(g.triangle_id, cast.triangle_id, "{name}");
            assert_eq!(g.flags, cast.flags, "{name}");
            for i in 0..g.position.len() {
                let scale = footprint(&cast, i).max(f64::MIN_POSITIVE);
                let off = (g.position[i] - cast.position[i]).as_dvec3().length();
                assert!(
                    off <= 1e-3 * scale,
                    "{name} pixel {i}: {off} off, µQuad {scale}"
                );
            }
            assert_eq!(g.stats.shadow_tested, cast.stats.shadow_tested);
            checked += 1;
        }
        assert_eq!(checked, 2);
    }

    /// An id past the scene's triangles is a rejected miss, `NO_HIT` a
    /// plain miss, and a buffer of the wrong size a named error.
    #[test]
    fn bad_ids_are_rejected_misses() {
        let scene = crate::scene::load("default")
            .unwrap()
            .with_resolution([16, 9])
            .unwrap();
        let n = scene.triangles.len() as u32;
        let mut ids = vec![NO_HIT; 16 * 9];
        ids[3] = n;
        ids[4] = n + 1000;
        let v = gbuffer_from_visibility(&scene, &ids).unwrap();
        assert_eq!(v.rejected, 2);
        assert_eq!(v.gbuffer.stats.hits, 0);
        assert!(v.gbuffer.triangle_id.iter().all(|&t| t == NO_HIT));
        let e = gbuffer_from_visibility(&scene, &ids[1..]).err().unwrap();
        assert!(e.contains("143 ids") && e.contains("16x9"), "{e}");
    }
}
