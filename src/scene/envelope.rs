//! The precision envelope: the scene sizes and point-light distances in
//! which the `f32` passes stay exact (agree with the `f64` same-sample
//! reference sample for sample, decisions within their documented margin
//! excepted). Outside it a scene is refused by name, never rendered with
//! shadows that silently went wrong. Measured with
//! `examples/precision_envelope.rs` (`paper-notes/precision-envelope.md`):
//! every quantity is a ratio or an eye-relative length, since the passes
//! work relative to the eye and the pixel's P, so moving a scene away from
//! the origin (tried to 10⁸ radii) changes nothing.

use super::{Light, Scene};
use glam::DVec3;

/// Smallest eye-relative radius (the farthest bounds corner from the eye):
/// exact down to 3.2·10⁻⁹ (`default` scaled by 10⁻¹⁰); at 3.2·10⁻¹¹ the
/// depth test's `f32` plane normals underflow and shadows vanish. (Until
/// the CPU tree was scaled by a power of two, `obvhs`'s absolute 10⁻⁴
/// entry clamp made primary rays miss from 3.2·10⁻⁴: the limit was 10⁻².)
pub const MIN_EYE_RADIUS: f64 = 1e-9;

/// Largest eye-relative radius: exact up to 3.2·10¹⁰ (`default` scaled by
/// 10⁹); at 3.2·10¹¹ (and `city` at 3.6·10¹¹) shadows vanished: the
/// depth test's `f32` plane normals overflow (their squared length grows
/// as the fourth power of the scale).
pub const MAX_EYE_RADIUS: f64 = 1e9;

/// Farthest the eye may be from the scene, in scene radii: the scene's
/// reach from the eye over its own radius (half the bounds' diagonal).
/// Eye-relative `f32` positions round by ~reach·2⁻²⁴, which must stay far
/// below the scene's detail. `default` moved back along its view with the
/// field narrowed to frame the same image: exact to 10² radii, then 29
/// samples beyond float rounding at 3·10² and 492 at 10³ (160×90); the
/// numeric-extremes run found its small scenes wrong from 2·10⁴ radii on.
/// Ten times inside the first distance found wrong.
pub const MAX_EYE_REACH_RADII: f64 = 30.0;

/// Farthest the scene and its camera may lie from the origin, in units of
/// the smaller of its reach from the eye and the eye's distance to its
/// target: the passes subtract the eye in `f64`, so only the scene's own
/// `f64` coordinates (and the camera's, which set the view) round with the
/// distance. Moved 10¹⁰ radii (`default`, 2·10¹¹ units) the masks equal
/// the unmoved scene's; at 10¹² the `f64` vertices had rounded enough to
/// change the image. The numeric-extremes run found finer cases: a canopy
/// of small triangles and a camera 10⁻⁵ units from its target changed
/// their edge pixels' samples from 3·10⁸ such lengths (the inputs
/// themselves round by 10⁻⁸ of them): ten times inside that (was 10⁹).
pub const MAX_ORIGIN_RADII: f64 = 1e7;

/// Farthest a point light may be from the scene's centre, in scene radii
/// (half the bounds' diagonal): exact to 10⁵ on `default`, `far` and
/// `city`; at 10⁶ the light view lost occluders. A light that far is, to
/// within 1/10⁴ radian across the scene, the directional light toward it.
pub const MAX_POINT_LIGHT_RADII: f64 = 1e4;

/// Refuses `scene` when it lies outside the envelope, naming the quantity,
/// its value and the limit.
pub fn check(scene: &Scene) -> Result<(), String> {
    check_within(scene, scene.bounds())
}

/// [`check`] with the scene's bounds known (`Scene::bounds`): a view of a
/// resident scene (`crate::gpu::shadow_pass`) is checked without a walk
/// over its triangles.
pub fn check_within(scene: &Scene, (lo, hi): (DVec3, DVec3)) -> Result<(), String> {
    let eye = scene.camera.eye;
    let eye_radius = (lo - eye).abs().max((hi - eye).abs()).length();
    if eye_radius < MIN_EYE_RADIUS {
        return Err(format!(
            "the scene reaches only {eye_radius:.3e} units from the eye, below the {MIN_EYE_RADIUS:e} \
             the f32 passes are exact at: scale the scene and its camera up by one factor (the \
             shadows do not change)"
        ));
    }
    if eye_radius > MAX_EYE_RADIUS {
        return Err(format!(
            "the scene reaches {eye_radius:.3e} units from the eye, beyond the {MAX_EYE_RADIUS:e} the \
             f32 passes are exact at: scale the scene and its camera down by one factor (the \
             shadows do not change)"
        ));
    }
    // Half the bounds' diagonal; never 0, so the ratios below stay finite.
    let scene_radius = ((hi - lo).length() * 0.5).max(f64::MIN_POSITIVE);
    let reach_radii = eye_radius / scene_radius;
    if reach_radii > MAX_EYE_REACH_RADII {
        return Err(format!(
            "the scene reaches {eye_radius:.3e} units from the eye, {reach_radii:.3e} times its \
             own {scene_radius:.3e} radius and beyond the {MAX_EYE_REACH_RADII} radii at which \
             eye-relative f32 positions keep its detail: move the camera nearer the scene (a \
             wider field of view frames the same)"
        ));
    }
    let farthest = lo
        .abs()
        .max(hi.abs())
        .max(eye.abs())
        .max(scene.camera.target.abs())
        .length();
    let view = (scene.camera.target - eye).length();
    let (detail, what) = if view < eye_radius {
        (view, "the eye's distance to its target")
    } else {
        (eye_radius, "its reach from the eye")
    };
    let origin_radii = farthest / detail;
    if origin_radii > MAX_ORIGIN_RADII {
        return Err(format!(
            "the scene lies {farthest:.3e} units from the origin, {origin_radii:.3e} times \
             {what} ({detail:.3e}) and beyond the {MAX_ORIGIN_RADII:e} its f64 coordinates keep \
             its detail at: move the scene and its camera nearer the origin"
        ));
    }
    if let Light::Point { position } = scene.light {
        let centre = (lo + hi) * 0.5;
        let radii = (position - centre).length() / scene_radius;
        if radii > MAX_POINT_LIGHT_RADII {
            let toward = (centre - position).normalize();
            return Err(format!(
                "the point light is {radii:.3e} scene radii from the scene's centre, beyond the \
                 {MAX_POINT_LIGHT_RADII:e} its f32 light view is exact at; that far it is a \
                 directional light: use \"type\": \"directional\", \"direction\": [{:.6}, {:.6}, {:.6}]",
                toward.x, toward.y, toward.z
            ));
        }
    }
    Ok(())
}
