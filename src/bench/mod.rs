//! Run time against error (paper-notes/reference-estimator.md, issue 6): every method on one scene,
//! in one process, repetitions interleaved so that drift in the machine's
//! speed hits every method alike, medians reported, every metric measured
//! against one supersampled ground truth.
//!
//! Methods:
//! - `izb1`, `izb32`, `izb32-exact`: the irregular z-buffer;
//! - `rt32`: brute-force ray tracing of the same 32 µQuad samples (CPU BVH,
//!   [`crate::reference::same_samples`]): what the IZB must equal;
//! - `rt32-rays`: those samples' plain shadow rays through a BVH, on
//!   Vulkan a compute pass (what a GPU without ray-tracing cores runs), on
//!   the CPU its twin ([`crate::peer::shadow_rays`]);
//! - `rt32-embree` (cargo feature `embree`): Intel Embree tracing those
//!   samples' shadow rays (`crate::peer::embree`): what a user would run
//!   instead; its shadow seconds are the tracing, its BVH build is in
//!   `details`;
//! - shadow maps, [`crate::baseline`] (`sm-R`, `pcf3-R`, `pcf5-R`,
//!   `csmN-pcfK-R`, `pcss-R`, `vsm-R`, `msm-R`, `esm-R`);
//! - `volumes`: per-triangle shadow volumes counted depth-fail in the
//!   stencil ([`crate::baseline::volumes`]), exact at one sample like
//!   `izb1`; its details carry the fill (volume fragments per pixel).
//!
//! Times: the *shadow seconds* of a method are everything after the
//! G-buffer the methods share (light setup and the method's own passes);
//! `rt32` traces its own primary rays, so its shadow seconds are its whole
//! run. `total_seconds` adds the G-buffer.

mod cpu_run;
pub mod document;
pub mod flicker;
mod methods;

pub use methods::{parse_methods, Method, MethodKind, DEFAULT_MAP_SIDES};

use crate::bvh::SceneBvh;
use crate::cpu::{resolve, PassTimes};
use crate::gbuffer::{gbuffer, GBuffer};
use crate::metrics::{metrics, sample_mismatches, Metrics};
use crate::output::write_exr;
use crate::reference::{reference, ReferenceImage, ReferenceSettings};
use crate::scene::Scene;
use cpu_run::{run_once, same_sample_masks_of};
use serde_json::{json, Value};
use std::path::Path;
use std::time::Instant;

/// How to measure.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub repeat: usize,
    pub reference: ReferenceSettings,
    /// Where to write each method's visibility (`<dir>/<scene>/<method>.exr`,
    /// plus `truth.exr`) for the report's crops; `None`: nowhere.
    pub images: Option<std::path::PathBuf>,
}

/// One method's last image and its times over the repetitions.
struct Runs {
    seconds: Vec<Value>,
    shadow: Vec<f64>,
    total: Vec<f64>,
    visibility: Vec<f32>,
    masks: Option<Vec<u32>>,
    details: Value,
    error: Option<String>,
}

fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// [fastest, slowest] of non-empty `v`.
fn range(v: &[f64]) -> [f64; 2] {
    v.iter()
        .fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], &x| {
            [lo.min(x), hi.max(x)]
        })
}

/// A file-name-safe form of a method name.
pub fn file_stem(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The ground truth and what every method shares on one scene.
pub struct SceneTruth {
    pub bvh: SceneBvh,
    pub gbuffer: GBuffer,
    pub gbuffer_seconds: f64,
    pub truth: ReferenceImage,
    pub bvh_seconds: f64,
}

impl SceneTruth {
    pub fn new(
        scene: &Scene,
        settings: ReferenceSettings,
        progress: &(dyn Fn(u64) + Sync),
    ) -> SceneTruth {
        let t = Instant::now();
        let bvh = SceneBvh::build(scene);
        let bvh_seconds = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let g = gbuffer(scene, &bvh);
        let gbuffer_seconds = t.elapsed().as_secs_f64();
        let truth = reference(scene, &bvh, settings, progress);
        SceneTruth {
            bvh,
            gbuffer: g,
            gbuffer_seconds,
            truth,
            bvh_seconds,
        }
    }
}

/// Everything measured of one method on one scene.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct MethodRow {
    pub method: String,
    /// `izb`, `shadow-map` or `ray-traced`.
    pub family: String,
    /// `cpu` or `vulkan`.
    pub backend: String,
    pub repeat: usize,
    /// Median of each pass (seconds; the last repetition's pass names).
    pub seconds: Value,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub shadow_seconds: f64,
    /// Fastest and slowest repetition: the run-to-run spread behind the
    /// median.
    #[serde(deserialize_with = "crate::output::nan_pair_if_null")]
    pub shadow_seconds_range: [f64; 2],
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub total_seconds: f64,
    /// Against the ground truth.
    pub metrics: Metrics,
    /// Differing samples / all samples against `rt32` (32-sample methods).
    pub sample_mismatch_rate: Option<f64>,
    /// This method's time over `izb32`'s, measured in this run.
    pub shadow_seconds_over_izb32: Option<f64>,
    /// Visibility image, relative to the bench JSON's folder.
    pub image: Option<String>,
    pub details: Value,
}

