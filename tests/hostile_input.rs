//! Inputs a hostile or careless user gives (issue 28's table): each ends
//! in a named error or the right answer, never a panic, a hang, or a
//! file read that the scene had no business reading.

mod common;

use common::*;
use izb::scene::load_gltf;
use std::process::{Command, Stdio};

/// A glTF whose buffer URI names a file outside its folder, or by an
/// absolute path or a scheme, is refused before anything is read; the
/// same buffer by a plain relative path (into a subfolder, percent-encoded
/// or not) still loads.
#[test]
fn gltf_buffer_uris_stay_in_the_gltf_folder() {
    let dir = TempDir::new("hostile-uris");
    let gltf = Gltf::single_mesh(&[[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]]);
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    std::fs::write(dir.join("sub/data.bin"), &gltf.bin).unwrap();
    // The same bytes one folder up, where only a `..` could reach them.
    let outside = TempDir::new("hostile-uris-outside");
    std::fs::write(outside.join("data.bin"), &gltf.bin).unwrap();
    let up = format!(
        "../{}/data.bin",
        outside.path().file_name().unwrap().to_str().unwrap()
    );
    let refused: [(&str, &str); 7] = [
        ("/etc/passwd", "absolute path"),
        ("\\etc\\passwd", "absolute path"),
        ("file:///etc/passwd", "scheme"),
        ("C:/Windows/win.ini", "drive letter"),
        (&up, "'..' segment"),
        ("sub/../../x.bin", "'..' segment"),
        ("%2e%2e/%2E%2E/etc/hostname", "'..' segment"),
    ];
    let mut checked = 0;
    for (k, (uri, why)) in refused.iter().enumerate() {
        let path = dir.join(format!("hostile{k}.gltf"));
        write_json(&path, &gltf.to_json(Some(uri)));
        let err = load_gltf(&path)
            .err()
            .unwrap_or_else(|| panic!("{uri}: loaded"));
        let message = err.to_string();
        assert!(message.contains(why), "{uri}: {message}");
        assert!(message.contains("buffer 0"), "{uri}: {message}");
        checked += 1;
    }
    assert_eq!(checked, refused.len());
    for uri in ["sub/data.bin", "sub/%64ata.bin", "./sub/data.bin"] {
        let path = dir.join("fine.gltf");
        write_json(&path, &gltf.to_json(Some(uri)));
        let meshes = load_gltf(&path).unwrap_or_else(|e| panic!("{uri}: {e}"));
        assert!(!meshes.triangles.is_empty(), "{uri}");
    }
}

/// Runs `izb` with its stdout the write end of a pipe whose read end is
/// already closed.
fn izb_into_a_closed_pipe(args: &[&str]) -> std::process::Output {
    let (reader, writer) = std::io::pipe().expect("a pipe");
    drop(reader);
    Command::new(env!("CARGO_BIN_EXE_izb"))
        .args(args)
        .stdout(Stdio::from(writer))
        .stderr(Stdio::piped())
        .output()
        .unwrap_or_else(|e| panic!("izb {args:?} did not start: {e}"))
}

