//! What the viewer shows: the camera orbit and light turn applied to the
//! loaded scene, the method(s), the view and the split. A frame is
//! recomputed when [`ViewState::shadow_key`] changes, the truth restarts
//! when [`ViewState::truth_key`] does.

use crate::bench::{parse_methods, MethodKind};
use crate::scene::{Light, Scene};
use crate::settings::IzbSettings;
use glam::DVec3;

/// The methods the viewer offers: every IZB mode, then each shadow-map
/// family (the side is a separate control, `map_side`), then the methods
/// without a size.
pub const IZB_METHODS: [&str; 5] = [
    "izb1",
    "izb32",
    "izb32-exact",
    "izb32-paired",
    "izb64-paired",
];
/// Shadow-map families, named `FAMILY-SIDE` (`paper-notes/baselines.md`).
pub const MAP_FAMILIES: [&str; 8] = [
    "sm",
    "pcf3",
    "pcf5",
    "csm4-pcf3",
    "pcss",
    "vsm",
    "msm",
    "esm",
];
/// Methods without a size: shadow volumes (`paper-notes/baselines.md`).
pub const OTHER_METHODS: [&str; 1] = ["volumes"];
/// Map sides the control steps through.
pub const MAP_SIDES: [u32; 5] = [512, 1024, 2048, 4096, 8192];

/// What each pixel of the image area shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewKind {
    /// Ambient + Lambert × lit fraction, as `render`'s `shaded.png`.
    Shaded,
    /// The lit fraction in grey, magenta where not shadow-tested.
    LitFraction,
    /// Candidate triangles per pixel (CPU twin's bins), log heat map.
    Candidates,
    /// |lit fraction − progressive truth|, heat map.
    Error,
}

impl ViewKind {
    pub const ALL: [ViewKind; 4] = [
        ViewKind::Shaded,
        ViewKind::LitFraction,
        ViewKind::Candidates,
        ViewKind::Error,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ViewKind::Shaded => "shaded",
            ViewKind::LitFraction => "lit fraction",
            ViewKind::Candidates => "candidates",
            ViewKind::Error => "error",
        }
    }

    /// The script's word for the view.
    pub fn parse(word: &str) -> Option<ViewKind> {
        match word {
            "shaded" => Some(ViewKind::Shaded),
            "lit" | "visibility" => Some(ViewKind::LitFraction),
            "candidates" | "heat" => Some(ViewKind::Candidates),
            "error" => Some(ViewKind::Error),
            _ => None,
        }
    }
}

/// Everything the user controls.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewState {
    /// Camera orbit about the scene camera's target: degrees about the
    /// up axis, degrees of elevation, and a distance factor.
    pub orbit: [f64; 3],
    /// Light turn: degrees about the up axis and of elevation, applied to
    /// the scene's light (a point light turns about the camera target).
    pub light_turn: [f64; 2],
    /// The light's size in the scene spec's unit (degrees of angular
    /// radius, or a point light's radius); 0: hard shadows.
    pub light_size: f64,
    pub method: String,
    /// The right half's method, `None` for a single view.
    pub split: Option<String>,
    /// The divider's position, as a fraction of the image width.
    pub divider: f32,
    pub view: ViewKind,
    /// Show the overlay of times, work counters, memory and error.
    pub overlay: bool,
    /// The light-size slider's end: 5° for a sun, 5 % of the scene's
    /// diagonal for a point light (computed once: the bounds visit every
    /// vertex).
    pub light_size_top: f64,
}

/// The state a shadow frame depends on.
#[derive(Clone, Debug, PartialEq)]
pub struct ShadowKey {
    pub orbit: [f64; 3],
    pub light_turn: [f64; 2],
    pub light_size: f64,
    pub methods: Vec<String>,
    pub candidates: bool,
}

impl ViewState {
    pub fn new(scene: &Scene) -> ViewState {
        ViewState {
            orbit: [0.0, 0.0, 1.0],
            light_turn: [0.0, 0.0],
            light_size: light_size_of(scene),
            method: "izb32".into(),
            split: None,
            divider: 0.5,
            view: ViewKind::Shaded,
            overlay: true,
            light_size_top: match scene.light {
                Light::Directional { .. } => 5.0,
                Light::Point { .. } => {
                    let (lo, hi) = scene.bounds();
                    (hi - lo).length() * 0.05
                }
            },
        }
    }

    /// The methods to render, left (or only) first.
    pub fn methods(&self) -> Vec<String> {
        std::iter::once(self.method.clone())
            .chain(self.split.clone())
            .collect()
    }

    pub fn shadow_key(&self) -> ShadowKey {
        ShadowKey {
            orbit: self.orbit,
            light_turn: self.light_turn,
            light_size: self.light_size,
            methods: self.methods(),
            candidates: self.view == ViewKind::Candidates,
        }
    }

    /// What the ground truth depends on: the scene as seen.
    pub fn truth_key(&self) -> ([f64; 3], [f64; 2], f64) {
        (self.orbit, self.light_turn, self.light_size)
    }