/// Measures `methods` on `scene` on the CPU against `shared.truth`.
/// Methods that cannot run on the scene (a point light surrounded by its
/// receivers for a shadow map) are reported in the returned error list.
pub fn bench_scene_cpu(
    scene: &Scene,
    shared: &SceneTruth,
    methods: &[Method],
    options: &BenchOptions,
    image_prefix: Option<&str>,
) -> anyhow::Result<(Vec<MethodRow>, Vec<String>)> {
    let mut runs: Vec<Option<Runs>> = methods.iter().map(|_| None).collect();
    let mut refused = Vec::new();
    for _ in 0..options.repeat.max(1) {
        for (k, m) in methods.iter().enumerate() {
            if runs[k].as_ref().is_some_and(|r| r.error.is_some()) {
                continue;
            }
            match run_once(scene, shared, &m.kind) {
                Ok(one) => match &mut runs[k] {
                    Some(all) => {
                        all.seconds.extend(one.seconds);
                        all.shadow.extend(one.shadow);
                        all.total.extend(one.total);
                        all.visibility = one.visibility;
                        all.masks = one.masks;
                        all.details = one.details;
                    }
                    None => runs[k] = Some(one),
                },
                Err(e) => {
                    refused.push(e.clone());
                    let mut r = run_placeholder();
                    r.error = Some(e);
                    runs[k] = Some(r);
                }
            }
        }
    }
    // The same-sample masks: the method's own run, or traced once here.
    // Per flavour: the pixel centre's µQuad alone, or edge surfaces.
    let rt_masks_of = |edges: bool| {
        match methods
        .iter()
        .zip(&runs)
        .find(|(m, _)| matches!(m.kind, MethodKind::RayTraced32 { edge_surfaces } if edge_surfaces == edges))
        .and_then(|(_, r)| r.as_ref()?.masks.clone())
    {
        Some(m) => Some(m),
        None if methods.iter().any(|m| m.kind.masks_32() && m.kind.edge_surfaces(scene) == edges) => {
            Some(same_sample_masks_of(scene, &shared.bvh, edges).0)
        }
        None => None,
    }
    };
    let rt_masks = [rt_masks_of(false), rt_masks_of(true)];
    let [w, h] = scene.resolution;
    if let Some(dir) = &options.images {
        let scene_dir = dir.join(file_stem(&scene.name));
        write_exr(
            &scene_dir.join("truth.exr"),
            w,
            h,
            &[
                ("visibility", &shared.truth.visibility),
                ("smooth", &shared.truth.smooth),
            ],
        )?;
    }
    let tested = |i: usize| !shared.truth.visibility[i].is_nan();
    let mut rows = Vec::new();
    for (m, r) in methods.iter().zip(runs) {
        let Some(r) = r else { continue };
        if r.error.is_some() {
            continue;
        }
        let image = match (&options.images, image_prefix) {
            (Some(dir), Some(prefix)) => {
                let rel = format!("{}/{}.exr", file_stem(&scene.name), file_stem(&m.name));
                write_exr(&dir.join(&rel), w, h, &[("visibility", &r.visibility)])?;
                Some(format!("{prefix}/{rel}"))
            }
            _ => None,
        };
        let sample_mismatch_rate = match (&r.masks, &rt_masks[m.kind.edge_surfaces(scene) as usize])
        {
            (Some(a), Some(b)) if m.kind.masks_32() => {
                let (d, n) = sample_mismatches(a, b, tested);
                Some(d as f64 / n.max(1) as f64)
            }
            _ => None,
        };
        let mut metrics = metrics(
            &r.visibility,
            &shared.truth.visibility,
            &shared.truth.smooth,
        );
        metrics.sample_mismatch_rate = sample_mismatch_rate;
        let seconds = median_passes(&r.seconds);
        rows.push(MethodRow {
            method: m.name.clone(),
            family: m.kind.family().to_string(),
            backend: "cpu".to_string(),
            repeat: r.shadow.len(),
            seconds,
            shadow_seconds: median(&r.shadow),
            shadow_seconds_range: range(&r.shadow),
            total_seconds: median(&r.total),
            metrics,
            sample_mismatch_rate,
            shadow_seconds_over_izb32: None,
            image,
            details: r.details,
        });
    }
    set_izb32_ratios(&mut rows);
    Ok((rows, refused))
}

