//! `izb view` driven by a script in a real window (Xvfb when there is no
//! display) on the real Vulkan device: the screenshots are not blank, the
//! shadow moves when the light turns, the halves of a split show their own
//! methods, resizing works, the error view compares against a progressive
//! truth, and the validation layer stays silent. Without a display or a
//! device the test prints that it skipped; with `IZB_REQUIRE_GPU=1` it
//! fails instead.

mod common;

use common::TempDir;
use izb::output::read_exr_channel;
use serde_json::Value;
use std::path::Path;
use std::process::Command;

fn required() -> bool {
    std::env::var("IZB_REQUIRE_GPU").is_ok_and(|v| v == "1")
}

fn skip(why: &str) {
    assert!(!required(), "IZB_REQUIRE_GPU=1 but {why}");
    eprintln!("skipped: {why}");
}

/// `izb view ARGS` in a window: on `DISPLAY` when set, else under
/// `xvfb-run -a`; `None` (skipped) when neither exists.
fn view_command(args: &[&str]) -> Option<Command> {
    let izb = env!("CARGO_BIN_EXE_izb");
    if std::env::var_os("DISPLAY").is_some() {
        let mut c = Command::new(izb);
        c.arg("view").args(args);
        return Some(c);
    }
    let has_xvfb = Command::new("xvfb-run").arg("--help").output().is_ok();
    if !has_xvfb {
        skip("no DISPLAY and no xvfb-run (Debian: apt install xvfb xauth)");
        return None;
    }
    let mut c = Command::new("xvfb-run");
    c.args(["-a", "-s", "-screen 0 1280x1024x24", izb, "view"])
        .args(args);
    Some(c)
}

fn report(dir: &Path) -> Value {
    let text = std::fs::read_to_string(dir.join("report.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn window(dir: &Path) -> image::RgbImage {
    image::open(dir.join("window.png")).unwrap().to_rgb8()
}

fn luma(p: &image::Rgb<u8>) -> f64 {
    0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2])
}

/// The image area of a screenshot: (x0, y0, x1, y1) in window pixels.
fn image_rect(dir: &Path) -> [u32; 4] {
    let r = &report(dir)["window"]["image_rect_px"];
    let v: Vec<u32> = (0..4)
        .map(|i| r[i].as_f64().unwrap().round() as u32)
        .collect();
    [v[0], v[1], v[2], v[3]]
}

/// Runs `izb view ARGS --script` over `script` (written into `tmp`) with
/// `env` added, asserts that it exits 0, and returns its `--stats`;
/// `None` when skipped (no display).
fn run_script(tmp: &TempDir, args: &[&str], script: &str, env: &[(&str, &str)]) -> Option<Value> {
    let script_path = tmp.join("script.txt");
    std::fs::write(&script_path, script).unwrap();
    let stats_path = tmp.join("stats.json");
    let (script_arg, stats_arg) = (script_path.to_str().unwrap(), stats_path.to_str().unwrap());
    let mut all = args.to_vec();
    all.extend(["--script", script_arg, "--stats", stats_arg]);
    let mut cmd = view_command(&all)?;
    cmd.envs(env.iter().copied());
    let out = cmd.output().expect("izb view did not start");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "izb view failed:\n{stderr}");
    Some(serde_json::from_str(&std::fs::read_to_string(&stats_path).unwrap()).unwrap())
}

/// Whether a Vulkan device opens; skips (or fails when required) if not.
fn has_device() -> bool {
    match izb::gpu::list_devices() {
        Ok(list) if !list.is_empty() => true,
        other => {
            skip(&format!("no Vulkan device ({:?})", other.err()));
            false
        }
    }
}

