//! Scenes: the world-space triangle soup, the camera and the light.
//!
//! Conventions (README, Conventions): right-handed, +Y up, the camera looks along -Z in
//! view space; pixel (x, y) has x to the right and y down, its centre at
//! (x + 0.5, y + 0.5). World positions are kept in `f64` so that a scene
//! 1e5 units from the origin keeps its sub-millimetre detail; everything that
//! later goes to `f32` is made relative to the camera first
//! ([`Scene::eye_relative_triangles`]).

mod camera;
pub mod envelope;
#[cfg(feature = "cli")]
mod gltf_load;
mod light;
pub mod procedural;
mod spec;
mod watertight_ray;

pub use camera::{Camera, CameraFrame};
#[cfg(feature = "cli")]
pub use gltf_load::{load_gltf, load_gltf_bytes};

/// Triangles read from a glTF file, before degenerate ones are dropped.
#[derive(Debug, Default)]
pub struct GltfMeshes {
    /// World-space triangles in traversal order (the stable source id is the
    /// index here).
    pub triangles: Vec<Triangle>,
    pub skipped_non_triangle_primitives: usize,
    pub warnings: Vec<String>,
}

/// Without the `cli` feature (the pass alone) there is no glTF loader: a
/// scene naming a glTF file is refused by name.
#[cfg(not(feature = "cli"))]
pub fn load_gltf(path: &Path) -> Result<GltfMeshes, SceneError> {
    Err(SceneError::Gltf {
        path: path.display().to_string(),
        message: "this build has no glTF loader (it is part of the `cli` feature)".into(),
    })
}
pub use light::{light_disk, light_disk_f32, Light, LightDisk, MAX_ANGULAR_RADIUS_DEG};
pub(crate) use spec::check_resolution;
pub use spec::{CameraSpec, LightSpec, SceneSpec, MAX_RESOLUTION};
pub use watertight_ray::WatertightRay;

use glam::DVec3;
use std::path::Path;
use std::sync::Arc;

/// One triangle in world space, `f64`.
pub type Triangle = [DVec3; 3];

/// Why a scene could not be built. Every variant names the offending input.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The OS error is part of the message, not a `source` (a chain
    /// printer would repeat it).
    #[error("{path}: cannot read: {cause}")]
    Io { path: String, cause: std::io::Error },
    #[error("{path}: invalid scene spec: {message}")]
    Spec { path: String, message: String },
    #[error("{path}: invalid glTF: {message}")]
    Gltf { path: String, message: String },
    #[error("{0}")]
    Invalid(String),
    #[error(
        "unknown scene '{0}': expected a scene spec path (*.scene.json) or one of the \
         procedural scenes: {names}",
        names = procedural::NAMES.join(", ")
    )]
    Unknown(String),
}

/// Counts gathered while flattening the source geometry.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct GeometryStats {
    /// Triangles in the source (index count / 3 per primitive instance,
    /// strips and fans converted), before dropping degenerate ones.
    pub source_triangles: usize,
    /// Zero-area or collinear triangles that were dropped (they cannot cast a
    /// shadow and have no normal to shade with).
    pub dropped_degenerate: usize,
    /// Primitives with point or line topology that were skipped.
    pub skipped_non_triangle_primitives: usize,
    /// Copies of one triangle past the first [`MAX_COINCIDENT`] (the same
    /// three vertices in any order), dropped: they add no shadow and no
    /// surface, and the BVH builder's time grew with the square of such a
    /// group (20 000 copies: 11 s; 30 000 overflowed its stack).
    pub dropped_coincident: usize,
}

/// Copies of one triangle a scene keeps (a double-sided mesh has two).
pub const MAX_COINCIDENT: u32 = 64;

