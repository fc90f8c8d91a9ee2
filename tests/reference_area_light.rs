//! The area-light ground truth (`reference` with `light_radius > 0`)
//! against the closed form of the `analytic` scene under a disk sun
//! (`reference::analytic_soft`), and its sanity under point lights and at
//! radius 0.

use glam::DVec3;
use izb::bvh::SceneBvh;
use izb::reference::analytic_soft::{PixelTruth, SoftCheck, SoftShadow, QUADRATURE_SIDE};
use izb::reference::{reference, ReferenceImage, ReferenceSettings, LIGHT_SAMPLES_PER_RAY};
use izb::scene::{self, Light, Scene};
use std::sync::OnceLock;

const SAMPLES_PER_SIDE: u32 = 8;
/// The sun's angular radius in degrees: 11× the real sun's, for a
/// penumbra tens of pixels wide at this resolution.
const SUN_DEG: f64 = 3.0;
const RESOLUTION: [u32; 2] = [320, 180];

fn trace(scene: &Scene) -> ReferenceImage {
    let bvh = SceneBvh::build(scene);
    let settings = ReferenceSettings {
        samples_per_side: SAMPLES_PER_SIDE,
        seed: 7,
    };
    reference(scene, &bvh, settings, &|_| {})
}

fn sun_scene(degrees: f64) -> Scene {
    scene::load("analytic")
        .unwrap()
        .with_resolution(RESOLUTION)
        .unwrap()
        .with_light_size(degrees)
        .unwrap()
}

/// The exact solution under the 3° sun, computed once for every test.
fn truth() -> &'static [PixelTruth] {
    static TRUTH: OnceLock<Vec<PixelTruth>> = OnceLock::new();
    TRUTH.get_or_init(|| {
        let exact = SoftShadow::new(&sun_scene(SUN_DEG)).unwrap();
        exact.truth(QUADRATURE_SIDE)
    })
}

fn check_against_truth(traced_deg: f64) -> (SoftCheck, ReferenceImage) {
    let image = trace(&sun_scene(traced_deg));
    let check = SoftShadow::check(truth(), &image.visibility, SAMPLES_PER_SIDE);
    println!("traced at {traced_deg}°: {check:#?}");
    (check, image)
}