#[test]
fn scripted_window_moves_the_shadow_and_splits_the_methods() {
    if !has_device() {
        return;
    }
    let tmp = TempDir::new("viewer_script");
    let d = |name: &str| tmp.join(name).display().to_string();
    let script = format!(
        "overlay off\n\
         screenshot {}\n\
         light 50 0\n\
         screenshot {}\n\
         method izb32\nsplit sm-512\ndivider 0.5\n\
         screenshot {}\n\
         magnify 120 70\noverlay on\nview candidates\n\
         screenshot {}\n\
         resize 720 480\nview error\nwait-truth 8\n\
         screenshot {}\n\
         split volumes\n\
         screenshot {}\n\
         light 40 10\nwait-truth 4\n\
         screenshot {}\n\
         quit\n",
        d("lit"),
        d("turned"),
        d("split"),
        d("candidates"),
        d("error"),
        d("volumes"),
        d("moved")
    );
    let args = ["default", "--resolution", "240x135", "--window", "960x600"];
    let Some(stats) = run_script(&tmp, &args, &script, &[]) else {
        return;
    };
    assert_eq!(
        stats["validation_messages"].as_array().unwrap().len(),
        0,
        "validation messages: {}",
        stats["validation_messages"]
    );
    assert_eq!(
        stats["errors"].as_array().unwrap().len(),
        0,
        "{}",
        stats["errors"]
    );
    assert_eq!(stats["screenshots"].as_array().unwrap().len(), 7);

    // Every screenshot holds render's files and a window that is not blank.
    let shots = ["lit", "turned", "split", "candidates", "error"];
    for name in shots {
        let dir = tmp.join(name);
        for file in [
            "visibility.exr",
            "visibility.png",
            "shaded.png",
            "report.json",
            "window.png",
        ] {
            assert!(dir.join(file).is_file(), "{name}/{file} missing");
        }
        let w = window(&dir);
        let [x0, y0, x1, y1] = image_rect(&dir);
        let values: Vec<f64> = (y0..y1.min(w.height()))
            .step_by(3)
            .flat_map(|y| (x0..x1.min(w.width())).step_by(3).map(move |x| (x, y)))
            .map(|(x, y)| luma(w.get_pixel(x, y)))
            .collect();
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / values.len() as f64;
        assert!(
            var.sqrt() > 10.0,
            "{name}: the image area is flat (σ {:.1})",
            var.sqrt()
        );
    }
    assert_eq!(shots.len(), 5);

    // The shadow moves when the light turns: many tested pixels change
    // lit fraction by more than a half.
    let (_, _, before) = read_exr_channel(&tmp.join("lit/visibility.exr"), "visibility").unwrap();
    let (_, _, after) = read_exr_channel(&tmp.join("turned/visibility.exr"), "visibility").unwrap();
    let moved = before
        .iter()
        .zip(&after)
        .filter(|(a, b)| !a.is_nan() && !b.is_nan() && (*a - *b).abs() > 0.5)
        .count();
    assert!(
        moved > before.len() / 100,
        "only {moved} pixels changed under the turned light"
    );
    let (lit_w, turned_w) = (window(&tmp.join("lit")), window(&tmp.join("turned")));
    let window_changed = lit_w
        .pixels()
        .zip(turned_w.pixels())
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        window_changed > 1000,
        "the window did not change ({window_changed} pixels)"
    );

    // The split: where the two methods' shaded images differ, the window
    // shows the left method left of the divider and the right one right
    // of it. Read at texel centres: the UI renderer filters bilinearly.
    let split = tmp.join("split");
    let left = image::open(split.join("shaded.png")).unwrap().to_rgb8();
    let right = image::open(split.join("right/shaded.png"))
        .unwrap()
        .to_rgb8();
    let w = window(&split);
    let [x0, y0, x1, y1] = image_rect(&split);
    let divider_x = x0 as f64 + 0.5 * f64::from(x1 - x0);
    let (mut agree, mut checked) = ([0usize; 2], [0usize; 2]);
    let scale = [
        f64::from(x1 - x0) / f64::from(left.width()),
        f64::from(y1 - y0) / f64::from(left.height()),
    ];
    for v in 0..left.height() {
        for u in 0..left.width() {
            let fx = f64::from(x0) + (f64::from(u) + 0.5) * scale[0];
            let fy = f64::from(y0) + (f64::from(v) + 0.5) * scale[1];
            let (x, y) = (fx as u32, fy as u32);
            let (l, r) = (luma(left.get_pixel(u, v)), luma(right.get_pixel(u, v)));
            if (l - r).abs() < 40.0 || (fx - divider_x).abs() < 4.0 {
                continue;
            }
            let shown = luma(w.get_pixel(x, y));
            let side = usize::from(fx > divider_x);
            let closer_to_left = (shown - l).abs() < (shown - r).abs();
            checked[side] += 1;
            agree[side] += usize::from(closer_to_left == (side == 0));
        }
    }
    for side in 0..2 {
        assert!(
            checked[side] > 40,
            "side {side}: only {} differing pixels",
            checked[side]
        );
        let share = agree[side] as f64 / checked[side] as f64;
        assert!(
            share > 0.9,
            "side {side}: {share:.3} of differing pixels show their method"
        );
    }
    let r = report(&split);
    assert_eq!(r["methods"].as_array().unwrap().len(), 2);
    assert_eq!(r["command"], "view");

    // The resized window is screenshotted at its new size, with the error
    // against a truth of at least 8 samples per pixel.
    let error = tmp.join("error");
    let w = window(&error);
    assert_eq!((w.width(), w.height()), (720, 480));
    let r = report(&error);
    assert_eq!(r["view"]["view"], "error");
    let e = &r["methods"][0]["error_against_truth"];
    assert!(e["truth_spp"].as_u64().unwrap() >= 8, "{e}");
    let mae = e["mae"].as_f64().unwrap();
    assert!(mae < 0.1, "izb32's error against the truth is {mae}");

    // Shadow volumes render in the viewer too (on the rasteriser), with
    // an error against the truth like the IZB's 1 spp.
    let r = report(&tmp.join("volumes"));
    let methods = r["methods"].as_array().unwrap();
    assert_eq!(methods.len(), 2);
    assert_eq!(methods[1]["method"], "volumes");
    let mae = methods[1]["error_against_truth"]["mae"].as_f64().unwrap();
    assert!(mae < 0.1, "volumes' error against the truth is {mae}");

    // `wait-truth` right after the light moved waits for the new view's
    // truth (an earlier version took the previous view's samples, and the
    // screenshot had no truth at all).
    let r = report(&tmp.join("moved"));
    assert_eq!(r["view"]["light_turn_deg"], serde_json::json!([40.0, 10.0]));
    let e = &r["methods"][0]["error_against_truth"];
    assert!(e["truth_spp"].as_u64().is_some_and(|spp| spp >= 4), "{e}");
    let mae = e["mae"].as_f64().unwrap();
    assert!(
        mae < 0.1,
        "izb32's error against the new view's truth is {mae}"
    );

    // An error view says why it is empty exactly when it has no truth.
    let mut checked = 0;
    for name in ["error", "volumes", "moved"] {
        let r = report(&tmp.join(name));
        let has_truth = !r["methods"][0]["error_against_truth"].is_null();
        assert_eq!(
            r["view"]["notice"].is_null(),
            has_truth,
            "{name}: {}",
            r["view"]
        );
        checked += 1;
    }
    assert_eq!(checked, 3);
}

