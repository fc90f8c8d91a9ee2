//! `bench.json` as one typed document: `izb bench` writes a
//! [`BenchDocument`], `izb report` reads the same type back. A renamed or
//! missing field is a named error when the report reads the file, never a
//! silent `NaN` or `?` in a chart (every field the report reads is typed;
//! `details` and the timings per pass stay free-form, for people).

use super::flicker::FlickerRow;
use super::MethodRow;
use crate::gpu::DeviceInfo;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::Path;

/// The whole `bench.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BenchDocument {
    /// Always `"bench"`.
    pub command: String,
    /// izb32's shadow time between the smallest and largest resolution of
    /// each scene benchmarked at several.
    pub izb32_scaling: Vec<Scaling>,
    /// The Vulkan device, when a GPU method ran.
    pub device: Option<DeviceInfo>,
    /// The CPU's model name (Linux).
    pub cpu: Option<String>,
    pub threads: usize,
    pub logical_cores: usize,
    pub repeat: usize,
    /// Samples per pixel of the ground truth.
    pub reference_spp: u32,
    pub flicker_settings: Option<FlickerSettings>,
    pub scenes: Vec<SceneEntry>,
    pub results: Vec<ResultRow>,
    pub flicker: Vec<SceneFlicker>,
}

/// izb32's time at the largest resolution over the smallest.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Scaling {
    pub scene: String,
    pub backend: String,
    pub from: String,
    pub to: String,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub pixel_ratio: f64,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub time_ratio: f64,
}

/// One scene: what it is and its ground truth.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SceneEntry {
    /// The scene's name as the results carry it (`scene@WxH` with several
    /// resolutions).
    pub name: String,
    /// Triangles, camera, light (`izb info`'s summary).
    pub summary: Value,
    pub truth: TruthEntry,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub gbuffer_seconds: f64,
    /// Methods that could not run on the scene, and why.
    pub refused: Vec<String>,
}

/// The ground truth of one scene.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TruthEntry {
    pub spp: u32,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub seconds: f64,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub rays_per_second: f64,
    #[serde(deserialize_with = "crate::output::nan_if_null")]
    pub bvh_build_seconds: f64,
    pub stats: Value,
    /// Its EXR, relative to the bench JSON's folder.
    pub image: String,
}

/// One method on one scene.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ResultRow {
    pub scene: String,
    #[serde(flatten)]
    pub row: MethodRow,
}

/// How the light moved in the flicker measurement.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct FlickerSettings {
    pub frames: usize,
    pub step_degrees: f64,
}

/// Every method's flicker on one scene.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SceneFlicker {
    pub scene: String,
    pub rows: Vec<FlickerRow>,
}

impl BenchDocument {
    /// Reads `path`; errors name the file and the JSON path of a missing or
    /// mistyped field.
    pub fn read(path: &Path) -> anyhow::Result<BenchDocument> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| anyhow::anyhow!("reading {}: {e}", path.display()))?;
        let de = &mut serde_json::Deserializer::from_str(&text);
        serde_path_to_error::deserialize(de).map_err(|e| {
            anyhow::anyhow!(
                "{}: not an `izb bench` document (field `{}`: {})",
                path.display(),
                e.path(),
                e.inner()
            )
        })
    }
}
