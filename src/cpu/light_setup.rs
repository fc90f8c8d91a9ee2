//! Pass 1, `light_setup`: the light-view frame and the light-space grid
//! bounds, fitted to the µQuads of the shadow-tested pixels.
//!
//! Light view is a rotation plus a translation (no projection, no scale):
//! every test runs there, relative to the pixel ([Compute IZB]: never in NDC).
//! Only the *grid lookup* uses light NDC: `(x, y)` for a directional light
//! (orthographic), `(x/z, y/z)` for a point light (perspective, z along the
//! light's view axis).

use crate::cascades::{self, CascadeChoice, CascadeCount, MAX_CASCADES};
use crate::cpu::simd::SimdPath;
use crate::frustum::LightRel;
use crate::gbuffer::GBuffer;
use crate::scene::{light_disk_f32, Light, LightDisk, Scene};
use glam::{DMat3, DVec3, Mat3, Vec2, Vec3};

mod boxes;
mod receiver_bounds;
mod receiver_lanes;

pub use boxes::{microquad_corners, BandBoxes, MicroquadBoxes, ReceiverBoxes};

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

/// One cascade's light-space grid. Every cascade shares the frame's
/// light view; only the NDC bounds and the cells differ.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct CascadeGrid {
    /// Grid bounds in light NDC: lower and upper corner.
    pub ndc_min: Vec2,
    pub ndc_max: Vec2,
    /// Cells along x and y; `[0, 0]` for a cascade without receivers.
    pub cells: [u32; 2],
    /// Index of this grid's first cell in the frame's cell arrays: the
    /// cascades' pyramids lie back to back.
    pub cell_offset: u32,
    /// Levels of the grid pyramid: level 0 has `cells`, each next level
    /// halves both sides (rounded up), the last is 1×1; 0 for a cascade
    /// without receivers.
    pub levels: u32,
    /// A triangle is binned at the finest level where its cell rectangle
    /// holds at most this many cells.
    pub level_cells: u32,
    /// Shadow-tested pixels in this cascade.
    pub receivers: usize,
}

impl CascadeGrid {
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

    /// Index of cell (x, y) of level 0 in the frame's cell arrays.
    #[inline]
    pub fn cell_index(&self, x: u32, y: u32) -> usize {
        self.cell_index_at(0, x, y)
    }

    /// Index of cell (x, y) of pyramid level `level` in the frame's cell
    /// arrays: the levels lie back to back, finest first.
    #[inline]
    pub fn cell_index_at(&self, level: u32, x: u32, y: u32) -> usize {
        (self.level_offset(level) + y * self.level_dims(level)[0] + x) as usize
    }

    /// Where pyramid level `level` lies in the cell arrays: hot loops take
    /// this once per level rather than [`Self::cell_index_at`] per cell
    /// (which sums the sizes of the finer levels).
    #[inline]
    pub fn level(&self, level: u32) -> LevelCells {
        LevelCells {
            start: self.level_offset(level) as usize,
            dims: self.level_dims(level),
        }
    }

    /// The cells of a set of rectangles (`cells[l]`: the cells of those
    /// at level l) per cell of their level, summed over the levels (a
    /// pixel visits each): a bound on the entries of a pixel's cells on
    /// average.
    pub fn rectangle_cells_per_cell(&self, cells: &[u64]) -> f64 {
        let per_cell = |(l, &c): (usize, &u64)| {
            let [w, h] = self.level_dims(l as u32);
            c as f64 / (f64::from(w) * f64::from(h)).max(1.0)
        };
        cells.iter().enumerate().map(per_cell).sum()
    }

    /// Cells along x and y of pyramid level `level`.
    #[inline]
    pub fn level_dims(&self, level: u32) -> [u32; 2] {
        self.cells.map(|n| level_side(n, level))
    }

    /// Index of the first cell of pyramid level `level`.
    #[inline]
    pub fn level_offset(&self, level: u32) -> u32 {
        self.cell_offset
            + (0..level)
                .map(|l| {
                    let [w, h] = self.level_dims(l);
                    w * h
                })
                .sum::<u32>()
    }

    /// [`Self::level`] of every level, finest first: for loops that visit
    /// levels per pixel ([`Self::level_offset`] sums the finer levels).
    pub fn level_table(&self) -> Vec<LevelCells> {
        (0..self.levels).map(|l| self.level(l)).collect()
    }

    /// Cells of the whole pyramid.
    pub fn cell_count(&self) -> u32 {
        self.level_offset(self.levels) - self.cell_offset
    }
}

