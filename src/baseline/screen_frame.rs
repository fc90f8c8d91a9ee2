//! The frame of the screen-space baselines: what shadow volumes
//! ([`super::volumes`]) and contact shadows ([`super::contact`]) need of
//! the light and the camera, and the camera's projection as the
//! rasteriser computes it.

use crate::scene::{Light, Scene};
use glam::{Vec2, Vec3};

/// The light and the camera as the screen-space baselines (shadow volumes,
/// contact shadows) need them, in the renderer's `f32` eye-relative
/// space (the GPU gets these very values; `shaders/camera.glsl` is the
/// twin of its camera functions).
#[derive(Clone, Copy, Debug)]
pub struct ScreenFrame {
    /// Toward the light (directional, unit) or the light's position.
    pub light_vec: Vec3,
    pub point_light: bool,
    /// How far a shadow volume's dark cap lies beyond its light cap:
    /// twice the scene's diagonal, past every receiver.
    pub extrusion: f32,
    /// The camera: ray direction through pixel (0, 0)'s corner, its
    /// derivatives per pixel, the view direction, the near plane.
    pub corner: Vec3,
    pub dx: Vec3,
    pub dy: Vec3,
    pub forward: Vec3,
    pub near: f32,
    pub size: [u32; 2],
}

impl ScreenFrame {
    pub fn new(scene: &Scene) -> ScreenFrame {
        let frame = scene.camera.frame(scene.resolution);
        let (light_vec, point_light) = match scene.light.relative_to(scene.camera.eye) {
            Light::Directional { direction } => ((-direction).as_vec3(), false),
            Light::Point { position } => (position.as_vec3(), true),
        };
        let (lo, hi) = scene.bounds();
        ScreenFrame {
            light_vec,
            point_light,
            extrusion: (2.0 * (hi - lo).length()) as f32,
            corner: frame.direction(0.0, 0.0).as_vec3(),
            dx: frame.direction_dx().as_vec3(),
            dy: frame.direction_dy().as_vec3(),
            forward: frame.forward.as_vec3(),
            near: scene.camera.near as f32,
            size: scene.resolution,
        }
    }

    /// View depth of an eye-relative point.
    #[inline]
    pub fn view_depth(&self, q: Vec3) -> f32 {
        q.dot(self.forward)
    }

    /// Framebuffer position of an eye-relative point in front of the near
    /// plane: the vertex shader's clip position, the division by `w` and
    /// the viewport transform, rounded as the GPU rounds them.
    pub fn framebuffer(&self, q: Vec3) -> Vec2 {
        let s = self.view_depth(q);
        let [w, h] = self.size.map(|v| v as f32);
        let r = q - self.corner * s;
        let clip = Vec2::new(
            r.dot(self.dx) / self.dx.dot(self.dx) * (2.0 / w) - s,
            r.dot(self.dy) / self.dy.dot(self.dy) * (2.0 / h) - s,
        );
        let ndc = clip / s;
        Vec2::new(ndc.x * (w * 0.5) + w * 0.5, ndc.y * (h * 0.5) + h * 0.5)
    }

    /// The reversed depth `near / s` the attachment holds for view depth
    /// `s`.
    #[inline]
    pub fn depth(&self, s: f32) -> f32 {
        self.near / s
    }
}
