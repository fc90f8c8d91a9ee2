//! Pass 3, `evaluate`: per shadow-tested pixel, gather the candidate
//! triangles of every grid cell its µQuad touches on every non-empty
//! pyramid level (plus the overflow list),
//! run the frustum-triangle test of each, and OR the occluded samples into
//! the pixel's 32-bit mask, stopping once it is full (Wyman et al. 2015, §6.6).
//!
//! No missed occluder: a sample S can only be shadowed by a triangle whose
//! light-NDC projection contains S's projection, and S lies in its µQuad,
//! whose projection lies in the bounding box of the projected corners (a
//! planar quad in front of the light projects to the hull of its corners).
//! So visiting every cell of that box on every level, padded like the
//! triangles' boxes, visits every triangle able to shadow any of the 32
//! samples: each is listed on its level in every padded cell its
//! projection touches.

use super::bin::{cell_range, Bins, NO_COVER};
use super::light_samples::{
    below_horizon, occluded_light_samples, paired_occluded_samples, LightView, PairedRays,
};
use super::light_setup::{BandBoxes, LightSetup, MicroquadBoxes, ReceiverBoxes};
use super::survivor_batch::{BatchTests, SurvivorBatch, WalkPoint};
use super::{is_receiver, SampleMode};
use crate::frustum::{
    above_tangent_plane, beyond_triangle_plane, edge_function, microquad_tolerance, winding,
    LightRel,
};
use crate::gbuffer::{flags, GBuffer};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use walk::{candidates_of, cover_of, level_ranges, LevelRanges};

mod walk;
pub use walk::for_each_candidate;

/// A full 32-sample mask.
pub const FULL: u32 = izb_contract::word::FULL_MASK;

pub use super::evaluate_stats::{EvaluateStats, WorkPerPixel};
pub use super::mask_rule::MaskRule;
use super::mask_rule::{and_of_edge_masks, and_of_edges, TestCounters};

/// What evaluate needs of one pixel. The frustum test runs in eye space,
/// relative to P (see [`triangle_mask`] for why not in light view): `p`,
/// `normal`, `ex`, `ey` are the G-buffer's own eye-relative values.
struct PixelFrustum {
    p: Vec3,
    normal: Vec3,
    ex: Vec3,
    ey: Vec3,
    /// The µQuad part of the depth tolerance (the same for every
    /// triangle), with the depth's uncertainty where a host's depth made P.
    microquad_part: f32,
    /// Where the light is, seen from P.
    light: LightRel<Vec3>,
    receiver: u32,
    /// The pixel's cascade.
    cascade: usize,
    /// The µQuad's level-0 grid box, when it touches the grid.
    grid_box: Option<(Vec2, Vec2)>,
    /// The level-0 grid cell of the µQuad centre (the conservative shadow
    /// map's texel; a negative coordinate as 0), when it has one: a
    /// coarser level's cell is this one shifted right by the level.
    centre: Option<[u32; 2]>,
    /// The light's disk seen from P, when the light has a size: the mask
    /// is then over the light's samples (`light_samples`).
    soft: Option<LightView>,
    /// With a paired mode under an area light: the pixel's 32
    /// (µQuad sample, light sample) rays of the rule's half. Boxed: held
    /// inline, its 1.5 kB were copied into every pixel's frustum, paired
    /// or not (`default` at 1080p: a sixth of `pixel_frustum`'s profile).
    paired: Option<Box<PairedRays>>,
    /// The samples whose bits count (an edge pixel's surface covers only
    /// some): the mask is full once these are set.
    wanted: u32,
}

