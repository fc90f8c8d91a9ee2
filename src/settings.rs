//! What a render is asked for and how its time is reported: the settings
//! both backends take (the CPU twins in [`crate::cpu`], the GPU passes in
//! [`crate::gpu`]), below both.

use crate::cascades::CascadeCount;
use crate::skips::Skips;

/// Samples per pixel and how each triangle's mask is formed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum SampleMode {
    /// One point test at the µQuad centre: the mask is all or nothing.
    One,
    /// 32 samples, each edge's mask from the edge LUT (Wyman et al. 2015, §4).
    Lut32,
    /// 32 samples, every edge function evaluated at every sample.
    Exact32,
    /// Under an area light, 32 pairs of a µQuad sample and a light sample
    /// (sample i of each pattern), each ray from the one toward the other
    /// evaluated exactly: the soft mask antialiased over the pixel, as the
    /// ground truth integrates it (`cpu::light_samples`). Under a
    /// point-like light it is `Exact32`.
    Paired32,
    /// `Paired32` twice: 32 more pairs, both patterns turned
    /// ([`izb_lut::pairs`]), in a second 32-bit mask (bits 32–63 of the
    /// pixel's 64). Each half is evaluated as `Paired32` evaluates its
    /// own, over the same bins; the lit fraction counts all 64. Under a
    /// point-like light it is `Exact32`.
    Paired64,
}

impl SampleMode {
    /// Whether rays pair µQuad samples with light samples (under an area
    /// light).
    pub fn is_paired(self) -> bool {
        matches!(self, SampleMode::Paired32 | SampleMode::Paired64)
    }

    /// The 32-bit mask halves a pixel has under an area light: 2 for
    /// `Paired64`, else 1.
    pub fn halves(self) -> usize {
        if self == SampleMode::Paired64 {
            2
        } else {
            1
        }
    }
}

/// When the CPU twin's bin takes the `behind_receivers` skip, the skip
/// itself being on. The cull needs every receiver registered in the cells
/// its µQuad touches, on every level that holds triangles: about 50 ns a
/// receiver per thread, 25–70 ms at 1920×1080 on 2 cores. Only grids
/// dense with triangles give it that much to save: measured on the twelve
/// scenes at 960×540 and 1920×1080 (`paper-notes/skipping-work.md`), it
/// paid on engine (+19 and +41 ms) and courtyard (+9 and +44 ms), whose
/// placed rectangles cover 37–87 cells per cell, and cost 1–60 ms on the
/// ten others, at 2–13. The GPU twin registers whenever the skip is on
/// (its costs were not measured on a GPU).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum ReceiverCull {
    /// Every frame.
    Always,
    /// Where it can pay: under an area light, whose per-cell penumbra
    /// bound reads the same registration, or where the placed triangles'
    /// cell rectangles cover at least [`Self::DENSE_RECTANGLE_CELLS`]
    /// cells per cell of their level, summed over a cascade's levels.
    #[default]
    WhereDense,
}

impl ReceiverCull {
    /// The rectangle cells per cell from which `WhereDense` culls: between
    /// the ten scenes where the cull did not pay (at most 12.8) and the two
    /// where it did (at least 36.7).
    pub const DENSE_RECTANGLE_CELLS: f64 = 20.0;

    /// Whether the bin registers the receivers and culls, for a light of
    /// `light_radius` and grids whose densest cascade has
    /// `rectangle_cells_per_cell`.
    pub fn culls(self, light_radius: f32, rectangle_cells_per_cell: f64) -> bool {
        match self {
            ReceiverCull::Always => true,
            ReceiverCull::WhereDense => {
                light_radius > 0.0 || rectangle_cells_per_cell >= Self::DENSE_RECTANGLE_CELLS
            }
        }
    }
}

/// How to render.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct IzbSettings {
    pub mode: SampleMode,
    /// The grids' cell budget as the side of a square (`--cells 200`: 40 000
    /// cells), shared between the cascades (None: chosen from the receiver
    /// and triangle counts).
    pub cells: Option<u32>,
    /// A triangle is binned at the finest pyramid level where its cell
    /// rectangle holds at most this many cells (None:
    /// [`crate::cascades::DEFAULT_LEVEL_CELLS`]).
    pub level_cells: Option<u32>,
    /// Sample-distribution cascades (Wyman et al. 2015, §6.4).
    pub cascades: CascadeCount,
    /// Split blend: 1 logarithmic, 0 uniform.
    pub split_lambda: f32,
    /// Exact shortcuts to take (all by default).
    pub skips: Skips,
    /// When the CPU twin takes the `behind_receivers` one.
    pub receiver_cull: ReceiverCull,
    /// Edge pixels' samples each on the surface its own ray sees
    /// ([`crate::gbuffer::edge_surfaces`]), where the mode has per-sample
    /// rays ([`Self::uses_edge_surfaces`]).
    pub edge_surfaces: bool,
    /// The CPU twin's instruction set for its batched tests (default: the
    /// widest this processor has, capped by `IZB_SIMD`); masks and
    /// counters do not depend on it.
    pub simd: crate::cpu::simd::SimdPath,
    /// When the CPU twin's bin writes its vertex cache.
    pub vertex_cache: VertexCache,
}

