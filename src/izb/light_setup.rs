//! Pass 1, `light_setup`: the light-view frame and the light-space grid
//! bounds, fitted to the µQuads of the shadow-tested pixels.
//!
//! Light view is a rotation plus a translation (no projection, no scale):
//! every test runs there, relative to the pixel (seed 000: never in NDC).
//! Only the *grid lookup* uses light NDC: `(x, y)` for a directional light
//! (orthographic), `(x/z, y/z)` for a point light (perspective, z along the
//! light's view axis).

use crate::gbuffer::{flags, GBuffer};
use crate::scene::{Light, Scene};
use glam::{DMat3, DVec3, Mat3, Vec2, Vec3};

/// How light view maps to the 2-D grid plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Projection {
    /// Directional light: light view looks along the light; `+z` points
    /// toward the light; NDC = (x, y).
    Orthographic,
    /// Point light at the light-view origin looking along `+z`;
    /// NDC = (x/z, y/z).
    Perspective,
}

/// Everything later passes need to map points into light space.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LightSetup {
    pub projection: Projection,
    /// Rows are the light-view axes (x, y, z) in eye-relative world space.
    #[serde(skip)]
    pub rotation: Mat3,
    /// Light-view origin, eye-relative (f32: the renderer's own frame).
    pub origin: Vec3,
    /// Grid bounds in light NDC: lower and upper corner.
    pub ndc_min: Vec2,
    pub ndc_max: Vec2,
    /// Grid cells along x and y.
    pub cells: [u32; 2],
    /// Light-view depth range of the receivers' µQuads (z, toward the light
    /// for a directional light; distance along the axis for a point light).
    pub receiver_z: [f32; 2],
    /// Shadow-tested pixels the bounds were fitted to.
    pub receivers: usize,
    /// True when the receivers cannot be put in one perspective frustum of
    /// the point light (they surround it): the grid is then disabled and
    /// every triangle goes to the overflow list (still exact, only slower).
    pub grid_disabled: bool,
}

/// Closest a receiver may come to the point light's image plane, relative
/// to its distance range, before the perspective grid is given up.
const MIN_PERSPECTIVE_DEPTH_RATIO: f32 = 1e-3;

impl LightSetup {
    /// Light-view coordinates of an eye-relative point (f32, as on the GPU).
    #[inline]
    pub fn to_light_view(&self, eye_relative: Vec3) -> Vec3 {
        self.rotation * (eye_relative - self.origin)
    }

    /// Light-view direction of an eye-relative vector (µQuad axes).
    #[inline]
    pub fn rotate(&self, v: Vec3) -> Vec3 {
        self.rotation * v
    }

    /// Light NDC of a light-view point; `None` for a point at or behind a
    /// point light's image plane.
    #[inline]
    pub fn ndc(&self, p: Vec3) -> Option<Vec2> {
        match self.projection {
            Projection::Orthographic => Some(Vec2::new(p.x, p.y)),
            Projection::Perspective => (p.z > 0.0).then(|| Vec2::new(p.x / p.z, p.y / p.z)),
        }
    }

    /// Continuous grid coordinates (cells) of a light NDC point.
    #[inline]
    pub fn grid_coords(&self, ndc: Vec2) -> Vec2 {
        let size = Vec2::new(self.cells[0] as f32, self.cells[1] as f32);
        (ndc - self.ndc_min) / (self.ndc_max - self.ndc_min) * size
    }

    /// Light NDC of grid coordinates (the inverse of [`Self::grid_coords`]).
    #[inline]
    pub fn ndc_of_grid(&self, g: Vec2) -> Vec2 {
        let size = Vec2::new(self.cells[0] as f32, self.cells[1] as f32);
        self.ndc_min + g / size * (self.ndc_max - self.ndc_min)
    }

    /// Grid-space bounding box of the µQuad (centre `p`, axes `ex`, `ey`,
    /// eye-relative): the box of its projected corners, which holds the
    /// projection of every point of the µQuad, its centre included. NaN
    /// when a corner is not in front of a point light.
    pub fn microquad_grid_box(&self, p: Vec3, ex: Vec3, ey: Vec3) -> (Vec2, Vec2) {
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for c in microquad_corners(p, ex, ey) {
            let n = self.ndc(self.to_light_view(c)).unwrap_or(Vec2::NAN);
            let gc = self.grid_coords(n);
            lo = lo.min(gc);
            hi = hi.max(gc);
        }
        (lo, hi)
    }

    /// Light-view position of the light: the origin for a point light,
    /// `None` for a directional one (it is at +z infinity).
    pub fn light_position(&self) -> Option<Vec3> {
        (self.projection == Projection::Perspective).then_some(Vec3::ZERO)
    }
}

/// The light-view rotation of a directional light travelling along
/// `direction` (unit): rows x, y, z with z pointing toward the light. The
/// GPU `light_setup` receives exactly this matrix.
pub fn directional_rotation(direction: DVec3) -> Mat3 {
    basis_with_z(-direction).as_mat3()
}

