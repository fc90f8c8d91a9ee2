//! The methods `izb bench` measures, and how a list of names becomes them.

use crate::baseline::ShadowMapSettings;
use crate::settings::{IzbSettings, SampleMode};

/// What a benchmarked method is.
#[derive(Clone, Copy, Debug)]
pub enum MethodKind {
    Izb(IzbSettings),
    /// The 32 µQuad samples traced exactly; with `edge_surfaces` each
    /// edge pixel's samples on their own surfaces
    /// ([`crate::reference::same_samples::edge_same_sample_masks`]).
    RayTraced32 {
        edge_surfaces: bool,
    },
    /// The 32 µQuad samples' shadow rays traced by Embree.
    Embree32,
    /// The 32 µQuad samples' shadow rays through a BVH (Vulkan pass or its
    /// CPU twin).
    ShadowRays32,
    ShadowMap(ShadowMapSettings),
    /// Per-triangle shadow volumes, depth-fail stencil counting
    /// ([`crate::baseline::volumes`]).
    ShadowVolumes,
}

impl MethodKind {
    /// The family a report groups by.
    pub fn family(&self) -> &'static str {
        match self {
            MethodKind::Izb(_) => "izb",
            MethodKind::RayTraced32 { .. } | MethodKind::Embree32 | MethodKind::ShadowRays32 => {
                "ray-traced"
            }
            MethodKind::ShadowMap(_) => "shadow-map",
            MethodKind::ShadowVolumes => "shadow-volume",
        }
    }

    /// Whether the method's masks place edge pixels' samples on their own
    /// surfaces in `scene`.
    pub(super) fn edge_surfaces(&self, scene: &crate::scene::Scene) -> bool {
        match self {
            MethodKind::Izb(s) => s.uses_edge_surfaces(scene),
            MethodKind::RayTraced32 { edge_surfaces } => *edge_surfaces && !scene.has_area_light(),
            _ => false,
        }
    }

    /// Whether the method produces 32-sample masks (compared sample by
    /// sample with `rt32`).
    pub(super) fn masks_32(&self) -> bool {
        match self {
            // Paired masks are over other rays than rt32 / rt-soft traces.
            MethodKind::Izb(s) => matches!(s.mode, SampleMode::Lut32 | SampleMode::Exact32),
            MethodKind::RayTraced32 { .. } | MethodKind::Embree32 | MethodKind::ShadowRays32 => {
                true
            }
            MethodKind::ShadowMap(_) | MethodKind::ShadowVolumes => false,
        }
    }
}

/// A named method to measure.
#[derive(Clone, Debug)]
pub struct Method {
    pub name: String,
    pub kind: MethodKind,
}

/// The default shadow-map sides `shadow-maps` expands over.
pub const DEFAULT_MAP_SIDES: [u32; 5] = [512, 1024, 2048, 4096, 8192];

/// Parses a method list. `shadow-maps` expands to `sm`, `pcf3`, `pcf5`,
/// `csm4-pcf3`, `vsm`, `msm` and `pcf3-…+contact` at every side of
/// `map_sides` (not `pcss`: under a hard light
/// it is only a narrow PCF; name `pcss-R` to time it); `reference` (the
/// ground truth's own timing) is always measured and skipped here.
pub fn parse_methods(
    names: &[String],
    map_sides: &[u32],
    izb: IzbSettings,
) -> Result<Vec<Method>, String> {
    let mut out = Vec::new();
    for name in names {
        let name = name.trim();
        // `-flat`: every sample on the pixel centre's µQuad (no edge
        // surfaces), for comparison with the default.
        let (name, flat) = match name.strip_suffix("-flat") {
            Some(base) if base.starts_with("izb") || base == "rt32" => (base, true),
            _ => (name, false),
        };
        let suffix = if flat { "-flat" } else { "" };
        let izb_mode = |mode| {
            MethodKind::Izb(IzbSettings {
                mode,
                edge_surfaces: izb.edge_surfaces && !flat,
                ..izb
            })
        };
        let izb_name = format!("{name}{suffix}");
        match name {
            "reference" => {}
            "izb1" => out.push((izb_name.clone(), izb_mode(SampleMode::One))),
            "izb32" => out.push((izb_name.clone(), izb_mode(SampleMode::Lut32))),
            "izb32-exact" => out.push((izb_name.clone(), izb_mode(SampleMode::Exact32))),
            "izb32-paired" => out.push((izb_name.clone(), izb_mode(SampleMode::Paired32))),
            "izb64-paired" => out.push((izb_name.clone(), izb_mode(SampleMode::Paired64))),
            // Under an area light the same-sample reference traces the
            // 32 light samples (`rt-soft`); the two names are one method.
            "rt32" | "rt-soft" => out.push((
                izb_name.clone(),
                MethodKind::RayTraced32 {
                    edge_surfaces: izb.edge_surfaces && !flat,
                },
            )),
            "rt32-rays" => out.push((name.to_string(), MethodKind::ShadowRays32)),
            "volumes" => out.push((name.to_string(), MethodKind::ShadowVolumes)),
            "rt32-embree" if cfg!(feature = "embree") => {
                out.push((name.to_string(), MethodKind::Embree32))
            }
            "rt32-embree" => {
                return Err("rt32-embree needs izb built with `--features embree` \
                            (and Debian's libembree-dev)"
                    .into())
            }
            "shadow-maps" => {
                for &side in map_sides {
                    let names = ["sm", "pcf3", "pcf5", "csm4-pcf3", "vsm", "msm", "pcf3"]
                        .iter()
                        .zip(["", "", "", "", "", "", "+contact"]);
                    for (prefix, suffix) in names {
                        let n = format!("{prefix}-{side}{suffix}");
                        out.push((
                            n.clone(),
                            MethodKind::ShadowMap(ShadowMapSettings::parse(&n)?),
                        ));
                    }
                }
            }
            other => out.push((
                other.to_string(),
                MethodKind::ShadowMap(ShadowMapSettings::parse(other).map_err(|e| {
                    format!(
                        "{e}; or one of reference, izb1, izb32, izb32-exact, izb32-paired, izb64-paired \
                         (each also as …-flat: no edge surfaces), rt32, rt-soft, rt32-rays, \
                         rt32-embree, volumes, shadow-maps"
                    )
                })?),
            )),
        }
    }
    Ok(out
        .into_iter()
        .map(|(name, kind)| Method { name, kind })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pcss_is_a_shadow_map_method() {
        let names = vec!["pcss-2048".to_string()];
        let methods = parse_methods(&names, &DEFAULT_MAP_SIDES, IzbSettings::default()).unwrap();
        assert_eq!(methods.len(), 1);
        assert_eq!(methods[0].name, "pcss-2048");
        assert_eq!(methods[0].kind.family(), "shadow-map");
        assert!(!methods[0].kind.masks_32());
        let err = parse_methods(
            &["pcss-128".to_string()],
            &DEFAULT_MAP_SIDES,
            IzbSettings::default(),
        )
        .unwrap_err();
        assert!(err.contains("pcss-128") && err.contains("512"), "{err}");
    }
}
