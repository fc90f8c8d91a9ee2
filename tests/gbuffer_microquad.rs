//! µQuad axes against finite differences of nearby camera rays.
//!
//! The G-buffer's `Ex = dP/dx`, `Ey = dP/dy` are exact derivatives of the
//! ray/tangent-plane intersection. On a planar triangle, the hit of a ray
//! through (x ± h, y) lies on that same plane, so the central difference
//! converges to the axis with error O(h²); we check both the neighbouring
//! pixel rays (h = 1) and a fine step (h = 1/256).

use glam::DVec3;
use izb::bvh::SceneBvh;
use izb::gbuffer::{microquad_axes, trace_primary, SurfaceHit};
use izb::scene::{self, CameraFrame, Scene};

/// Central differences of the hit point along x and y at the pixel centre
/// (px, py), or `None` if any of the four rays leaves the centre's triangle.
fn central_differences(
    bvh: &SceneBvh,
    scene: &Scene,
    frame: &CameraFrame,
    c: &SurfaceHit,
    px: f64,
    py: f64,
    h: f64,
) -> Option<(DVec3, DVec3)> {
    let at = |x: f64, y: f64| {
        trace_primary(bvh, frame, scene.camera.near, scene.camera.far, x, y)
            .filter(|s| s.triangle == c.triangle)
            .map(|s| s.position)
    };
    let dx = (at(px + h, py)? - at(px - h, py)?) / (2.0 * h);
    let dy = (at(px, py + h)? - at(px, py - h)?) / (2.0 * h);
    Some((dx, dy))
}

/// Worst relative error |axis − difference| / |axis| over the pixels of
/// `scene` whose centre hits one of `triangles` (all if empty) and whose
/// µQuad is not clamped; also the number of pixels compared.
fn worst_relative_error(scene: &Scene, triangles: &[u32], h: f64, stride: u32) -> (f64, usize) {
    let bvh = SceneBvh::build(scene);
    let frame = scene.camera.frame(scene.resolution);
    let (mut worst, mut count) = (0.0f64, 0);
    for y in (0..scene.resolution[1]).step_by(stride as usize) {
        for x in (0..scene.resolution[0]).step_by(stride as usize) {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let Some(c) = trace_primary(&bvh, &frame, scene.camera.near, scene.camera.far, px, py)
            else {
                continue;
            };
            if !triangles.is_empty() && !triangles.contains(&c.triangle) {
                continue;
            }
            let (ex, ey, clamped) = microquad_axes(&frame, px, py, &c);
            if clamped {
                continue;
            }
            let Some((dx, dy)) = central_differences(&bvh, scene, &frame, &c, px, py, h) else {
                continue;
            };
            worst = worst
                .max((ex - dx).length() / ex.length())
                .max((ey - dy).length() / ey.length());
            count += 1;
        }
    }
    (worst, count)
}

#[test]
fn axes_match_finite_differences_on_a_plane() {
    // The analytic scene's ground: triangles 0 and 1.
    let scene = scene::load("analytic").unwrap();
    let (fine, n) = worst_relative_error(&scene, &[0, 1], 1.0 / 256.0, 3);
    println!("plane, h = 1/256: worst relative error {fine:.3e} over {n} pixels");
    assert!(n > 5000, "only {n} pixels compared");
    assert!(fine < 1e-6, "h = 1/256: relative error {fine:.3e}");
    // Neighbouring pixel rays: the truncation error of a central difference
    // of the perspective map is O((h · pixel angle)²): measured 2e-5 here.
    let (coarse, _) = worst_relative_error(&scene, &[0, 1], 1.0, 3);
    println!("plane, h = 1 (neighbouring pixels): worst relative error {coarse:.3e}");
    assert!(coarse < 1e-3, "h = 1: relative error {coarse:.3e}");
    assert!(
        coarse > fine,
        "the finite difference should converge as h shrinks"
    );
}

#[test]
fn axes_match_finite_differences_on_a_sphere() {
    // The default scene's sphere: every facet has its own orientation, from
    // facing the camera to nearly edge-on at the silhouette.
    let scene = scene::load("default").unwrap();
    let sphere: Vec<u32> = (0..scene.triangles.len() as u32)
        .filter(|&i| {
            let c = (scene.triangles[i as usize][0]
                + scene.triangles[i as usize][1]
                + scene.triangles[i as usize][2])
                / 3.0;
            (c - DVec3::new(-0.5, 1.0, 0.5)).length() < 1.01
        })
        .collect();
    assert!(
        sphere.len() > 2000,
        "sphere facets not found: {}",
        sphere.len()
    );
    let (fine, n) = worst_relative_error(&scene, &sphere, 1.0 / 256.0, 1);
    println!("sphere, h = 1/256: worst relative error {fine:.3e} over {n} pixels");
    assert!(n > 2000, "only {n} pixels compared");
    assert!(fine < 1e-5, "h = 1/256: relative error {fine:.3e}");
    let (coarse, m) = worst_relative_error(&scene, &sphere, 1.0, 1);
    println!("sphere, h = 1 (neighbouring pixels, same facet): worst relative error {coarse:.3e} over {m} pixels");
    assert!(coarse < 1e-3, "h = 1: relative error {coarse:.3e}");
    assert!(m > 1000, "only {m} pixels compared at h = 1");
}

#[test]
fn grazing_microquads_are_clamped_and_counted() {
    let scene = scene::load("grazing")
        .unwrap()
        .with_resolution([240, 135])
        .unwrap();
    let bvh = SceneBvh::build(&scene);
    let g = izb::gbuffer::gbuffer(&scene, &bvh);
    let limit = izb::gbuffer::MAX_MICROQUAD_STRETCH as f32;
    let frame = scene.camera.frame(scene.resolution);
    let pixel_angle = frame.direction_dx().length() as f32;
    let mut clamped = 0;
    for i in 0..g.flags.len() {
        if g.flags[i] & izb::gbuffer::flags::HIT == 0 {
            continue;
        }
        // Footprint of a pixel facing the ray at this depth (|D| ≥ 1 off axis).
        let x = (i as u32 % g.width) as f64 + 0.5;
        let y = (i as u32 / g.width) as f64 + 0.5;
        let facing = g.depth[i] * pixel_angle * frame.direction(x, y).length() as f32;
        let longest = g.axis_x[i].length().max(g.axis_y[i].length());
        assert!(
            longest <= limit * facing * (1.0 + 1e-5),
            "pixel {i}: axis {longest} beyond the clamp {}",
            limit * facing
        );
        clamped += (g.flags[i] & izb::gbuffer::flags::AXES_CLAMPED != 0) as usize;
    }
    assert_eq!(clamped, g.stats.clamped_microquads);
    println!("grazing: {clamped} clamped µQuads of {} hits", g.stats.hits);
}