/// One pyramid level's place in the cell arrays ([`CascadeGrid::level`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct LevelCells {
    /// Index of the level's first cell.
    pub start: usize,
    /// Cells along x and y.
    pub dims: [u32; 2],
}

impl LevelCells {
    /// Index of cell (x, y) of this level in the frame's cell arrays.
    #[inline]
    pub fn index(&self, x: u32, y: u32) -> usize {
        self.start + (y * self.dims[0] + x) as usize
    }
}

/// Cells along one side of pyramid level `level` over `side` level-0
/// cells: halved per level, rounded up (0 stays 0).
#[inline]
pub fn level_side(side: u32, level: u32) -> u32 {
    if side == 0 {
        0
    } else {
        ((side - 1) >> level) + 1
    }
}

/// Levels of a pyramid over a `cells` grid: down to 1×1 (0 without cells).
pub fn pyramid_levels(cells: [u32; 2]) -> u32 {
    let side = cells[0].max(cells[1]);
    if side == 0 {
        return 0;
    }
    // ceil(log2(side)) halvings reach one cell.
    1 + (32 - (side - 1).leading_zeros())
}

/// Grid coordinates of level `level` from level-0 grid coordinates: a
/// multiplication by 2^-level, exact in `f32` (the GPU uses `ldexp`).
#[inline]
pub fn level_scale(level: u32) -> f32 {
    debug_assert!(level < 32, "pyramid level {level}");
    // 2^-level from its exponent bits: the same float as 1 / 2^level,
    // without a division per level visited.
    f32::from_bits((127 - level) << 23)
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
    /// The camera's unit view direction (f32): view depth = position · it.
    #[serde(skip)]
    pub view_forward: Vec3,
    /// How many cascades and why.
    pub cascade_choice: CascadeChoice,
    /// Upper view depth of each cascade ([`cascades::split_depths`]).
    pub split_depths: [f32; MAX_CASCADES],
    /// One grid per cascade, `cascade_choice.count` of them.
    pub cascades: Vec<CascadeGrid>,
    /// Light-view depth range of the receivers' µQuads (z, toward the light
    /// for a directional light; distance along the axis for a point light).
    pub receiver_z: [f32; 2],
    /// Shadow-tested pixels the bounds were fitted to.
    pub receivers: usize,
    /// True when the receivers cannot be put in one perspective frustum of
    /// the point light (they surround it): the grid is then disabled and
    /// every triangle goes to the overflow list (still exact, only slower).
    pub grid_disabled: bool,
    /// The light's size as the passes use it: tan of a directional
    /// light's angular radius, or a point light's sphere radius; 0 for a
    /// point-like light (hard shadows).
    pub light_radius: f32,
    /// The instruction set of the per-receiver loops
    /// ([`GridRequest::simd`]).
    #[serde(skip)]
    pub simd: SimdPath,
    /// A directional light's disk, the same from every receiver (host
    /// `f64`, then `f32`; the GPU frame receives these very floats), when
    /// the light has a size.
    #[serde(skip)]
    pub sun_disk: Option<LightDisk<Vec3>>,
}

