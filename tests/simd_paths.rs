//! The CPU twin's batched tests (`izb::cpu::survivor_batch`) and its walk
//! over the bin's vertex cache (`izb::cpu::cell_vertices`) give the same
//! masks and counters on every instruction-set path — scalar, AVX2,
//! AVX-512 — as the scalar walk that reads each candidate by id, on every
//! procedural and shared scene, in every mode (1 spp,
//! 32 LUT and 32 exact under the scene's light, the soft LUT masks,
//! `Paired32` and `Paired64` under a 1° area light; edge surfaces on). A
//! path this processor lacks is printed as skipped. And `IZB_SIMD=scalar`
//! (a machine without AVX2) makes `izb render` write the same image. No
//! shared scenes: they are skipped, unless `IZB_REQUIRE_SCENES=1`.

mod common;

use izb::bvh::SceneBvh;
use izb::cpu::light_setup::{
    light_setup, microquad_corners, BandBoxes, GridRequest, ReceiverBoxes,
};
use izb::cpu::simd::SimdPath;
use izb::cpu::{is_receiver, receiver_flags, render_cpu, IzbSettings, SampleMode, Skips};
use izb::gbuffer::{flags, gbuffer_with};
use izb::scene::{self, Scene};
use izb::settings::VertexCache;

const RESOLUTION: [u32; 2] = [64, 36];

const MODES: [(SampleMode, bool); 6] = [
    (SampleMode::One, false),
    (SampleMode::Lut32, false),
    (SampleMode::Exact32, false),
    (SampleMode::Lut32, true),
    (SampleMode::Paired32, true),
    (SampleMode::Paired64, true),
];

fn scenes() -> Vec<(String, Scene)> {
    let mut out: Vec<(String, Scene)> = scene::procedural::NAMES
        .iter()
        .map(|n| (n.to_string(), scene::load(n).unwrap()))
        .collect();
    if common::shared_scenes_dir().is_some() {
        for n in common::SHARED_SCENES {
            out.push((n.to_string(), common::shared_scene(n).unwrap()));
        }
    } else {
        assert!(
            std::env::var("IZB_REQUIRE_SCENES").as_deref() != Ok("1"),
            "IZB_REQUIRE_SCENES=1 but ../shared/scenes is missing"
        );
        println!("skipped the shared scenes (no ../shared/scenes)");
    }
    out
}

/// The paths this processor runs, narrowest first; the others printed as
/// skipped.
fn supported_paths() -> Vec<SimdPath> {
    SimdPath::ALL
        .into_iter()
        .filter(|p| {
            let ok = p.supported();
            if !ok {
                println!("skipped the {p:?} path: this processor lacks it");
            }
            ok
        })
        .collect()
}

#[test]
fn every_simd_path_gives_the_scalar_masks_and_counters() {
    let paths = supported_paths();
    let scenes = scenes();
    let mut compared = 0;
    for (name, scene) in &scenes {
        let scene = scene.clone().with_resolution(RESOLUTION).unwrap();
        let area = scene.clone().with_light_size(1.0).unwrap();
        let bvh = SceneBvh::build(&scene);
        for (mode, area_light) in MODES {
            let scene = if area_light { &area } else { &scene };
            let render = |simd, vertex_cache: bool| {
                let vertex_cache = match vertex_cache {
                    true => VertexCache::Always,
                    false => VertexCache::Never,
                };
                let settings = IzbSettings {
                    mode,
                    edge_surfaces: true,
                    simd,
                    vertex_cache,
                    ..Default::default()
                };
                let r = render_cpu(scene, &bvh, settings);
                let counters = serde_json::to_value(&r.report.evaluate).unwrap();
                (r.masks, r.masks_high, counters)
            };
            // The scalar path reading each candidate by id.
            let scalar = render(SimdPath::Scalar, false);
            for &path in &paths {
                let other = render(path, true);
                let what = format!("{name} {mode:?} area light {area_light}: {path:?}");
                assert!(scalar.0 == other.0, "{what}: masks differ from scalar");
                assert!(scalar.1 == other.1, "{what}: second halves differ");
                assert_eq!(scalar.2, other.2, "{what}: counters differ");
                compared += 1;
            }
        }
    }
    assert_eq!(compared, scenes.len() * MODES.len() * paths.len());
    println!(
        "{compared} (scene, mode, path) renders from the vertex cache equal to the scalar \
         path's by id ({} paths)",
        paths.len()
    );
}

#[test]
fn izb_simd_scalar_renders_the_same_image() {
    let dir = std::env::temp_dir().join(format!("izb_simd_paths_{}", std::process::id()));
    let render = |simd: Option<&str>, out: &str| {
        let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_izb"));
        cmd.args([
            "render",
            "default",
            "--backend",
            "cpu",
            "--resolution",
            "96x54",
        ])
        .arg("--out")
        .arg(dir.join(out));
        match simd {
            Some(p) => cmd.env("IZB_SIMD", p),
            None => cmd.env_remove("IZB_SIMD"),
        };
        let status = cmd.output().unwrap();
        assert!(status.status.success(), "{status:?}");
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join(out).join("report.json")).unwrap())
                .unwrap();
        let image = std::fs::read(dir.join(out).join("visibility.exr")).unwrap();
        (report["render"]["settings"]["simd"].clone(), image)
    };
    let (scalar_path, scalar) = render(Some("scalar"), "scalar");
    let (widest_path, widest) = render(None, "widest");
    assert_eq!(scalar_path, "scalar");
    let widest_expected = SimdPath::Avx512.or_supported();
    assert_eq!(widest_path, serde_json::to_value(widest_expected).unwrap());
    assert!(scalar == widest, "IZB_SIMD=scalar changed visibility.exr");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The light setup's per-receiver loops and the µQuad boxes, sixteen