#[test]
fn bad_scripts_are_refused_naming_the_line() {
    let tmp = TempDir::new("viewer_bad_script");
    let script = tmp.join("bad.txt");
    std::fs::write(&script, "light 10 0\nsplit rt32\n").unwrap();
    let out = common::izb_cli(&["view", "--script", script.to_str().unwrap()]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("line 2") && stderr.contains("rt32"),
        "{stderr}"
    );
}

#[test]
fn without_a_vulkan_device_the_viewer_says_so() {
    let out = Command::new(env!("CARGO_BIN_EXE_izb"))
        .args(["view", "default"])
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .env_remove("DISPLAY")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("izb view needs a Vulkan device"),
        "{stderr}"
    );
}

#[test]
fn a_hung_compute_device_is_a_message_in_the_window_not_a_crash() {
    if !has_device() {
        return;
    }
    let tmp = TempDir::new("viewer_hung_device");
    let shot = tmp.join("hung");
    let script = format!(
        "screenshot {}\nlight 30 0\nscreenshot {}\nquit\n",
        shot.display(),
        tmp.join("again").display()
    );
    // One microsecond: every frame outlives its limit, the device is
    // abandoned and reopened for the next frame.
    let args = ["default", "--resolution", "160x90", "--window", "640x400"];
    let timeout = [("IZB_GPU_TIMEOUT_S", "0.000001")];
    let Some(stats) = run_script(&tmp, &args, &script, &timeout) else {
        return;
    };
    let errors: Vec<&str> = stats["errors"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|e| e.as_str())
        .collect();
    let timeouts = errors
        .iter()
        .filter(|e| e.contains("did not finish the frame"))
        .count();
    let reopened = errors.iter().filter(|e| e.contains("reopened")).count();
    assert_eq!((timeouts, reopened), (2, 2), "{errors:?}");
    let r = report(&shot);
    assert!(
        r["errors"].to_string().contains("did not finish"),
        "{}",
        r["errors"]
    );
    assert!(shot.join("window.png").is_file());
}

#[test]
fn a_frame_refused_by_the_loop_cap_is_rendered_by_the_cpu_twin_and_says_so() {
    let cpu_device = match izb::gpu::list_devices() {
        Ok(list) if !list.is_empty() => match list.iter().position(|d| d.is_cpu()) {
            Some(i) => i.to_string(),
            None => return eprintln!("skipped: the loop cap is lavapipe's, and it is not here"),
        },
        other => return skip(&format!("no Vulkan device ({:?})", other.err())),
    };
    let tmp = TempDir::new("viewer_loop_cap");
    let shot = tmp.join("cap");
    let script = format!("screenshot {}\nquit\n", shot.display());
    let args = [
        "hairball",
        "--light-size",
        "3",
        "--resolution",
        "160x90",
        "--window",
        "640x400",
        "--device",
        &cpu_device,
    ];
    // Without the heavy step one subgroup of this frame needs more loop
    // trips than lavapipe allows (measured: 58 935 at the stop).
    if run_script(&tmp, &args, &script, &[("IZB_GPU_HEAVY_ENTRIES", "0")]).is_none() {
        return;
    }
    let r = report(&shot);
    let backend = r["backend"].as_str().unwrap();
    assert!(
        backend.starts_with("cpu twin") && backend.contains("loops after"),
        "{backend}"
    );
    let (_, _, v) = read_exr_channel(&shot.join("visibility.exr"), "visibility").unwrap();
    assert!(
        v.iter().any(|v| !v.is_nan() && *v < 1.0),
        "the CPU twin's frame has no shadow"
    );
}