/// Drops the copies of any triangle past its first [`MAX_COINCIDENT`]
/// (in id order). Keys are computed in parallel and counted in a table of
/// saturating counters indexed by the key: a group of more than
/// [`MAX_COINCIDENT`] copies overfills its bucket, so when no bucket does
/// (every ordinary scene) nothing is sorted at all (courtyard's load:
/// +0.08 s for sorting every key, ~+0.01 s for the table). Only the keys
/// of overfull buckets are sorted to find the real groups, and only their
/// keys are then looked up per triangle.
fn drop_coincident_copies(
    triangles: &mut Vec<Triangle>,
    source_ids: &mut Vec<u32>,
    stats: &mut GeometryStats,
) {
    use rayon::prelude::*;
    let keys: Vec<u64> = triangles.par_iter().map(coincidence_key).collect();
    // The key's top bits: the multiply mixes into them best.
    let bits = (2 * keys.len())
        .next_power_of_two()
        .max(64)
        .trailing_zeros();
    let bucket = |key: u64| (key >> (64 - bits)) as usize;
    let mut counts = vec![0u8; 1 << bits];
    for &key in &keys {
        let c = &mut counts[bucket(key)];
        *c = c.saturating_add(1);
    }
    let overfull = |key: u64| counts[bucket(key)] as u32 > MAX_COINCIDENT;
    let mut sorted: Vec<u64> = keys.iter().copied().filter(|&k| overfull(k)).collect();
    if sorted.is_empty() {
        return;
    }
    sorted.par_sort_unstable();
    let heavy: std::collections::HashMap<u64, u32> = sorted
        .chunk_by(|a, b| a == b)
        .filter(|run| run.len() > MAX_COINCIDENT as usize)
        .map(|run| (run[0], 0))
        .collect();
    if heavy.is_empty() {
        return;
    }
    let mut seen = heavy;
    let keep: Vec<bool> = keys
        .iter()
        .map(|key| match seen.get_mut(key) {
            Some(n) if *n >= MAX_COINCIDENT => false,
            Some(n) => {
                *n += 1;
                true
            }
            None => true,
        })
        .collect();
    let mut kept = keep.iter();
    triangles.retain(|_| *kept.next().expect("a flag per triangle"));
    let mut kept = keep.iter();
    source_ids.retain(|_| *kept.next().expect("a flag per triangle"));
    stats.dropped_coincident = keep.iter().filter(|&&k| !k).count();
}

/// The key of a triangle's vertex set: each vertex's coordinate bits
/// mixed into 64 bits (multiply-rotate, as FxHash), the three sorted
/// (three compare-swaps: any vertex order gives one key) and mixed again.
/// A collision of 64 distinct triangles is not a practical concern.
/// SipHash through a `HashMap` cost courtyard's load 0.33 s; sorting the
/// nine coordinates with `sort_unstable` ~0.04 s.
fn coincidence_key(t: &Triangle) -> u64 {
    const K: u64 = 0x51_7c_c1_b7_27_22_0a_95;
    let mix = |h: u64, w: u64| (h.rotate_left(5) ^ w).wrapping_mul(K);
    let [mut a, mut b, mut c] = t.map(|v| v.to_array().map(f64::to_bits).into_iter().fold(0, mix));
    if a > b {
        std::mem::swap(&mut a, &mut b);
    }
    if b > c {
        std::mem::swap(&mut b, &mut c);
    }
    if a > b {
        std::mem::swap(&mut a, &mut b);
    }
    [a, b, c].into_iter().fold(0, mix)
}

/// A scene ready to render: triangles, camera, light and image size.
#[derive(Clone, Debug)]
pub struct Scene {
    pub name: String,
    /// Non-degenerate world-space triangles. The index into this array is the
    /// triangle id used by every pass. Shared, never changed in place: a
    /// scene seen from another camera or light (the viewer's every frame)
    /// is a clone that copies no triangle.
    pub triangles: Arc<[Triangle]>,
    /// For each triangle, its index in the flattened source array (before
    /// degenerate triangles were dropped): a stable id across runs.
    pub source_ids: Arc<[u32]>,
    pub stats: GeometryStats,
    pub camera: Camera,
    pub light: Light,
    /// The light's size: the angular radius in radians of a directional
    /// light's disk (spec: `angular_radius_deg`), the radius of a point
    /// light's sphere (spec: `radius`). 0, the default, is a point-like
    /// light: hard shadows, every pass exactly as without this field.
    pub light_radius: f64,
    /// Image width and height in pixels.
    pub resolution: [u32; 2],
    /// Warnings from loading (skipped primitives, ...), printed once by the CLI.
    pub warnings: Vec<String>,
}

