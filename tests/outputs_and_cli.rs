//! Output files and the command line end to end: EXR channels round-trip
//! (NaN included), writes are atomic, the reference is deterministic for a
//! seed whatever the thread count, and bad arguments give clear errors.

mod common;

use common::TempDir;

use izb::bvh::SceneBvh;
use izb::output::{read_exr_channel, write_atomically, write_exr};
use izb::reference::{reference, ReferenceSettings};

#[test]
fn exr_channels_round_trip_bit_for_bit() {
    let dir = TempDir::new("exr");
    let path = dir.join("v.exr");
    let visibility = [0.0, 0.25, f32::NAN, 1.0, 0.5, 1.0 / 3.0];
    let smooth = [1.0, 0.0, f32::NAN, 1.0, 1.0, 0.0];
    write_exr(
        &path,
        3,
        2,
        &[("visibility", &visibility), ("smooth", &smooth)],
    )
    .unwrap();
    for (name, expected) in [("visibility", &visibility), ("smooth", &smooth)] {
        let (w, h, got) = read_exr_channel(&path, name).unwrap();
        assert_eq!((w, h), (3, 2));
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&got), bits(expected), "channel {name}");
    }
    let missing = read_exr_channel(&path, "mask").unwrap_err();
    assert!(
        format!("{missing:#}").contains("no channel 'mask'"),
        "{missing:#}"
    );
}

#[test]
fn a_failed_write_leaves_neither_file_nor_temporary() {
    let dir = TempDir::new("atomic");
    let path = dir.join("report.json");
    std::fs::write(&path, "old").unwrap();
    let err = write_atomically(&path, |tmp| {
        std::fs::write(tmp, "half")?;
        anyhow::bail!("simulated crash while writing")
    })
    .unwrap_err();
    assert!(format!("{err:#}").contains("simulated crash"), "{err:#}");
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        "old",
        "the old file must survive"
    );
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers.len(), 1, "temporary left behind: {leftovers:?}");
}

#[test]
fn reference_is_deterministic_across_thread_counts() {
    let scene = izb::scene::load("default")
        .unwrap()
        .with_resolution([160, 90])
        .unwrap();
    let bvh = SceneBvh::build(&scene);
    let settings = ReferenceSettings {
        samples_per_side: 4,
        seed: 99,
    };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| reference(&scene, &bvh, settings, &|_| {}))
    };
    let (one, two) = (run(1), run(2));
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&one.visibility), bits(&two.visibility));
    assert_eq!(bits(&one.smooth), bits(&two.smooth));
    // And the seed matters: another seed moves some penumbra pixels.
    let other = reference(
        &scene,
        &bvh,
        ReferenceSettings {
            seed: 100,
            ..settings
        },
        &|_| {},
    );
    assert_ne!(bits(&one.visibility), bits(&other.visibility));
}

use common::izb_cli as izb;

