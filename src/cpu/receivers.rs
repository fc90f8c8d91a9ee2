//! The receivers the `behind-receivers` skip (Wyman et al. 2015, §5.4,
//! exact) culls against: per cell of every pyramid level, how far the
//! farthest receiver able to test a triangle there lies from the light,
//! how many cells away its µQuad centre may lie, and the cell's box grown
//! by that reach. The test that drops a triangle with them is
//! [`super::receiver_cull`]. Used by [`super::bin::bin`]; the GPU twin is
//! `STEP_RECEIVERS` in `shaders/bin.comp`.

use super::footprint::{cell_range_in, CELL_PADDING};
use super::light_setup::{
    level_scale, CascadeGrid, LevelCells, LightSetup, MicroquadBoxes, Projection,
};
use super::registration_lanes::{RegistrationLanes, WantedLevel, LANES};
use super::{is_receiver, Skips};
use crate::gbuffer::GBuffer;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// What the `behind_receivers` skip knows of each cell (of every cascade,
/// indexed like the cell arrays): how far from the light the farthest µQuad
/// centre P of the receivers whose µQuad touches the cell lies, and how
/// many cells those centres may lie away from it.
pub struct CellReceivers {
    /// The farthest receiver as a lowest value: a directional light's
    /// lowest light-view z, a point light's lowest −z (z: depth along its
    /// axis, [`receiver_key`]); +∞ where no receiver touches the cell.
    pub z_min: Vec<f32>,
    pub reach: Vec<u32>,
    /// Each cell grown by its reach and [`CELL_PADDING`], in light NDC, as
    /// `[lo, hi]`: the box [`TriangleCull::behind`](super::receiver_cull::TriangleCull::behind) tests every triangle
    /// touching the cell against ([`cull_box`]), computed once per cell
    /// rather than once per (triangle, cell) pair (engine at 960×540: 472 k
    /// calls for 14 725 cells). Unset (zero) where no receiver touches the cell.
    pub cull_box: Vec<[Vec2; 2]>,
    pub projection: Projection,
}

/// The value a receiver at light-view `p` registers in
/// [`CellReceivers::z_min`]: z for a directional light (+z toward it), −z
/// for a point light (z its depth), so the lowest is the farthest.
#[inline]
pub fn receiver_key(projection: Projection, p: Vec3) -> f32 {
    match projection {
        Projection::Orthographic => p.z,
        Projection::Perspective => -p.z,
    }
}

impl CellReceivers {
    fn empty(cells: usize, projection: Projection) -> CellReceivers {
        CellReceivers {
            z_min: vec![f32::INFINITY; cells],
            reach: vec![0; cells],
            cull_box: Vec::new(),
            projection,
        }
    }

    /// Registers a receiver of key `z` and reach `reach` in the cells
    /// `[x0, y0, x1, y1]` of one level (`cells`).
    #[inline]
    fn register(&mut self, cells: LevelCells, [x0, y0, x1, y1]: [u32; 4], z: f32, reach: u32) {
        for y in y0..=y1 {
            for x in x0..=x1 {
                let c = cells.index(x, y);
                self.z_min[c] = self.z_min[c].min(z);
                self.reach[c] = self.reach[c].max(reach);
            }
        }
    }

    fn merge(mut self, other: CellReceivers) -> CellReceivers {
        for (c, (z, r)) in other.z_min.into_iter().zip(other.reach).enumerate() {
            self.z_min[c] = self.z_min[c].min(z);
            self.reach[c] = self.reach[c].max(r);
        }
        self
    }
}

