//! Edge pixels' per-sample surfaces (`izb::gbuffer::edge_surfaces`) on the
//! CPU twin:
//!
//! 1. exact masks equal the extended same-sample reference
//!    (`edge_same_sample_masks`: every sample on its own surface's µQuad,
//!    traced in `f64`) sample for sample, but where a sample lies within
//!    float rounding of a shadow boundary on its own surface, on every
//!    procedural scene and two shared ones;
//! 2. against the supersampled ground truth, the edge pixels' error is at
//!    most half of one sample's, and below the centre-µQuad masks' (the
//!    error they exist to remove), while smooth pixels keep their masks.

mod common;

use izb::bvh::SceneBvh;
use izb::cpu::{render_cpu, IzbSettings, SampleMode};
use izb::gbuffer::flags;
use izb::reference::same_samples::{
    decision_margin, edge_same_sample_masks, pixel_samples_at, FLOAT_DECISION_TOLERANCE,
};
use izb::reference::{reference, ReferenceSettings};
use izb::scene::{self, Scene};

const RESOLUTION: [u32; 2] = [240, 135];

fn edge_settings(mode: SampleMode) -> IzbSettings {
    IzbSettings {
        mode,
        edge_surfaces: true,
        ..Default::default()
    }
}

/// (mismatched samples, compared samples, edge pixels) of exact mode with
/// edge surfaces against the extended same-sample reference, after
/// checking that every mismatch lies within float rounding of a boundary
/// of the surface the sample stands on.
fn check_exact(name: &str, scene: Scene) -> (u64, u64, usize) {
    let scene = scene.with_resolution(RESOLUTION).unwrap();
    let bvh = SceneBvh::build(&scene);
    let pattern = izb::lut::sample_pattern();
    let reference = edge_same_sample_masks(&scene, &bvh, pattern);
    let exact = render_cpu(&scene, &bvh, edge_settings(SampleMode::Exact32));
    let edges = exact
        .gbuffer
        .edges
        .as_ref()
        .expect("edge surfaces asked for");
    assert_eq!(
        edges.counted, reference.counted,
        "{name}: the G-buffer and the reference count different samples"
    );
    let tested = |i: usize| exact.gbuffer.flags[i] & flags::SHADOW_TESTED != 0;
    let (diff, total) = izb::metrics::sample_mismatches(&exact.masks, &reference.masks, tested);
    let frame = scene.camera.frame(scene.resolution);
    let light = scene.light.relative_to(scene.camera.eye);
    let triangles = scene.eye_relative_triangles();
    let mut worst_margin = 0.0f64;
    for i in (0..exact.masks.len()).filter(|&i| tested(i) && exact.masks[i] != reference.masks[i]) {
        let (x, y) = (
            i as u32 % scene.resolution[0],
            i as u32 / scene.resolution[0],
        );
        let (centre, samples) = pixel_samples_at(&bvh, &scene, &frame, x, y, pattern).unwrap();
        let differing = exact.masks[i] ^ reference.masks[i];
        for bit in (0..32).filter(|b| differing & (1 << b) != 0) {
            let surface = samples
                .extra
                .iter()
                .find(|e| e.coverage & (1 << bit) != 0)
                .map_or(centre, |e| e.surface);
            let margin = decision_margin(&triangles, &surface, &light, pattern[bit]);
            worst_margin = worst_margin.max(margin);
            assert!(
                margin < FLOAT_DECISION_TOLERANCE,
                "{name}: pixel ({x}, {y}) sample {bit}: IZB and reference disagree with a \
                 decision margin {margin:.3e} (tolerance {FLOAT_DECISION_TOLERANCE:.3e})"
            );
        }
    }
    println!(
        "{name}: {} edge pixels, {} extra surfaces; exact vs extended same-sample: {diff} of \
         {total} samples differ ({:.2e}), worst margin {worst_margin:.2e}",
        edges.stats.edge_pixels,
        edges.stats.extra_surfaces,
        diff as f64 / total.max(1) as f64
    );
    assert!(total > 0, "{name}: nothing shadow-tested");
    (diff, total, edges.stats.edge_pixels)
}

#[test]
fn exact_edge_masks_match_the_extended_same_sample_reference() {
    let (mut diff, mut total, mut checked) = (0, 0, 0);
    let mut edge_pixels = 0;
    for name in scene::procedural::NAMES {
        let (d, t, e) = check_exact(name, scene::load(name).unwrap());
        diff += d;
        total += t;
        edge_pixels += e;
        checked += 1;
    }
    if let Some(dir) = common::shared_scenes_dir() {
        for name in ["deckchair", "engine"] {
            let path = format!("{}/{name}.scene.json", dir.display());
            let (d, t, e) = check_exact(name, scene::load(&path).unwrap());
            diff += d;
            total += t;
            edge_pixels += e;
            checked += 1;
        }
    }
    let expected =
        scene::procedural::NAMES.len() + 2 * common::shared_scenes_dir().is_some() as usize;
    assert_eq!(checked, expected);
    assert!(
        edge_pixels > 1000,
        "only {edge_pixels} edge pixels over the scenes"
    );
    common::assert_boundary_rate(diff, total);
}

