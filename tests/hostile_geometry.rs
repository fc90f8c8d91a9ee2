//! BVH builds on hostile geometry (issue 28): thousands of distinct
//! triangles whose `f32` boxes coincide. Before they were grouped
//! (`src/bvh/clusters.rs`) 30 000 of them took 60–80 s to build and made
//! a chain 30 000 levels deep; the triangles cast different shadows, so
//! all must stay reachable. Measured further by `examples/bvh_hostile.rs`.

use glam::DVec3;
use izb::bvh::{SceneBvh, WatertightRay};
use izb::gpu::gbuffer::{build_bvh, MAX_BVH_DEPTH};
use izb::gpu::shared::GpuTriangle;
use izb::scene::{Camera, Light, Scene};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use std::time::{Duration, Instant};

const N: usize = 30_000;
/// Far above the grouped build (~10 ms) and far below the old one.
const BUILD_LIMIT: Duration = Duration::from_secs(2);

/// Triangles spanning the unit cube at `base`, each with its vertices at
/// other points of the cube's faces (`same-box`), or one triangle moved
/// by less than a quarter `f32` ulp per copy (`sub-ulp`): identical `f32`
/// boxes, no two triangles equal.
fn hostile(case: &str, n: usize) -> Vec<[DVec3; 3]> {
    let mut rng = Pcg32::seed_from_u64(28);
    let base = DVec3::new(-0.5, 0.0, -3.0);
    (0..n)
        .map(|i| {
            let t = match case {
                "same-box" => [
                    DVec3::new(0.0, 0.0, rng.random()),
                    DVec3::new(1.0, rng.random(), 0.0),
                    DVec3::new(rng.random(), 1.0, 1.0),
                ],
                "sub-ulp" => {
                    let d = i as f64 * (f32::EPSILON as f64 / 4.0) / n as f64;
                    [
                        DVec3::new(0.0, 0.0, 0.0),
                        DVec3::new(1.0, d, 0.0),
                        DVec3::new(0.5 + d, 1.0, 0.5),
                    ]
                }
                "nested" => {
                    // One centre, boxes growing: no two boxes equal, yet
                    // PLOC builds a chain ~1 000 levels deep.
                    let s = 0.5 + i as f64 * 1e-3 / n as f64;
                    [
                        DVec3::new(-s, -s, 0.0),
                        DVec3::new(s, -s, s),
                        DVec3::new(0.0, s, -s),
                    ]
                }
                other => panic!("unknown case {other}"),
            };
            t.map(|v| base + v)
        })
        .collect()
}

fn scene(case: &str, n: usize) -> Scene {
    let camera = Camera {
        eye: DVec3::new(0.0, 0.5, 0.0),
        target: DVec3::new(0.0, 0.5, -3.0),
        up: DVec3::Y,
        fov_y_deg: 60.0,
        near: 0.05,
        far: 100.0,
    };
    let light = Light::directional(DVec3::new(-1.0, -2.0, -1.0));
    let scene = Scene::new(case, hostile(case, n), camera, light, [64, 64]).unwrap();
    assert_eq!(scene.triangles.len(), n, "{case}: no triangle dropped");
    scene
}

/// Random rays through the cube, eye-relative: closest hit and occlusion
/// equal a loop over every triangle. Returns the rays that hit.
fn matches_brute_force(scene: &Scene, bvh: &SceneBvh, rays: usize) -> usize {
    let tris = scene.eye_relative_triangles();
    let (lo, hi) = scene.bounds();
    let centre = (lo + hi) / 2.0 - scene.camera.eye;
    let mut rng = Pcg32::seed_from_u64(7);
    let mut hits = 0;
    for _ in 0..rays {
        // From anywhere around the triangles towards their middle.
        let mut p = |r: f64| centre + (DVec3::from(rng.random::<[f64; 3]>()) * 2.0 - 1.0) * r;
        let (origin, target) = (p(1.5), p(0.2));
        let dir = (target - origin).normalize();
        let ray = WatertightRay::new(origin, dir);
        let mut expected: Option<(u32, f64)> = None;
        for (i, t) in tris.iter().enumerate() {
            if let Some(t) = ray.intersect(t) {
                if t > 0.0 && expected.is_none_or(|(_, b)| t < b) {
                    expected = Some((i as u32, t));
                }
            }
        }
        let got = bvh.closest_hit(origin, dir, 0.0, f64::INFINITY, u32::MAX);
        assert_eq!(
            got.map(|h| (h.triangle, h.t)),
            expected,
            "ray {origin} {dir}"
        );
        let skip = expected.map_or(u32::MAX, |(i, _)| i);
        let brute = tris
            .iter()
            .enumerate()
            .any(|(i, t)| i as u32 != skip && ray.intersect(t).is_some_and(|t| t > 0.0 && t < 1.0));
        assert_eq!(bvh.occluded(origin, dir, 0.0, 1.0, skip), brute);
        hits += got.is_some() as usize;
    }
    hits
}