impl Runs {
    /// One run of a ray-traced method: its masks and `trace` seconds (the
    /// shadow seconds), `before` seconds of shared work it relies on added
    /// to its total.
    fn record_trace(&mut self, masks: Vec<u32>, trace: f64, before: f64, shared: &SceneTruth) {
        self.shadow.push(trace);
        self.total.push(trace + before);
        self.seconds.push(json!({ "trace": trace }));
        self.visibility = resolve(&masks, &shared.gbuffer);
        self.masks = Some(masks);
    }

    /// One run of a baseline on the shared G-buffer: `shadow` seconds,
    /// the per-pass `seconds`, its report as `details`, its lit fractions.
    fn record_baseline(
        &mut self,
        shadow: f64,
        seconds: Value,
        details: Value,
        visibility: Vec<f32>,
        shared: &SceneTruth,
    ) {
        self.shadow.push(shadow);
        self.total.push(shadow + shared.gbuffer_seconds);
        self.seconds.push(seconds);
        self.details = details;
        self.visibility = visibility;
    }
}

fn run_placeholder() -> Runs {
    Runs {
        seconds: Vec::new(),
        shadow: Vec::new(),
        total: Vec::new(),
        visibility: Vec::new(),
        masks: None,
        details: Value::Null,
        error: None,
    }
}

/// Per-pass medians of JSON objects of seconds.
fn median_passes(runs: &[Value]) -> Value {
    let Some(Value::Object(first)) = runs.last() else {
        return Value::Null;
    };
    let mut out = serde_json::Map::new();
    for (key, v) in first {
        if v.is_number() {
            let all: Vec<f64> = runs.iter().filter_map(|r| r.get(key)?.as_f64()).collect();
            out.insert(key.clone(), json!(median(&all)));
        }
    }
    Value::Object(out)
}

/// Fills `shadow_seconds_over_izb32` from the `izb32` row of the same
/// backend.
pub fn set_izb32_ratios(rows: &mut [MethodRow]) {
    let base: Vec<(String, f64)> = rows
        .iter()
        .filter(|r| r.method == "izb32")
        .map(|r| (r.backend.clone(), r.shadow_seconds))
        .collect();
    for r in rows.iter_mut() {
        if let Some(&(_, b)) = base.iter().find(|(backend, _)| *backend == r.backend) {
            r.shadow_seconds_over_izb32 = Some(r.shadow_seconds / b);
        }
    }
}

/// Median of GPU pass milliseconds as seconds per pass.
pub fn gpu_seconds(ms: &PassTimes) -> Value {
    json!({
        "gbuffer": ms.gbuffer / 1e3,
        "light_setup": ms.light_setup / 1e3,
        "bin": ms.bin / 1e3,
        "evaluate": ms.evaluate / 1e3,
        "resolve": ms.resolve / 1e3,
        "total": ms.total / 1e3,
    })
}

/// Relative path of `path` from `base`'s folder, when under it.
pub fn relative_to(path: &Path, base: &Path) -> String {
    let dir = base.parent().unwrap_or(Path::new(""));
    path.strip_prefix(dir).unwrap_or(path).display().to_string()
}

/// Repetitions of the passes per timed GPU frame on a GPU
/// ([`crate::gpu::GpuRenderer::timed`]); a CPU device (lavapipe) runs
/// them once, its clocks do not idle and its frames take seconds.
pub const GPU_TIMED_REPEATS: u32 = 8;

/// `gpu` set up for timing: [`GPU_TIMED_REPEATS`] on a GPU, 1 on a CPU.
pub fn timed_renderer(gpu: crate::gpu::GpuRenderer) -> crate::gpu::GpuRenderer {
    let repeats = if gpu.context.info().is_cpu() {
        1
    } else {
        GPU_TIMED_REPEATS
    };
    gpu.timed(repeats)
}

