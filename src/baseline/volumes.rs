//! Shadow volumes (Crow 1977; Agenjo 2020), counted depth-fail (Everitt &
//! Kilgard 2002, "Carmack's reverse"): exact hard shadows at one sample
//! per pixel, the rasteriser's exact competitor of `izb1`.
//!
//! Every triangle casts its own closed volume — per-triangle volumes, as
//! Sintorn et al. 2011 use for the triangle soups most real scenes are
//! (silhouette extraction needs closed, consistently wound meshes, which
//! glTF does not promise): the triangle turned to face the light as the
//! light cap, its vertices moved [`FrameParams::volume_extrusion`] away
//! from the light as the dark cap, three side quads
//! ([`izb_contract::VOLUME_CORNERS`]). A pixel is in shadow when the
//! volumes' faces *behind* its receiver point, back faces +1 and front
//! faces −1, do not sum to 0 modulo 256 (the 8-bit stencil wraps: a
//! point inside a multiple of 256 volumes reads as lit, the method's own
//! limit). Counting behind the receiver makes the near plane harmless,
//! and the dark cap lies past every receiver, so no far plane is needed.
//!
//! The receiver's depth is moved toward the camera by
//! [`NUDGE_PIXELS`] of its pixel's footprint: the receiver lies on its own
//! triangle's light cap, and moved so it sits outside its own volume,
//! which a tie at equal depth would not decide.
//!
//! The GPU draws the volumes on the rasteriser into a D32_SFLOAT_S8_UINT
//! attachment holding the receivers' depths (`crate::gpu::shadow_volumes`,
//! `shaders/shadow_volume.vert`); this CPU twin rasterises the same faces
//! by the same rules ([`super::raster`]) and counts the same way.
//!
//! [`FrameParams::volume_extrusion`]: izb_contract::FrameParams

use super::raster::{clip_to_plane, raster_triangle, snapped_area, RasterBias, RasterTriangle};
use super::screen_frame::ScreenFrame;
use crate::cpu::eye_relative_f32;
use crate::cpu::light_setup::Projection;
use crate::gbuffer::{flags, GBuffer};
use crate::scene::Scene;
use glam::{Vec2, Vec3};
use izb_contract::VOLUME_CORNERS;
use rayon::prelude::*;
use std::sync::atomic::{AtomicI32, Ordering};
use std::time::Instant;

/// How far a receiver moves toward the camera before the depth test, in
/// widths of its pixel's footprint at its depth. Measured against `izb1`
/// and the `f64` ray from the receiver to the light on all 12 scenes at
/// 160×90: a larger nudge moves receivers into volumes whose faces pass
/// just in front of them (1/16: 3.2 % of hairball's pixels wrong, 1/256:
/// 0.56 %, 1/1024: 0.23 %), a smaller one loses the tie with the
/// receiver's own light cap to the float depth's rounding (1/16 384:
/// the GPU and CPU counts part on 12 % of `analytic`'s pixels; 1/65 536:
/// 2.4 % wrong on `default`).
pub const NUDGE_PIXELS: f32 = izb_contract::tolerance::VOLUME_NUDGE_PIXELS;

/// The volume-specific parts of the frame.
impl ScreenFrame {
    /// The six corners of `tri`'s volume (light cap, then dark cap), or
    /// `None` when the triangle is edge-on to the light (no volume).
    /// `shadow_volume.vert` computes the same, same order.
    pub fn corners(&self, tri: [Vec3; 3]) -> Option<[Vec3; 6]> {
        let [a, mut b, mut c] = tri;
        let n = (b - a).cross(c - a);
        let to_light = if self.point_light {
            self.light_vec - a
        } else {
            self.light_vec
        };
        let facing = n.dot(to_light);
        if facing.is_nan() || facing == 0.0 {
            return None;
        }
        if facing < 0.0 {
            std::mem::swap(&mut b, &mut c);
        }
        let away = |v: Vec3| {
            if self.point_light {
                let d = v - self.light_vec;
                v + d * (self.extrusion / d.length())
            } else {
                v - self.light_vec * self.extrusion
            }
        };
        Some([a, b, c, away(a), away(b), away(c)])
    }

    /// The depth a receiver at eye-relative `p` is tested at: moved
    /// toward the camera by [`NUDGE_PIXELS`] of its footprint.
    pub fn receiver_depth(&self, p: Vec3) -> f32 {
        let s = self.view_depth(p);
        let nudge = NUDGE_PIXELS * self.dx.length();
        self.depth(s - s * nudge)
    }
}

