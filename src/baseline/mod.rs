//! Shadow-map baselines (Williams 1978, Reeves et al. 1987; [Shadow acne notes], [Shadow mapping mechanics], Agenjo 2020: paper-notes/references.md): what a user would pick
//! instead of the IZB, rendered into the same G-buffer and judged by the
//! same metrics.
//!
//! - `sm-R`: one tap, slope-scaled bias ([Shadow mapping mechanics]);
//! - `pcf3-R`, `pcf5-R`: 3×3 / 5×5 bilinear PCF with receiver-plane depth
//!   bias, one comparison depth per texel ([Shadow acne notes]'s Gather variant);
//! - `csmN-pcf3-R`: N cascaded maps on the IZB cascades' logarithmic splits,
//!   each fitted to its own receivers (Agenjo 2020, Lauritzen's sample
//!   distribution), 3×3 PCF;
//! - `pcss-R`: percentage-closer soft shadows (Fernando 2005) for area
//!   lights: a blocker search sized by the light, a penumbra estimate, a
//!   PCF disk of that size ([`pcss`]);
//! - `…+contact`: any of them with screen-space contact shadows
//!   ([`contact`]);
//! - `vsm-R`, `msm-R`, `esm-R`: variance (Donnelly & Lauritzen 2006),
//!   moment (Peters & Klein 2015) and exponential (Annen et al. 2008)
//!   shadow maps, blurred by a 9² Gaussian ([`moments`]).
//!
//! `R` is the side of each map in texels. The passes are
//! [`shadow_map::shadow_map`] and [`shadow_map::shadow_lookup`]; their
//! Vulkan twins are `crate::gpu::shadow_map` (see `paper-notes/baselines.md`).

pub mod contact;
pub mod moments;
pub mod pcss;
pub mod raster;
pub mod screen_frame;
pub mod shadow_map;
pub mod volumes;

use crate::cascades::CascadeCount;
use crate::cpu::{eye_relative_f32, light_setup, GridRequest};
use crate::gbuffer::{flags, GBuffer};
use crate::scene::Scene;
pub use shadow_map::Filter;
use std::fmt;
use std::time::Instant;

/// Largest map side accepted (8192² · 4 B = 256 MiB per cascade).
pub const MAX_MAP_SIDE: u32 = 8192;

/// Smallest side of a `pcss-R` map: its margin of
/// [`izb_contract::pcss::MAX_RADIUS_TEXELS`] texels on every side then
/// takes at most a quarter of the map.
pub const PCSS_MIN_SIDE: u32 = 8 * izb_contract::pcss::MAX_RADIUS_TEXELS;

/// One shadow-map configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ShadowMapSettings {
    pub filter: Filter,
    /// Texels per side of each cascade's map.
    pub side: u32,
    /// 1 for a single map.
    pub cascades: u32,
    /// `+contact`: screen-space contact shadows on top ([`contact`]).
    pub contact: bool,
}

impl ShadowMapSettings {
    /// Parses a method name: `sm-R`, `pcf3-R`, `pcf5-R`, `csmN-pcfK-R`,
    /// `pcss-R` (one map, R ≥ [`PCSS_MIN_SIDE`]), `vsm-R`, `msm-R`,
    /// `esm-R` (and their cascaded `csmN-…`).
    pub fn parse(full_name: &str) -> Result<ShadowMapSettings, String> {
        let (name, contact) = match full_name.strip_suffix("+contact") {
            Some(base) => (base, true),
            None => (full_name, false),
        };
        let bad = || {
            format!("`{name}` is not a shadow-map method (sm-R, pcf3-R, pcf5-R, csmN-pcfK-R, pcss-R, vsm-R, msm-R, esm-R, csmN-vsm-R, csmN-msm-R, csmN-esm-R, any of them +contact; R a side 16..={MAX_MAP_SIDE})")
        };
        let mut parts: Vec<&str> = name.split('-').collect();
        let side: u32 = parts.pop().and_then(|s| s.parse().ok()).ok_or_else(bad)?;
        if !(16..=MAX_MAP_SIDE).contains(&side) {
            return Err(bad());
        }
        let mut cascades = 1;
        if let Some(c) = parts.first().and_then(|p| p.strip_prefix("csm")) {
            cascades = c.parse().map_err(|_| bad())?;
            if !(1..=crate::cascades::MAX_CASCADES as u32).contains(&cascades) {
                return Err(bad());
            }
            parts.remove(0);
        }
        let filter = match parts.as_slice() {
            ["sm"] => Filter::OneTap,
            ["vsm"] => Filter::Vsm,
            ["msm"] => Filter::Msm,
            ["esm"] => Filter::Esm,
            ["pcss"] => {
                if cascades > 1 {
                    return Err(format!(
                        "`{name}`: PCSS runs on one map (pcss-R); cascaded PCSS is not offered"
                    ));
                }
                if side < PCSS_MIN_SIDE {
                    return Err(format!(
                        "`{name}`: pcss-R needs R ≥ {PCSS_MIN_SIDE}: the map keeps a margin of {} texels \
                         on every side for the widest blocker search",
                        Filter::Pcss.reach()
                    ));
                }
                Filter::Pcss
            }
            [p] => match p.strip_prefix("pcf").and_then(|k| k.parse::<u32>().ok()) {
                Some(k) if k % 2 == 1 && (3..=9).contains(&k) => Filter::Pcf(k),
                _ => return Err(bad()),
            },
            _ => return Err(bad()),
        };
        Ok(ShadowMapSettings {
            filter,
            side,
            cascades,
            contact,
        })
    }
}

