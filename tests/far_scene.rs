//! Precision far from the origin: the `far` scene is the `default` scene
//! moved 1e5 units along every axis. With eye-relative `f64` tracing the two
//! references must agree pixel for pixel (same seed, same sub-sample
//! positions): no acne from self-intersection, no leaks from rounding.

use izb::bvh::SceneBvh;
use izb::reference::{reference, ReferenceImage, ReferenceSettings};
use izb::scene;

const RESOLUTION: [u32; 2] = [240, 135];
const SAMPLES_PER_SIDE: u32 = 8;

fn trace(name: &str) -> ReferenceImage {
    let scene = scene::load(name)
        .unwrap()
        .with_resolution(RESOLUTION)
        .unwrap();
    let bvh = SceneBvh::build(&scene);
    let settings = ReferenceSettings {
        samples_per_side: SAMPLES_PER_SIDE,
        seed: 3,
    };
    reference(&scene, &bvh, settings, &|_| {})
}

#[test]
fn far_scene_reference_matches_the_default_scene() {
    let near = trace("default");
    let far = trace("far");
    let n = near.visibility.len();
    let (mut tested_differently, mut differing, mut max_diff) = (0, 0, 0.0f32);
    let mut shadowed = 0;
    for i in 0..n {
        let (a, b) = (near.visibility[i], far.visibility[i]);
        if a.is_nan() != b.is_nan() {
            tested_differently += 1;
            continue;
        }
        if a.is_nan() {
            continue;
        }
        shadowed += (a < 1.0) as usize;
        if a != b {
            differing += 1;
            max_diff = max_diff.max((a - b).abs());
        }
    }
    println!(
        "{n} pixels, {shadowed} with some shadow: {tested_differently} tested differently, \
         {differing} differ (max {max_diff})"
    );
    assert!(shadowed > 1000, "the scene should have shadows: {shadowed}");
    // Same rays up to a relative rounding of 1e-16 · 1e5: a sample flips only
    // if it passes within ~1e-11 of an edge. Allow one pixel in 10⁴ to flip
    // one sample (1/k²), nothing more.
    assert!(
        tested_differently <= n / 10_000,
        "{tested_differently} pixels changed shadow-tested status"
    );
    assert!(differing <= n / 10_000, "{differing} pixels differ");
    let one_sample = 1.0 / (SAMPLES_PER_SIDE * SAMPLES_PER_SIDE) as f32;
    assert!(
        max_diff <= one_sample + f32::EPSILON,
        "max difference {max_diff} > one sample {one_sample}"
    );
    assert_eq!(
        near.stats.smooth_pixels, far.stats.smooth_pixels,
        "smooth-pixel classes differ"
    );
}

#[test]
fn analytic_scene_far_from_the_origin_meets_the_exact_bound() {
    use izb::reference::analytic::AnalyticShadow;
    use izb::scene::procedural::FAR_OFFSET;
    let scene = scene::load("analytic").unwrap().translated(FAR_OFFSET);
    let exact = AnalyticShadow::translated(&scene, FAR_OFFSET).unwrap();
    let bvh = SceneBvh::build(&scene);
    let settings = ReferenceSettings {
        samples_per_side: 16,
        seed: 11,
    };
    let image = reference(&scene, &bvh, settings, &|_| {});
    let check = exact.check(&image.visibility, scene.resolution[0], 16);
    println!("{check:#?}");
    assert!(check.penumbra_pixels > 500);
    assert!(
        check.holds(),
        "acne or leaks at 1e5 from the origin: {check:#?}"
    );
}