    /// `base` with the orbit, the light turn and the light size applied;
    /// `bounds` are `base`'s, computed once: the clone shares the
    /// triangles, so a new view costs no pass over them.
    pub fn scene(&self, base: &Scene, bounds: (DVec3, DVec3)) -> Result<Scene, String> {
        let mut scene = base.clone();
        let c = base.camera;
        let up = c.up.normalize();
        let [yaw, pitch, zoom] = self.orbit;
        let offset = turn(c.eye - c.target, up, yaw, pitch) * zoom;
        scene.camera.eye = c.target + offset;
        let [light_yaw, light_pitch] = self.light_turn;
        scene.light = match base.light {
            Light::Directional { direction } => {
                Light::directional(-turn(-direction, up, light_yaw, light_pitch))
            }
            Light::Point { position } => Light::Point {
                position: c.target + turn(position - c.target, up, light_yaw, light_pitch),
            },
        };
        scene = scene
            .with_light_size_in(self.light_size, bounds)
            .map_err(|e| e.to_string())?;
        scene.validate_view(bounds).map_err(|e| e.to_string())?;
        Ok(scene)
    }
}

/// The scene's light size in the spec's unit (degrees for a directional
/// light).
pub fn light_size_of(scene: &Scene) -> f64 {
    match scene.light {
        Light::Directional { .. } => scene.light_radius.to_degrees(),
        Light::Point { .. } => scene.light_radius,
    }
}

/// `v` turned by `yaw` degrees about `up`, then `pitch` degrees further up
/// (elevation clamped to ±89° so the camera never flips over the pole).
pub fn turn(v: DVec3, up: DVec3, yaw_deg: f64, pitch_deg: f64) -> DVec3 {
    let length = v.length();
    if length == 0.0 {
        return v;
    }
    let d = v / length;
    let elevation = d.dot(up).clamp(-1.0, 1.0).asin();
    let horizontal = d - up * d.dot(up);
    let e1 = if horizontal.length_squared() > 1e-12 {
        horizontal.normalize()
    } else {
        up.any_orthonormal_vector()
    };
    let e2 = up.cross(e1);
    let azimuth = yaw_deg.to_radians();
    let limit = 89f64.to_radians();
    let el = (elevation + pitch_deg.to_radians()).clamp(-limit, limit);
    (e1 * azimuth.cos() + e2 * azimuth.sin()) * el.cos() * length + up * el.sin() * length
}

/// A viewer method by name: an IZB mode or a shadow-map baseline (the
/// names `izb bench` takes).
pub fn method_kind(name: &str) -> Result<MethodKind, String> {
    // Edge pixels take their per-sample surfaces as in `izb render`;
    // `izb32-flat` keeps every sample on the centre's µQuad.
    let izb = IzbSettings {
        edge_surfaces: true,
        ..IzbSettings::default()
    };
    let methods = parse_methods(&[name.to_string()], &[], izb)?;
    match methods.as_slice() {
        [m] if matches!(
            m.kind,
            MethodKind::Izb(_) | MethodKind::ShadowMap(_) | MethodKind::ShadowVolumes
        ) =>
        {
            Ok(m.kind)
        }
        _ => Err(format!(
            "`{name}`: the viewer shows the IZB modes ({}), shadow maps (FAMILY-SIDE with \
             FAMILY one of {}) and {}",
            IZB_METHODS.join(", "),
            MAP_FAMILIES.join(", "),
            OTHER_METHODS.join(", ")
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turn_keeps_length_and_composes_about_the_up_axis() {
        let up = DVec3::Z;
        let v = DVec3::new(3.0, 0.0, 4.0);
        let t = turn(v, up, 90.0, 0.0);
        assert!((t - DVec3::new(0.0, 3.0, 4.0)).length() < 1e-12, "{t}");
        let t = turn(v, up, 0.0, 10.0);
        assert!((t.length() - 5.0).abs() < 1e-12);
        assert!(t.z > 4.0);
        // Past the pole the elevation stops at 89°.
        let t = turn(v, up, 0.0, 180.0);
        assert!((t.normalize().dot(up) - 89f64.to_radians().sin()).abs() < 1e-12);
    }

    #[test]
    fn viewer_methods_parse_and_others_are_refused() {
        let mut checked = 0;
        for name in IZB_METHODS {
            assert!(
                matches!(method_kind(name), Ok(MethodKind::Izb(_))),
                "{name}"
            );
            checked += 1;
        }
        for family in MAP_FAMILIES {
            for side in MAP_SIDES {
                let name = format!("{family}-{side}");
                assert!(
                    matches!(method_kind(&name), Ok(MethodKind::ShadowMap(_))),
                    "{name}"
                );
                checked += 1;
            }
        }
        assert!(matches!(
            method_kind("volumes"),
            Ok(MethodKind::ShadowVolumes)
        ));
        checked += 1;
        assert_eq!(checked, 46);
        assert!(method_kind("rt32").is_err());
        assert!(method_kind("izb7").is_err());
    }

    #[test]
    fn the_untouched_state_renders_the_scene_as_loaded() {
        let base = crate::scene::load("default").unwrap();
        let s = ViewState::new(&base).scene(&base, base.bounds()).unwrap();
        assert!((s.camera.eye - base.camera.eye).length() < 1e-9);
        match (s.light, base.light) {
            (Light::Directional { direction: a }, Light::Directional { direction: b }) => {
                assert!((a - b).length() < 1e-12)
            }
            (Light::Point { position: a }, Light::Point { position: b }) => {
                assert!((a - b).length() < 1e-9)
            }
            _ => panic!("light kind changed"),
        }
    }
}
