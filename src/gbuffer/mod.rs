//! Primary visibility: the G-buffer every later pass reads (README, Conventions).
//!
//! CPU twin of the GPU G-buffer pass: one `f64` ray per pixel centre against
//! the real geometry. Per pixel it stores the hit triangle, the view depth,
//! the eye-relative hit point, the geometric normal flipped to face the
//! camera, whether the pixel is shadow-tested, and the µQuad axes
//! `Ex = dP/dx`, `Ey = dP/dy` (Wyman et al. 2015, §4: the pixel's footprint on its
//! tangent plane, the base of its shadow frustum).

mod depth;
pub mod edge_surfaces;
mod multisampled;
mod visibility;

pub use depth::{
    depth_uncertainty, gbuffer_from_depth, DepthConvention, DEPTH_SURFACE, UNORM24_DEPTH_STEP,
};
pub use multisampled::{
    gbuffer_from_multisampled_visibility, gbuffer_from_multisampled_visibility_on,
    MAX_VISIBILITY_SAMPLES,
};
pub use visibility::{gbuffer_from_visibility, VisibilityGBuffer};
// The ray-cast producer needs the CPU BVH (obvhs): not part of the pass
// alone (`--no-default-features`).
#[cfg(feature = "cli")]
mod ray_cast;
#[cfg(feature = "cli")]
pub use ray_cast::{gbuffer, gbuffer_with, pixel_surface, trace_primary};

use crate::scene::{CameraFrame, Light};
use edge_surfaces::EdgeSurfaces;
use glam::{DVec3, Vec3};

/// Triangle id of a pixel whose centre ray hits nothing.
pub const NO_HIT: u32 = izb_contract::word::NO_HIT;

/// Largest µQuad axis length, in units of the pixel's footprint on a plane
/// facing the ray. At grazing views (N·V → 0) the exact axes grow without
/// bound; beyond 64× (N·V < 1/64, 89.1° from the normal) they are scaled
/// down to this length. The same clamp must be used by every consumer of
/// µQuads (paper-notes/reference-estimator.md); clamped pixels are counted in [`GBufferStats`].
pub const MAX_MICROQUAD_STRETCH: f64 = 64.0;

/// Per-pixel flags.
pub use izb_contract::flags;

/// The primary hit of one ray, in `f64`, eye-relative.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    pub triangle: u32,
    /// Ray parameter along the unnormalised camera direction: equal to the
    /// view depth, since that direction has unit component along `forward`.
    pub t: f64,
    pub position: DVec3,
    /// Unit geometric normal, flipped to face the camera.
    pub normal: DVec3,
}

/// The unit geometric normal of `tri`, flipped to face a ray along
/// `direction`.
pub fn facing_normal(tri: &crate::scene::Triangle, direction: DVec3) -> DVec3 {
    let normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
    if normal.dot(direction) > 0.0 {
        -normal
    } else {
        normal
    }
}

/// Exact µQuad axes at the pixel whose centre ray hit `hit`: the derivatives
/// with respect to pixel x and y of the intersection of the ray with the
/// hit's tangent plane. With D(x, y) the unnormalised ray direction (affine
/// in x, y) and P = s·D, s = (n·P₀)/(n·D):
/// `dP/dx = s · (dD/dx − (n·dD/dx)/(n·D) · D)` (and likewise for y).
/// Returns the axes after the grazing clamp and whether it applied.
pub fn microquad_axes(
    frame: &CameraFrame,
    px: f64,
    py: f64,
    hit: &SurfaceHit,
) -> (DVec3, DVec3, bool) {
    let d = frame.direction(px, py);
    let n = hit.normal;
    let n_dot_d = n.dot(d);
    let axis = |dd: DVec3| hit.t * (dd - d * (n.dot(dd) / n_dot_d));
    let (mut ex, mut ey) = (axis(frame.direction_dx()), axis(frame.direction_dy()));
    // Footprint of one pixel on a plane facing the ray at this distance.
    let facing = hit.t * frame.direction_dx().length() * d.length();
    let limit = MAX_MICROQUAD_STRETCH * facing;
    let mut clamped = false;
    for a in [&mut ex, &mut ey] {
        let len = a.length();
        // NaN or infinite axes (a ray exactly in the plane) also clamp.
        if len.is_nan() || len > limit {
            *a = if len.is_finite() {
                *a * (limit / len)
            } else {
                DVec3::ZERO
            };
            clamped = true;
        }
    }
    (ex, ey, clamped)
}

/// Whether a surface point with camera-facing normal `normal` faces the light.
pub fn faces_light(light: &Light, position: DVec3, normal: DVec3) -> bool {
    normal.dot(light.toward(position).0) > 0.0
}

/// Counts over the image.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct GBufferStats {
    pub pixels: usize,
    pub hits: usize,
    pub shadow_tested: usize,
    pub clamped_microquads: usize,
}

/// Struct-of-arrays G-buffer, row-major, `f32` and eye-relative so a GPU
/// buffer can mirror it one array per binding.
#[derive(Clone, Debug)]
pub struct GBuffer {
    pub width: u32,
    pub height: u32,
    /// Hit triangle id, [`NO_HIT`] for a miss.
    pub triangle_id: Vec<u32>,
    /// View depth of the hit, +inf for a miss.
    pub depth: Vec<f32>,
    /// Eye-relative hit point.
    pub position: Vec<Vec3>,
    /// Unit geometric normal facing the camera.
    pub normal: Vec<Vec3>,
    /// µQuad axis along +x pixels (`dP/dx`).
    pub axis_x: Vec<Vec3>,
    /// µQuad axis along +y pixels (`dP/dy`, y down).
    pub axis_y: Vec<Vec3>,
    /// [`flags`] bits.
    pub flags: Vec<u32>,
    pub stats: GBufferStats,
    /// The edge pixels' per-sample surfaces ([`gbuffer_with`]), `None`
    /// when every sample stands on its pixel's centre surface.
    pub edges: Option<Box<EdgeSurfaces>>,
    /// `Paired64`'s second half's: the surfaces its own µQuad pattern's
    /// samples see (samples 32–63), when the G-buffer has two halves.
    pub edges_high: Option<Box<EdgeSurfaces>>,
    /// Per entry, how far its point may lie off its surface along the
    /// normal: a host depth's error ([`gbuffer_from_depth`]), by which the
    /// frustum test's depth tolerance grows. `None` where every point is
    /// exact to rounding.
    pub depth_uncertainty: Option<Vec<f32>>,
}

