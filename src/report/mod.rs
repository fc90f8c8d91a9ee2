//! `izb report`: turns a `bench.json` into pictures people can look at.
//!
//! Per scene and backend a Pareto chart (time on a log x axis; MAE,
//! smooth-penumbra MAE, edge MAE and % wrong pixels on y; one point per
//! method and setting, the front of undominated points joined), as PNG and
//! SVG; per scene side-by-side crops of the ground truth, IZB 32 spp,
//! IZB 1 spp and the most accurate shadow map at the window with the most
//! penumbra, each with its error heat map; and an `index.html` that shows it
//! all with the numbers. Nothing here is committed: the command makes it.

mod chart;
mod crops;

pub use crops::{edge_window, penumbra_window, CROP_SIDE, CROP_ZOOM};

use crate::bench::document::{BenchDocument, ResultRow};
use crate::metrics::Metrics;
use crate::output::{read_exr_channel, write_atomically};
use anyhow::Result;
use chart::write_chart;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One plotted method.
#[derive(Clone, Debug)]
struct Point {
    method: String,
    family: String,
    seconds: f64,
    metrics: Metrics,
}

/// IZB 32 spp against one shadow-map setting on one scene and backend.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Verdict {
    pub scene: String,
    pub backend: String,
    pub shadow_map: String,
    /// Shadow-map error minus IZB 32 error: positive = the IZB is better.
    pub penumbra_mae_margin: f64,
    pub mae_margin: f64,
    /// Shadow-map shadow seconds over IZB 32's.
    pub time_ratio: f64,
}

impl Verdict {
    /// The IZB is more accurate on both smooth-penumbra and overall MAE.
    pub fn izb_more_accurate(&self) -> bool {
        self.penumbra_mae_margin > 0.0 && self.mae_margin > 0.0
    }
}

/// IZB 32 spp (`izb32`) against every shadow-map row of the same scene and
/// backend.
pub fn verdicts(results: &[ResultRow]) -> Vec<Verdict> {
    let mut out = Vec::new();
    for izb in results.iter().filter(|r| r.row.method == "izb32") {
        for sm in results.iter().filter(|r| {
            r.row.family == "shadow-map" && r.scene == izb.scene && r.row.backend == izb.row.backend
        }) {
            let (s, i) = (&sm.row.metrics, &izb.row.metrics);
            out.push(Verdict {
                scene: izb.scene.clone(),
                backend: izb.row.backend.clone(),
                shadow_map: sm.row.method.clone(),
                penumbra_mae_margin: s.smooth_penumbra_mae - i.smooth_penumbra_mae,
                mae_margin: s.mae - i.mae,
                time_ratio: sm.row.shadow_seconds / izb.row.shadow_seconds,
            });
        }
    }
    out
}

