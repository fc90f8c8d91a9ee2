//! Percentage-closer soft shadows (Fernando 2005): the tap patterns and
//! limits the CPU twin (`izb::baseline::pcss`) and `shaders/pcss.glsl`
//! share. The disks are declared here once and rendered into
//! `contract.glsl` as `const vec2` arrays by [`crate::glsl_header`].
//!
//! Both disks are Mitchell's best-candidate sampling (Mitchell 1991) of the
//! unit disk (fixed seeds, 64·i candidates for point i, area-uniform), the
//! coordinates rounded to multiples of 2⁻¹² so that every one is exact in
//! `f32` and in a short GLSL literal. The smallest spacing (0.41 for the
//! 16 blocker taps, 0.30 for the 32 filter taps, in disk radii) is checked
//! by the tests below.

use crate::macros::shared_constants;

shared_constants! {
    /// Tap counts, the filter code and the radius cap (`PCSS_*`).
    pub mod pcss: u32 as Uint, prefix "PCSS_" {
        /// `FrameParams::map_filter` of a PCSS lookup (PCF sizes are odd
        /// and ≥ 3, one tap is 0).
        FILTER = 1;
        /// Taps of the blocker search.
        BLOCKER_TAPS = 16;
        /// Taps of the percentage-closer filter.
        FILTER_TAPS = 32;
        /// Largest search and filter radius, in texels of the map's finer
        /// axis; also the margin (`Filter::reach`) the map keeps beyond the
        /// receivers' bounds so that a capped disk reads drawn texels. With
        /// 32 taps on a disk of 64 texels the taps already lie 20 texels
        /// apart: a wider disk would skip whole occluders (a 4-texel pole)
        /// between taps, and the margin would eat more of the map.
        MAX_RADIUS_TEXELS = 64;
    }
}

/// The blocker search's taps, in units of the search radius.
pub const BLOCKER_DISK: [[f32; 2]; 16] = disk([
    [-573, -328],
    [2982, 2802],
    [3599, -1603],
    [-1374, 3691],
    [211, -4002],
    [-4052, -405],
    [-2396, -2778],
    [1907, 438],
    [-2734, 1627],
    [374, 2278],
    [1467, -2165],
    [3910, 488],
    [1442, 3813],
    [-2334, -958],
    [-273, -2077],
    [-998, 1281],
]);

/// The filter's taps, in units of the filter radius.
pub const FILTER_DISK: [[f32; 2]; 32] = disk([
    [198, -195],
    [-3514, 2085],
    [696, 3968],
    [-1274, -3892],
    [3813, 1203],
    [2911, -2736],
    [-3660, -1427],
    [-1025, 2018],
    [594, -2554],
    [-1972, 61],
    [1674, 1857],
    [2311, -377],
    [-1379, -1836],
    [-2791, -2978],
    [-1279, 3881],
    [3994, -715],
    [-3681, 262],
    [2271, 3347],
    [1531, -3792],
    [-2359, 2986],
    [272, 1354],
    [1762, -1782],
    [88, -4061],
    [-2264, 1425],
    [279, 2703],
    [-817, 653],
    [2965, 2214],
    [2550, 868],
    [1296, 582],
    [-87, -1436],
    [-2469, -1170],
    [2938, -1424],
]);

/// Taps written in units of 2⁻¹² (exact in `f32`).
const fn disk<const N: usize>(units: [[i16; 2]; N]) -> [[f32; 2]; N] {
    let mut out = [[0.0; 2]; N];
    let mut i = 0;
    while i < N {
        out[i] = [units[i][0] as f32 / 4096.0, units[i][1] as f32 / 4096.0];
        i += 1;
    }
    out
}

/// The GLSL `const vec2` arrays of both disks (exact literals).
pub fn glsl_disks() -> String {
    let array = |name: &str, taps: &[[f32; 2]]| {
        let items: Vec<String> = taps
            .iter()
            .map(|[x, y]| {
                let l = |v: f32| crate::macros::literal(crate::macros::GlslKind::Float, v as f64);
                format!("vec2({}, {})", l(*x), l(*y))
            })
            .collect();
        format!(
            "const vec2 {name}[{}] = vec2[{}](\n    {}\n);\n",
            taps.len(),
            taps.len(),
            items.join(",\n    ")
        )
    };
    array("PCSS_BLOCKER_DISK", &BLOCKER_DISK) + &array("PCSS_FILTER_DISK", &FILTER_DISK)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spacing(taps: &[[f32; 2]]) -> f32 {
        let mut best = f32::INFINITY;
        for (i, a) in taps.iter().enumerate() {
            assert!(a[0].hypot(a[1]) <= 1.0, "{a:?} outside the unit disk");
            for b in &taps[i + 1..] {
                best = best.min((a[0] - b[0]).hypot(a[1] - b[1]));
            }
        }
        best
    }

    #[test]
    fn disks_are_poisson_and_sized_as_declared() {
        assert_eq!(BLOCKER_DISK.len(), pcss::BLOCKER_TAPS as usize);
        assert_eq!(FILTER_DISK.len(), pcss::FILTER_TAPS as usize);
        assert!(spacing(&BLOCKER_DISK) > 0.4);
        assert!(spacing(&FILTER_DISK) > 0.29);
    }

    #[test]
    fn glsl_arrays_list_every_tap() {
        let g = glsl_disks();
        assert!(g.contains("PCSS_BLOCKER_DISK[16]"), "{g}");
        assert!(g.contains("PCSS_FILTER_DISK[32]"), "{g}");
        assert_eq!(g.matches("vec2(").count(), 48);
    }
}
