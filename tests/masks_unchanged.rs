//! The CPU twin's masks stay what they were when issue 30 (the CPU twin's
//! speed) began: every procedural and shared scene at 128×72, in every
//! mode — 1 spp, 32 LUT and 32 exact under the scene's own light (the
//! 32-sample modes with edge surfaces, as `izb render` has them), and
//! under a 1° area light the soft LUT masks, `Paired32` and `Paired64`
//! (with edge surfaces) — each hashed (FNV-1a over the masks, both halves)
//! and compared with `tests/data/mask_hashes.json`, written once by the
//! code before that work (the file was written at the commit that added
//! this test, whose `izb render` wrote byte-identical `visibility.exr` to
//! commit 65a0377's in all 72 cases). A change that only reorganises the work
//! (batches, SIMD paths, caches) must leave every hash as it is; a change
//! that means to move masks rewrites the file on purpose
//! (`IZB_WRITE_MASK_HASHES=1`) and says why in its commit.
//!
//! The LUT's angle goes through the platform's `atan2f`; the file holds
//! this toolchain's (Debian 12's glibc), the one CI runs. No shared
//! scenes: they are skipped, unless `IZB_REQUIRE_SCENES=1`.

mod common;

use izb::bvh::SceneBvh;
use izb::cpu::{render_cpu, IzbSettings, SampleMode};
use izb::scene::{self, Scene};
use std::collections::BTreeMap;

const RESOLUTION: [u32; 2] = [128, 72];
const HASHES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/mask_hashes.json");

/// FNV-1a, 64 bits, over the words' little-endian bytes.
fn fnv1a(words: impl Iterator<Item = u32>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for w in words {
        for b in w.to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

/// (case name, scene, settings) for every mode of `scene`.
fn cases(name: &str, scene: &Scene) -> Vec<(String, Scene, IzbSettings)> {
    let area = scene.clone().with_light_size(1.0).unwrap();
    let modes = [
        ("one", SampleMode::One, false),
        ("lut32", SampleMode::Lut32, false),
        ("exact32", SampleMode::Exact32, false),
        ("soft-lut32", SampleMode::Lut32, true),
        ("paired32", SampleMode::Paired32, true),
        ("paired64", SampleMode::Paired64, true),
    ];
    modes
        .into_iter()
        .map(|(label, mode, area_light)| {
            let settings = IzbSettings {
                mode,
                edge_surfaces: true,
                ..Default::default()
            };
            let scene = if area_light { &area } else { scene };
            (format!("{name}/{label}"), scene.clone(), settings)
        })
        .collect()
}

#[test]
fn masks_equal_those_before_issue_30() {
    let mut scenes: Vec<(String, Scene)> = scene::procedural::NAMES
        .iter()
        .map(|n| (n.to_string(), scene::load(n).unwrap()))
        .collect();
    let with_shared = common::shared_scenes_dir().is_some();
    if with_shared {
        for n in common::SHARED_SCENES {
            scenes.push((n.to_string(), common::shared_scene(n).unwrap()));
        }
    } else {
        assert!(
            std::env::var("IZB_REQUIRE_SCENES").as_deref() != Ok("1"),
            "IZB_REQUIRE_SCENES=1 but ../shared/scenes is missing"
        );
        println!("skipped the shared scenes (no ../shared/scenes)");
    }
    let mut hashes = BTreeMap::new();
    for (name, scene) in &scenes {
        let scene = scene.clone().with_resolution(RESOLUTION).unwrap();
        let bvh = SceneBvh::build(&scene);
        for (case, scene, settings) in cases(name, &scene) {
            let r = render_cpu(&scene, &bvh, settings);
            let hash = fnv1a(r.masks.iter().chain(&r.masks_high).copied());
            hashes.insert(case, format!("{hash:016x}"));
        }
    }
    if std::env::var("IZB_WRITE_MASK_HASHES").as_deref() == Ok("1") {
        let json = serde_json::to_string_pretty(&hashes).unwrap();
        std::fs::write(HASHES, json + "\n").unwrap();
        println!("wrote {} hashes to {HASHES}", hashes.len());
        return;
    }
    let recorded: BTreeMap<String, String> =
        serde_json::from_str(&std::fs::read_to_string(HASHES).unwrap()).unwrap();
    let mut checked = 0;
    let mut differing = Vec::new();
    for (case, hash) in &hashes {
        let want = recorded
            .get(case)
            .unwrap_or_else(|| panic!("{case}: no recorded hash in {HASHES}"));
        if want != hash {
            differing.push(format!("{case}: {hash}, recorded {want}"));
        }
        checked += 1;
    }
    let expected = 6 * (scene::procedural::NAMES.len() + 5 * usize::from(with_shared));
    assert_eq!(checked, expected, "cases checked");
    assert!(
        differing.is_empty(),
        "masks moved:\n{}",
        differing.join("\n")
    );
    println!("{checked} cases' masks as recorded");
}