impl Scene {
    /// Assembles a scene from raw triangles, dropping degenerate ones and
    /// validating camera, light and resolution.
    pub fn new(
        name: impl Into<String>,
        triangles: Vec<Triangle>,
        camera: Camera,
        light: Light,
        resolution: [u32; 2],
    ) -> Result<Self, SceneError> {
        let mut stats = GeometryStats {
            source_triangles: triangles.len(),
            ..Default::default()
        };
        let mut kept = Vec::with_capacity(triangles.len());
        let mut source_ids = Vec::with_capacity(triangles.len());
        for (id, tri) in triangles.into_iter().enumerate() {
            if let Some(bad) = tri.iter().find(|v| !v.is_finite()) {
                return Err(SceneError::Invalid(format!(
                    "triangle {id} has a non-finite vertex position {bad}"
                )));
            }
            if is_degenerate(&tri) {
                stats.dropped_degenerate += 1;
                continue;
            }
            kept.push(tri);
            source_ids.push(id as u32);
        }
        drop_coincident_copies(&mut kept, &mut source_ids, &mut stats);
        let warnings = if stats.dropped_coincident > 0 {
            vec![format!(
                "{} copies of coincident triangles dropped (at most {MAX_COINCIDENT} of each kept)",
                stats.dropped_coincident
            )]
        } else {
            Vec::new()
        };
        let scene = Scene {
            name: name.into(),
            triangles: kept.into(),
            source_ids: source_ids.into(),
            stats,
            camera,
            light,
            light_radius: 0.0,
            resolution,
            warnings,
        };
        scene.validate()?;
        Ok(scene)
    }

    /// Checks everything a renderer relies on; called by every constructor.
    /// The scene as reports record it: name, size, counts, camera, light.
    pub fn summary(&self) -> serde_json::Value {
        serde_json::json!({
            "name": self.name,
            "resolution": self.resolution,
            "triangles": self.triangles.len(),
            "source_triangles": self.stats.source_triangles,
            "dropped_degenerate_triangles": self.stats.dropped_degenerate,
            "dropped_coincident_triangles": self.stats.dropped_coincident,
            "skipped_non_triangle_primitives": self.stats.skipped_non_triangle_primitives,
            "camera": self.camera,
            "light": self.light,
            "light_radius": self.light_radius,
        })
    }

    pub fn validate(&self) -> Result<(), SceneError> {
        if self.triangles.is_empty() {
            // Every triangle collapsing is also what coordinates far beyond
            // the f64 range of their detail look like.
            let far = self.camera.eye.length() > 1e15;
            return Err(SceneError::Invalid(format!(
                "scene '{}' has no triangles ({} in the source, {} degenerate dropped{})",
                self.name,
                self.stats.source_triangles,
                self.stats.dropped_degenerate,
                if far {
                    "; the camera is beyond 1e15 units from the origin, where f64 coordinates \
                     round away a scene's detail"
                } else {
                    ""
                }
            )));
        }
        self.validate_view(self.bounds())
    }

    /// What [`Self::validate`] checks of the view — resolution, camera,
    /// light and its size, the precision envelope — with the triangles'
    /// `bounds` known: a resident scene's new camera or light.
    pub fn validate_view(&self, bounds: (DVec3, DVec3)) -> Result<(), SceneError> {
        spec::check_resolution(self.resolution).map_err(SceneError::Invalid)?;
        self.camera.validate().map_err(SceneError::Invalid)?;
        self.light.validate().map_err(SceneError::Invalid)?;
        let radius = self.light_radius;
        let spec_units = match self.light {
            Light::Directional { .. } => radius.to_degrees(),
            Light::Point { .. } => radius,
        };
        self.light
            .validate_size(spec_units)
            .map_err(SceneError::Invalid)?;
        let (lo, hi) = bounds;
        self.light
            .validate_sphere_size(radius, (hi - lo).length() * 0.5)
            .map_err(SceneError::Invalid)?;
        envelope::check_within(self, bounds).map_err(SceneError::Invalid)?;
        Ok(())
    }