/// Pixel `i`'s frustum; `ndc_box` its µQuad's light-NDC box
/// ([`LightSetup::microquad_ndc_box`]); the light's disk when `rule` is
/// over light samples.
fn pixel_frustum(
    setup: &LightSetup,
    g: &GBuffer,
    i: usize,
    ndc_box: (Vec2, Vec2),
    rule: &MaskRule,
) -> PixelFrustum {
    let (p, ex, ey) = (g.position[i], g.axis_x[i], g.axis_y[i]);
    let cascade = setup.cascade_of(p);
    let grid = &setup.cascades[cascade];
    let (mut grid_box, mut centre) = (None, None);
    if !setup.grid_disabled {
        // Every receiver corner is in front of the light (else the grid is
        // disabled), so the box is not NaN.
        let (lo, hi) = (grid.grid_coords(ndc_box.0), grid.grid_coords(ndc_box.1));
        if cell_range(grid, lo, hi).is_some() {
            grid_box = Some((lo, hi));
            centre = setup.ndc(setup.to_light_view(p)).map(|n| {
                let c = grid.grid_coords(n);
                [c.x.max(0.0) as u32, c.y.max(0.0) as u32]
            });
        }
    }
    let soft = rule
        .light_samples
        .then(|| setup.light_disk_from(p))
        .flatten()
        .map(|disk| LightView {
            disk,
            finite: setup.projection == super::light_setup::Projection::Perspective,
        });
    let paired = soft.as_ref().filter(|_| rule.mode.is_paired()).map(|view| {
        Box::new(PairedRays::new(
            view,
            ex,
            ey,
            rule.pair_pattern,
            rule.pattern,
        ))
    });
    PixelFrustum {
        p,
        normal: g.normal[i],
        ex,
        ey,
        microquad_part: microquad_tolerance::<Vec3>(ex.length().max(ey.length()))
            + g.depth_uncertainty.as_ref().map_or(0.0, |u| u[i]),
        light: setup.light_from(p),
        receiver: g.triangle_id[i],
        cascade,
        grid_box,
        centre,
        soft,
        paired,
        wanted: FULL,
    }
}

/// Occluded samples of `tri` (eye-relative, not yet relative to P) for
/// one pixel, or 0 when it fails the depth test: the AND of its three edge
/// masks. With the `saturated_edges` skip an edge that misses the whole
/// µQuad ends the test and an edge that contains it costs one comparison.
///
/// Eye space, not light view (paper-notes/frustum-test.md and [Compute IZB] say light view; both
/// are relative to P, so equally precise): the depth test's inputs —
/// vertices, P, normal, µQuad — do not depend on the light, so in eye space
/// they are the same floats in every frame while the light moves, and a
/// triangle whose height sits within rounding of the tolerance keeps its
/// verdict. In light view every vertex is re-rounded by a new rotation each
/// frame and such a triangle passes and fails at random: measured with
/// `izb bench --flicker` on `engine` (240×135, 0.01° steps), one pixel's
/// neighbour at 1/256 µQuad above the tangent plane toggled three samples
/// on and one off in 9 of 40 frames while the `f64` same-sample reference
/// held still (paper-notes/frustum-test.md, "Temporal stability").
#[inline]
fn triangle_mask(
    px: &PixelFrustum,
    tri: &[Vec3; 3],
    rule: &MaskRule,
    counters: &mut TestCounters,
) -> u32 {
    let t = tri.map(|v| v - px.p);
    // Most candidates are below the tangent plane: that check stays inline
    // in the candidate loop, the rest of the test is called.
    let Some(height) = above_tangent_plane(&t, px.normal, px.microquad_part) else {
        return 0;
    };
    counters.tangent_passed += 1;
    match (&px.soft, &px.paired) {
        (None, _) => occluded_samples(px, &t, height, rule, counters),
        (Some(view), None) => {
            occluded_light_samples(&t, height, px.microquad_part, view, rule, counters)
        }
        (Some(view), Some(rays)) => {
            paired_occluded_samples(&t, height, px.microquad_part, view.finite, rays, counters)
        }
    }
}

/// [`triangle_mask`] outside the entry loop: the walk's step for a
/// candidate tested alone (an area light's), kept out so that the step the
/// batched walk takes stays small enough to inline.
#[inline(never)]
fn unbatched_mask(
    px: &PixelFrustum,
    tri: &[Vec3; 3],
    rule: &MaskRule,
    counters: &mut TestCounters,
) -> u32 {
    triangle_mask(px, tri, rule, counters)
}

/// [`triangle_mask`] for a triangle above the tangent plane by `height`.
#[inline(never)]
fn occluded_samples(
    px: &PixelFrustum,
    t: &[Vec3; 3],
    height: f32,
    rule: &MaskRule,
    counters: &mut TestCounters,
) -> u32 {
    let light = px.light;
    if !beyond_triangle_plane(t, height, px.microquad_part, light) {
        return 0;
    }
    counters.depth_passed += 1;
    let w = winding(t, light);
    if !(w != 0.0) {
        return 0; // edge-on from the light (or NaN): no shadow area
    }
    and_of_edges(
        rule,
        3,
        |k| edge_function(t, k, px.ex, px.ey, light, w < 0.0),
        counters,
    )
}