#[test]
fn identical_boxes_build_fast_and_every_triangle_stays_reachable() {
    let mut cases = 0;
    for case in ["same-box", "sub-ulp"] {
        let scene = scene(case, N);
        let start = Instant::now();
        let bvh = SceneBvh::build(&scene);
        let took = start.elapsed();
        assert!(took < BUILD_LIMIT, "{case}: CPU BVH took {took:?}");
        assert_eq!(bvh.len(), N);
        let hits = matches_brute_force(&scene, &bvh, 200);
        assert!(hits > 50, "{case}: only {hits} of 200 rays hit");
        // Each of every 97th triangle is found by a ray at its centroid
        // that accepts only it.
        let tris = scene.eye_relative_triangles();
        let mut reached = 0;
        for id in (0..N).step_by(97) {
            let t = &tris[id];
            let centroid = (t[0] + t[1] + t[2]) / 3.0;
            let normal = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
            let origin = centroid + normal * 2.0;
            assert!(
                bvh.any_hit(origin, -normal, 0.0, 3.0, |hit| hit == id as u32),
                "{case}: triangle {id} unreachable"
            );
            reached += 1;
        }
        assert_eq!(reached, N.div_ceil(97));

        let gpu_tris: Vec<GpuTriangle> = tris
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| v.as_vec3().to_array());
                GpuTriangle { a, b, c }
            })
            .collect();
        let start = Instant::now();
        let gpu = build_bvh(&gpu_tris).unwrap_or_else(|e| panic!("{case}: {e}"));
        let took = start.elapsed();
        assert!(took < BUILD_LIMIT, "{case}: GPU BVH took {took:?}");
        assert!(gpu.depth <= MAX_BVH_DEPTH, "{case}: depth {}", gpu.depth);
        let mut prims = gpu.prims.clone();
        prims.sort_unstable();
        assert_eq!(
            prims,
            (0..N as u32).collect::<Vec<_>>(),
            "{case}: GPU prims"
        );
        let in_leaves: u32 = gpu.nodes.iter().map(|n| n.prim_count).sum();
        assert_eq!(in_leaves as usize, N, "{case}: every prim in one leaf");
        cases += 1;
    }
    assert_eq!(cases, 2);
}

/// Nested boxes make a BVH2 ~1 000 levels deep: the CPU build converts it
/// on a stack of its own (no overflow here, in a 2 MiB test thread) and
/// stays exact; the GPU build refuses it by name, never a panic.
#[test]
fn a_deep_tree_neither_overflows_nor_passes_the_gpu_cap() {
    let scene = scene("nested", 1_000);
    let bvh = SceneBvh::build(&scene);
    let hits = matches_brute_force(&scene, &bvh, 300);
    assert!(hits > 50, "only {hits} of 300 rays hit");
    let gpu_tris: Vec<GpuTriangle> = scene
        .eye_relative_triangles()
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| v.as_vec3().to_array());
            GpuTriangle { a, b, c }
        })
        .collect();
    match build_bvh(&gpu_tris) {
        Ok(gpu) => assert!(gpu.depth <= MAX_BVH_DEPTH),
        Err(e) => assert!(e.to_string().contains("levels deep"), "{e}"),
    }
}
