//! The scene spec file (`*.scene.json`, README, Conventions).

use super::{Camera, Light, Scene, SceneError};
use glam::DVec3;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Largest accepted image side. Beyond it a 32-bit mask image alone would
/// exceed 1 GiB, and GPU image limits are commonly 16384.
pub const MAX_RESOLUTION: u32 = 16384;

/// A parsed `*.scene.json`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneSpec {
    /// glTF file (`.gltf` or `.glb`), relative to the spec file.
    pub gltf: Option<String>,
    /// Name of a built-in procedural scene providing the geometry.
    pub procedural: Option<String>,
    pub camera: CameraSpec,
    pub light: LightSpec,
    #[serde(deserialize_with = "exactly")]
    pub resolution: [u32; 2],
    /// The file this spec was read from (for relative paths and messages).
    #[serde(skip)]
    pub path: PathBuf,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    #[serde(deserialize_with = "exactly")]
    pub eye: [f64; 3],
    #[serde(deserialize_with = "exactly")]
    pub target: [f64; 3],
    #[serde(default = "default_up", deserialize_with = "exactly")]
    pub up: [f64; 3],
    pub fov_y_deg: f64,
    pub near: f64,
    pub far: f64,
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum LightSpec {
    Directional {
        #[serde(deserialize_with = "exactly")]
        direction: [f64; 3],
        /// The sun as a disk of this angular radius around `direction`
        /// (degrees; the real sun: 0.27). Absent or 0: hard shadows.
        #[serde(default)]
        angular_radius_deg: f64,
    },
    Point {
        #[serde(deserialize_with = "exactly")]
        position: [f64; 3],
        /// A sphere light of this radius. Absent or 0: hard shadows.
        #[serde(default)]
        radius: f64,
    },
}

/// A fixed-length array field that says how many numbers it wants:
/// serde's own message for a longer array is serde_json's "trailing
/// characters".
fn exactly<'de, D, T, const N: usize>(deserializer: D) -> Result<[T; N], D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de>,
{
    let values = Vec::<T>::deserialize(deserializer)?;
    let n = values.len();
    values
        .try_into()
        .map_err(|_| serde::de::Error::custom(format!("expected an array of {N} numbers, got {n}")))
}

pub(crate) fn check_resolution(resolution: [u32; 2]) -> Result<(), String> {
    let [w, h] = resolution;
    if w == 0 || h == 0 || w > MAX_RESOLUTION || h > MAX_RESOLUTION {
        return Err(format!(
            "resolution {w}x{h} is out of range: each side must be in 1..={MAX_RESOLUTION}"
        ));
    }
    Ok(())
}

impl CameraSpec {
    pub fn to_camera(&self) -> Camera {
        Camera {
            eye: DVec3::from(self.eye),
            target: DVec3::from(self.target),
            up: DVec3::from(self.up),
            fov_y_deg: self.fov_y_deg,
            near: self.near,
            far: self.far,
        }
    }
}

impl LightSpec {
    /// The light's size as written: degrees or scene units.
    pub fn size(&self) -> f64 {
        match self {
            LightSpec::Directional {
                angular_radius_deg, ..
            } => *angular_radius_deg,
            LightSpec::Point { radius, .. } => *radius,
        }
    }

    pub fn to_light(&self) -> Light {
        match self {
            LightSpec::Directional { direction, .. } => Light::directional(DVec3::from(*direction)),
            LightSpec::Point { position, .. } => Light::Point {
                position: DVec3::from(*position),
            },
        }
    }
}

impl SceneSpec {
    /// Reads and parses a spec file. Errors name the file and the JSON path
    /// of the offending field (e.g. `camera.eye`).
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|cause| SceneError::Io {
            path: path.display().to_string(),
            cause,
        })?;
        let mut spec = Self::parse(&text).map_err(|message| SceneError::Spec {
            path: path.display().to_string(),
            message,
        })?;
        spec.path = path.to_path_buf();
        Ok(spec)
    }

    /// Parses spec text; the error names the field and what was expected.
    pub fn parse(text: &str) -> Result<Self, String> {
        // A byte-order mark, as some Windows editors write one, is no JSON.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let de = &mut serde_json::Deserializer::from_str(text);
        serde_path_to_error::deserialize(de).map_err(|e| {
            let field = e.path().to_string();
            let inner = e.into_inner();
            if field == "." {
                inner.to_string()
            } else {
                format!("field `{field}`: {inner}")
            }
        })
    }

    /// Builds the scene this spec describes: loads its glTF (or procedural
    /// geometry) and validates camera, light and resolution.
    pub fn build(&self) -> Result<Scene, SceneError> {
        let spec_error = |message: String| SceneError::Spec {
            path: self.path.display().to_string(),
            message,
        };
        check_resolution(self.resolution)
            .map_err(|m| spec_error(format!("field `resolution`: {m}")))?;
        let camera = self.camera.to_camera();
        camera.validate().map_err(spec_error)?;
        let light = self.light.to_light();
        light.validate().map_err(spec_error)?;
        light.validate_size(self.light.size()).map_err(spec_error)?;
        let light_radius = light.radius_from_spec(self.light.size());
        let name = self
            .path
            .file_name()
            .map(|n| {
                n.to_string_lossy()
                    .trim_end_matches(".scene.json")
                    .to_string()
            })
            .unwrap_or_else(|| "spec".into());
        match (&self.gltf, &self.procedural) {
            (Some(gltf), None) => {
                let base = self.path.parent().unwrap_or(Path::new("."));
                let meshes = super::load_gltf(&base.join(gltf))?;
                let mut scene = Scene::new(name, meshes.triangles, camera, light, self.resolution)?;
                scene.light_radius = light_radius;
                scene.validate()?;
                scene.stats.skipped_non_triangle_primitives = meshes.skipped_non_triangle_primitives;
                scene.warnings.extend(meshes.warnings);
                Ok(scene)
            }
            (None, Some(procedural)) => {
                let geometry = super::procedural::geometry(procedural).ok_or_else(|| {
                    spec_error(format!(
                        "field `procedural`: unknown procedural scene '{procedural}', expected one of {}",
                        super::procedural::NAMES.join(", ")
                    ))
                })?;
                let mut scene = Scene::new(name, geometry, camera, light, self.resolution)?;
                scene.light_radius = light_radius;
                scene.validate()?;
                Ok(scene)
            }
            (Some(_), Some(_)) => Err(spec_error(
                "fields `gltf` and `procedural` are exclusive: give one".into(),
            )),
            (None, None) => Err(spec_error(
                "no geometry: expected field `gltf` (a .gltf/.glb path) or `procedural` (a scene name)"
                    .into(),
            )),
        }
    }
}