/// What the report wrote.
#[derive(Debug, Default)]
pub struct ReportFiles {
    pub index: PathBuf,
    pub verdicts: Vec<Verdict>,
    pub charts: Vec<PathBuf>,
    pub crops: Vec<PathBuf>,
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// `x` with `digits` decimals, or a dash when there is none.
fn num(x: impl Into<Option<f64>>, digits: usize) -> String {
    x.into()
        .filter(|x| !x.is_nan())
        .map_or("–".to_string(), |x| format!("{x:.digits$}"))
}

/// Reads `bench` (a `bench.json`) and writes the report into `out`.
/// Every image the document names, relative to `base`, is a file: checked
/// before the report writes anything, so a moved or half-deleted bench
/// folder stops it with the missing image's name, not half-way with its
/// charts written.
fn check_images_exist(doc: &BenchDocument, base: &Path, bench: &Path) -> Result<()> {
    let truths = doc.scenes.iter().map(|s| s.truth.image.as_str());
    let methods = doc.results.iter().filter_map(|r| r.row.image.as_deref());
    for rel in truths.chain(methods) {
        let path = base.join(rel);
        anyhow::ensure!(
            path.is_file(),
            "{} names the image {}, which is missing (was the bench's .images folder moved \
             or deleted?); nothing written",
            bench.display(),
            path.display()
        );
    }
    Ok(())
}

pub fn report(bench: &Path, out: &Path) -> Result<ReportFiles> {
    let doc = BenchDocument::read(bench)?;
    let results = &doc.results;
    let base = bench.parent().unwrap_or(Path::new("."));
    check_images_exist(&doc, base, bench)?;
    crate::output::create_folder(out)?;
    let mut files = ReportFiles::default();
    let mut scene_names: Vec<String> = Vec::new();
    for r in results {
        if !scene_names.contains(&r.scene) {
            scene_names.push(r.scene.clone());
        }
    }
    let mut html = String::new();
    let device = doc.device.as_ref().map_or("none (CPU only)", |d| &d.name);
    let cpu = doc.cpu.as_deref().unwrap_or("unknown CPU");
    let _ = write!(
        html,
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>izb: run time against error</title>\n\
         <style>body{{font-family:sans-serif;margin:2em;max-width:1300px}}table{{border-collapse:collapse;font-size:13px}}\
         td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}td:first-child,th:first-child{{text-align:left}}\
         figure{{display:inline-block;margin:4px;text-align:center;font-size:12px}}img{{image-rendering:pixelated}}\
         .chart{{width:100%;max-width:1200px}}</style></head><body>\n\
         <h1>Run time against error</h1>\n<p>From <code>{}</code>: CPU {} ({} threads of {} logical cores), Vulkan device {}; \
         ground truth {} spp; medians of {} interleaved repetitions. Times are the shadow passes (everything after the shared G-buffer); \
         compare times only within one backend.</p>\n",
        html_escape(&bench.display().to_string()),
        html_escape(cpu),
        doc.threads,
        doc.logical_cores,
        html_escape(device),
        doc.reference_spp,
        doc.repeat,
    );
    for scene in &scene_names {
        let stem = crate::bench::file_stem(scene);
        let rows: Vec<&ResultRow> = results.iter().filter(|r| &r.scene == scene).collect();
        let _ = writeln!(html, "<h2 id=\"{0}\">{0}</h2>", html_escape(scene));
        // The table.
        html.push_str("<table><tr><th>method</th><th>backend</th><th>shadow s, median (fastest–slowest)</th><th>/ izb32</th><th>MAE</th><th>smooth-penumbra MAE</th><th>edge MAE</th><th>% wrong</th><th>samples ≠ rt32</th></tr>\n");
        for ResultRow { row: r, .. } in &rows {
            let m = &r.metrics;
            let _ = writeln!(
                html,
                "<tr><td>{}</td><td>{}</td><td>{} <small>({}–{})</small></td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                html_escape(&r.method),
                html_escape(&r.backend),
                num(r.shadow_seconds, 5),
                num(r.shadow_seconds_range[0], 5),
                num(r.shadow_seconds_range[1], 5),
                num(r.shadow_seconds_over_izb32, 2),
                num(m.mae, 5),
                num(m.smooth_penumbra_mae, 4),
                num(m.edge_mae, 4),
                num(m.percent_over_one_sample, 3),
                num(r.sample_mismatch_rate, 6),
            );
        }
        html.push_str("</table>\n");
        let scene_verdicts: Vec<Verdict> = verdicts(results)
            .into_iter()
            .filter(|v| &v.scene == scene)
            .collect();
        if !scene_verdicts.is_empty() {
            let better = scene_verdicts
                .iter()
                .filter(|v| v.izb_more_accurate())
                .count();
            let worse: Vec<String> = scene_verdicts
                .iter()
                .filter(|v| !v.izb_more_accurate())
                .map(|v| format!("{} ({})", v.shadow_map, v.backend))
                .collect();
            let _ = writeln!(
                html,
                "<p class=\"verdict\">IZB 32 spp is more accurate (smooth-penumbra and overall MAE) than {better} of {} shadow-map settings{}.</p>",
                scene_verdicts.len(),
                if worse.is_empty() { String::new() } else { format!("; not than {}", html_escape(&worse.join(", "))) }
            );
        }
        // One chart per backend.
        let mut backends: Vec<&str> = rows.iter().map(|r| r.row.backend.as_str()).collect();
        backends.dedup();
        for backend in backends {
            let points: Vec<Point> = rows
                .iter()
                .filter(|r| r.row.backend == backend)
                .map(|r| Point {
                    method: r.row.method.clone(),
                    family: r.row.family.clone(),
                    seconds: r.row.shadow_seconds,
                    metrics: r.row.metrics.clone(),
                })
                .collect();
            if points.is_empty() {
                continue;
            }
            let chart_stem = format!("{stem}-{backend}-pareto");
            let title = format!("{scene} ({backend}): run time against error");
            files
                .charts
                .extend(write_chart(out, &chart_stem, &title, &points)?);
            let _ = writeln!(
                html,
                "<p><img class=\"chart\" src=\"{chart_stem}.svg\" alt=\"Pareto chart, {0}\" onerror=\"console.error('missing image: ' + this.src)\"><br>\
                 <a href=\"{chart_stem}.png\">PNG</a> · <a href=\"{chart_stem}.svg\">SVG</a></p>",
                html_escape(&title)
            );
        }
        // Crops.
        let Some(truth_rel) = doc
            .scenes
            .iter()
            .find(|s| &s.name == scene)
            .map(|s| &s.truth.image)
        else {
            continue;
        };
        let (w, h, truth) = read_exr_channel(&base.join(truth_rel), "visibility")?;
        let side = CROP_SIDE.min(w).min(h);
        let corner = penumbra_window(&truth, w, h, side);
        let cpu_rows: Vec<&crate::bench::MethodRow> = rows
            .iter()
            .map(|r| &r.row)
            .filter(|r| r.backend == "cpu" && r.image.is_some())
            .collect();
        let best_sm = cpu_rows
            .iter()
            .filter(|r| r.family == "shadow-map")
            .min_by(|a, b| a.metrics.mae.total_cmp(&b.metrics.mae))
            .copied();
        let pick = |name: &str| cpu_rows.iter().find(|r| r.method == name).copied();
        let mut shown: Vec<(String, Option<&crate::bench::MethodRow>)> = vec![
            ("ground truth".to_string(), None),
            ("izb32".to_string(), pick("izb32")),
            ("izb1".to_string(), pick("izb1")),
            (
                best_sm.map_or("best shadow map".to_string(), |r| {
                    format!("best shadow map: {}", r.method)
                }),
                best_sm,
            ),
        ];
        // The other exact 1-spp method, when the bench ran it.
        if let Some(volumes) = pick("volumes") {
            shown.insert(3, ("volumes".to_string(), Some(volumes)));
        }
        let crops = crops::CropSet {
            truth: &truth,
            size: (w, h),
            side,
            base,
            out,
            stem: &stem,
        };
        let title = format!(
            "Crops at the shadow edge ({side}×{side} pixels from ({}, {}), ×{CROP_ZOOM})",
            corner.0, corner.1
        );
        crops.write_row(&mut html, &mut files.crops, &title, "crop", corner, &shown)?;
        // Where a pixel's footprint covers several surfaces: the edge
        // surfaces (izb32, izb32-paired) against every sample on the
        // centre's µQuad (izb32-flat) and one sample.
        let (_, _, smooth) = read_exr_channel(&base.join(truth_rel), "smooth")?;
        let edge_corner = edge_window(&truth, &smooth, w, h, side);
        let mut edge_shown = vec![("ground truth".to_string(), None)];
        for name in ["izb32", "izb32-paired", "izb32-flat", "izb1"] {
            if let Some(r) = pick(name) {
                edge_shown.push((name.to_string(), Some(r)));
            }
        }
        let title = format!(
            "Crops at edge pixels: partly lit pixels that see several surfaces \
             ({side}×{side} pixels from ({}, {}), ×{CROP_ZOOM})",
            edge_corner.0, edge_corner.1
        );
        crops.write_row(
            &mut html,
            &mut files.crops,
            &title,
            "edge-crop",
            edge_corner,
            &edge_shown,
        )?;
    }
    // Flicker.
    if let (false, Some(settings)) = (doc.flicker.is_empty(), doc.flicker_settings) {
        let _ = writeln!(
            html,
            "<h2 id=\"flicker\">Temporal stability</h2><p>Light turned by {}° per frame over {} frames; mean per-pixel |Δ visibility| \
             between frames, and its ratio to the ground truth's (1 = no shimmer beyond the shadow's real motion), with a 95 % \
             interval from a moving-block bootstrap over frame steps.</p>",
            num(settings.step_degrees, 3),
            settings.frames
        );
        html.push_str(
            "<table><tr><th>scene</th><th>method</th><th>mean |Δ|</th><th>/ truth</th><th>95 % interval</th></tr>\n",
        );
        for s in &doc.flicker {
            for r in &s.rows {
                let _ = writeln!(
                    html,
                    "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}–{}</td></tr>",
                    html_escape(&s.scene),
                    html_escape(&r.method),
                    num(r.mean_abs_delta, 6),
                    num(r.ratio_to_truth, 2),
                    num(r.ratio_ci95[0], 2),
                    num(r.ratio_ci95[1], 2)
                );
            }
        }
        html.push_str("</table>\n");
    }
    html.push_str("</body></html>\n");
    let index = out.join("index.html");
    write_atomically(&index, |tmp| Ok(std::fs::write(tmp, &html)?))?;
    files.index = index;
    files.verdicts = verdicts(results);
    Ok(files)
}