impl IzbSettings {
    /// Whether a render of `scene` with these settings forms its masks
    /// over the light's samples (soft shadows): the light has a size and
    /// the mode has 32 samples. One sample per pixel tests P against the
    /// light's centre alone, a hard shadow whatever the light's size.
    pub fn light_samples(&self, scene: &crate::scene::Scene) -> bool {
        scene.has_area_light() && self.mode != SampleMode::One
    }

    /// Whether a render of `scene` with these settings places edge
    /// pixels' samples on their own surfaces: asked for, and each of the
    /// mode's bits is a sample of the pixel — a µQuad sample under a
    /// point-like light, or `Paired32`'s (µQuad sample, light sample)
    /// pair under an area light. One sample per pixel stays the centre's
    /// point test. Masks over the light's samples seen from P alone
    /// (`Lut32`, `Exact32` under an area light) have no pixel samples to
    /// place: measured with surfaces weighted by coverage, the light seen
    /// from a surface's re-centred P, off the part of the plane the pixel
    /// shows, darkened the deckchair's slats (edge MAE 0.044 against 0.026
    /// without). `Paired64`'s second half has its own µQuad pattern and
    /// its own edge surfaces ([`Self::edge_halves`]).
    pub fn uses_edge_surfaces(&self, scene: &crate::scene::Scene) -> bool {
        let mode_ok = if self.light_samples(scene) {
            self.mode.is_paired()
        } else {
            self.mode != SampleMode::One
        };
        self.edge_surfaces && mode_ok
    }

    /// The mask halves whose samples a render of `scene` places on their
    /// own surfaces at edge pixels: each half's µQuad pattern is traced
    /// apart (0 without edge surfaces).
    pub fn edge_halves(&self, scene: &crate::scene::Scene) -> usize {
        if self.uses_edge_surfaces(scene) {
            self.mask_halves(scene)
        } else {
            0
        }
    }

    /// The 32-bit mask halves per pixel a render of `scene` forms: 2 for
    /// `Paired64` under an area light, else 1.
    pub fn mask_halves(&self, scene: &crate::scene::Scene) -> usize {
        if self.light_samples(scene) {
            self.mode.halves()
        } else {
            1
        }
    }
}

impl Default for IzbSettings {
    fn default() -> Self {
        IzbSettings {
            mode: SampleMode::Lut32,
            cells: None,
            level_cells: None,
            cascades: CascadeCount::Auto,
            split_lambda: 1.0,
            skips: Skips::ALL,
            receiver_cull: ReceiverCull::WhereDense,
            edge_surfaces: false,
            simd: crate::cpu::simd::SimdPath::detected(),
            vertex_cache: VertexCache::WhereLong,
        }
    }
}

/// Whether the CPU twin's bin writes its cell lists' vertices in cell
/// order for evaluate to read sixteen at a time
/// ([`crate::cpu::cell_vertices`]). Masks and counters do not depend on
/// it; only the time does.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum VertexCache {
    /// Under a point-like light, every frame.
    Always,
    /// Under a point-like light, where an entry's cell list is on average
    /// at least 24 entries long (`cpu::cell_vertices::LONG_LISTS`).
    #[default]
    WhereLong,
    /// Never: every candidate is read by id.
    Never,
}

impl VertexCache {
    /// Whether the cache is written for cell lists whose entries sit in
    /// lists of `list_length_per_entry` on average.
    pub fn pays(self, list_length_per_entry: f64) -> bool {
        match self {
            VertexCache::Always => true,
            VertexCache::WhereLong => {
                list_length_per_entry >= crate::cpu::cell_vertices::LONG_LISTS
            }
            VertexCache::Never => false,
        }
    }
}

/// Time per pass, the same five passes on both backends; the unit is
/// the caller's (the CPU reports seconds, the GPU timestamp milliseconds).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct PassTimes {
    pub gbuffer: f64,
    pub light_setup: f64,
    pub bin: f64,
    pub evaluate: f64,
    pub resolve: f64,
    pub total: f64,
}

/// CPU wall seconds per pass.
pub type PassSeconds = PassTimes;

impl PassTimes {
    /// The per-pass median of non-empty `runs` (the upper median for an
    /// even count).
    pub fn median<'a>(runs: impl Iterator<Item = &'a PassTimes> + Clone) -> PassTimes {
        let pass = |f: fn(&PassTimes) -> f64| {
            let mut v: Vec<f64> = runs.clone().map(f).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        PassTimes {
            gbuffer: pass(|t| t.gbuffer),
            light_setup: pass(|t| t.light_setup),
            bin: pass(|t| t.bin),
            evaluate: pass(|t| t.evaluate),
            resolve: pass(|t| t.resolve),
            total: pass(|t| t.total),
        }
    }

    /// Everything but the G-buffer: the shadow passes proper.
    pub fn shadow(&self) -> f64 {
        self.total - self.gbuffer
    }
}