/// G-buffer entries at a time (`light_setup::receiver_lanes`), give the
/// same floats on every path: the same light setup, and the same boxes,
/// bit for bit. On the scalar path the boxes of whole µQuads are those
/// of `LightSetup::microquad_ndc_box`, one receiver at a time, and the
/// receivers' light-view depth range that of all their corners. The
/// boxes evaluate projects band by band where the bin's cull stored none
/// equal the stored ones.
#[test]
fn every_simd_path_gives_the_one_receiver_light_setup_and_boxes() {
    let paths = supported_paths();
    let scenes = scenes();
    let bits = |(lo, hi): (glam::Vec2, glam::Vec2)| [lo.x, lo.y, hi.x, hi.y].map(f32::to_bits);
    let (mut compared, mut whole_boxes, mut band_boxes) = (0, 0u64, 0u64);
    for (name, scene) in &scenes {
        // Rows and layers whose lengths are not multiples of sixteen: the
        // chunks' tails run one entry at a time.
        let scene = scene.clone().with_resolution([101, 37]).unwrap();
        let bvh = SceneBvh::build(&scene);
        let settings = IzbSettings {
            edge_surfaces: true,
            ..Default::default()
        };
        let g = gbuffer_with(&scene, &bvh, settings.edge_halves(&scene));
        let for_path = |simd| {
            let request = GridRequest {
                simd,
                ..GridRequest::from(&settings)
            };
            let setup = light_setup(&scene, &g, request);
            let boxes = setup.receiver_boxes(&g, Skips::ALL, true);
            (setup, boxes)
        };
        let (setup, boxes) = for_path(SimdPath::Scalar);
        let (mut z_lo, mut z_hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for layer in g.layers() {
            for i in 0..layer.flags.len() {
                if layer.flags[i] & flags::SHADOW_TESTED == 0 {
                    continue;
                }
                let (p, ex, ey) = (layer.position[i], layer.axis_x[i], layer.axis_y[i]);
                for corner in microquad_corners(p, ex, ey) {
                    let z = setup.to_light_view(corner).z;
                    (z_lo, z_hi) = (z_lo.min(z), z_hi.max(z));
                }
            }
        }
        assert_eq!(
            setup.receiver_z.map(f32::to_bits),
            [z_lo, z_hi].map(f32::to_bits),
            "{name}: the receivers' light-view depth range"
        );
        let coverage = g.edges.as_ref().map(|e| &e.centre_coverage);
        for i in 0..g.flags.len() {
            let whole = coverage.is_none_or(|c| c[i] == u32::MAX || c[i] == 0);
            if whole && is_receiver(g.flags[i], Skips::ALL) {
                let one = setup.microquad_ndc_box(g.position[i], g.axis_x[i], g.axis_y[i]);
                assert_eq!(bits(boxes.ndc[i]), bits(one), "{name}: pixel {i}'s box");
                whole_boxes += 1;
            }
        }
        // Evaluate's boxes where no cull stored them, projected band by
        // band (bands of four 101-entry rows: not whole chunks), equal
        // the stored ones on every path.
        let mut per_band = |setup: &izb::cpu::light_setup::LightSetup,
                            boxes: &izb::cpu::light_setup::MicroquadBoxes,
                            path: SimdPath| {
            let coverages = [
                g.edges.as_ref().map(|e| &e.centre_coverage[..]),
                g.edges.as_ref().map(|e| &e.coverage[..]),
                None,
            ];
            let per_band = ReceiverBoxes::PerBand { covered_only: true };
            let mut band = BandBoxes::default();
            for ((layer, stored), coverage) in g.layers().zip(boxes.layers()).zip(coverages) {
                let n = layer.flags.len();
                for start in (0..n).step_by(404) {
                    let entries = start..(start + 404).min(n);
                    let receivers = receiver_flags(Skips::ALL);
                    per_band.project_band(
                        setup,
                        layer,
                        entries.clone(),
                        coverage,
                        receivers,
                        &mut band,
                    );
                    for i in entries.filter(|&i| is_receiver(layer.flags[i], Skips::ALL)) {
                        let (a, b) = (per_band.ndc_box(i, &band), stored.ndc[i]);
                        assert_eq!(bits(a), bits(b), "{name} {path:?}: band box of entry {i}");
                        band_boxes += 1;
                    }
                }
            }
        };
        per_band(&setup, &boxes, SimdPath::Scalar);
        for &path in &paths[1..] {
            let (other_setup, other_boxes) = for_path(path);
            per_band(&other_setup, &other_boxes, path);
            assert_eq!(
                serde_json::to_value(&setup).unwrap(),
                serde_json::to_value(&other_setup).unwrap(),
                "{name} {path:?}: the light setup differs from the scalar path's"
            );
            for (layer, (a, b)) in boxes.layers().zip(other_boxes.layers()).enumerate() {
                assert_eq!(a.ndc.len(), b.ndc.len());
                for (i, (&a, &b)) in a.ndc.iter().zip(&b.ndc).enumerate() {
                    assert_eq!(bits(a), bits(b), "{name} {path:?}: layer {layer} entry {i}");
                }
            }
            compared += 1;
        }
    }
    assert_eq!(compared, scenes.len() * (paths.len() - 1));
    assert!(whole_boxes > 0);
    assert!(band_boxes >= whole_boxes * paths.len() as u64);
    println!(
        "{compared} (scene, path) light setups and boxes equal to the scalar path's; \
         {whole_boxes} boxes equal to one receiver's; {band_boxes} band boxes equal to the stored"
    );
}