/// Clips a face to the near plane `s ≥ near` (as the rasteriser clips at
/// `z ≤ w`); up to four corners.
fn clip_to_near(frame: &ScreenFrame, face: [Vec3; 3]) -> Vec<Vec3> {
    clip_to_plane(face, |v| frame.view_depth(v) - frame.near)
}

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct VolumesReport {
    pub seconds: f64,
    /// Casters with a volume (not edge-on to the light).
    pub volumes: usize,
    /// Volume fragments rasterised: the fill cost.
    pub fragments: u64,
    /// `fragments` per pixel of the image.
    pub fragments_per_pixel: f64,
    /// Shadow-tested pixels inside a nonzero multiple of 256 volumes: the
    /// 8-bit stencil wraps to 0 and reads them lit (the full count says
    /// shadow). The method's own error, counted so it is seen.
    pub wrapped_pixels: usize,
    /// The largest count at a shadow-tested pixel (volumes it lies in,
    /// counted from behind): how far the scene stays from the wrap.
    pub deepest_count: u32,
}

pub struct VolumesRender {
    /// Lit fraction (0 or 1), NaN where not shadow-tested.
    pub visibility: Vec<f32>,
    pub report: VolumesReport,
}

/// Renders `volumes` on the CPU into the G-buffer `g` of `scene`.
pub fn shadow_volumes(scene: &Scene, g: &GBuffer) -> VolumesRender {
    let start = Instant::now();
    let frame = ScreenFrame::new(scene);
    let [w, h] = scene.resolution;
    let pixels = (w * h) as usize;
    let receiver: Vec<f32> = (0..pixels)
        .into_par_iter()
        .map(|i| match g.flags[i] & flags::SHADOW_TESTED {
            0 => 0.0,
            _ => frame.receiver_depth(g.position[i]),
        })
        .collect();
    let count: Vec<AtomicI32> = (0..pixels).map(|_| AtomicI32::new(0)).collect();
    let no_bias = RasterBias {
        constant_factor: 0.0,
        slope_factor: 0.0,
    };
    let (volumes, fragments) = eye_relative_f32(scene)
        .par_iter()
        .map(|&tri| {
            let Some(corners) = frame.corners(tri) else {
                return (0, 0u64);
            };
            let mut fragments = 0;
            for face in VOLUME_CORNERS.chunks_exact(3) {
                let face = [0, 1, 2].map(|k| corners[face[k] as usize]);
                let polygon = clip_to_near(&frame, face);
                if polygon.len() < 3 {
                    continue;
                }
                let at: Vec<Vec2> = polygon.iter().map(|&q| frame.framebuffer(q)).collect();
                let depth: Vec<f32> = polygon
                    .iter()
                    .map(|&q| frame.depth(frame.view_depth(q)))
                    .collect();
                for k in 1..polygon.len() - 1 {
                    let fan = RasterTriangle {
                        position: [at[0], at[k], at[k + 1]],
                        depth: [depth[0], depth[k], depth[k + 1]],
                    };
                    // Back faces (positive snapped area) count +1 where
                    // they fail the depth test, front faces −1.
                    let step = if snapped_area(&fan.position) > 0.0 {
                        1
                    } else {
                        -1
                    };
                    fragments += raster_triangle(
                        &fan,
                        [w, h],
                        Projection::Perspective,
                        no_bias,
                        |x, y, d| {
                            let i = (y * w + x) as usize;
                            // GREATER fails: the face is not in front.
                            if d <= receiver[i] {
                                count[i].fetch_add(step, Ordering::Relaxed);
                            }
                        },
                    );
                }
            }
            (1, fragments)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    let (mut wrapped_pixels, mut deepest_count) = (0, 0);
    let visibility = (0..pixels)
        .map(|i| {
            let count = count[i].load(Ordering::Relaxed);
            if g.flags[i] & flags::SHADOW_TESTED == 0 {
                return f32::NAN;
            }
            deepest_count = deepest_count.max(count.unsigned_abs());
            if count.rem_euclid(256) == 0 {
                wrapped_pixels += (count != 0) as usize;
                1.0
            } else {
                0.0
            }
        })
        .collect();
    VolumesRender {
        visibility,
        report: VolumesReport {
            seconds: start.elapsed().as_secs_f64(),
            volumes,
            fragments,
            fragments_per_pixel: fragments as f64 / pixels.max(1) as f64,
            wrapped_pixels,
            deepest_count,
        },
    }
}