/// What a pixel's evaluation fills and empties, reused pixel after pixel:
/// the survivor batch and its results, the levels' cell ranges.
#[derive(Default)]
struct PixelScratch {
    batch: SurvivorBatch,
    batch_tests: BatchTests,
    chunk: super::cell_vertices::ChunkTests,
    ranges: LevelRanges,
}

/// The occlusion mask of receiver pixel `i` and its tests (and its
/// counters).
fn evaluate_pixel(
    setup: &LightSetup,
    bins: &Bins,
    triangles: &[[Vec3; 3]],
    px: &PixelFrustum,
    rule: &MaskRule,
    scratch: &mut PixelScratch,
    stats: &mut EvaluateStats,
) -> (u32, u64) {
    let PixelScratch {
        batch,
        batch_tests,
        chunk,
        ranges,
    } = scratch;
    // An area light's samples below the receiver's horizon are hidden by
    // the receiver itself.
    let mut mask = match (&px.soft, &px.paired) {
        (None, _) => 0,
        (Some(view), None) => below_horizon(px.normal, view, rule),
        (Some(_), Some(rays)) => rays.below_horizon(px.normal),
    };
    let mut tests = 0u64;
    let mut counters = TestCounters::default();
    // The conservative shadow map: the cover triangle of the centre's cell
    // first. Its mask is 0 unless it is one of the pixel's candidates (the
    // grid offers every triangle that can shadow a sample), so ORing it in
    // and skipping it in the loop leaves the mask as it was; when it fills
    // the mask alone, the loop is skipped.
    level_ranges(setup, bins, px, ranges);
    // A bin without covers (a point light's, or a directional one whose
    // triangles cover no cell whole) has only `NO_COVER` to read.
    let cover = if rule.skips.shadow_map && bins.stats.covered_cells > 0 {
        cover_of(bins, px, ranges)
    } else {
        NO_COVER
    };
    if cover != NO_COVER && cover != px.receiver {
        tests += 1;
        mask |= triangle_mask(px, &triangles[cover as usize], rule, &mut counters);
    }
    let full = |mask: u32| mask & px.wanted == px.wanted;
    let (cells, levels) = if full(mask) {
        stats.shadow_map_early_outs += 1;
        (0, 0)
    } else {
        let stop_when_full = rule.skips.full_mask;
        // Under a point-like light the candidates above the tangent plane
        // wait in a batch for the rest of their test (`survivor_batch`);
        // where the mask fills inside a batch, the counters go back to that
        // candidate's, as if the walk had stopped there.
        let batching = px.soft.is_none();
        // With the vertex cache, the levels' cells are read sixteen
        // entries at a time (`survivors_in_chunks`) after the overflow list.
        let chunked = bins.vertices.as_ref().filter(|_| batching);
        let scalar_ranges = match chunked {
            Some(_) => &[],
            None => ranges.as_slice(),
        };
        batch.len = 0;
        let mut stopped: Option<WalkPoint> = None;
        let prefetch =
            |id: u32| crate::cpu::simd::prefetch(triangles.as_ptr().wrapping_add(id as usize));
        let mut sink = walk::BatchSink {
            mask: &mut mask,
            counters: &mut counters,
            batch: &mut *batch,
            batch_tests: &mut *batch_tests,
        };
        let mut walked = candidates_of(bins, px, scalar_ranges, prefetch, |id, walked| {
            if id == px.receiver || id == cover {
                return false;
            }
            tests += 1;
            if !batching {
                let tri = &triangles[id as usize];
                *sink.mask |= unbatched_mask(px, tri, rule, sink.counters);
                return stop_when_full && full(*sink.mask);
            }
            stopped = sink.offer((px, rule), &triangles[id as usize], tests, walked);
            stopped.is_some()
        });
        if let (Some(cache), None) = (chunked, stopped) {
            let tally = walk::WalkTally {
                sink,
                tests: &mut tests,
                chunk: &mut *chunk,
            };
            (walked, stopped) = walk::survivors_in_chunks(
                bins,
                (cache, triangles),
                px,
                (ranges, cover),
                rule,
                tally,
            );
        }
        if stopped.is_none() {
            stopped = test_batch(
                px,
                rule,
                (&mut *batch, &mut *batch_tests),
                &mut mask,
                &mut counters,
                stop_when_full,
            );
        }
        if let Some(point) = stopped {
            tests = point.tests;
            counters.tangent_passed = point.tangent_passed;
            walked = point.walked;
        }
        stats.early_outs += (stop_when_full && full(mask)) as usize;
        walked
    };
    stats.tests_spawned += tests;
    stats.tangent_passed += counters.tangent_passed;
    stats.depth_passed += counters.depth_passed;
    stats.saturated_masks += counters.saturated_masks;
    stats.masks_nonempty += counters.masks_nonempty;
    stats.survivor_batches += counters.survivor_batches;
    stats.survivor_lanes += counters.survivor_lanes;
    stats.survivor_lanes_issued += counters.survivor_lanes_issued;
    stats.cells_visited += cells;
    stats.levels_visited += levels;
    (mask, tests)
}