/// A closed stdout (`izb … | true`, `| head`) ends a command quietly with
/// status 141, never with a panic; what it wrote to files is whole.
#[test]
fn a_closed_stdout_ends_a_command_quietly() {
    let dir = TempDir::new("closed-stdout");
    let (out, lut) = (dir.join("render"), dir.join("lut"));
    let (out, lut) = (out.to_str().unwrap(), lut.to_str().unwrap());
    let cases: [&[&str]; 3] = [
        &["info", "default"],
        &[
            "render",
            "default",
            "--resolution",
            "64x36",
            "--backend",
            "cpu",
            "--out",
            out,
        ],
        &["lut", "--out", lut],
    ];
    for args in cases {
        let run = izb_into_a_closed_pipe(args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
        assert_eq!(run.status.code(), Some(141), "{args:?}: {stderr}");
    }
    // The render's files were written before its summary line failed.
    assert!(dir.join("render/visibility.exr").exists());
}

/// A closed stderr loses the notes and nothing else: the command runs to
/// its end (a panic's message would be lost with it, so the status is the
/// witness: 101 for a panic, 0 here).
#[test]
fn a_closed_stderr_loses_only_the_notes() {
    let dir = TempDir::new("closed-stderr");
    let out = dir.join("render");
    let out = out.to_str().unwrap();
    let mut checked = 0;
    for args in [
        &[
            "render",
            "default",
            "--resolution",
            "64x36",
            "--backend",
            "cpu",
            "--out",
            out,
        ][..],
        &["render", "missing.scene.json"][..],
    ] {
        let (reader, writer) = std::io::pipe().expect("a pipe");
        drop(reader);
        let run = Command::new(env!("CARGO_BIN_EXE_izb"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::from(writer))
            .output()
            .unwrap_or_else(|e| panic!("izb {args:?} did not start: {e}"));
        let expected = if args.len() > 2 { 0 } else { 1 };
        assert_eq!(run.status.code(), Some(expected), "{args:?}");
        checked += 1;
    }
    assert_eq!(checked, 2);
    assert!(dir.join("render/visibility.exr").exists());
}

/// Numeric flags that would measure nothing or run away are refused by
/// name before any work.
#[test]
fn numeric_flags_out_of_range_are_refused() {
    let cases: [(&[&str], &str); 7] = [
        (
            &["bench", "default", "--flicker", "--flicker-frames", "0"],
            "--flicker-frames 0",
        ),
        (
            &["bench", "default", "--flicker", "--flicker-frames", "1"],
            "at least 2",
        ),
        (
            &["bench", "default", "--flicker", "--flicker-step", "NaN"],
            "--flicker-step NaN",
        ),
        (
            &["bench", "default", "--flicker", "--flicker-step=-1"],
            "positive number of degrees",
        ),
        (
            &["render", "default", "--threads", "100000"],
            "--threads 100000: at most",
        ),
        (
            &["reference", "default", "--spp", "1048576"],
            "--spp 1048576: at most 65536",
        ),
        (&["reference", "default", "--spp", "0"], "perfect square"),
    ];
    for (args, expected) in cases {
        assert_cli_refuses(args, expected);
    }
}

/// A run over several scenes that fails on one writes nothing (its images
/// are staged and renamed into place only when it finishes), and a report
/// whose bench folder lost an image stops before writing a chart.
#[test]
fn multi_output_runs_are_written_whole_or_not_at_all() {
    let dir = TempDir::new("all-or-nothing");
    let json = dir.join("bench.json");
    let json = json.to_str().unwrap();
    let bench = |scenes: &[&str]| {
        let mut args = vec!["bench"];
        args.extend_from_slice(scenes);
        args.extend_from_slice(&[
            "--methods",
            "izb1,izb32",
            "--resolution",
            "48x27",
            "--spp",
            "4",
            "--backend",
            "cpu",
            "--out",
            json,
        ]);
        izb_cli(&args)
    };
    let failed = bench(&["default", "missing.scene.json"]);
    let stderr = String::from_utf8_lossy(&failed.stderr);
    assert!(!failed.status.success());
    assert!(stderr.contains("missing.scene.json"), "{stderr}");
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "a failed bench left {left:?}");

    let done = bench(&["default"]);
    assert!(
        done.status.success(),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    assert!(dir.join("bench.images").is_dir());
    let truth = dir.join("bench.images/default/truth.exr");
    std::fs::remove_file(&truth).unwrap();
    let report_dir = dir.join("report");
    let report = izb_cli(&["report", json, "--out", report_dir.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&report.stderr);
    assert!(!report.status.success());
    assert!(
        stderr.contains("truth.exr") && stderr.contains("missing"),
        "{stderr}"
    );
    assert!(!report_dir.exists(), "the report wrote before failing");
}

/// The smaller messages of issue 28's list say what is wrong in the
/// user's terms.
#[test]
fn messages_name_the_problem_once() {
    let dir = TempDir::new("messages");
    Gltf::single_mesh(&[[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
        .write_glb(dir.path(), "tri");
    // A spec saved with a byte-order mark loads.
    let text = serde_json::to_string(&spec_json("tri.glb")).unwrap();
    let bom = dir.join("bom.scene.json");
    std::fs::write(&bom, format!("\u{feff}{text}")).unwrap();
    load_path(&bom).unwrap_or_else(|e| panic!("a spec with a BOM: {e}"));
    // A zero up vector is named as such.
    let mut spec = spec_json("tri.glb");
    spec["camera"]["up"] = serde_json::json!([0.0, 0.0, 0.0]);
    let zero_up = write_spec(dir.path(), "zero-up", &spec);
    let message = error_message(load_path(&zero_up), "zero up");
    assert!(
        message.contains("`camera.up` is the zero vector"),
        "{message}"
    );
    // A vector of the wrong length says how many numbers it wants.
    let mut checked = 0;
    for (field, value, expected) in [
        (
            "eye",
            serde_json::json!([0.0, 1.0, 10.0, 5.0]),
            "`camera.eye`: expected an array of 3 numbers, got 4",
        ),
        (
            "target",
            serde_json::json!([0.0, 1.0]),
            "`camera.target`: expected an array of 3 numbers, got 2",
        ),
    ] {
        let mut spec = spec_json("tri.glb");
        spec["camera"][field] = value;
        let path = write_spec(dir.path(), field, &spec);
        let message = error_message(load_path(&path), field);
        assert!(message.contains(expected), "{message}");
        checked += 1;
    }
    let mut spec = spec_json("tri.glb");
    spec["resolution"] = serde_json::json!([64, 48, 1]);
    let path = write_spec(dir.path(), "resolution", &spec);
    let message = error_message(load_path(&path), "resolution");
    assert!(
        message.contains("expected an array of 2 numbers, got 3"),
        "{message}"
    );
    assert_eq!(checked + 1, 3);
    let file = dir.join("a-file");
    std::fs::write(&file, "not a folder").unwrap();
    let cases: [(&[&str], &str); 4] = [
        // The OS error once, not twice (message and source).
        (
            &["render", "missing.scene.json"],
            "cannot read: No such file or directory (os error 2)",
        ),
        (
            &[
                "render",
                "default",
                "--resolution",
                "32x18",
                "--out",
                file.to_str().unwrap(),
            ],
            "is a file",
        ),
        (
            &["render", "default", "--skip", "none,saturated-edges"],
            "\"none\" stands alone",
        ),
        (
            &["render", "default", "--cells", "99999999"],
            "99999999 is not in 1..=4096",
        ),
    ];
    let under_file = dir.join("a-file/bench");
    let under_file = under_file.to_str().unwrap();
    let cases: [(&[&str], &str); 6] = [
        cases[0],
        cases[1],
        cases[2],
        cases[3],
        // A bench folder under a file, named before any scene renders.
        (
            &[
                "bench",
                "default",
                "--resolution",
                "32x18",
                "--methods",
                "izb1",
                "--out",
                under_file,
            ],
            "a-file is a file",
        ),
        // Render checks its folder before the frame: nothing else said.
        (
            &["render", "default", "--out", under_file],
            "a-file is a file",
        ),
    ];
    for (args, expected) in cases {
        let stderr = assert_cli_refuses(args, expected);
        if args[0] == "render" && args.contains(&under_file) {
            assert!(
                !stderr.contains("backend"),
                "{args:?}: the folder was checked after the frame began: {stderr}"
            );
        }
        let os_errors = stderr.matches("(os error").count();
        assert!(
            os_errors <= 1,
            "{args:?}: the OS error {os_errors} times: {stderr}"
        );
    }
}

/// The scene `name` with every position mapped by `f` (camera and point
/// light too), near and far scaled by `depth`, under `light`.
fn mapped(
    name: &str,
    f: impl Fn(glam::DVec3) -> glam::DVec3,
    depth: f64,
    light: Option<izb::scene::Light>,
) -> Result<izb::scene::Scene, izb::scene::SceneError> {
    use izb::scene::{Camera, Light, Scene};
    let base = izb::scene::load(name)
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    let c = &base.camera;
    let camera = Camera {
        eye: f(c.eye),
        target: f(c.target),
        near: c.near * depth,
        far: c.far * depth,
        ..*c
    };
    let light = light.unwrap_or(match base.light {
        Light::Point { position } => Light::Point {
            position: f(position),
        },
        directional => directional,
    });
    let triangles = base.triangles.iter().map(|t| t.map(&f)).collect();
    Scene::new(name, triangles, camera, light, base.resolution)
}

/// Outside the precision envelope a scene is refused, naming the quantity
/// (these rendered without a word before: shadows gone at 10¹² scale and
/// beyond 10⁶ light radii, a BVH panic at 10¹⁹ and an eye at 10³⁰).
#[test]
fn scenes_outside_the_precision_envelope_are_refused_by_name() {
    use glam::DVec3;
    use izb::scene::Light;
    let far_light = Light::Point {
        position: DVec3::new(1.0, 3.0, 2.0) * 1e7,
    };
    let cases: [(Result<izb::scene::Scene, izb::scene::SceneError>, &str); 5] = [
        (
            mapped("default", |p| p * 1e12, 1e12, None),
            "units from the eye, beyond",
        ),
        (
            mapped("default", |p| p * 1e19, 1e19, None),
            "units from the eye, beyond",
        ),
        (
            mapped("default", |p| p * 1e-12, 1e-12, None),
            "units from the eye, below",
        ),
        (
            mapped("default", |p| p + DVec3::splat(1e30), 1.0, None),
            "from the origin",
        ),
        (
            mapped("default", |p| p, 1.0, Some(far_light)),
            "\"type\": \"directional\"",
        ),
    ];
    let mut checked = 0;
    for (result, expected) in cases {
        let message = error_message(result, expected);
        assert!(
            message.contains(expected),
            "expected '{expected}' in: {message}"
        );
        checked += 1;
    }
    assert_eq!(checked, 5);
}

/// A point light far from the scene, inside the envelope, keeps the exact
/// masks equal to the `f64` same-sample reference. Before the side planes
/// were computed as (x − l) × (y − x), `default` with the light 10³ radii
/// away had 5.5·10⁻⁴ of its samples on the wrong side (10⁴: 8·10⁻³).
#[test]
fn far_point_lights_stay_exact() {
    use glam::DVec3;
    use izb::cpu::{render_cpu, IzbSettings, SampleMode};
    use izb::scene::Light;
    let mut checked = 0;
    for radii in [1e3, 9e3] {
        let base = izb::scene::load("default").unwrap();
        let (lo, hi) = base.bounds();
        let (centre, radius) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
        let toward = DVec3::new(0.4, 1.0, 0.3).normalize();
        let light = Light::Point {
            position: centre + toward * radius * radii,
        };
        let scene = mapped("default", |p| p, 1.0, Some(light)).unwrap();
        let bvh = izb::bvh::SceneBvh::build(&scene);
        let reference = izb::reference::same_samples::same_sample_masks(
            &scene,
            &bvh,
            izb::lut::sample_pattern(),
        );
        let settings = IzbSettings {
            mode: SampleMode::Exact32,
            ..Default::default()
        };
        let exact = render_cpu(&scene, &bvh, settings);
        let tested = |i: usize| exact.gbuffer.flags[i] & izb::gbuffer::flags::SHADOW_TESTED != 0;
        let (diff, total) = izb::metrics::sample_mismatches(&exact.masks, &reference, tested);
        let shadowed: u32 = reference.iter().map(|m| m.count_ones()).sum();
        println!(
            "light {radii:e} radii away: {diff} of {total} samples differ, {shadowed} shadowed"
        );
        assert!(shadowed > 1000, "{radii:e}: hardly any shadow to compare");
        assert!(
            diff as f64 <= 1e-5 * total as f64,
            "{radii:e}: {diff} of {total}"
        );
        checked += 1;
    }
    assert_eq!(checked, 2);
}

/// Thousands of copies of one triangle (which made the BVH build take
/// the square of their number, then overflow its stack at 30 000) load
/// with at most `MAX_COINCIDENT` of them kept, counted and warned about;
/// the scene renders.
#[test]
fn coincident_triangles_build_in_bounded_time() {
    use glam::DVec3;
    let base = izb::scene::load("default").unwrap();
    let mut triangles = base.triangles.to_vec();
    let copy = [
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::new(1.0, 1.0, 0.0),
        DVec3::new(0.0, 2.0, 0.0),
    ];
    // Every order of the corners is the same triangle.
    for k in 0..30_000 {
        triangles.push(if k % 2 == 0 {
            copy
        } else {
            [copy[2], copy[1], copy[0]]
        });
    }
    let scene =
        izb::scene::Scene::new("copies", triangles, base.camera, base.light, [64, 36]).unwrap();
    let kept = izb::scene::MAX_COINCIDENT as usize;
    assert_eq!(scene.stats.dropped_coincident, 30_000 - kept);
    assert_eq!(scene.triangles.len(), base.triangles.len() + kept);
    assert!(
        scene.warnings.iter().any(|w| w.contains("coincident")),
        "{:?}",
        scene.warnings
    );
    // Before, the build below aborted the test binary (stack overflow).
    let bvh = izb::bvh::SceneBvh::build(&scene);
    let render = izb::cpu::render_cpu(&scene, &bvh, Default::default());
    assert!(render.masks.iter().any(|&m| m != 0));
}

/// A point light's sphere is capped as the sun's disk is: no wider than
/// the scene (`--light-size 1e6` was accepted while a sun is capped at
/// 30°); one within it renders.
#[test]
fn a_point_lights_sphere_is_capped_like_the_suns_disk() {
    let dir = TempDir::new("sphere-light");
    // Bounds 4 × 0.5 × 4: radius √(16 + 0.25 + 16) / 2 ≈ 2.839.
    Gltf::single_mesh(&[
        [[-2.0, 0.0, -2.0], [2.0, 0.0, 2.0], [2.0, 0.0, -2.0]],
        [[-0.3, 0.5, -0.3], [0.3, 0.5, 0.3], [0.3, 0.5, -0.3]],
    ])
    .write_glb(dir.path(), "two");
    let mut spec = spec_json("two.glb");
    spec["light"] = serde_json::json!({ "type": "point", "position": [0.0, 4.0, 0.0] });
    let path = write_spec(dir.path(), "point", &spec);
    let path = path.to_str().unwrap();
    let mut checked = 0;
    for (size, refused) in [("1e6", true), ("2.9", true), ("0.3", false)] {
        let out = dir.join(format!("out-{size}"));
        let args = [
            "render",
            path,
            "--light-size",
            size,
            "--resolution",
            "32x24",
            "--backend",
            "cpu",
            "--out",
            out.to_str().unwrap(),
        ];
        if refused {
            let stderr = assert_cli_refuses(&args, "wider than the scene itself");
            assert_mentions(&stderr, &["--light-size", "radius 2.8395e0"]);
        } else {
            let run = izb_cli(&args);
            assert!(
                run.status.success(),
                "{args:?}: {}",
                String::from_utf8_lossy(&run.stderr)
            );
        }
        checked += 1;
    }
    assert_eq!(checked, 3);
    // The spec's own `radius` takes the same check.
    spec["light"]["radius"] = serde_json::json!(3.0);
    let too_big = write_spec(dir.path(), "too-big", &spec);
    let message = error_message(load_path(&too_big), "a sphere wider than the scene");
    assert_mentions(
        &message,
        &["`light.radius` is 3", "wider than the scene itself"],
    );
}

/// The whole scene scaled by a power of two, which `f64` and `f32`
/// represent exactly, renders the same exact masks bit for bit, down to
/// 2⁻³⁰ (≈ 10⁻⁹, an eye reach of 3·10⁻⁸): before, `obvhs`'s absolute
/// 10⁻⁴ clamp on a box's entry distance culled every box of a scene below
/// ~10⁻³ units (the primary rays missed) and the envelope refused such
/// scenes below 10⁻²; the CPU tree is now scaled by a power of two.
#[test]
fn a_scene_scaled_by_a_power_of_two_casts_the_same_shadows() {
    use izb::bvh::SceneBvh;
    use izb::cpu::{render_cpu, IzbSettings, SampleMode};
    let render = |scene: izb::scene::Scene| {
        let scene = scene.with_resolution([96, 54]).unwrap();
        let bvh = SceneBvh::build(&scene);
        let settings = IzbSettings {
            mode: SampleMode::Exact32,
            edge_surfaces: true,
            ..Default::default()
        };
        let r = render_cpu(&scene, &bvh, settings);
        (r.masks, r.gbuffer.flags)
    };
    let (masks, flags) = render(mapped("default", |p| p, 1.0, None).unwrap());
    assert!(
        masks.iter().filter(|&&m| m != 0).count() > 100,
        "too few shadowed pixels"
    );
    let mut checked = 0;
    for k in [-30, -20, -10, 10, 24] {
        let s = 2f64.powi(k);
        let scaled = mapped("default", |p| p * s, s, None)
            .unwrap_or_else(|e| panic!("scaled by 2^{k}: {e}"));
        let (m, f) = render(scaled);
        assert_eq!(f, flags, "scaled by 2^{k}: other pixels tested");
        let differing: u32 = m
            .iter()
            .zip(&masks)
            .map(|(a, b)| (a ^ b).count_ones())
            .sum();
        assert_eq!(differing, 0, "scaled by 2^{k}: {differing} samples differ");
        checked += 1;
    }
    assert_eq!(checked, 5);
}