/// An orthonormal basis whose third row is `z`.
fn basis_with_z(z: DVec3) -> DMat3 {
    let helper = if z.y.abs() < 0.9 { DVec3::Y } else { DVec3::X };
    let x = helper.cross(z).normalize();
    let y = z.cross(x);
    DMat3::from_cols(x, y, z).transpose()
}

/// The four corners of a pixel's µQuad, eye-relative.
pub fn microquad_corners(p: Vec3, ex: Vec3, ey: Vec3) -> [Vec3; 4] {
    let (hx, hy) = (ex * 0.5, ey * 0.5);
    [p - hx - hy, p + hx - hy, p + hx + hy, p - hx + hy]
}

/// Cells along the grid's longer side when none is asked for: a square grid
/// with about 4 receivers per cell, or about 16 triangles per cell where
/// the scene has more than 4 triangles per receiver (a dense scene at a low
/// resolution would otherwise put thousands of triangles in every cell),
/// clamped to 8..=1024. The shorter side keeps cells square in NDC. The GPU
/// `light_setup` computes the same expression in `f32`.
pub fn default_grid_side(receivers: usize, triangles: usize) -> u32 {
    let per_cell = (receivers as f32 / 4.0).max(triangles as f32 / 16.0);
    (per_cell.sqrt().ceil() as u32).clamp(8, 1024)
}

/// Fits the light view and grid to the shadow-tested pixels of `gbuffer`.
/// `cells_hint` overrides the automatic grid size (cells along the longer
/// side).
pub fn light_setup(scene: &Scene, gbuffer: &GBuffer, cells_hint: Option<u32>) -> LightSetup {
    let light = scene.light.relative_to(scene.camera.eye);
    let tested: Vec<usize> = (0..gbuffer.flags.len())
        .filter(|&i| gbuffer.flags[i] & flags::SHADOW_TESTED != 0)
        .collect();
    // Receivers' eye-relative bounds centre: the light-view origin of a
    // directional light, the aim of a point light.
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for &i in &tested {
        lo = lo.min(gbuffer.position[i]);
        hi = hi.max(gbuffer.position[i]);
    }
    let centre = if tested.is_empty() {
        Vec3::ZERO
    } else {
        (lo + hi) * 0.5
    };
    let (projection, rotation, origin) = match light {
        Light::Directional { direction } => {
            (Projection::Orthographic, basis_with_z(-direction), centre)
        }
        Light::Point { position } => {
            let axis = (centre.as_dvec3() - position).normalize_or(DVec3::NEG_Y);
            (
                Projection::Perspective,
                basis_with_z(axis),
                position.as_vec3(),
            )
        }
    };
    let mut setup = LightSetup {
        projection,
        rotation: rotation.as_mat3(),
        origin,
        ndc_min: Vec2::ZERO,
        ndc_max: Vec2::ONE,
        cells: [1, 1],
        receiver_z: [0.0, 0.0],
        receivers: tested.len(),
        grid_disabled: false,
    };
    let (mut nmin, mut nmax) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    let (mut zmin, mut zmax) = (f32::INFINITY, f32::NEG_INFINITY);
    for &i in &tested {
        for corner in microquad_corners(gbuffer.position[i], gbuffer.axis_x[i], gbuffer.axis_y[i]) {
            let p = setup.to_light_view(corner);
            zmin = zmin.min(p.z);
            zmax = zmax.max(p.z);
            match setup.ndc(p) {
                Some(n) => {
                    nmin = nmin.min(n);
                    nmax = nmax.max(n);
                }
                None => setup.grid_disabled = true,
            }
        }
    }
    if tested.is_empty() {
        return setup;
    }
    if projection == Projection::Perspective && zmin <= MIN_PERSPECTIVE_DEPTH_RATIO * zmax {
        setup.grid_disabled = true;
    }
    setup.receiver_z = [zmin, zmax];
    if setup.grid_disabled {
        return setup;
    }
    // Pad the bounds by a relative 1e-4 so µQuad corners on the boundary
    // stay inside after rounding.
    let pad = (nmax - nmin).max_element().max(f32::MIN_POSITIVE) * 1e-4;
    setup.ndc_min = nmin - pad;
    setup.ndc_max = nmax + pad;
    let longest =
        cells_hint.unwrap_or_else(|| default_grid_side(tested.len(), scene.triangles.len()));
    let extent = setup.ndc_max - setup.ndc_min;
    let (cx, cy) = if extent.x >= extent.y {
        (
            longest,
            ((longest as f32 * extent.y / extent.x).ceil() as u32).max(1),
        )
    } else {
        (
            ((longest as f32 * extent.x / extent.y).ceil() as u32).max(1),
            longest,
        )
    };
    setup.cells = [cx, cy];
    setup
}