/// The masks of `batch`'s candidates, ORed into `mask` in their order as
/// [`occluded_samples`] forms them; empties the batch. Returns the
/// candidate at which the mask's wanted samples filled, when the walk is
/// to stop there. Called once per batch: kept out of the entry loop.
#[inline(never)]
fn test_batch(
    px: &PixelFrustum,
    rule: &MaskRule,
    (batch, r): (&mut SurvivorBatch, &mut BatchTests),
    mask: &mut u32,
    counters: &mut TestCounters,
    stop_when_full: bool,
) -> Option<WalkPoint> {
    let len = batch.len;
    if len == 0 {
        return None;
    }
    batch.test(rule, px.microquad_part, px.light, px.ex, px.ey, r);
    batch.len = 0;
    counters.survivor_batches += 1;
    counters.survivor_lanes += len as u64;
    counters.survivor_lanes_issued += super::survivor_batch::lanes_issued(len) as u64;
    // With the `saturated_edges` skip a lane whose edges provably leave
    // no sample inside takes mask 0 without the LUT, counted as a
    // saturated mask (`empty_certificate`).
    let certify = rule.skips.saturated_edges;
    let needs_mask =
        |l: usize| r.beyond[l] && r.winding[l] != 0.0 && !(certify && r.no_sample_inside[l] != 0);
    let lut = rule.mode == SampleMode::Lut32;
    if lut {
        let wanted = |l: usize| l < len && needs_mask(l);
        super::lut_batch::lut_coordinates(rule.simd, rule.lut, &r.edges, wanted, &mut r.lut);
    }
    for l in 0..len {
        if r.beyond[l] {
            counters.depth_passed += 1;
            // Edge-on from the light (or NaN): no shadow area.
            if needs_mask(l) {
                let r = &*r;
                *mask |= if lut {
                    // The batch's masks, or the scalar one where its row
                    // was too near a boundary to be sure.
                    let edge_mask = |k: usize| {
                        let known = r.lut.mask(rule.lut, k, l);
                        known.unwrap_or_else(|| rule.edge_mask(r.edge(l, k)))
                    };
                    and_of_edge_masks(rule, 3, edge_mask, counters)
                } else {
                    and_of_edges(rule, 3, |k| r.edge(l, k), counters)
                };
            } else if r.winding[l] != 0.0 {
                counters.saturated_masks += 1;
            }
        }
        if stop_when_full && *mask & px.wanted == px.wanted {
            return Some(batch.point[l]);
        }
    }
    None
}

/// The occluded samples of triangle `id` for shadow-tested pixel `i`,
/// whether or not the grid would have offered it (for tests that check the
/// grid against brute force).
pub fn triangle_mask_for_pixel(
    setup: &LightSetup,
    triangles: &[[Vec3; 3]],
    g: &GBuffer,
    i: usize,
    id: u32,
    rule: &MaskRule,
) -> u32 {
    let ndc_box = setup.microquad_ndc_box(g.position[i], g.axis_x[i], g.axis_y[i]);
    let px = pixel_frustum(setup, g, i, ndc_box, rule);
    if id == px.receiver {
        return 0;
    }
    triangle_mask(
        &px,
        &triangles[id as usize],
        rule,
        &mut TestCounters::default(),
    )
}

