//! Evaluate's walk over a pixel's candidates: the overflow list, then
//! the cells under its µQuad on every non-empty pyramid level, finest
//! first; and the conservative shadow map's cover triangle under its
//! centre.

use super::{pixel_frustum, test_batch, MaskRule, PixelFrustum, TestCounters};
use crate::cpu::bin::{cell_range_at, Bins, NO_COVER};
use crate::cpu::cell_vertices::{tangent_chunk, CellVertices, ChunkQuery, ChunkTests};
use crate::cpu::light_setup::{LevelCells, LightSetup};
use crate::cpu::simd::Kernel;
use crate::cpu::survivor_batch::{BatchTests, SurvivorBatch, WalkPoint, LANES};
use crate::cpu::{SampleMode, Skips};
use crate::frustum::above_tangent_plane;
use crate::gbuffer::GBuffer;
use glam::Vec3;

/// Cell lists shorter than this are read by id in the chunked walk, not
/// from the vertex cache: a chunk costs its sixteen lanes and ten planes'
/// cache lines however few entries it holds.
const MIN_CHUNK: usize = 4;

/// One pyramid level's cells under a pixel's µQuad: the level, its place
/// in the cell arrays and the inclusive cell range `[x0, y0, x1, y1]`.
#[derive(Clone, Copy, Default)]
pub(super) struct LevelRange {
    level: u32,
    cells: LevelCells,
    range: [u32; 4],
}

/// The levels a pixel visits, with their cell ranges ([`level_ranges`]).
/// In the pixel's scratch, not on the heap: a `Vec` per band, written
/// every pixel, shared cache lines between the threads (`default` at
/// 1080p: evaluate 117 → 140 ms on two threads, faster on one).
#[derive(Default)]
pub(super) struct LevelRanges {
    len: usize,
    /// A level mask has 32 bits.
    ranges: [LevelRange; 32],
}

impl LevelRanges {
    pub(super) fn as_slice(&self) -> &[LevelRange] {
        &self.ranges[..self.len]
    }
}

/// The non-empty pyramid levels, finest first, whose padded cells pixel
/// `px`'s grid box meets, with their cell ranges, into `out`: worked out
/// once per pixel for the cover lookup and the walk, which both took each
/// level's range (a sixth of `evaluate_pixel`'s profile on `default` at
/// 1080p was the two ranges' casts and clamps).
pub(super) fn level_ranges(
    setup: &LightSetup,
    bins: &Bins,
    px: &PixelFrustum,
    out: &mut LevelRanges,
) {
    out.len = 0;
    let Some((lo, hi)) = px.grid_box else {
        return;
    };
    let grid = &setup.cascades[px.cascade];
    for level in levels_of(bins.levels[px.cascade]) {
        if let Some(range) = cell_range_at(grid, level, lo, hi) {
            out.ranges[out.len] = LevelRange {
                level,
                cells: bins.level_cells[px.cascade][level as usize],
                range,
            };
            out.len += 1;
        }
    }
}