#[test]
fn without_a_display_the_viewer_says_how_to_get_one() {
    if !has_device() {
        return;
    }
    let out = Command::new(env!("CARGO_BIN_EXE_izb"))
        .args(["view", "default"])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("WAYLAND_SOCKET")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("cannot reach a display") && stderr.contains("xvfb-run -a"),
        "{stderr}"
    );
}

/// The viewer keeps each IZB method's shadow pass resident: turning the
/// light and orbiting the eye record new parameters into the pass the
/// first frame made (no scene clone, BVH build or upload: the pass makes
/// its vertices and BVH nodes eye-relative on the GPU), and every frame's
/// masks and lit fraction equal the batch `render` of the same view
/// (exact mode, edge surfaces on: bit for bit).
#[test]
fn the_viewer_keeps_its_pass_resident_while_the_light_and_eye_move() {
    use izb::bench::MethodKind;
    use izb::gpu::{GBufferSource, GpuOptions, GpuRenderer};
    use izb::view::state::{method_kind, ViewState};
    if !has_device() {
        return;
    }
    let tmp = TempDir::new("viewer_resident");
    // (screenshot, orbit, light turn, whether the frame makes its pass)
    let views = [
        ("first", [0.0, 0.0], [0.0, 0.0], None),
        ("turned", [0.0, 0.0], [20.0, 5.0], Some(false)),
        ("turned_more", [0.0, 0.0], [35.0, 12.0], Some(false)),
        ("orbited", [12.0, 4.0], [35.0, 12.0], Some(false)),
        ("orbited_turned", [12.0, 4.0], [10.0, 20.0], Some(false)),
    ];
    let method = "izb32-exact";
    let mut script = format!("overlay off\nmethod {method}\n");
    for (name, orbit, light, _) in &views {
        let d = tmp.join(name).display().to_string();
        script += &format!(
            "orbit {} {}\nlight {} {}\nscreenshot {d}\n",
            orbit[0], orbit[1], light[0], light[1]
        );
    }
    script += "quit\n";
    let args = ["default", "--resolution", "96x54", "--window", "640x400"];
    let Some(stats) = run_script(&tmp, &args, &script, &[]) else {
        return;
    };
    assert_eq!(
        stats["errors"].as_array().unwrap().len(),
        0,
        "{}",
        stats["errors"]
    );
    assert_eq!(
        stats["validation_messages"].as_array().unwrap().len(),
        0,
        "{}",
        stats["validation_messages"]
    );
    assert!(stats["resident_frames"].as_u64().unwrap() >= 3, "{stats}");

    let base = izb::scene::load("default")
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    let Ok(MethodKind::Izb(settings)) = method_kind(method) else {
        panic!("{method} is an IZB method");
    };
    assert!(settings.uses_edge_surfaces(&base));
    let renderer = GpuRenderer::new(&GpuOptions::from_env()).unwrap();
    let mut compared = 0;
    for (name, orbit, light, made) in &views {
        let dir = tmp.join(name);
        let r = report(&dir);
        let resident = &r["methods"][0]["render"]["resident_pass"];
        if let Some(made) = made {
            assert_eq!(resident["made_pass"], *made, "{name}: {resident}");
        }
        let mut state = ViewState::new(&base);
        state.orbit = [orbit[0], orbit[1], 1.0];
        state.light_turn = *light;
        let scene = state.scene(&base, base.bounds()).unwrap();
        let batch = renderer
            .render(&scene, settings, GBufferSource::Gpu)
            .unwrap();
        let exr = dir.join("visibility.exr");
        let (_, _, masks) = izb::output::read_exr_mask(&exr, "mask").unwrap();
        assert_eq!(
            masks, batch.masks,
            "{name}: the viewer's masks differ from render's"
        );
        let (_, _, lit) = read_exr_channel(&exr, "visibility").unwrap();
        let same = |a: f32, b: f32| a == b || (a.is_nan() && b.is_nan());
        let differ = lit
            .iter()
            .zip(&batch.visibility)
            .filter(|(a, b)| !same(**a, **b));
        assert_eq!(
            differ.count(),
            0,
            "{name}: the lit fraction differs from render's"
        );
        compared += 1;
    }
    assert_eq!(compared, views.len());
}
