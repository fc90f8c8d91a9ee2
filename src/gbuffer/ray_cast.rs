//! The ray-cast G-buffer: one `f64` ray per pixel centre through the
//! scene's BVH, and 32 sample rays per edge pixel (the CPU twin of the
//! GPU's ray-cast producer).

use super::edge_surfaces::{self, EdgeStats, EdgeSurfaces, PixelSamples};
use super::{facing_normal, GBuffer, PixelSurface, SurfaceHit, NO_HIT};
use crate::bvh::SceneBvh;
use crate::scene::{CameraFrame, Scene};
use glam::DVec3;
use rayon::prelude::*;

/// Closest hit of the camera ray through image point (`px`, `py`), with view
/// depth inside [near, far].
pub fn trace_primary(
    bvh: &SceneBvh,
    frame: &CameraFrame,
    near: f64,
    far: f64,
    px: f64,
    py: f64,
) -> Option<SurfaceHit> {
    let direction = frame.direction(px, py);
    let hit = bvh.closest_hit(DVec3::ZERO, direction, near, far, NO_HIT)?;
    Some(SurfaceHit {
        triangle: hit.triangle,
        t: hit.t,
        position: direction * hit.t,
        normal: facing_normal(bvh.triangle(hit.triangle), direction),
    })
}

/// The `f64` G-buffer entry of pixel (`x`, `y`), or `None` for a miss.
pub fn pixel_surface(
    bvh: &SceneBvh,
    scene: &Scene,
    frame: &CameraFrame,
    x: u32,
    y: u32,
) -> Option<PixelSurface> {
    let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
    let hit = trace_primary(bvh, frame, scene.camera.near, scene.camera.far, px, py)?;
    let light = scene.light.relative_to(scene.camera.eye);
    Some(PixelSurface::of_hit(frame, (px, py), hit, &light))
}

/// Primary visibility for the whole image (rayon over rows): one surface
/// per pixel, the one its centre ray hits.
pub fn gbuffer(scene: &Scene, bvh: &SceneBvh) -> GBuffer {
    gbuffer_with(scene, bvh, 0)
}

/// [`gbuffer`], and with `edge_halves` of 1 or 2 the edge pixels'
/// per-sample surfaces ([`edge_surfaces`]) for the µQuad pattern of each
/// mask half ([`crate::lut::paired_patterns`]; half 0's is the µQuad
/// pattern of every 32-sample mode).
pub fn gbuffer_with(scene: &Scene, bvh: &SceneBvh, edge_halves: usize) -> GBuffer {
    let [w, h] = scene.resolution;
    let frame = scene.camera.frame(scene.resolution);
    let rows: Vec<Vec<Option<PixelSurface>>> = (0..h)
        .into_par_iter()
        .map(|y| {
            (0..w)
                .map(|x| pixel_surface(bvh, scene, &frame, x, y))
                .collect()
        })
        .collect();
    let mut g = GBuffer::with_capacity(w, h);
    for s in rows.iter().flatten() {
        g.push(s.as_ref());
    }
    let edges_of = |half| {
        let pattern = crate::lut::paired_patterns(half).1;
        Box::new(edge_surfaces_of(scene, bvh, &frame, &rows, pattern))
    };
    g.edges = (edge_halves >= 1).then(|| edges_of(0));
    g.edges_high = (edge_halves >= 2).then(|| edges_of(1));
    g
}

/// The edge pixels' surfaces of the image whose centre surfaces are
/// `rows`: 32 sample rays per edge candidate.
fn edge_surfaces_of(
    scene: &Scene,
    bvh: &SceneBvh,
    frame: &CameraFrame,
    rows: &[Vec<Option<PixelSurface>>],
    pattern: &[[f32; 2]; 32],
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
    let samples: Vec<(usize, PixelSamples)> = (0..h)
        .into_par_iter()
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
            if edge_surfaces::neighbours_on_triangle(x, y, [w, h], triangle, at) {
                return None;
            }
            let centre = rows[y as usize][x as usize]
                .as_ref()
                .filter(|c| c.shadow_tested)?;
            let (probes, n) = edge_surfaces::neighbour_probes(x, y, [w, h], |nx, ny| {
                rows[ny as usize][nx as usize].map(|s| s.hit)
            });
            let probes = &probes[..n];
            edge_surfaces::is_edge_candidate(centre, probes).then(|| {
                let s = edge_surfaces::sample_surfaces(
                    bvh, scene, frame, x, y, centre, probes, pattern,
                );
                (i, s)
            })
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