/// Pixel groups of the SIMD-efficiency counter: 8×4, a 32-lane subgroup
/// of the GPU evaluate's 8×8 tiles.
pub const GROUP: [usize; 2] = [8, 4];

/// Occlusion masks of every pixel: 0 for pixels not shadow-tested (with the
/// `facing_away` skip off those facing away from the light are evaluated
/// all the same, and their masks then dropped).
pub fn evaluate(
    setup: &LightSetup,
    bins: &Bins,
    triangles: &[[Vec3; 3]],
    g: &GBuffer,
    boxes: &MicroquadBoxes,
    rule: &MaskRule,
) -> (Vec<u32>, EvaluateStats) {
    let boxes = ReceiverBoxes::Stored(boxes);
    evaluate_wanted(setup, bins, triangles, g, boxes, rule, None)
}

/// [`evaluate`] where only the samples `wanted[i]` of entry `i` count
/// (an edge pixel's surface, [`crate::gbuffer::edge_surfaces`]): a mask
/// is full, and its pixel stops, once those are set. Bits outside them
/// are left as they fall (the caller masks them out). The receivers'
/// µQuad boxes come from `boxes`: stored, or projected band by band.
pub fn evaluate_wanted(
    setup: &LightSetup,
    bins: &Bins,
    triangles: &[[Vec3; 3]],
    g: &GBuffer,
    boxes: ReceiverBoxes<'_>,
    rule: &MaskRule,
    wanted: Option<&[u32]>,
) -> (Vec<u32>, EvaluateStats) {
    let w = (g.width as usize).max(1);
    let n = g.flags.len();
    // Bands of GROUP[1] rows, so each 8×4 group lies in one band; a
    // one-row layer (the edge surfaces, `GBuffer::layers`) in bands of
    // 1024 entries, its groups 32 consecutive entries.
    let one_row = g.height == 1;
    let band = if one_row { 1024 } else { w * GROUP[1] };
    // Each band writes its masks in place: one allocation, no copy of
    // band vectors into it.
    let mut masks = vec![0u32; n];
    // Every band a job of its own (`with_max_len(1)`): rayon's adaptive
    // split otherwise hands each thread a run of bands it walks alone, and
    // the tests' heavy tail (courtyard: the top 1 % of pixels make a third
    // of them) left one thread idle for up to a third of a layer.
    let bands: Vec<EvaluateStats> = masks
        .par_chunks_mut(band)
        .with_max_len(1)
        .enumerate()
        .map(|(b, out)| {
            let start = b * band;
            let entries = start..start + out.len();
            let group_of = |i: usize| {
                if one_row {
                    (i - start) / (GROUP[0] * GROUP[1])
                } else {
                    (i % w) / GROUP[0]
                }
            };
            let mut stats = EvaluateStats::default();
            let mut longest = vec![0u64; group_of(entries.end - 1) + 1];
            let mut scratch = PixelScratch::default();
            let mut band_boxes = BandBoxes::default();
            let receiver_flags = super::receiver_flags(rule.skips);
            boxes.project_band(
                setup,
                g,
                entries.clone(),
                wanted,
                receiver_flags,
                &mut band_boxes,
            );
            for (i, slot) in entries.zip(out) {
                if !is_receiver(g.flags[i], rule.skips) {
                    continue;
                }
                stats.pixels_tested += 1;
                let ndc_box = boxes.ndc_box(i, &band_boxes);
                let mut px = pixel_frustum(setup, g, i, ndc_box, rule);
                if let Some(w) = wanted {
                    px.wanted = w[i];
                }
                let (mask, tests) =
                    evaluate_pixel(setup, bins, triangles, &px, rule, &mut scratch, &mut stats);
                stats.longest_pixel_tests = stats.longest_pixel_tests.max(tests);
                let group = &mut longest[group_of(i)];
                *group = (*group).max(tests);
                if g.flags[i] & flags::SHADOW_TESTED != 0 {
                    *slot = mask;
                }
            }
            stats.group_longest_tests = longest.iter().sum();
            stats
        })
        .collect();
    let mut stats = EvaluateStats::default();
    for s in bands {
        stats.add(&s);
    }
    (masks, stats)
}