impl fmt::Display for ShadowMapSettings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.cascades > 1 {
            write!(f, "csm{}-", self.cascades)?;
        }
        match self.filter {
            Filter::OneTap => write!(f, "sm-{}", self.side),
            Filter::Pcf(k) => write!(f, "pcf{k}-{}", self.side),
            Filter::Pcss => write!(f, "pcss-{}", self.side),
            Filter::Vsm => write!(f, "vsm-{}", self.side),
            Filter::Msm => write!(f, "msm-{}", self.side),
            Filter::Esm => write!(f, "esm-{}", self.side),
        }?;
        if self.contact {
            write!(f, "+contact")?;
        }
        Ok(())
    }
}

/// CPU seconds of the baseline's passes (the G-buffer is shared with the
/// IZB and not counted).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct BaselineSeconds {
    pub light_setup: f64,
    pub shadow_map: f64,
    pub shadow_lookup: f64,
    /// The three together: comparable with the IZB's shadow passes.
    pub shadow: f64,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct BaselineReport {
    pub settings: ShadowMapSettings,
    pub seconds: BaselineSeconds,
    pub map_bytes: u64,
    pub triangles_drawn: usize,
    pub texels_written: u64,
    /// Cascades actually used (a point light whose receivers surround it
    /// cannot be one frustum: the method is refused then).
    pub cascades: usize,
}

pub struct BaselineRender {
    /// Lit fraction per pixel, NaN where not shadow-tested.
    pub visibility: Vec<f32>,
    pub report: BaselineReport,
}

/// Renders `settings` on the CPU into the G-buffer `g` of `scene`.
pub fn render_shadow_map(
    scene: &Scene,
    g: &GBuffer,
    settings: ShadowMapSettings,
) -> Result<BaselineRender, String> {
    let start = Instant::now();
    let setup = light_setup(
        scene,
        g,
        GridRequest {
            cells: Some(8),
            level_cells: None,
            cascades: CascadeCount::Fixed(settings.cascades),
            split_lambda: 1.0,
            simd: crate::cpu::simd::SimdPath::detected(),
        },
    );
    if setup.grid_disabled {
        return Err(format!(
            "{settings} on {}: the receivers surround the point light, which one shadow-map frustum cannot hold (a cube map would)",
            scene.name
        ));
    }
    let light_setup_s = start.elapsed().as_secs_f64();
    let t = Instant::now();
    let triangles = eye_relative_f32(scene);
    let pcss_light = pcss::PcssLight::new(scene, triangles.iter().flatten().copied());
    let mut maps = shadow_map::shadow_map(&setup, &triangles, settings.side, settings.filter);
    if let Some(kind) = settings.filter.moments() {
        maps.moments = moments::shadow_blur(&setup, &maps, kind);
    }
    let shadow_map_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let visibility = if g.flags.iter().any(|f| f & flags::SHADOW_TESTED != 0) {
        let mut lit = shadow_map::shadow_lookup(&setup, &maps, g, settings.filter, &pcss_light);
        if settings.contact {
            contact::contact_shadows(scene, &setup, &maps, g, &mut lit);
        }
        lit
    } else {
        vec![f32::NAN; g.flags.len()]
    };
    let lookup_s = t.elapsed().as_secs_f64();
    Ok(BaselineRender {
        visibility,
        report: BaselineReport {
            settings,
            seconds: BaselineSeconds {
                light_setup: light_setup_s,
                shadow_map: shadow_map_s,
                shadow_lookup: lookup_s,
                shadow: start.elapsed().as_secs_f64(),
            },
            map_bytes: maps.bytes(),
            triangles_drawn: maps.triangles_drawn,
            texels_written: maps.texels_written,
            cascades: setup.cascades.len(),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_names_round_trip() {
        for name in [
            "sm-512",
            "pcf3-2048",
            "pcf5-8192",
            "csm4-pcf3-1024",
            "csm2-pcf5-64",
            "csm3-sm-256",
            "pcss-512",
            "pcss-2048",
            "vsm-1024",
            "msm-512+contact",
            "esm-2048",
            "csm2-esm-256",
        ] {
            let s = ShadowMapSettings::parse(name).unwrap();
            assert_eq!(s.to_string(), name);
        }
        for bad in [
            "sm",
            "pcf4-512",
            "sm-99999",
            "csm9-pcf3-512",
            "csm2-pcf-512",
            "izb32",
            "pcf3-x",
            "pcss-256",
            "csm2-pcss-1024",
            "pcss",
        ] {
            assert!(ShadowMapSettings::parse(bad).is_err(), "{bad} parsed");
        }
    }
}
