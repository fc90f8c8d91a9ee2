//! The BVH ray caster against a brute-force loop over every triangle (the
//! way obvhs checks its own traversals): same closest hit, same occlusion
//! answer, for random rays through a scene of thin random triangles.

use glam::DVec3;
use izb::bvh::{SceneBvh, WatertightRay};
use izb::scene::{self, Scene};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;

fn brute_closest(
    tris: &[[DVec3; 3]],
    origin: DVec3,
    dir: DVec3,
    t_min: f64,
    t_max: f64,
) -> Option<(u32, f64)> {
    let ray = WatertightRay::new(origin, dir);
    let mut best: Option<(u32, f64)> = None;
    for (i, t) in tris.iter().enumerate() {
        if let Some(t) = ray.intersect(t) {
            if t > t_min && t < t_max && best.is_none_or(|(_, b)| t < b) {
                best = Some((i as u32, t));
            }
        }
    }
    best
}

fn random_rays(scene: &Scene, count: usize, seed: u64) -> Vec<(DVec3, DVec3)> {
    let mut rng = Pcg32::seed_from_u64(seed);
    // Endpoints in the box around the ball of hair (centre (0, 2, 0),
    // radius 1.5, wherever the scene was moved), eye-relative.
    let (lo, hi) = scene.bounds();
    let centre =
        DVec3::new((lo.x + hi.x) / 2.0, lo.y + 2.0, (lo.z + hi.z) / 2.0) - scene.camera.eye;
    let (lo, hi) = (centre - 1.6, centre + 1.6);
    (0..count)
        .map(|_| {
            let p = |rng: &mut Pcg32| {
                DVec3::new(
                    rng.random_range(lo.x..hi.x),
                    rng.random_range(lo.y..hi.y),
                    rng.random_range(lo.z..hi.z),
                )
            };
            let (a, b) = (p(&mut rng), p(&mut rng));
            (a, (b - a).normalize())
        })
        .collect()
}

#[test]
fn closest_hit_and_occlusion_match_brute_force() {
    let scene = scene::procedural::build("hairball").unwrap().unwrap();
    let bvh = SceneBvh::build(&scene);
    let tris = scene.eye_relative_triangles();
    let (mut hits, mut occluded) = (0, 0);
    for (origin, dir) in random_rays(&scene, 4000, 5) {
        let expected = brute_closest(&tris, origin, dir, 0.0, f64::INFINITY);
        let got = bvh.closest_hit(origin, dir, 0.0, f64::INFINITY, u32::MAX);
        assert_eq!(
            got.map(|h| (h.triangle, h.t)),
            expected,
            "ray {origin} {dir}"
        );
        hits += got.is_some() as usize;
        // Occlusion on a bounded segment, skipping the first hit.
        let skip = expected.map_or(u32::MAX, |(i, _)| i);
        let t_max = 2.0;
        let brute = tris.iter().enumerate().any(|(i, t)| {
            i as u32 != skip
                && WatertightRay::new(origin, dir)
                    .intersect(t)
                    .is_some_and(|t| t > 0.0 && t < t_max)
        });
        let fast = bvh.occluded(origin, dir, 0.0, t_max, skip);
        assert_eq!(fast, brute, "occlusion of ray {origin} {dir}");
        occluded += fast as usize;
    }
    println!("4000 rays: {hits} hits, {occluded} occluded segments");
    assert!(
        hits > 1000 && occluded > 200,
        "rays should exercise both outcomes"
    );
}

#[test]
fn far_from_origin_the_bvh_still_matches_brute_force() {
    // 1e5 from the origin, eye-relative f64 coordinates keep the traversal
    // exact; a world-space f32 BVH would misplace these 4 mm wide slivers.
    let scene = scene::procedural::build("hairball")
        .unwrap()
        .unwrap()
        .translated(DVec3::splat(1e5));
    let bvh = SceneBvh::build(&scene);
    let tris = scene.eye_relative_triangles();
    for (origin, dir) in random_rays(&scene, 2000, 9) {
        let expected = brute_closest(&tris, origin, dir, 0.0, f64::INFINITY);
        let got = bvh.closest_hit(origin, dir, 0.0, f64::INFINITY, u32::MAX);
        assert_eq!(got.map(|h| (h.triangle, h.t)), expected);
    }
}

#[test]
fn watertight_rays_through_a_shared_edge_never_slip_between() {
    // Two triangles sharing the diagonal of a unit square; rays aimed
    // exactly at points of the diagonal must hit at least one of them.
    let a = DVec3::new(0.0, 0.0, 0.0);
    let b = DVec3::new(1.0, 0.0, 0.0);
    let c = DVec3::new(1.0, 0.0, 1.0);
    let d = DVec3::new(0.0, 0.0, 1.0);
    let tris = [[a, b, c], [a, c, d]];
    let mut rng = Pcg32::seed_from_u64(1);
    for _ in 0..10_000 {
        let s: f64 = rng.random();
        let target = DVec3::new(s, 0.0, s);
        let origin = DVec3::new(
            rng.random_range(-3.0..3.0),
            rng.random_range(0.1..3.0),
            rng.random_range(-3.0..3.0),
        );
        let ray = WatertightRay::new(origin, target - origin);
        assert!(
            tris.iter().any(|t| ray.intersect(t).is_some()),
            "ray from {origin} to {target} slipped through the shared edge"
        );
    }
}