/// The conservative shadow map's candidate for pixel `px`, whose levels
/// are `ranges` ([`level_ranges`]): the cover triangle of the cell under
/// the µQuad centre on the finest non-empty level that has one (a cover
/// at a coarse level covers the fine cells inside it too), or
/// [`NO_COVER`].
pub(super) fn cover_of(bins: &Bins, px: &PixelFrustum, ranges: &LevelRanges) -> u32 {
    let Some([cx, cy]) = px.centre else {
        return NO_COVER;
    };
    for r in ranges.as_slice() {
        let [x0, y0, x1, y1] = r.range;
        // ⌊c · 2⁻ˡ⌋ = ⌊⌊c⌋ / 2ˡ⌋ for c ≥ 0: the level's cell from the
        // level-0 one, without a cast per level (a saturated ⌊c⌋ is past
        // every level's last cell, as the scaled cast's would be).
        let x = (cx >> r.level).clamp(x0, x1);
        let y = (cy >> r.level).clamp(y0, y1);
        let cover = bins.cover[r.cells.index(x, y)];
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
    let px = pixel_frustum(setup, g, i, ndc_box, &hard);
    let mut ranges = LevelRanges::default();
    level_ranges(setup, bins, &px, &mut ranges);
    candidates_of(bins, &px, ranges.as_slice(), |_| {}, |id, _| visit(id))
}

/// How many entries ahead of the one being tested the walk asks for a
/// triangle ([`crate::cpu::simd::prefetch`]).
const PREFETCH_AHEAD: usize = 8;

/// [`for_each_candidate`]'s walk; `visit` also gets the cells and levels
/// visited so far (what the walk returns if it stops there).
///
/// The overflow list is walked first as one more cell, tested whole, so
/// that the walk calls `visit` in one place: inlined there with the walk
/// into the caller, the per-candidate step is not a call (courtyard 1080p
/// evaluate 0.718 → 0.681 s; with two calls LLVM kept it out of line).
#[inline(always)]
pub(super) fn candidates_of(
    bins: &Bins,
    px: &PixelFrustum,
    ranges: &[LevelRange],
    prefetch: impl Fn(u32),
    mut visit: impl FnMut(u32, (u64, u64)) -> bool,
) -> (u64, u64) {
    let (mut cells, mut levels) = (0, 0);
    let overflow = &bins.overflow[px.cascade][..];
    // `None`: the overflow list.
    for level in std::iter::once(None).chain(ranges.iter().map(Some)) {
        let (range, level_cells) = match level {
            None => ([0; 4], None),
            Some(r) => {
                levels += 1;
                (r.range, Some(r.cells))
            }
        };
        let [x0, y0, x1, y1] = range;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (list, following) = match level_cells {
                    None => (overflow, overflow),
                    Some(level_cells) => {
                        cells += 1;
                        bins.cell_and_following(level_cells.index(x, y))
                    }
                };
                for (k, e) in list.iter().enumerate() {
                    if let Some(ahead) = following.get(k + PREFETCH_AHEAD) {
                        prefetch(ahead.id);
                    }
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

/// Where a pixel's candidates above the tangent plane go: the survivor
/// batch, and the mask and counters its tests add to.
pub(super) struct BatchSink<'a> {
    pub mask: &'a mut u32,
    pub counters: &'a mut TestCounters,
    pub batch: &'a mut SurvivorBatch,
    pub batch_tests: &'a mut BatchTests,
}

impl BatchSink<'_> {
    /// A candidate read by id (`triangle`, eye-relative): the tangent-plane
    /// condition, then [`Self::join`] where it passes. Returns the
    /// candidate at which the mask filled, when it did.
    #[inline(always)]
    pub fn offer(
        &mut self,
        (px, rule): (&PixelFrustum, &MaskRule),
        triangle: &[Vec3; 3],
        tests: u64,
        walked: (u64, u64),
    ) -> Option<WalkPoint> {
        let t = triangle.map(|v| v - px.p);
        let height = above_tangent_plane(&t, px.normal, px.microquad_part)?;
        self.join((px, rule), &t, height, tests, walked)
    }

    /// A candidate above the tangent plane by `height` (`t`: its vertices
    /// minus P) joins the batch, the walk's tests up to and including it
    /// being `tests` and its cells and levels `walked`; the batch is tested
    /// when this fills it. Returns the candidate at which the mask filled,
    /// when it did.
    #[inline(always)]
    pub fn join(
        &mut self,
        (px, rule): (&PixelFrustum, &MaskRule),
        t: &[Vec3; 3],
        height: f32,
        tests: u64,
        walked: (u64, u64),
    ) -> Option<WalkPoint> {
        self.counters.tangent_passed += 1;
        let point = WalkPoint {
            tests,
            tangent_passed: self.counters.tangent_passed,
            walked,
        };
        if !self.batch.push(t, height, point) {
            return None;
        }
        let batch = (&mut *self.batch, &mut *self.batch_tests);
        test_batch(
            px,
            rule,
            batch,
            self.mask,
            self.counters,
            rule.skips.full_mask,
        )
    }
}

/// What the chunked walk adds to as it goes: the batch, the pixel's tests
/// and the chunk's results.
pub(super) struct WalkTally<'a> {
    pub sink: BatchSink<'a>,
    pub tests: &'a mut u64,
    pub chunk: &'a mut ChunkTests,
}

/// [`candidates_of`]'s walk over the levels (the overflow list apart) for
/// a batching pixel, each cell's entries read from the vertex cache
/// sixteen at a time and asked the tangent-plane condition together
/// ([`tangent_chunk`]); the survivors join the batch in the walk's order,
/// so the batch is tested, and the walk stops, at the same candidate as
/// one entry at a time. Returns the cells and levels visited, and the
/// candidate at which the mask filled when it did. Compiled once per
/// instruction set, chosen by the rule's `simd`.
pub(super) fn survivors_in_chunks(
    bins: &Bins,
    data: (&CellVertices, &[[Vec3; 3]]),
    px: &PixelFrustum,
    walk: (&LevelRanges, u32),
    rule: &MaskRule,
    tally: WalkTally<'_>,
) -> ((u64, u64), Option<WalkPoint>) {
    let WalkTally { sink, tests, chunk } = tally;
    let kernel = ChunkWalk {
        bins,
        data,
        px,
        walk,
        rule,
        tally: (sink, tests),
    };
    rule.simd.dispatch(kernel, chunk)
}

/// [`chunks`]' arguments, as a [`Kernel`].
struct ChunkWalk<'a> {
    bins: &'a Bins,
    data: (&'a CellVertices, &'a [[Vec3; 3]]),
    px: &'a PixelFrustum,
    walk: (&'a LevelRanges, u32),
    rule: &'a MaskRule<'a>,
    tally: (BatchSink<'a>, &'a mut u64),
}

impl Kernel for ChunkWalk<'_> {
    type Out = ChunkTests;
    type Output = ((u64, u64), Option<WalkPoint>);
    #[inline(always)]
    fn run(self, chunk: &mut ChunkTests) -> Self::Output {
        let ChunkWalk {
            bins,
            data,
            px,
            walk,
            rule,
            tally,
        } = self;
        chunks(bins, data, px, walk, rule, tally, chunk)
    }
}

