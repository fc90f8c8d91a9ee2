//! The ray-cast G-buffer: one `f64` ray per pixel centre through the
//! scene's BVH, and 32 sample rays per edge pixel (the CPU twin of the
//! GPU's ray-cast producer).

use super::edge_surfaces;
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
    // A job per row (`with_max_len(1)`): rows under dense geometry cost
    // many times a sky row's, and rayon's adaptive split would leave one
    // thread walking a long run of them alone.
    let rows: Vec<Vec<Option<PixelSurface>>> = (0..h)
        .into_par_iter()
        .with_max_len(1)
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
    let sample_surfaces =
        |pattern: &[[f32; 2]; 32], x, y, centre: &PixelSurface, probes: &[Option<SurfaceHit>]| {
            edge_surfaces::sample_surfaces(bvh, scene, &frame, x, y, centre, probes, pattern)
        };
    edge_surfaces::add_edge_surfaces(&mut g, scene, &rows, edge_halves, sample_surfaces);
    g
}