/// Closest a receiver may come to the point light's image plane, relative
/// to its distance range, before the perspective grid is given up.
const MIN_PERSPECTIVE_DEPTH_RATIO: f32 = izb_contract::tolerance::MIN_PERSPECTIVE_DEPTH_RATIO;

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

    /// View depth of an eye-relative point.
    #[inline]
    pub fn view_depth(&self, eye_relative: Vec3) -> f32 {
        eye_relative.dot(self.view_forward)
    }

    /// The cascade of a receiver at eye-relative `position`.
    #[inline]
    pub fn cascade_of(&self, position: Vec3) -> usize {
        cascades::cascade_of_depth(&self.split_depths, self.view_depth(position))
            .min(self.cascades.len() - 1)
    }

    /// [`CascadeGrid::level_table`] of every cascade, computed once per
    /// frame for the loops that visit levels per receiver and per pixel.
    pub fn level_tables(&self) -> Vec<Vec<LevelCells>> {
        self.cascades.iter().map(CascadeGrid::level_table).collect()
    }

    /// Cells of all cascades together.
    pub fn total_cells(&self) -> usize {
        self.cascades.iter().map(|c| c.cell_count() as usize).sum()
    }

    /// Where the light is, seen from the eye-relative point `p`, in eye
    /// space: a point light at the light-view origin, or a directional
    /// light along the light view's +z row (the frustum test runs in eye
    /// space: see `evaluate`).
    #[inline]
    pub fn light_from(&self, p: Vec3) -> LightRel<Vec3> {
        match self.projection {
            Projection::Orthographic => LightRel::Toward(self.rotation.row(2)),
            Projection::Perspective => LightRel::At(self.origin - p),
        }
    }

    /// The light's disk seen from the eye-relative point `p`
    /// ([`LightDisk`]), or `None` for a point-like light: the sun's disk
    /// for a directional light, the sphere's disk facing `p` for a point
    /// light (f32, the arithmetic the GPU repeats).
    #[inline]
    pub fn light_disk_from(&self, p: Vec3) -> Option<LightDisk<Vec3>> {
        match self.projection {
            Projection::Orthographic => self.sun_disk,
            Projection::Perspective => (self.light_radius > 0.0)
                .then(|| light_disk_f32(self.origin - p, self.light_radius)),
        }
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

/// Receivers per level-0 cell the default grid aims at.
pub const RECEIVERS_PER_CELL: f32 = izb_contract::tolerance::RECEIVERS_PER_CELL;

/// Triangles per level-0 cell the default grid aims at when the scene has
/// more triangles than receivers per cell allow.
pub const TRIANGLES_PER_CELL: f32 = izb_contract::tolerance::TRIANGLES_PER_CELL;

/// The frame's cell budget, as the side of a square of cells, when none is
/// asked for: about [`RECEIVERS_PER_CELL`] receivers per cell, or about
/// [`TRIANGLES_PER_CELL`] triangles per cell where the scene has more
/// triangles than that (a dense scene at a low resolution would otherwise
/// put thousands of triangles in every cell), clamped to 8..=1024.
/// [`cascades::cascade_cells`] spends the budget on the cascades' grids
/// with square cells whatever their aspect. The GPU `light_setup` computes
/// the same expression in `f32`. Measured with the pyramid at 1920×1080
/// (CPU shadow seconds, six scenes): 6 receivers per cell is as fast as 4
/// (default, wires and engine 10–18 % faster, courtyard 3 % slower, the
/// rest within noise) with two thirds of the cell arrays; 8 pushed
/// courtyard to 42 tests per pixel and 15 % more time
/// (`paper-notes/performance.md`).
pub fn default_grid_side(receivers: usize, triangles: usize) -> u32 {
    let per_cell =
        (receivers as f32 / RECEIVERS_PER_CELL).max(triangles as f32 / TRIANGLES_PER_CELL);
    (per_cell.sqrt().ceil() as u32).clamp(
        izb_contract::word::GRID_SIDE_MIN,
        izb_contract::word::GRID_SIDE_MAX,
    )
}

/// What [`light_setup`] is asked for besides the scene and G-buffer.
#[derive(Clone, Copy, Debug)]
pub struct GridRequest {
    /// The cell budget as the side of a square (`None`: from the receiver
    /// and triangle counts, [`default_grid_side`]), shared between cascades.
    pub cells: Option<u32>,
    /// Cells a triangle's rectangle may hold at the pyramid level it is
    /// binned at (`None`: [`cascades::DEFAULT_LEVEL_CELLS`]).
    pub level_cells: Option<u32>,
    pub cascades: CascadeCount,
    /// Blend of logarithmic (1) and uniform (0) splits.
    pub split_lambda: f32,
    /// The instruction set of the per-receiver loops (the light setup's
    /// and [`LightSetup::receiver_boxes`]'): every path gives the same
    /// floats.
    pub simd: SimdPath,
}

impl From<&crate::settings::IzbSettings> for GridRequest {
    /// What the light setup is asked for.
    fn from(s: &crate::settings::IzbSettings) -> GridRequest {
        GridRequest {
            cells: s.cells,
            level_cells: s.level_cells,
            cascades: s.cascades,
            split_lambda: s.split_lambda,
            simd: s.simd,
        }
    }
}

/// Fits the light view, the cascades and their grids to the shadow-tested
/// pixels of `gbuffer`.
pub fn light_setup(scene: &Scene, gbuffer: &GBuffer, request: GridRequest) -> LightSetup {
    light_setup_for(scene, gbuffer, request, scene.triangles.len())
}

/// [`light_setup`] for `triangles` occluders other than the scene's own
/// (the host's draws: the default grid's side follows their count).
pub fn light_setup_for(
    scene: &Scene,
    gbuffer: &GBuffer,
    request: GridRequest,
    triangles: usize,
) -> LightSetup {
    let light = scene.light.relative_to(scene.camera.eye);
    let view_forward = scene.camera.frame(scene.resolution).forward.as_vec3();
    // Receivers' eye-relative bounds centre: the light-view origin of a
    // directional light, the aim of a point light. View depth range: the
    // cascade splits.
    // The path this processor runs, as the setup records it.
    let simd = request.simd.or_supported();
    let bounds = receiver_bounds::view_bounds(gbuffer, view_forward, simd);
    let (lo, hi, near, far) = (bounds.lo, bounds.hi, bounds.near, bounds.far);
    let tested = bounds.count;
    let centre = if tested == 0 {
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
        view_forward,
        cascade_choice: CascadeChoice {
            requested: request.cascades,
            count: 1,
            split_lambda: request.split_lambda,
            reason: "no shadow-tested pixels".into(),
            ..Default::default()
        },
        split_depths: [f32::INFINITY; MAX_CASCADES],
        cascades: vec![CascadeGrid {
            ndc_max: Vec2::ONE,
            cells: [1, 1],
            levels: 1,
            level_cells: request.level_cells.unwrap_or(cascades::DEFAULT_LEVEL_CELLS),
            ..Default::default()
        }],
        receiver_z: [0.0, 0.0],
        receivers: tested,
        grid_disabled: false,
        light_radius: 0.0,
        simd,
        sun_disk: None,
    };
    if scene.has_area_light() {
        setup.light_radius = light.disk_radius(scene.light_radius) as f32;
        if let Light::Directional { .. } = light {
            let disk = light.disk_from(scene.light_radius, DVec3::ZERO);
            setup.sun_disk = Some(LightDisk {
                centre: setup.rotation.row(2),
                axis_u: disk.axis_u.as_vec3(),
                axis_v: disk.axis_v.as_vec3(),
            });
        }
    }
    if tested == 0 {
        return setup;
    }
    // The pixels' cascades.
    let choice = CascadeChoice::new(request.cascades, near, far, request.split_lambda);
    setup.split_depths = cascades::split_depths(near, far, choice.count, request.split_lambda);
    let count = choice.count as usize;
    setup.cascade_choice = choice;
    let cascade_of = |p: Vec3| {
        cascades::cascade_of_depth(&setup.split_depths, p.dot(view_forward)).min(count - 1)
    };
    // Per cascade: light-NDC bounds of its µQuads' corners.
    let bounds = receiver_bounds::light_bounds(gbuffer, &setup, simd, (count, cascade_of));
    let (nmin, nmax, receivers) = (bounds.nmin, bounds.nmax, bounds.receivers);
    let (zmin, zmax) = (bounds.zmin, bounds.zmax);
    setup.grid_disabled |= bounds.no_ndc;
    if projection == Projection::Perspective && zmin <= MIN_PERSPECTIVE_DEPTH_RATIO * zmax {
        setup.grid_disabled = true;
    }
    setup.receiver_z = [zmin, zmax];
    if setup.grid_disabled {
        setup.split_depths = [f32::INFINITY; MAX_CASCADES];
        setup.cascade_choice.count = 1;
        setup.cascade_choice.reason =
            "no grid: the receivers surround the point light, every triangle overflows".into();
        return setup;
    }
    let side = request
        .cells
        .unwrap_or_else(|| default_grid_side(tested, triangles));
    let mut offset = 0;
    setup.cascades = (0..count)
        .map(|k| {
            let mut grid = CascadeGrid {
                cell_offset: offset,
                receivers: receivers[k],
                ..Default::default()
            };
            if receivers[k] == 0 {
                return grid; // an empty cascade: no cells, nothing binned
            }
            // Pad the bounds by a relative 1e-4 so µQuad corners on the
            // boundary stay inside after rounding.
            let pad = (nmax[k] - nmin[k]).max_element().max(f32::MIN_POSITIVE)
                * izb_contract::tolerance::BOUNDS_PADDING;
            grid.ndc_min = nmin[k] - pad;
            grid.ndc_max = nmax[k] + pad;
            grid.cells = cascades::cascade_cells(
                side,
                receivers[k],
                tested,
                count as u32,
                grid.ndc_max - grid.ndc_min,
            );
            grid.levels = pyramid_levels(grid.cells);
            grid.level_cells = request.level_cells.unwrap_or(cascades::DEFAULT_LEVEL_CELLS);
            offset += grid.cell_count();
            grid
        })
        .collect();
    setup
}

#[cfg(test)]
mod tests;