/// Measures the IZB and shadow-map methods of `methods` on a Vulkan
/// device (full pipeline from the GPU G-buffer, timestamp queries),
/// repetitions interleaved, against `shared.truth`. `rt32` has no Vulkan
/// twin (the IZB's exact mode is the GPU's exact answer) and stays a CPU
/// row. Methods the device refuses (lavapipe's loop cap, a map above its
/// storage-buffer range) are returned in the second list.
pub fn bench_scene_vulkan(
    gpu: &crate::gpu::GpuRenderer,
    scene: &Scene,
    shared: &SceneTruth,
    methods: &[Method],
    repeat: usize,
) -> anyhow::Result<(Vec<MethodRow>, Vec<String>)> {
    use crate::gpu::GBufferSource;
    struct GpuRuns {
        millis: Vec<PassTimes>,
        visibility: Vec<f32>,
        details: Value,
        error: Option<String>,
    }
    let mut runs: Vec<Option<GpuRuns>> = methods.iter().map(|_| None).collect();
    let device = gpu.context.info().name.clone();
    // Repetition 0 warms the driver up (pipeline JIT, first-touch paging)
    // and is not timed.
    for rep in 0..=repeat.max(1) {
        for (k, m) in methods.iter().enumerate() {
            if runs[k].as_ref().is_some_and(|r| r.error.is_some()) {
                continue;
            }
            let one = match m.kind {
                MethodKind::Izb(settings) => {
                    gpu.render(scene, settings, GBufferSource::Gpu).map(|out| {
                        let details = json!({
                            "device": device,
                            "steps_ms": out.report.gpu_step_milliseconds,
                            "counters": out.report.counters,
                            "memory_total_bytes": out.report.memory_total_bytes,
                            "memory": out.report.memory,
                            "light": out.report.light,
                        });
                        (out.report.gpu_milliseconds, out.visibility, details)
                    })
                }
                MethodKind::ShadowMap(settings) => gpu
                    .render_shadow_map(scene, settings, GBufferSource::Gpu)
                    .map(|out| {
                        let details = json!({
                            "device": device,
                            "map_bytes": out.map_bytes,
                            "memory_total_bytes": out.memory_total_bytes,
                            "passes": "bin = shadow_map (raster, blur), evaluate = shadow_lookup (lookup, contact march)",
                        });
                        let ms = out.gpu_milliseconds.map(|m| m.as_pass_times());
                        (ms, out.visibility, details)
                    }),
                MethodKind::ShadowVolumes => gpu
                    .render_shadow_volumes(scene, GBufferSource::Gpu)
                    .map(|out| {
                        let details = json!({
                            "device": device,
                            "buffer_bytes": out.map_bytes,
                            "memory_total_bytes": out.memory_total_bytes,
                            "passes": "bin = volume_depth + stencil pass + copies, evaluate = volume_lookup",
                        });
                        let ms = out.gpu_milliseconds.map(|m| m.as_pass_times());
                        (ms, out.visibility, details)
                    }),
                // The µQuad's samples toward the light's centre: no peer of
                // a soft mask (the CPU run says so).
                MethodKind::ShadowRays32 if scene.has_area_light() => continue,
                MethodKind::ShadowRays32 => {
                    gpu.render_shadow_rays(scene, GBufferSource::Gpu)
                        .map(|out| {
                            let details = json!({
                                "device": device,
                                "memory_total_bytes": out.memory_total_bytes,
                                "passes": "evaluate = shadow_rays (32 rays per pixel, BVH any-hit)",
                            });
                            (out.gpu_milliseconds, out.visibility, details)
                        })
                }
                MethodKind::RayTraced32 { .. } | MethodKind::Embree32 => continue,
            };
            let entry = runs[k].get_or_insert(GpuRuns {
                millis: Vec::new(),
                visibility: Vec::new(),
                details: Value::Null,
                error: None,
            });
            match one {
                Ok(_) if rep == 0 => {}
                Ok((Some(ms), visibility, details)) => {
                    entry.millis.push(ms);
                    entry.visibility = visibility;
                    entry.details = details;
                }
                Ok((None, ..)) => {
                    entry.error = Some(format!("{device}: no timestamps to time {} with", m.name))
                }
                Err(e) => entry.error = Some(format!("{} on {device}: {e}", m.name)),
            }
        }
    }
    let mut rows = Vec::new();
    let mut refused = Vec::new();
    for (m, r) in methods.iter().zip(runs) {
        let Some(r) = r else { continue };
        if let Some(e) = r.error {
            refused.push(e);
            continue;
        }
        let ms = PassTimes::median(r.millis.iter());
        let metrics = metrics(
            &r.visibility,
            &shared.truth.visibility,
            &shared.truth.smooth,
        );
        rows.push(MethodRow {
            method: m.name.clone(),
            family: m.kind.family().to_string(),
            backend: "vulkan".to_string(),
            repeat: r.millis.len(),
            seconds: gpu_seconds(&ms),
            shadow_seconds: ms.shadow() / 1e3,
            shadow_seconds_range: range(
                &r.millis
                    .iter()
                    .map(|m| m.shadow() / 1e3)
                    .collect::<Vec<_>>(),
            ),
            total_seconds: ms.total / 1e3,
            metrics,
            sample_mismatch_rate: None,
            shadow_seconds_over_izb32: None,
            image: None,
            details: r.details,
        });
    }
    set_izb32_ratios(&mut rows);
    Ok((rows, refused))
}