impl GBuffer {
    /// An empty G-buffer of `width × height` entries.
    fn with_capacity(width: u32, height: u32) -> GBuffer {
        let n = width as usize * height as usize;
        GBuffer {
            width,
            height,
            triangle_id: Vec::with_capacity(n),
            depth: Vec::with_capacity(n),
            position: Vec::with_capacity(n),
            normal: Vec::with_capacity(n),
            axis_x: Vec::with_capacity(n),
            axis_y: Vec::with_capacity(n),
            flags: Vec::with_capacity(n),
            stats: GBufferStats {
                pixels: n,
                ..Default::default()
            },
            edges: None,
            edges_high: None,
            depth_uncertainty: None,
        }
    }

    /// Appends one entry (`None`: a miss), rounding the `f64` surface.
    fn push(&mut self, s: Option<&PixelSurface>) {
        match s {
            Some(s) => {
                let mut f = flags::HIT;
                self.stats.hits += 1;
                if s.shadow_tested {
                    f |= flags::SHADOW_TESTED;
                    self.stats.shadow_tested += 1;
                }
                if s.axes_clamped {
                    f |= flags::AXES_CLAMPED;
                    self.stats.clamped_microquads += 1;
                }
                self.triangle_id.push(s.hit.triangle);
                self.depth.push(s.hit.t as f32);
                self.position.push(s.hit.position.as_vec3());
                self.normal.push(s.hit.normal.as_vec3());
                self.axis_x.push(s.axis_x.as_vec3());
                self.axis_y.push(s.axis_y.as_vec3());
                self.flags.push(f);
            }
            None => {
                self.triangle_id.push(NO_HIT);
                self.depth.push(f32::INFINITY);
                self.position.push(Vec3::ZERO);
                self.normal.push(Vec3::ZERO);
                self.axis_x.push(Vec3::ZERO);
                self.axis_y.push(Vec3::ZERO);
                self.flags.push(0);
            }
        }
    }

    /// Keeps the first `n` entries.
    pub fn truncate(&mut self, n: usize) {
        self.triangle_id.truncate(n);
        self.depth.truncate(n);
        self.position.truncate(n);
        self.normal.truncate(n);
        self.axis_x.truncate(n);
        self.axis_y.truncate(n);
        self.flags.truncate(n);
        if let Some(u) = &mut self.depth_uncertainty {
            u.truncate(n);
        }
    }

    /// Entries `order` of this G-buffer as a one-row G-buffer (no edges).
    pub fn select(&self, order: &[usize]) -> GBuffer {
        let mut g = GBuffer::with_capacity(order.len() as u32, 1);
        for &k in order {
            g.triangle_id.push(self.triangle_id[k]);
            g.depth.push(self.depth[k]);
            g.position.push(self.position[k]);
            g.normal.push(self.normal[k]);
            g.axis_x.push(self.axis_x[k]);
            g.axis_y.push(self.axis_y[k]);
            g.flags.push(self.flags[k]);
        }
        g.depth_uncertainty = self
            .depth_uncertainty
            .as_ref()
            .map(|u| order.iter().map(|&k| u[k]).collect());
        g
    }

    /// The samples that count at pixel `i` over `halves` mask halves: 32 a
    /// half, or with that half's edge surfaces those on a kept surface
    /// (the lit fraction's denominator on both backends).
    pub fn counted_samples(&self, i: usize, halves: usize) -> u32 {
        [&self.edges, &self.edges_high]
            .iter()
            .take(halves)
            .map(|e| e.as_ref().map_or(32, |e| e.counted[i].count_ones()))
            .sum()
    }

    /// Every receiver entry: the pixels' centre surfaces, then the edge
    /// pixels' extra surfaces of each half (each as a one-row G-buffer).
    pub fn layers(&self) -> impl Iterator<Item = &GBuffer> {
        std::iter::once(self)
            .chain(self.edges.as_deref().map(|e| &e.surfaces))
            .chain(self.edges_high.as_deref().map(|e| &e.surfaces))
    }
}

/// One pixel's G-buffer entry in `f64` (the form the reference uses).
#[derive(Clone, Copy, Debug)]
pub struct PixelSurface {
    pub hit: SurfaceHit,
    pub axis_x: DVec3,
    pub axis_y: DVec3,
    pub axes_clamped: bool,
    pub shadow_tested: bool,
}

impl PixelSurface {
    /// The entry of `hit`, seen through image point (`px`, `py`): its
    /// µQuad axes and whether it faces `light` (eye-relative).
    pub fn of_hit(
        frame: &CameraFrame,
        (px, py): (f64, f64),
        hit: SurfaceHit,
        light: &Light,
    ) -> Self {
        let (axis_x, axis_y, axes_clamped) = microquad_axes(frame, px, py, &hit);
        PixelSurface {
            hit,
            axis_x,
            axis_y,
            axes_clamped,
            shadow_tested: faces_light(light, hit.position, hit.normal),
        }
    }
}