#[test]
fn area_light_reference_meets_its_bound_against_the_exact_penumbra() {
    let (check, image) = check_against_truth(SUN_DEG);
    // The configuration must exercise the bound: many pixels, a wide penumbra.
    assert!(check.pixels > 40_000, "checked {} pixels", check.pixels);
    assert!(
        check.penumbra_pixels > 3_000,
        "only {} penumbra pixels",
        check.penumbra_pixels
    );
    assert!(check.constant_pixels > 30_000, "{}", check.constant_pixels);
    assert_eq!(check.excluded_sky, 0);
    assert_eq!(
        check.violations, 0,
        "pixels beyond their bound (worst excess {:.3e})",
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
    // The quadrature allowance must stay small against the statistics it
    // is added to, or the check would be toothless.
    assert!(
        check.mean_quadrature_allowance < 0.25 * check.mean_abs_bound,
        "quadrature allowance {:.3e} vs mean bound {:.3e}",
        check.mean_quadrature_allowance,
        check.mean_abs_bound
    );
    // Every ground receiver sees the whole disk above its horizon: one
    // real shadow ray per light sample.
    let s = &image.stats;
    let per_pixel = (SAMPLES_PER_SIDE * SAMPLES_PER_SIDE * LIGHT_SAMPLES_PER_RAY) as u64;
    assert_eq!(s.shadow_rays, s.shadow_tested_pixels as u64 * per_pixel);
}

#[test]
fn a_reference_with_a_wrong_sun_size_fails_the_check() {
    let mut flagged = 0;
    for factor in [0.7, 1.4] {
        let (check, _) = check_against_truth(SUN_DEG * factor);
        assert!(!check.holds(), "a sun {factor}× too wide went unnoticed");
        flagged += 1;
    }
    assert_eq!(flagged, 2);
}

#[test]
fn zero_radius_is_bit_identical_to_the_hard_reference() {
    let hard = scene::load("analytic")
        .unwrap()
        .with_resolution(RESOLUTION)
        .unwrap();
    let zero = hard.clone().with_light_size(0.0).unwrap();
    assert_eq!(zero.light_radius, 0.0);
    let (a, b) = (trace(&hard), trace(&zero));
    assert_eq!(a.visibility.len(), b.visibility.len());
    let same = a
        .visibility
        .iter()
        .zip(&b.visibility)
        .filter(|(x, y)| x.to_bits() == y.to_bits())
        .count();
    assert_eq!(same, a.visibility.len());
    assert_eq!(a.stats.shadow_rays, b.stats.shadow_rays);
    // And the soft path really is another path: a 3° sun changes the image.
    let soft = trace(&sun_scene(SUN_DEG));
    let differ = soft
        .visibility
        .iter()
        .zip(&a.visibility)
        .filter(|(x, y)| x.to_bits() != y.to_bits())
        .count();
    assert!(differ > 1_000, "only {differ} pixels changed");
}

/// The pixel whose square holds the ground point `p`.
fn pixel_of(scene: &Scene, p: DVec3) -> usize {
    let q = izb::reference::analytic::project_to_pixels(scene, p).unwrap();
    let (x, y) = (q.x.floor() as u32, q.y.floor() as u32);
    assert!(
        x < scene.resolution[0] && y < scene.resolution[1],
        "{p} off-screen"
    );
    (y * scene.resolution[0] + x) as usize
}

#[test]
fn a_point_light_with_a_radius_casts_a_penumbra() {
    let base = scene::load("analytic")
        .unwrap()
        .with_resolution(RESOLUTION)
        .unwrap();
    // A sphere of radius 0.5 three units above the occluder's centre: the
    // ground under the centre is umbra, the hard edge (x = 1.5) is in the
    // penumbra, x = 4 sees the whole sphere.
    let mut scene = base.clone();
    scene.light = Light::Point {
        position: DVec3::new(0.0, 3.0, 0.0),
    };
    let hard = scene.clone();
    let soft = scene.with_light_size(0.5).unwrap();
    let (h, s) = (trace(&hard), trace(&soft));
    let at = |img: &ReferenceImage, p: DVec3| img.visibility[pixel_of(&soft, p)];
    assert_eq!(at(&s, DVec3::new(0.0, 0.0, 0.0)), 0.0, "umbra");
    assert_eq!(at(&s, DVec3::new(4.0, 0.0, 0.0)), 1.0, "lit");
    let edge = at(&s, DVec3::new(1.5, 0.0, 0.0));
    assert!(edge > 0.2 && edge < 0.8, "penumbra {edge}");
    let partial = |img: &ReferenceImage| {
        img.visibility
            .iter()
            .filter(|v| **v > 0.05 && **v < 0.95)
            .count()
    };
    let (hp, sp) = (partial(&h), partial(&s));
    assert!(
        sp > 2_000 && sp > 5 * hp,
        "soft {sp} vs hard {hp} partial pixels"
    );
    let per_pixel = (SAMPLES_PER_SIDE * SAMPLES_PER_SIDE * LIGHT_SAMPLES_PER_RAY) as u64;
    assert_eq!(
        s.stats.shadow_rays,
        s.stats.shadow_tested_pixels as u64 * per_pixel
    );
}

#[test]
fn light_below_the_horizon_is_hidden_by_the_receiver() {
    // A sphere of radius 0.5 centred 0.2 above the ground, far off to the
    // side: a distant ground point sees it almost edge-on, with the part
    // below y = 0 hidden by the ground itself; the visible share is the
    // unit disk's part above the chord at −0.4:
    // (acos(−0.4) + 0.4 √0.84) / π ≈ 0.748.
    let mut scene = scene::load("analytic")
        .unwrap()
        .with_resolution(RESOLUTION)
        .unwrap();
    scene.light = Light::Point {
        position: DVec3::new(200.0, 0.2, 0.0),
    };
    let scene = scene.with_light_size(0.5).unwrap();
    let image = trace(&scene);
    let share = ((-0.4f64).acos() + 0.4 * 0.84f64.sqrt()) / std::f64::consts::PI;
    let v = image.visibility[pixel_of(&scene, DVec3::new(4.0, 0.0, 3.0))] as f64;
    // 256 samples: σ ≤ 1/32; 0.15 is ~5σ.
    assert!((v - share).abs() < 0.15, "{v} vs {share}");
    // Samples below the horizon cost no ray.
    let per_pixel = (SAMPLES_PER_SIDE * SAMPLES_PER_SIDE * LIGHT_SAMPLES_PER_RAY) as u64;
    let tested = image.stats.shadow_tested_pixels as u64;
    assert!(image.stats.shadow_rays < tested * per_pixel * 9 / 10);
    assert!(image.stats.shadow_rays > tested * per_pixel / 2);
    let truth_pixels = image.visibility.iter().filter(|v| !v.is_nan()).count();
    assert_eq!(truth_pixels as u64, tested);
}
