//! `pcss-R` (Fernando 2005): its penumbra follows the light's size, a
//! hard light degrades it to a narrow PCF instead of failing, bad names are
//! refused, and the Vulkan twin gives the CPU's lit fractions on the same
//! G-buffer (suns of 1° and a sphere light).

mod common;

use common::gpu::{assert_no_validation_messages, lock, renderer};
use glam::DVec3;
use izb::baseline::{render_shadow_map, ShadowMapSettings};
use izb::bvh::SceneBvh;
use izb::gbuffer::gbuffer;
use izb::scene::{self, Light, Scene};

/// `name` at 160×90 under a light of `size` (degrees or scene units).
fn small(name: &str, size: f64) -> Scene {
    scene::load(name)
        .unwrap()
        .with_resolution([160, 90])
        .unwrap()
        .with_light_size(size)
        .unwrap()
}

/// `default` under a sphere light of radius `radius` above its objects.
fn sphere_light(radius: f64) -> Scene {
    let mut s = scene::load("default")
        .unwrap()
        .with_resolution([160, 90])
        .unwrap();
    s.light = Light::Point {
        position: DVec3::new(1.0, 25.0, 0.0),
    };
    s.name = "default-sphere-light".into();
    s.with_light_size(radius).unwrap()
}

/// CPU PCSS lit fractions of `scene` with `method`.
fn cpu_pcss(scene: &Scene, method: &str) -> Vec<f32> {
    let bvh = SceneBvh::build(scene);
    let g = gbuffer(scene, &bvh);
    let settings = ShadowMapSettings::parse(method).unwrap();
    render_shadow_map(scene, &g, settings).unwrap().visibility
}

/// Tested pixels and those strictly inside a penumbra (0 < lit < 1).
fn penumbra(visibility: &[f32]) -> (usize, usize) {
    let tested = visibility.iter().filter(|v| !v.is_nan()).count();
    let soft = visibility.iter().filter(|&&v| v > 0.0 && v < 1.0).count();
    (tested, soft)
}

#[test]
fn penumbra_widens_with_the_light() {
    let mut counts = Vec::new();
    for size in [0.0, 0.25, 1.0, 3.0] {
        let (tested, soft) = penumbra(&cpu_pcss(&small("analytic", size), "pcss-1024"));
        println!("analytic, sun {size}°: {soft} of {tested} pixels in a penumbra");
        assert!(tested > 5000, "{tested} tested pixels");
        counts.push(soft);
    }
    // A hard light: PCSS degrades to a one-texel PCF, a thin edge.
    assert!(counts[0] < counts[1], "{counts:?}");
    assert!(counts.windows(2).all(|w| w[0] <= w[1]), "{counts:?}");
    assert!(counts[3] > 3 * counts[1], "{counts:?}");
}

#[test]
fn sphere_light_penumbra_widens_too() {
    let (_, small_light) = penumbra(&cpu_pcss(&sphere_light(0.05), "pcss-1024"));
    let (tested, large_light) = penumbra(&cpu_pcss(&sphere_light(1.5), "pcss-1024"));
    println!("sphere light: {small_light} / {large_light} of {tested} pixels in a penumbra");
    assert!(
        2 * large_light > 3 * small_light,
        "{small_light} vs {large_light}"
    );
}

#[test]
fn pcss_names_are_checked() {
    for (bad, says) in [
        ("pcss-256", "R ≥ 512"),
        ("csm2-pcss-1024", "one map"),
        ("pcss-x", "not a shadow-map method"),
    ] {
        let err = ShadowMapSettings::parse(bad).unwrap_err();
        assert!(err.contains(bad) && err.contains(says), "{bad}: {err}");
    }
    assert_eq!(
        ShadowMapSettings::parse("pcss-2048").unwrap().to_string(),
        "pcss-2048"
    );
}

/// Largest share of shadow-tested pixels whose GPU lit fraction may differ
/// from the CPU's: `tests/baselines.rs`'s bound for the PCF twins. A PCSS
/// value is a count of 32 taps, so any difference is at least 1/32: a tap
/// whose coordinate rounds to the other texel (lavapipe's division is not
/// always correctly rounded) or a blocker exactly at its bias limit.
const MAX_GPU_PIXEL_MISMATCH: f64 = 2e-3;

#[test]
fn gpu_pcss_matches_the_cpu_twin() {
    let Some(r) = renderer() else { return };
    let r = lock(r);
    let scenes = [
        small("analytic", 1.0),
        small("default", 1.0),
        small("city", 1.0),
        sphere_light(0.3),
    ];
    let name = "pcss-512";
    let settings = ShadowMapSettings::parse(name).unwrap();
    let mut total = 0;
    for scene in &scenes {
        let bvh = SceneBvh::build(scene);
        let g = gbuffer(scene, &bvh);
        let cpu = render_shadow_map(scene, &g, settings).unwrap();
        let gpu = r
            .render_shadow_map(scene, settings, izb::gpu::GBufferSource::Upload(&g))
            .unwrap();
        assert_no_validation_messages(&r, name);
        // The same rounding allowance as the PCF twins (tests/baselines.rs).
        let rounding = 8.0 * settings.side as f32 * f32::EPSILON;
        let (mut tested, mut differ, mut soft, mut worst) = (0usize, 0usize, 0usize, 0.0f32);
        for (a, b) in cpu.visibility.iter().zip(&gpu.visibility) {
            assert_eq!(
                a.is_nan(),
                b.is_nan(),
                "{}: tested pixels differ",
                scene.name
            );
            if !a.is_nan() {
                tested += 1;
                soft += (*a > 0.0 && *a < 1.0) as usize;
                let d = (a - b).abs();
                differ += (d > rounding) as usize;
                worst = worst.max(d);
            }
        }
        println!(
            "{} {name}: {tested} pixels compared ({soft} in a penumbra), {differ} differ; largest |Δ| {worst:.3}",
            scene.name
        );
        assert!(tested > 5000, "{}: only {tested} pixels", scene.name);
        assert!(soft > 50, "{}: only {soft} penumbra pixels", scene.name);
        assert!(
            differ as f64 <= MAX_GPU_PIXEL_MISMATCH * tested as f64,
            "{}: {differ} of {tested} pixels differ (largest |Δ| {worst})",
            scene.name
        );
        total += tested;
    }
    println!("compared {total} pixels over {} scenes", scenes.len());
}