/// [`survivors_in_chunks`] on the instruction set it is inlined into.
#[inline(always)]
fn chunks(
    bins: &Bins,
    data: (&CellVertices, &[[Vec3; 3]]),
    px: &PixelFrustum,
    (ranges, cover): (&LevelRanges, u32),
    rule: &MaskRule,
    (mut sink, tests): (BatchSink<'_>, &mut u64),
    chunk: &mut ChunkTests,
) -> ((u64, u64), Option<WalkPoint>) {
    let (cache, triangles) = data;
    let (mut cells, mut levels) = (0, 0);
    let mut query = ChunkQuery {
        p: px.p,
        normal: px.normal,
        microquad_part: px.microquad_part,
        receiver: px.receiver,
        cover,
        need: 0,
    };
    for r in ranges.as_slice() {
        levels += 1;
        let [x0, y0, x1, y1] = r.range;
        for y in y0..=y1 {
            for x in x0..=x1 {
                cells += 1;
                let c = r.cells.index(x, y);
                let (start, end) = (bins.cell_start[c] as usize, bins.cell_start[c + 1] as usize);
                if end - start < MIN_CHUNK {
                    // As `candidates_of` reads a list.
                    for e in &bins.cell_triangles[start..end] {
                        if !e.tested_in(x, y, x0, y0) || e.id == px.receiver || e.id == cover {
                            continue;
                        }
                        *tests += 1;
                        let triangle = &triangles[e.id as usize];
                        if let Some(point) =
                            sink.offer((px, rule), triangle, *tests, (cells, levels))
                        {
                            return ((cells, levels), Some(point));
                        }
                    }
                    continue;
                }
                query.need = ChunkQuery::flags_needed(x, y, x0, y0);
                let mut first = start;
                while first < end {
                    // The next chunk: this list's, or the next cell's along
                    // the row, whose entries follow these.
                    cache.prefetch(first + LANES);
                    tangent_chunk(cache, first, (end - first).min(LANES), &query, chunk);
                    let mut above = chunk.above;
                    while above != 0 {
                        let l = above.trailing_zeros() as usize;
                        above &= above - 1;
                        let tests_so_far =
                            *tests + u64::from((chunk.tested & ((2 << l) - 1)).count_ones());
                        let t = cache.triangle_minus(first + l, px.p);
                        let height = chunk.height[l];
                        let walked = (cells, levels);
                        if let Some(point) = sink.join((px, rule), &t, height, tests_so_far, walked)
                        {
                            return ((cells, levels), Some(point));
                        }
                    }
                    *tests += u64::from(chunk.tested.count_ones());
                    first += LANES;
                }
            }
        }
    }
    ((cells, levels), None)
}
