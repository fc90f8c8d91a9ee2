//! The ground truth against a closed form: a square occluder over a ground
//! plane under a directional light (`reference::analytic`). The stratified
//! estimator must meet its proven per-pixel and mean bounds; a reference
//! traced with a slightly wrong light must not.

use glam::{DQuat, DVec3};
use izb::bvh::SceneBvh;
use izb::reference::analytic::AnalyticShadow;
use izb::reference::{reference, ReferenceSettings};
use izb::scene::{self, Light};

const SAMPLES_PER_SIDE: u32 = 16;

fn trace(scene: &izb::scene::Scene) -> Vec<f32> {
    let bvh = SceneBvh::build(scene);
    let settings = ReferenceSettings {
        samples_per_side: SAMPLES_PER_SIDE,
        seed: 7,
    };
    reference(scene, &bvh, settings, &|_| {}).visibility
}

#[test]
fn stratified_reference_meets_its_bound_against_the_exact_shadow() {
    let scene = scene::load("analytic").unwrap();
    let exact = AnalyticShadow::new(&scene).unwrap();
    let visibility = trace(&scene);
    let check = exact.check(&visibility, scene.resolution[0], SAMPLES_PER_SIDE);
    println!("{check:#?}");
    // The configuration must exercise the bound: many pixels, a real penumbra.
    assert!(
        check.pixels > 40_000,
        "too few checked pixels: {}",
        check.pixels
    );
    assert!(
        check.penumbra_pixels > 500,
        "too few penumbra pixels: {}",
        check.penumbra_pixels
    );
    assert_eq!(
        check.violations, 0,
        "pixels beyond the deterministic bound c/N (worst excess {:.3e})",
        check.max_excess_over_bound
    );
    assert!(
        check.mean_abs_error <= check.mean_abs_bound,
        "mean |error| {:.3e} > bound {:.3e}",
        check.mean_abs_error,
        check.mean_abs_bound
    );
    assert!(
        check.mean_signed_error.abs() <= check.mean_signed_bound,
        "mean signed error {:.3e} beyond ±{:.3e}",
        check.mean_signed_error,
        check.mean_signed_bound
    );
    // A single straight edge cuts at most 2k − 1 of the k×k strata.
    let single_edge =
        (2 * SAMPLES_PER_SIDE - 1) as f64 / (SAMPLES_PER_SIDE * SAMPLES_PER_SIDE) as f64;
    assert!(
        check.max_abs_error <= 2.0 * single_edge,
        "max error {} above two edges' worth {}",
        check.max_abs_error,
        2.0 * single_edge
    );
}

#[test]
fn a_reference_with_a_wrong_light_direction_fails_the_check() {
    let scene = scene::load("analytic").unwrap();
    let exact = AnalyticShadow::new(&scene).unwrap();
    let Light::Directional { direction } = scene.light else {
        unreachable!()
    };
    // Rotate the light by 1° about a horizontal axis: the shadow moves by
    // about 3 cm, several pixels at this resolution.
    let wrong = DQuat::from_axis_angle(DVec3::X, 1f64.to_radians()) * direction;
    let mut wrong_scene = scene.clone();
    wrong_scene.light = Light::directional(wrong);
    let check = exact.check(&trace(&wrong_scene), scene.resolution[0], SAMPLES_PER_SIDE);
    println!("{check:#?}");
    assert!(
        !check.holds(),
        "a 1° light error went unnoticed: {check:#?}"
    );
    assert!(
        check.violations > 100,
        "only {} pixels flagged",
        check.violations
    );
}