/// [`CellReceivers`] of the receivers of `g` (`None` for a disabled
/// grid), their µQuads' boxes taken from `boxes`, on each level of each
/// receiver's own cascade's pyramid that `levels` (per cascade, bit l =
/// level l) names; `level_cells` is [`LightSetup::level_tables`]. At level
/// l a receiver's µQuad box and reach are those of level 0 scaled by 2⁻ˡ.
/// Cells of other levels stay empty (the bin never reads them).
pub fn cell_receivers(
    setup: &LightSetup,
    g: &GBuffer,
    boxes: &MicroquadBoxes,
    skips: Skips,
    levels: &[u32],
    level_cells: &[Vec<LevelCells>],
) -> Option<CellReceivers> {
    if setup.grid_disabled {
        return None;
    }
    let projection = setup.projection;
    let cells = setup.total_cells();
    // One partial array per thread, merged once: a split per 64 k pixels
    // would allocate and merge a whole pyramid's arrays each time. Split
    // over the receivers, not the pixels: the sky rows at the top of an
    // image would leave one thread with most of the work (measured at
    // 1080p: deckchair 0.079 → 0.042 s, the threads finishing together).
    // Every receiver of every layer: the pixels' centre surfaces, then the
    // edge pixels' extra surfaces (`GBuffer::layers`).
    let layers: Vec<(&GBuffer, &MicroquadBoxes)> = g.layers().zip(boxes.layers()).collect();
    // Blocks of entries with their receiver counts, then runs of blocks
    // holding equal shares of the receivers, one per thread.
    let blocks: Vec<(usize, std::ops::Range<usize>, usize)> = layers
        .iter()
        .enumerate()
        .flat_map(|(l, (g, _))| {
            let n = g.flags.len();
            (0..n.div_ceil(RECEIVER_BLOCK))
                .into_par_iter()
                .map(move |b| {
                    let range = b * RECEIVER_BLOCK..((b + 1) * RECEIVER_BLOCK).min(n);
                    let count = g.flags[range.clone()]
                        .iter()
                        .filter(|&&f| is_receiver(f, skips))
                        .count();
                    (l, range, count)
                })
                .collect::<Vec<_>>()
        })
        .collect();
    let total: usize = blocks.iter().map(|b| b.2).sum();
    let per_thread = total.div_ceil(rayon::current_num_threads()).max(1);
    let mut shares: Vec<&[(usize, std::ops::Range<usize>, usize)]> = Vec::new();
    let (mut first, mut sum) = (0, 0);
    for (b, block) in blocks.iter().enumerate() {
        sum += block.2;
        if sum >= per_thread || b + 1 == blocks.len() {
            shares.push(&blocks[first..=b]);
            (first, sum) = (b + 1, 0);
        }
    }
    // Per cascade, the levels to register on, finest first, with their
    // scale and sides.
    let wanted_levels: Vec<Vec<WantedLevel>> = setup
        .cascades
        .iter()
        .zip(levels)
        .map(|(grid, wanted)| {
            (0..grid.levels)
                .filter(|l| wanted & (1 << l) != 0)
                .map(|l| (l, level_scale(l), grid.level_dims(l)))
                .collect()
        })
        .collect();
    let receivers = shares
        .into_par_iter()
        .map(|share| {
            let mut out = CellReceivers::empty(cells, projection);
            if let [grid] = &setup.cascades[..] {
                let one = (setup, grid, &wanted_levels[0][..], &level_cells[0][..]);
                register_gathered(&mut out, one, &layers, share, skips);
                return out;
            }
            let receivers = share.iter().flat_map(|(l, range, _)| {
                range
                    .clone()
                    .filter(|&i| is_receiver(layers[*l].0.flags[i], skips))
                    .map(|i| (*l, i))
            });
            for (l, i) in receivers {
                let (g, boxes) = layers[l];
                let k = setup.cascade_of(g.position[i]);
                let grid = &setup.cascades[k];
                let (lo, hi) = boxes.grid_box(grid, i);
                let p = setup.to_light_view(g.position[i]);
                let z = receiver_key(projection, p);
                let (reach_lo, reach_hi) = reach_box(setup, grid, p, (lo, hi));
                for &(level, s, dims) in &wanted_levels[k] {
                    let (lo, hi) = (lo * s, hi * s);
                    // `cell_range_at`, its level's scale and sides read
                    // from the table.
                    let Some(range) = cell_range_in(dims, lo, hi) else {
                        break;
                    };
                    let reach = receiver_reach(reach_lo * s, reach_hi * s);
                    out.register(level_cells[k][level as usize], range, z, reach);
                }
            }
            out
        })
        .reduce(
            || CellReceivers::empty(cells, projection),
            CellReceivers::merge,
        );
    Some(receivers.with_cull_boxes(setup, &wanted_levels, level_cells))
}

/// The receivers of `share` (blocks of `layers`' entries) registered in
/// `out` under one cascade (`grid`, its wanted levels and their cells),
/// sixteen gathered receivers' arithmetic at a time
/// ([`RegistrationLanes`]): runs of G-buffer entries would idle most
/// lanes where few pixels are receivers (engine), as the sky or a skip
/// leaves them.
fn register_gathered(
    out: &mut CellReceivers,
    (setup, grid, wanted, level_cells): (&LightSetup, &CascadeGrid, &[WantedLevel], &[LevelCells]),
    layers: &[(&GBuffer, &MicroquadBoxes)],
    share: &[(usize, std::ops::Range<usize>, usize)],
    skips: Skips,
) {
    let mut lanes = Box::<RegistrationLanes>::default();
    let (mut position, mut ndc) = (Vec::with_capacity(LANES), Vec::with_capacity(LANES));
    let mut register = |position: &mut Vec<Vec3>, ndc: &mut Vec<(Vec2, Vec2)>| {
        lanes.fill((setup, grid), setup.simd, (position, ndc), wanted);
        for lane in 0..position.len() {
            for (w, &(level, ..)) in wanted.iter().enumerate() {
                let Some((range, reach)) = lanes.level(w, lane) else {
                    break;
                };
                out.register(level_cells[level as usize], range, lanes.key[lane], reach);
            }
        }
        position.clear();
        ndc.clear();
    };
    for (l, range, _) in share {
        let (g, boxes) = layers[*l];
        for i in range.clone().filter(|&i| is_receiver(g.flags[i], skips)) {
            position.push(g.position[i]);
            ndc.push(boxes.ndc[i]);
            if position.len() == LANES {
                register(&mut position, &mut ndc);
            }
        }
    }
    if !position.is_empty() {
        register(&mut position, &mut ndc);
    }
}

