//! Evaluate's walk over a pixel's candidates: the overflow list, then
//! the cells under its µQuad on every non-empty pyramid level, finest
//! first; and the conservative shadow map's cover triangle under its
//! centre.

use super::{pixel_frustum, MaskRule, PixelFrustum};
use crate::cpu::bin::{cell_range_at, Bins, NO_COVER};
use crate::cpu::light_setup::{level_scale, LightSetup};
use crate::cpu::{SampleMode, Skips};
use crate::gbuffer::GBuffer;
/// The conservative shadow map's candidate for pixel `px`: the cover
/// triangle of the cell under the µQuad centre on the finest non-empty
/// level that has one (a cover at a coarse level covers the fine cells
/// inside it too), or [`NO_COVER`].
pub(super) fn cover_of(setup: &LightSetup, bins: &Bins, px: &PixelFrustum) -> u32 {
    let (Some((lo, hi)), Some(c)) = (px.grid_box, px.centre) else {
        return NO_COVER;
    };
    let grid = &setup.cascades[px.cascade];
    for level in levels_of(bins.levels[px.cascade]) {
        let Some([x0, y0, x1, y1]) = cell_range_at(grid, level, lo, hi) else {
            continue;
        };
        let c = c * level_scale(level);
        let x = (c.x.max(0.0) as u32).clamp(x0, x1);
        let y = (c.y.max(0.0) as u32).clamp(y0, y1);
        let cover = bins.cover[bins.level_cells[px.cascade][level as usize].index(x, y)];
        if cover != NO_COVER {
            return cover;
        }
    }
    NO_COVER
}

/// The levels set in `mask`, finest first (a filter over all 32 bits was
/// 13 % of `evaluate_pixel`'s profile on `default` at 1080p).
fn levels_of(mask: u32) -> impl Iterator<Item = u32> {
    let mut rest = mask;
    std::iter::from_fn(move || {
        let level = (rest != 0).then(|| rest.trailing_zeros())?;
        rest &= rest - 1;
        Some(level)
    })
}

/// Calls `visit(id)` for every candidate triangle of shadow-tested pixel
/// `i` — the overflow list of its cascade, then each triangle listed in
/// the cells under the µQuad on every non-empty pyramid level, finest
/// first — until `visit` returns `true` (the mask is full). Returns the
/// cells and levels visited.
pub fn for_each_candidate(
    setup: &LightSetup,
    bins: &Bins,
    g: &GBuffer,
    i: usize,
    mut visit: impl FnMut(u32) -> bool,
) -> (u64, u64) {
    let ndc_box = setup.microquad_ndc_box(g.position[i], g.axis_x[i], g.axis_y[i]);
    let hard = MaskRule::new(SampleMode::One, Skips::ALL);
    candidates_of(
        setup,
        bins,
        &pixel_frustum(setup, g, i, ndc_box, &hard),
        |id, _| visit(id),
    )
}

/// [`for_each_candidate`]'s walk; `visit` also gets the cells and levels
/// visited so far (what the walk returns if it stops there).
///
/// The overflow list is walked first as one more cell, tested whole, so
/// that the walk calls `visit` in one place: inlined there with the walk
/// into the caller, the per-candidate step is not a call (courtyard 1080p
/// evaluate 0.718 → 0.681 s; with two calls LLVM kept it out of line).
#[inline(always)]
pub(super) fn candidates_of(
    setup: &LightSetup,
    bins: &Bins,
    px: &PixelFrustum,
    mut visit: impl FnMut(u32, (u64, u64)) -> bool,
) -> (u64, u64) {
    let (mut cells, mut levels) = (0, 0);
    let grid = &setup.cascades[px.cascade];
    // Without a grid box the walk has no grid levels, only the overflow
    // list, so the default box is never read.
    let (lo, hi) = px.grid_box.unwrap_or_default();
    let grid_levels = px.grid_box.map_or(0, |_| bins.levels[px.cascade]);
    // `None`: the overflow list.
    for level in std::iter::once(None).chain(levels_of(grid_levels).map(Some)) {
        let (range, level_cells) = match level {
            None => ([0; 4], None),
            Some(level) => {
                let Some(range) = cell_range_at(grid, level, lo, hi) else {
                    continue;
                };
                levels += 1;
                (range, Some(bins.level_cells[px.cascade][level as usize]))
            }
        };
        let [x0, y0, x1, y1] = range;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let list = match level_cells {
                    None => &bins.overflow[px.cascade][..],
                    Some(level_cells) => {
                        cells += 1;
                        bins.cell_at(level_cells.index(x, y))
                    }
                };
                for e in list {
                    // A triangle in several of the visited cells is tested
                    // in the first of them (see `CellEntry`).
                    if e.tested_in(x, y, x0, y0) && visit(e.id, (cells, levels)) {
                        return (cells, levels);
                    }
                }
            }
        }
    }
    (cells, levels)
}