#[test]
fn cli_reference_writes_every_output() {
    let dir = TempDir::new("cli");
    let out = dir.to_str().unwrap();
    let run = izb(&[
        "reference",
        "default",
        "--spp",
        "4",
        "--resolution",
        "96x54",
        "--threads",
        "2",
        "--out",
        out,
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    for f in [
        "visibility.exr",
        "visibility.png",
        "shaded.png",
        "report.json",
    ] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["spp"], 4);
    assert_eq!(report["scene"]["resolution"], serde_json::json!([96, 54]));
    assert_eq!(report["threads"], 2);
    assert!(report["rays_per_second"].as_f64().unwrap() > 0.0);
    let (w, h, v) = read_exr_channel(&dir.join("visibility.exr"), "visibility").unwrap();
    assert_eq!((w, h, v.len()), (96, 54, 96 * 54));
    assert!(v.iter().any(|x| x.is_nan()) && v.contains(&1.0) && v.contains(&0.0));
    let png = image::open(dir.join("visibility.png")).unwrap().to_rgb8();
    let sky = png.get_pixel(0, 0).0;
    assert_eq!(
        sky,
        izb::output::UNTESTED_RGB,
        "untested pixels must be drawn distinctly"
    );
}

#[test]
fn cli_rejects_bad_arguments_with_a_clear_message() {
    let cases: &[(&[&str], &str)] = &[
        (
            &["reference", "--resolution", "0x5"],
            "resolution 0x5 is out of range",
        ),
        (&["reference", "--resolution", "20000x10"], "out of range"),
        (&["reference", "--spp", "10"], "perfect square"),
        (
            &["reference", "no-such-scene"],
            "unknown scene 'no-such-scene'",
        ),
        (
            &["reference", "missing/file.scene.json"],
            "missing/file.scene.json: cannot read",
        ),
        (
            &["reference", "--threads", "0"],
            "--threads must be at least 1",
        ),
    ];
    for (args, expected) in cases {
        common::assert_cli_refuses(args, expected);
    }
}

#[test]
fn cli_render_writes_masks_consistent_with_visibility() {
    // `--backend vulkan` with edge surfaces (the CPU's G-buffer uploaded)
    // where a device is required; `auto` would take the CPU for them.
    let vulkan = std::env::var("IZB_REQUIRE_GPU").is_ok_and(|v| v == "1");
    if !vulkan {
        eprintln!("the --backend vulkan case skipped (IZB_REQUIRE_GPU is not 1)");
    }
    let cases = [
        ("32", false, false),
        ("32", true, false),
        ("1", false, false),
    ]
    .into_iter()
    .chain(vulkan.then_some(("32", false, true)));
    for (spp, exact, on_vulkan) in cases {
        let dir = TempDir::new(&format!("render-{spp}-{exact}-{on_vulkan}"));
        let out = dir.to_str().unwrap();
        let mut args = vec![
            "render",
            "default",
            "--spp",
            spp,
            "--resolution",
            "96x54",
            "--out",
            out,
        ];
        if exact {
            // One run pins the CPU twin; the others take `auto`.
            args.extend(["--exact", "--backend", "cpu"]);
        }
        if on_vulkan {
            args.extend(["--backend", "vulkan"]);
        }
        let run = izb(&args);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        for f in [
            "visibility.exr",
            "visibility.png",
            "shaded.png",
            "report.json",
        ] {
            assert!(dir.join(f).is_file(), "{f} missing");
        }
        let (_, _, v) = read_exr_channel(&dir.join("visibility.exr"), "visibility").unwrap();
        let (_, _, masks) =
            izb::output::read_exr_mask(&dir.join("visibility.exr"), "mask").unwrap();
        // With edge surfaces (32 samples by default) the samples that count
        // are in `coverage`; without, all 32 do.
        let coverage = izb::output::read_exr_mask(&dir.join("visibility.exr"), "coverage")
            .map(|(_, _, c)| c)
            .unwrap_or_else(|_| vec![u32::MAX; masks.len()]);
        assert_eq!(spp == "32", coverage.iter().any(|&c| c != u32::MAX));
        for ((m, v), c) in masks.iter().zip(&v).zip(&coverage) {
            if v.is_nan() {
                assert_eq!(*m, 0);
            } else {
                assert_eq!(*m & !c, 0, "shadowed samples that do not count");
                assert_eq!(*v, 1.0 - m.count_ones() as f32 / c.count_ones() as f32);
                if spp == "1" {
                    assert!(*m == 0 || *m == u32::MAX, "1 spp masks are all or nothing");
                }
            }
        }
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
        let r = &report["render"];
        let passes = [
            "gbuffer",
            "light_setup",
            "bin",
            "evaluate",
            "resolve",
            "total",
        ];
        // `auto` renders on Vulkan where a device opens, else on the CPU;
        // the report says which and carries that backend's timings.
        assert!(!on_vulkan || report["backend"] == "vulkan");
        match report["backend"].as_str().unwrap() {
            "cpu" => {
                for pass in passes {
                    assert!(
                        r["seconds"][pass].as_f64().unwrap() >= 0.0,
                        "seconds.{pass}"
                    );
                }
                for counter in ["binned", "overflow", "culled", "cell_entries"] {
                    assert!(r["bin"][counter].is_u64(), "bin.{counter}");
                }
                assert!(r["evaluate"]["tests_spawned"].as_u64().unwrap() > 0);
                assert!(r["evaluate"]["early_outs"].is_u64());
            }
            "vulkan" => {
                assert!(r["device"].is_string());
                // Edge surfaces at 32 spp: the CPU's G-buffer went up.
                let gbuffer = if spp == "32" {
                    "cpu (uploaded)"
                } else {
                    "vulkan"
                };
                assert_eq!(report["gbuffer"], gbuffer);
                if !r["gpu_milliseconds"].is_null() {
                    for pass in passes {
                        assert!(
                            r["gpu_milliseconds"][pass].as_f64().unwrap() >= 0.0,
                            "gpu_milliseconds.{pass}"
                        );
                    }
                }
                for counter in ["triangles_binned", "overflow", "culled", "cell_entries"] {
                    assert!(r["counters"][counter].is_u64(), "counters.{counter}");
                }
                assert!(r["counters"]["tests_spawned"].as_u64().unwrap() > 0);
                assert!(r["memory_total_bytes"].as_u64().unwrap() > 0);
                assert_eq!(report["validation_messages"].as_array().unwrap().len(), 0);
            }
            other => panic!("unknown backend {other}"),
        }
    }
}

#[test]
fn cli_lut_and_compare_write_their_files() {
    let dir = TempDir::new("lut");
    let run = izb(&[
        "lut",
        "--angles",
        "16",
        "--distances",
        "8",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let table = std::fs::read(dir.join("edge_lut.bin")).unwrap();
    let lut = izb_lut::EdgeLut::from_bytes(&table).unwrap();
    assert_eq!((lut.angles, lut.distances), (16, 8));
    assert!(dir.join("edge_lut.png").is_file());

    let dir = TempDir::new("compare");
    let run = izb(&[
        "compare",
        "analytic",
        "--resolution",
        "96x54",
        "--reference-spp",
        "16",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("compare.json")).unwrap()).unwrap();
    let methods: Vec<&str> = report["methods"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["method"].as_str().unwrap())
        .collect();
    assert_eq!(methods, ["izb32", "izb32-exact", "izb1"]);
    for m in ["izb32", "izb32-exact", "izb1"] {
        assert!(dir.join(format!("error_{m}.png")).is_file());
    }
    let exact = &report["methods"][1]["metrics"];
    assert_eq!(
        exact["sample_mismatch_rate"], 0.0,
        "exact mode vs same-sample reference on the analytic scene"
    );
}
