//! `izb bench` smoke run and `izb report`, end to end through the CLI; the
//! report page is then loaded in headless Chromium, which must log nothing
//! to the console (every image of the page reports a failed load with
//! `console.error`). A page with one image deleted must be caught: the test
//! of the test. Without Chromium the browser part prints that it skipped;
//! with `IZB_REQUIRE_CHROMIUM=1` (CI installs Debian's `chromium`) it fails.

mod common;

use common::TempDir;
use std::path::{Path, PathBuf};
use std::process::Command;

fn izb(args: &[&str]) -> String {
    let out = common::izb_cli(args);
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "izb {args:?} failed:\n{text}");
    text
}

fn chromium() -> Option<PathBuf> {
    if let Ok(p) = std::env::var("IZB_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .find_map(|name| {
            std::env::var_os("PATH").and_then(|paths| {
                std::env::split_paths(&paths)
                    .map(|d| d.join(name))
                    .find(|p| p.is_file())
            })
        })
}

/// Console lines Chromium logged while loading `page` (headless, no
/// network, a fresh profile), and the DOM after load.
fn load_in_chromium(browser: &Path, page: &Path, profile: &Path) -> (Vec<String>, String) {
    let url = format!("file://{}", page.canonicalize().unwrap().display());
    let out = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--enable-logging=stderr",
            "--v=0",
            "--virtual-time-budget=5000",
            "--dump-dom",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(&url)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "chromium failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let console = String::from_utf8_lossy(&out.stderr)
        .lines()
        .filter(|l| l.contains(":CONSOLE"))
        .map(str::to_string)
        .collect();
    (console, String::from_utf8_lossy(&out.stdout).into_owned())
}

#[test]
fn bench_smoke_run_and_report_render_in_chromium() {
    let dir = TempDir::new("report-chromium");
    let bench = dir.join("bench.json");
    let report = dir.join("report");
    izb(&[
        "bench",
        "default",
        "--resolution",
        "96x54",
        "--spp",
        "4",
        "--repeat",
        "1",
        "--methods",
        "izb1,izb32,izb32-flat,rt32,sm-256,pcf3-256,csm2-pcf3-128",
        "--flicker",
        "--flicker-frames",
        "3",
        "--out",
        bench.to_str().unwrap(),
    ]);
    // The report reads bench.json as one typed document (the bench's own
    // type): a renamed field is a named error, not a chart of NaNs.
    let text = std::fs::read_to_string(&bench).unwrap();
    let typed = izb::bench::document::BenchDocument::read(&bench).unwrap();
    assert_eq!(typed.results.len(), 7);
    let renamed = dir.join("renamed.json");
    std::fs::write(
        &renamed,
        text.replace("\"shadow_seconds\":", "\"shadow_secs\":"),
    )
    .unwrap();
    let out = common::izb_cli(&[
        "report",
        renamed.to_str().unwrap(),
        "--out",
        report.to_str().unwrap(),
    ]);
    let message = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && message.contains("shadow_seconds")
            && message.contains("results[0]"),
        "a renamed field must be refused by name: {message}"
    );
    let doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    let results = doc["results"].as_array().unwrap();
    assert_eq!(results.len(), 7, "one row per method");
    for r in results {
        assert!(r["shadow_seconds"].as_f64().unwrap() > 0.0, "{r}");
        assert!(r["metrics"]["pixels"].as_u64().unwrap() > 1000, "{r}");
        let image = bench.parent().unwrap().join(r["image"].as_str().unwrap());
        assert!(image.is_file(), "{}", image.display());
    }
    // rt32 is the same-sample reference: it matches itself, and the IZB
    // matches it up to the LUT's bound.
    let rt32 = results.iter().find(|r| r["method"] == "rt32").unwrap();
    assert_eq!(rt32["sample_mismatch_rate"].as_f64(), Some(0.0));
    assert!(doc["logical_cores"].as_u64().unwrap() >= 1);
    let flicker = doc["flicker"][0]["rows"].as_array().unwrap();
    assert_eq!(flicker.len(), 8, "the truth and every method");
    assert!(flicker
        .iter()
        .all(|r| r["mean_abs_delta"].as_f64().unwrap().is_finite()));

    izb(&[
        "report",
        bench.to_str().unwrap(),
        "--out",
        report.to_str().unwrap(),
    ]);
    let index = report.join("index.html");
    for f in [
        "default-cpu-pareto.png",
        "default-cpu-pareto.svg",
        "default-crop-0.png",
        "default-crop-3-error.png",
        "default-edge-crop-0.png",
        "default-edge-crop-2-error.png",
    ] {
        assert!(report.join(f).is_file(), "{f} missing");
    }
    let png = image::open(report.join("default-cpu-pareto.png")).unwrap();
    assert_eq!((png.width(), png.height()), (1200, 900));
    let svg = std::fs::read_to_string(report.join("default-cpu-pareto.svg")).unwrap();
    assert!(
        svg.contains("<svg") && svg.contains("izb32"),
        "the SVG chart names its points"
    );

    let Some(browser) = chromium() else {
        if std::env::var("IZB_REQUIRE_CHROMIUM").as_deref() == Ok("1") {
            panic!("IZB_REQUIRE_CHROMIUM=1 but no chromium on PATH");
        }
        eprintln!("skipped: no chromium on PATH (set IZB_REQUIRE_CHROMIUM=1 to require it)");
        return;
    };
    let (console, dom) = load_in_chromium(&browser, &index, &dir.join("profile-1"));
    assert!(console.is_empty(), "console messages: {console:#?}");
    assert!(dom.contains("<h2 id=\"default\">default</h2>"), "{dom}");
    assert!(
        dom.contains("best shadow map: "),
        "crops of the best shadow map"
    );
    assert!(
        dom.contains("Crops at edge pixels") && dom.contains("default-edge-crop-2.png"),
        "crops of the edge pixels, izb32-flat among them"
    );
    assert!(dom.contains("Temporal stability"));
    // The check can fail: a deleted crop is reported.
    std::fs::remove_file(report.join("default-crop-2.png")).unwrap();
    let (console, _) = load_in_chromium(&browser, &index, &dir.join("profile-2"));
    assert!(
        console
            .iter()
            .any(|l| l.contains("missing image") && l.contains("default-crop-2.png")),
        "a missing image went unnoticed: {console:#?}"
    );
}