impl CellReceivers {
    /// Fills [`Self::cull_box`] for the cells of `wanted_levels` (per
    /// cascade: level, scale, sides) that a receiver touches.
    fn with_cull_boxes(
        mut self,
        setup: &LightSetup,
        wanted_levels: &[Vec<WantedLevel>],
        level_cells: &[Vec<LevelCells>],
    ) -> CellReceivers {
        let mut boxes = vec![[Vec2::ZERO; 2]; self.z_min.len()];
        for (k, grid) in setup.cascades.iter().enumerate() {
            for &(level, _, [w, h]) in &wanted_levels[k] {
                let cells = level_cells[k][level as usize];
                let range = cells.start..cells.start + (w * h) as usize;
                let row_len = w.max(1) as usize;
                boxes[range.clone()]
                    .par_chunks_mut(row_len)
                    .zip(self.z_min[range.clone()].par_chunks(row_len))
                    .zip(self.reach[range].par_chunks(row_len))
                    .enumerate()
                    .for_each(|(y, ((row, z_min), reach))| {
                        for (x, b) in row.iter_mut().enumerate() {
                            if z_min[x] != f32::INFINITY {
                                *b = cull_box(grid, level, (x as u32, y as u32), reach[x]);
                            }
                        }
                    });
            }
        }
        self.cull_box = boxes;
        self
    }
}

/// Cell (`x`, `y`) of level `level` of `grid`, grown by `reach` cells and
/// [`CELL_PADDING`], in light NDC, as `[lo, hi]`: the box whose pyramid
/// (point light) or column (directional) [`TriangleCull::behind`](super::receiver_cull::TriangleCull::behind) tests.
#[inline]
pub fn cull_box(grid: &CascadeGrid, level: u32, (x, y): (u32, u32), reach: u32) -> [Vec2; 2] {
    let r = reach as f32 + CELL_PADDING;
    // Level-l grid coordinates to level 0: times 2^l, exact.
    let up = (1u32 << level) as f32;
    let (g_lo, g_hi) = (
        Vec2::new(x as f32 - r, y as f32 - r) * up,
        Vec2::new(x as f32 + 1.0 + r, y as f32 + 1.0 + r) * up,
    );
    [grid.ndc_of_grid(g_lo), grid.ndc_of_grid(g_hi)]
}

/// Entries per block when the receivers are shared out between threads.
const RECEIVER_BLOCK: usize = 4096;

/// The box whose larger side gives a receiver's reach: its µQuad's grid
/// box `[lo, hi]` (`grid`'s level 0) and its µQuad centre P (light view
/// `p`), where the depth test is taken. The two differ where the box spans
/// only the part of the µQuad an edge surface's samples cover
/// ([`LightSetup::receiver_boxes`]): P can then lie cells away from it
/// (ficus at 1920×1080: an edge surface's P 2.5 cells beyond its box
/// grown by the box's reach), and the cull's box must still hold it.
/// `shaders/bin.comp`'s `STEP_RECEIVERS` is the GPU twin.
#[inline]
pub fn reach_box(
    setup: &LightSetup,
    grid: &CascadeGrid,
    p: Vec3,
    (lo, hi): (Vec2, Vec2),
) -> (Vec2, Vec2) {
    match setup.ndc(p) {
        Some(n) => {
            let centre = grid.grid_coords(n);
            (lo.min(centre), hi.max(centre))
        }
        None => (lo, hi),
    }
}

/// How many cells a receiver's µQuad centre may lie from a cell its grid
/// box touches, given its [`reach_box`] `[lo, hi]` (at that cell's level):
/// the larger side, rounded up, plus one for the cell itself and the
/// padding.
#[inline]
pub fn receiver_reach(lo: Vec2, hi: Vec2) -> u32 {
    super::footprint::as_u32((hi - lo).max_element().ceil()).saturating_add(1)
}