/// MAE of `v` against `truth` over the shadow-tested pixels `keep` selects.
fn mae(v: &[f32], truth: &[f32], keep: impl Fn(usize) -> bool) -> (f64, usize) {
    let (mut sum, mut n) = (0.0, 0);
    for i in (0..v.len()).filter(|&i| !truth[i].is_nan() && !v[i].is_nan() && keep(i)) {
        sum += (v[i] - truth[i]).abs() as f64;
        n += 1;
    }
    (sum / n.max(1) as f64, n)
}

#[test]
fn edge_surfaces_halve_the_edge_pixels_error() {
    let mut checked = 0;
    for name in ["default", "city", "grazing"] {
        let scene = scene::load(name)
            .unwrap()
            .with_resolution(RESOLUTION)
            .unwrap();
        let bvh = SceneBvh::build(&scene);
        let truth = reference(
            &scene,
            &bvh,
            ReferenceSettings::from_spp(64, 1).unwrap(),
            &|_| {},
        );
        let one = render_cpu(&scene, &bvh, edge_settings(SampleMode::One));
        let lut = render_cpu(&scene, &bvh, edge_settings(SampleMode::Lut32));
        let flat = render_cpu(&scene, &bvh, IzbSettings::default());
        let edge = |i: usize| truth.smooth[i] == 0.0;
        let (e1, n) = mae(&one.visibility, &truth.visibility, edge);
        let (e32, _) = mae(&lut.visibility, &truth.visibility, edge);
        let (eflat, _) = mae(&flat.visibility, &truth.visibility, edge);
        println!(
            "{name}: {n} edge pixels, MAE 1 spp {e1:.4}, 32 LUT centre µQuad {eflat:.4}, \
             32 LUT edge surfaces {e32:.4} ({:.2} of 1 spp)",
            e32 / e1
        );
        assert!(n > 500, "{name}: only {n} edge pixels");
        assert!(
            e32 <= 0.5 * e1,
            "{name}: edge MAE {e32:.4} above half of 1 spp's {e1:.4}"
        );
        assert!(
            e32 < eflat,
            "{name}: edge surfaces ({e32:.4}) no better than the centre µQuad ({eflat:.4})"
        );
        // A pixel whose samples all stand on its centre's surface keeps
        // the centre-µQuad mask bit for bit.
        let edges = lut.gbuffer.edges.as_ref().unwrap();
        let smooth = (0..lut.masks.len())
            .filter(|&i| edges.centre_coverage[i] == u32::MAX && edges.counted[i] == u32::MAX)
            .filter(|&i| lut.gbuffer.flags[i] & flags::SHADOW_TESTED != 0);
        let (mut same, mut count) = (0, 0);
        for i in smooth {
            same += (lut.masks[i] == flat.masks[i]) as usize;
            count += 1;
        }
        assert!(count > 2_000, "{name}: {count} smooth pixels");
        assert_eq!(same, count, "{name}: smooth pixels' masks changed");
        checked += 1;
    }
    assert_eq!(checked, 3);
}

/// Under an area light `izb render`'s default, paired rays with edge
/// surfaces, beats the paired rays on the centre µQuad overall and halves
/// one sample's error at edge pixels.
#[test]
fn paired_rays_with_edge_surfaces_under_an_area_light() {
    let mut checked = 0;
    for (name, size) in [("city", 1.0), ("default", 0.25)] {
        let scene = scene::load(name)
            .unwrap()
            .with_resolution(RESOLUTION)
            .unwrap()
            .with_light_size(size)
            .unwrap();
        let bvh = SceneBvh::build(&scene);
        let truth = reference(
            &scene,
            &bvh,
            ReferenceSettings::from_spp(64, 1).unwrap(),
            &|_| {},
        );
        let one = render_cpu(&scene, &bvh, edge_settings(SampleMode::One));
        let all = |_: usize| true;
        let edge = |i: usize| truth.smooth[i] == 0.0;
        let (e1, _) = mae(&one.visibility, &truth.visibility, edge);
        // Paired64's second half has its own µQuad pattern and surfaces.
        for mode in [SampleMode::Paired32, SampleMode::Paired64] {
            let paired = render_cpu(&scene, &bvh, edge_settings(mode));
            assert!(paired.gbuffer.edges.is_some(), "{name}: no edge surfaces");
            assert_eq!(
                paired.gbuffer.edges_high.is_some(),
                mode == SampleMode::Paired64,
                "{name} {mode:?}: the second half's surfaces"
            );
            let flat = render_cpu(
                &scene,
                &bvh,
                IzbSettings {
                    mode,
                    ..Default::default()
                },
            );
            let (m, _) = mae(&paired.visibility, &truth.visibility, all);
            let (mflat, _) = mae(&flat.visibility, &truth.visibility, all);
            let (e, n) = mae(&paired.visibility, &truth.visibility, edge);
            println!(
                "{name}~{size} {mode:?}: MAE {mflat:.5} -> with edge surfaces {m:.5}; {n} edge \
                 pixels {e:.4} against 1 spp {e1:.4}"
            );
            assert!(m < mflat, "{name} {mode:?}: {m:.5} not below {mflat:.5}");
            assert!(
                e <= 0.5 * e1,
                "{name} {mode:?}: edge MAE {e:.4} above half of 1 spp's {e1:.4}"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 4);
}