    /// Same scene under a light of another size, in the spec's units
    /// (`--light-size`: degrees for a directional light, scene units for
    /// a point light; 0 for hard shadows).
    pub fn with_light_size(self, size: f64) -> Result<Self, SceneError> {
        let bounds = self.bounds();
        self.with_light_size_in(size, bounds)
    }

    /// [`Self::with_light_size`] with the triangles' `bounds` known (a
    /// resident scene's: no pass over its triangles).
    pub fn with_light_size_in(
        mut self,
        size: f64,
        bounds: (DVec3, DVec3),
    ) -> Result<Self, SceneError> {
        self.light
            .validate_size(size)
            .map_err(|m| SceneError::Invalid(format!("--light-size: {m}")))?;
        let radius = self.light.radius_from_spec(size);
        self.light
            .validate_sphere_size(radius, (bounds.1 - bounds.0).length() * 0.5)
            .map_err(|m| SceneError::Invalid(format!("--light-size: {m}")))?;
        self.light_radius = radius;
        Ok(self)
    }

    /// Whether the light has a size: soft shadows.
    pub fn has_area_light(&self) -> bool {
        self.light_radius > 0.0
    }

    /// Same scene at another image size (the CLI's `--resolution`).
    pub fn with_resolution(mut self, resolution: [u32; 2]) -> Result<Self, SceneError> {
        spec::check_resolution(resolution).map_err(SceneError::Invalid)?;
        self.resolution = resolution;
        Ok(self)
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.resolution[0] as usize * self.resolution[1] as usize
    }

    /// Triangles relative to the camera position, computed in `f64`: the
    /// only form in which coordinates may be rounded to `f32` (paper-notes/frustum-test.md).
    pub fn eye_relative_triangles(&self) -> Vec<Triangle> {
        let eye = self.camera.eye;
        self.triangles
            .iter()
            .map(|t| [t[0] - eye, t[1] - eye, t[2] - eye])
            .collect()
    }

    /// Half the diagonal of [`Self::bounds`].
    pub fn radius(&self) -> f64 {
        let (lo, hi) = self.bounds();
        (hi - lo).length() * 0.5
    }

    /// World-space bounds of all triangles.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for v in self.triangles.iter().flatten() {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
        (lo, hi)
    }

    /// Moves the whole scene (geometry, camera, point light) by `offset`.
    pub fn translated(mut self, offset: DVec3) -> Self {
        self.triangles = self
            .triangles
            .iter()
            .map(|t| t.map(|v| v + offset))
            .collect();
        self.camera.eye += offset;
        self.camera.target += offset;
        if let Light::Point { position } = &mut self.light {
            *position += offset;
        }
        self
    }
}

/// A triangle is degenerate when its height over its longest edge is below
/// `4 ε32` of that edge: its normal is then decided by the rounding of the
/// `f32` input (glTF stores `f32`), so it has no well-defined plane and can
/// neither be shaded nor cast a shadow distinguishable from its neighbours'.
/// The test is relative to the triangle's own extent, never its distance
/// from the origin, so translating a scene does not change what is dropped.
pub fn is_degenerate(tri: &Triangle) -> bool {
    let e0 = tri[1] - tri[0];
    let e1 = tri[2] - tri[0];
    let e2 = tri[2] - tri[1];
    let twice_area = e0.cross(e1).length();
    let longest = e0.length().max(e1.length()).max(e2.length());
    if twice_area == 0.0 || longest == 0.0 || !twice_area.is_finite() {
        return true;
    }
    let height = twice_area / longest;
    height <= 4.0 * f32::EPSILON as f64 * longest
}

/// Loads a scene from a command-line argument: a procedural scene name or a
/// path to a `*.scene.json` spec.
pub fn load(arg: &str) -> Result<Scene, SceneError> {
    if let Some(scene) = procedural::build(arg)? {
        return Ok(scene);
    }
    let path = Path::new(arg);
    let looks_like_path = arg.ends_with(".json") || arg.contains('/') || path.exists();
    if !looks_like_path {
        return Err(SceneError::Unknown(arg.to_string()));
    }
    SceneSpec::load(path)?.build()
}
