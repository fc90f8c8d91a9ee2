//! Work a render may skip because it cannot change any mask (Wyman et al. 2015
//! §6.5–6.6, [Compute IZB]'s culling), each behind its own switch so its effect
//! can be measured (`--skip all|none|name,name,…`) and each with a counter
//! in the report. Every skip is exact: `tests/skips_are_exact.rs` renders
//! every scene with all skips on and all off and requires bit-identical
//! masks, on both backends.

use izb_contract::skip;
use std::fmt;

/// Which exact shortcuts a render takes. `Default` is all of them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Skips {
    /// Pixels that face away from the light (N·L ≤ 0, Wyman et al. 2015, §6.5) are
    /// neither fitted, binned against nor tested: their lit fraction is 0
    /// by the shading model. Off: they are fitted and tested like any
    /// receiver, and their masks are then discarded.
    pub facing_away: bool,
    /// Triangles whose light-space box misses every cell (they cannot
    /// shadow any receiver) are dropped. Off: they join the overflow list
    /// that every pixel tests.
    pub outside_bounds: bool,
    /// A pixel stops testing once its mask is full (Wyman et al. 2015, §6.6).
    pub full_mask: bool,
    /// An occluder whose shadow prism contains or misses the whole µQuad
    /// takes the cheap path: one comparison per edge instead of a LUT read
    /// or 32 sample evaluations, and the remaining edges are not computed
    /// once one edge misses the µQuad. On the CPU a batched occluder whose
    /// edges, alone or two by two, provably leave no sample inside takes
    /// it too (`cpu::empty_certificate`).
    pub saturated_edges: bool,
    /// A cell does not list a triangle that lies behind (farther from the
    /// light than) every receiver that can test it there, nor anything at
    /// all when no receiver touches it (Wyman et al. 2015, §5.4): see
    /// [`crate::cpu::receiver_cull::behind_receivers`]; directional and point lights.
    pub behind_receivers: bool,
    /// The conservative shadow-map early-out (Tokuyoshi 2018, [Compute IZB]),
    /// exact by construction: the bin pass records per cell the triangle
    /// whose shadow covers the whole cell with the highest floor
    /// ([`crate::cpu::bin::cover_floor`]); a pixel tests that one first, with
    /// the ordinary test, and skips the rest of its loop when it alone
    /// fills the mask. Directional lights only.
    pub shadow_map: bool,
}

impl Default for Skips {
    fn default() -> Self {
        Skips::ALL
    }
}

/// One skip's name (as `--skip` spells it), its `SKIP_*` bit (the
/// contract's, by name) and its field.
type SkipField = (&'static str, u32, fn(&mut Skips) -> &mut bool);

const FIELDS: [SkipField; 6] = [
    ("facing-away", skip::FACING_AWAY, |s| &mut s.facing_away),
    ("outside-bounds", skip::OUTSIDE_BOUNDS, |s| {
        &mut s.outside_bounds
    }),
    ("full-mask", skip::FULL_MASK, |s| &mut s.full_mask),
    ("saturated-edges", skip::SATURATED_EDGES, |s| {
        &mut s.saturated_edges
    }),
    ("behind-receivers", skip::BEHIND_RECEIVERS, |s| {
        &mut s.behind_receivers
    }),
    ("shadow-map", skip::SHADOW_MAP, |s| &mut s.shadow_map),
];

impl Skips {
    pub const ALL: Skips = Skips {
        facing_away: true,
        outside_bounds: true,
        full_mask: true,
        saturated_edges: true,
        behind_receivers: true,
        shadow_map: true,
    };
    pub const NONE: Skips = Skips {
        facing_away: false,
        outside_bounds: false,
        full_mask: false,
        saturated_edges: false,
        behind_receivers: false,
        shadow_map: false,
    };

    /// Every skip's `--skip` name.
    pub fn names() -> impl Iterator<Item = &'static str> {
        FIELDS.iter().map(|(n, _, _)| *n)
    }

    /// Parses `all`, `none` or a comma-separated list of names.
    pub fn parse(text: &str) -> Result<Skips, String> {
        match text.trim() {
            "all" => return Ok(Skips::ALL),
            "none" | "" => return Ok(Skips::NONE),
            _ => {}
        }
        let mut skips = Skips::NONE;
        for name in text.split(',').map(str::trim) {
            if name == "all" || name == "none" {
                return Err(format!(
                    "{name:?} stands alone (--skip {name}), not in a list with other skips"
                ));
            }
            let (_, _, field) = FIELDS.iter().find(|(n, _, _)| *n == name).ok_or_else(|| {
                format!(
                    "unknown skip {name:?}: expected all, none or some of {}",
                    Skips::names().collect::<Vec<_>>().join(", ")
                )
            })?;
            *field(&mut skips) = true;
        }
        Ok(skips)
    }

    /// (`SKIP_*` bit, name) of every skip that is on.
    fn enabled(mut self) -> impl Iterator<Item = (u32, &'static str)> {
        let on: Vec<bool> = FIELDS
            .iter()
            .map(|(_, _, field)| *field(&mut self))
            .collect();
        FIELDS
            .iter()
            .enumerate()
            .filter(move |(k, _)| on[*k])
            .map(|(_, (name, bit, _))| (*bit, *name))
    }

    /// The `SKIP_*` bits of `FrameParams::skips` (izb-contract's `skip`).
    pub fn bits(self) -> u32 {
        self.enabled().fold(0, |bits, (bit, _)| bits | bit)
    }
}

impl fmt::Display for Skips {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Skips::ALL => write!(f, "all"),
            Skips::NONE => write!(f, "none"),
            s => {
                let on: Vec<&str> = s.enabled().map(|(_, name)| name).collect();
                write!(f, "{}", on.join(","))
            }
        }
    }
}

impl std::str::FromStr for Skips {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Skips::parse(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_and_print_round_trip() {
        for text in ["all", "none", "full-mask", "facing-away,saturated-edges"] {
            assert_eq!(Skips::parse(text).unwrap().to_string(), text);
        }
        assert_eq!(Skips::ALL.bits(), 0b111111);
        assert_eq!(Skips::NONE.bits(), 0);
        assert_eq!(Skips::parse("outside-bounds").unwrap().bits(), 0b10);
        let e = Skips::parse("full-mask,bogus").unwrap_err();
        assert!(e.contains("bogus") && e.contains("saturated-edges"), "{e}");
    }
}
