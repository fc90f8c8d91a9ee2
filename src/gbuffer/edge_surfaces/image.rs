//! An image's edge surfaces: the edge candidates among its shadow-tested
//! pixels, each one's samples as a [`PixelSamples`], and the extra
//! surfaces and coverage masks gathered into [`EdgeSurfaces`] — for any
//! way of finding the samples' hits (the BVH's sample rays, a multisampled
//! visibility buffer's candidates).

use super::{EdgeStats, EdgeSurfaces, PixelSamples};
use crate::gbuffer::{GBuffer, PixelSurface, SurfaceHit};
use crate::scene::Scene;
use rayon::prelude::*;

/// Gives `g`, whose centre surfaces are `rows`, the edge surfaces of its
/// `edge_halves` mask halves (0, 1, or 2 for the paired mode's second
/// µQuad pattern, [`crate::lut::paired_patterns`]): per edge candidate
/// what `sample_surfaces(pattern, x, y, centre, probes)` finds.
pub fn add_edge_surfaces(
    g: &mut GBuffer,
    scene: &Scene,
    rows: &[Vec<Option<PixelSurface>>],
    edge_halves: usize,
    sample_surfaces: impl Fn(&[[f32; 2]; 32], u32, u32, &PixelSurface, &[Option<SurfaceHit>]) -> PixelSamples
        + Sync,
) {
    let edges_of = |half| {
        let pattern = crate::lut::paired_patterns(half).1;
        let of_pattern = |x, y, centre: &PixelSurface, probes: &[Option<SurfaceHit>]| {
            sample_surfaces(pattern, x, y, centre, probes)
        };
        Box::new(edge_surfaces_of(scene, rows, of_pattern))
    };
    g.edges = (edge_halves >= 1).then(|| edges_of(0));
    g.edges_high = (edge_halves >= 2).then(|| edges_of(1));
}

/// The edge pixels' surfaces of `scene`'s image whose centre surfaces
/// are `rows`: per edge candidate (a shadow-tested pixel whose neighbours'
/// centre hits leave its plane, [`super::is_edge_candidate`]) what
/// `sample_surfaces(x, y, centre, probes)` finds its 32 samples see.
pub fn edge_surfaces_of(
    scene: &Scene,
    rows: &[Vec<Option<PixelSurface>>],
    sample_surfaces: impl Fn(u32, u32, &PixelSurface, &[Option<SurfaceHit>]) -> PixelSamples + Sync,
) -> EdgeSurfaces {
    let [w, h] = scene.resolution;
    // Each pixel's centre triangle (`u32::MAX` for a miss) in one flat
    // array: the id test reads 8 neighbours for every pixel, and reading
    // them from the 100-byte surfaces cost more (default at 1080p: the
    // whole render 5 % faster, median of 8 pairs).
    let hit_ids: Vec<u32> = rows
        .par_iter()
        .flat_map_iter(|row| {
            row.iter()
                .map(|s| s.as_ref().map_or(u32::MAX, |s| s.hit.triangle))
        })
        .collect();
    // Only the candidates' results are kept: a smooth pixel's entries are
    // the defaults below.
    // A job per row, as the G-buffer's: edge pixels bunch in a few rows.
    let samples: Vec<(usize, PixelSamples)> = (0..h)
        .into_par_iter()
        .with_max_len(1)
        .flat_map_iter(|y| (0..w).map(move |x| (x, y)))
        .filter_map(|(x, y)| {
            let i = y as usize * w as usize + x as usize;
            let triangle = hit_ids[i];
            if triangle == u32::MAX {
                return None;
            }
            let at = |nx: u32, ny: u32| {
                let id = hit_ids[ny as usize * w as usize + nx as usize];
                (id != u32::MAX).then_some(id)
            };
            if super::neighbours_on_triangle(x, y, [w, h], triangle, at) {
                return None;
            }
            let centre = rows[y as usize][x as usize]
                .as_ref()
                .filter(|c| c.shadow_tested)?;
            let (probes, n) = super::neighbour_probes(x, y, [w, h], |nx, ny| {
                rows[ny as usize][nx as usize].map(|s| s.hit)
            });
            let probes = &probes[..n];
            super::is_edge_candidate(centre, probes)
                .then(|| (i, sample_surfaces(x, y, centre, probes)))
        })
        .collect();
    let n = w as usize * h as usize;
    let extra_count: usize = samples.iter().map(|(_, s)| s.extra.len()).sum();
    let mut e = EdgeSurfaces {
        surfaces: GBuffer::with_capacity(extra_count as u32, 1),
        pixel: Vec::with_capacity(extra_count),
        coverage: Vec::with_capacity(extra_count),
        centre_coverage: vec![u32::MAX; n],
        counted: vec![u32::MAX; n],
        facing_away: vec![0; n],
        stats: EdgeStats {
            candidates: samples.len(),
            sample_rays: 32 * samples.len() as u64,
            ..Default::default()
        },
    };
    for (i, s) in &samples {
        let i = *i;
        e.stats.sample_rays_unbounded += s.unbounded_rays as u64;
        e.stats.edge_pixels += s.is_edge() as usize;
        e.stats.extra_surfaces += s.extra.len();
        e.stats.facing_away_samples += s.facing_away.count_ones() as u64;
        e.stats.dropped_samples += s.dropped.count_ones() as u64;
        e.stats.missed_samples += s.missed.count_ones() as u64;
        e.centre_coverage[i] = s.centre_coverage;
        e.counted[i] = s.counted;
        e.facing_away[i] = s.facing_away;
        for x in &s.extra {
            e.surfaces.push(Some(&x.surface));
            e.pixel.push(i as u32);
            e.coverage.push(x.coverage);
        }
    }
    e
}
