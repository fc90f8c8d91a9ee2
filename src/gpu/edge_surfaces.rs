//! The edge pixels' extra surfaces on the GPU ([`crate::gbuffer::edge_surfaces`]):
//! more receivers of the same bins, as on the CPU twin.
//!
//! Layout: the G-buffer buffers hold the pixels, then the extra surfaces
//! in rows of `width` below the image (the last padded with misses), so
//! every pass that runs over receivers — light setup's fit and extents,
//! the bin's behind-receivers gather, evaluate's tiles — runs over
//! `FrameParams::receiver_rows` rows and needs no other change; an extra
//! surface's neighbours in its row are the next edge pixels' surfaces,
//! near it on screen, so a tile's elected cells stay shared. Two tables
//! carry what only the edges have (`shaders/edge_receivers.glsl`):
//! `B_EDGE_PIXELS`, a word per pixel (0, or 1 + the index of its record)
//! and per edge pixel a record of the samples on its centre's surface,
//! the samples that count, those facing away and its extra surfaces
//! (sparse: courtyard's 224 k edge pixels of 2 M at 1080p); and
//! `B_EDGE_COVERAGE`, per extra surface the samples it covers. Evaluate
//! stops a receiver when its own samples are full (`evaluate_wanted`),
//! and under a point-like light bins and evaluates a partial one over the
//! part of its µQuad its samples span (`receiver_boxes`); resolve combines
//! a pixel's surfaces (`EdgeSurfaces::combine`) and divides by the samples
//! that count.
//!
//! The surfaces come from the `edge_surfaces` pass (`shaders/edge_surfaces.comp`,
//! after the `gbuffer` pass: the 32 sample rays of each edge candidate,
//! into slots taken by an atomic counter, [`FrameEdges::Traced`]) or from
//! the CPU twin's G-buffer ([`super::GBufferSource::Upload`], the twin
//! tests' exact input, [`FrameEdges::Uploaded`]).

use super::frame_inputs::SceneUpload;
use super::frame_memory::EdgeSlots;
use super::frame_report::FramePasses;
use super::shared::{self, ID_MASK};
use super::GpuError;
use crate::gbuffer::edge_surfaces::{EdgeSurfaces, MAX_SURFACES};
use crate::gbuffer::GBuffer;
use glam::Vec3;

/// An edge pixel record's fourth word: first extra surface below this
/// bit, count above it.
const COUNT_SHIFT: u32 = izb_contract::size::EDGE_COUNT_SHIFT;
// Up to MAX_SURFACES − 1 extra surfaces per mask half, two halves.
const _: () = assert!(2 * (MAX_SURFACES - 1) < 1 << (32 - COUNT_SHIFT));

/// What a frame uploads for its edge surfaces.
pub(super) struct EdgeUpload {
    /// `B_EDGE_PIXELS`: per pixel 0 or 1 + its record's index, then the
    /// edge pixels' records, per mask half (centre coverage, counted,
    /// facing away, first extra surface | count << `EDGE_COUNT_SHIFT`).
    pub(super) pixel_words: Vec<u32>,
    /// Records (edge pixels).
    pub(super) records: u64,
    /// `B_EDGE_COVERAGE`: per extra surface a word per mask half (the
    /// samples of that half it covers: 0 in the other half's).
    pub(super) coverage: Vec<u32>,
    /// Extra surfaces (of both halves).
    pub(super) surfaces: u64,
    /// The G-buffer entries: the pixels', then the extra surfaces' rows.
    pub(super) position: Vec<Vec3>,
    pub(super) axis_x: Vec<Vec3>,
    pub(super) axis_y: Vec<Vec3>,
    pub(super) id_flags: Vec<u32>,
}

impl EdgeUpload {
    /// The upload of `g`'s pixels and the edge surfaces of its mask halves
    /// (`g.edges`, and `g.edges_high` for `Paired64`), `width` entries a
    /// row: a pixel's surfaces of both halves consecutive, in pixel order.
    pub(super) fn new(g: &GBuffer, upload: &SceneUpload) -> Result<Self, GpuError> {
        let halves: Vec<&EdgeSurfaces> =
            g.edges.iter().chain(&g.edges_high).map(|e| &**e).collect();
        let h = halves.len();
        let order = merged_order(&halves)?;
        let extra = order.len();
        if extra >= 1 << COUNT_SHIFT {
            return Err(GpuError::Unsupported(format!(
                "{extra} edge surfaces: the GPU's edge table indexes below 2^{COUNT_SHIFT}"
            )));
        }
        let stride = 4 * h;
        let mut records = vec![0u32; g.flags.len() * stride];
        for (i, r) in records.chunks_exact_mut(stride).enumerate() {
            for (half, e) in halves.iter().enumerate() {
                r[4 * half..4 * half + 3].copy_from_slice(&[
                    e.centre_coverage[i],
                    e.counted[i],
                    e.facing_away[i],
                ]);
            }
        }
        let mut coverage = vec![0u32; extra * h];
        let mut previous = None;
        for (j, &(p, half, k)) in order.iter().enumerate() {
            coverage[j * h + half] = halves[half].coverage[k];
            let r = &mut records[p as usize * stride..][..stride];
            let range = if previous == Some(p) {
                r[3] + (1 << COUNT_SHIFT)
            } else {
                j as u32 | 1 << COUNT_SHIFT
            };
            for half in 0..h {
                r[4 * half + 3] = range;
            }
            previous = Some(p);
        }
        let width = g.width as usize;
        let padding = extra.div_ceil(width.max(1)) * width - extra;
        let words: Vec<Vec<u32>> = halves
            .iter()
            .map(|e| upload.gbuffer_words(&e.surfaces))
            .collect::<Result<_, _>>()?;
        let entries = |pixels: &[Vec3], of: fn(&GBuffer) -> &[Vec3]| -> Vec<Vec3> {
            let surfaces = order
                .iter()
                .map(|&(_, half, k)| of(&halves[half].surfaces)[k]);
            let pad = std::iter::repeat_n(Vec3::ZERO, padding);
            pixels.iter().copied().chain(surfaces).chain(pad).collect()
        };
        let mut id_flags = upload.gbuffer_words(g)?;
        id_flags.extend(order.iter().map(|&(_, half, k)| words[half][k]));
        id_flags.extend(std::iter::repeat_n(ID_MASK, padding));
        let (pixel_words, records) = sparse_records(&records, stride);
        Ok(EdgeUpload {
            pixel_words,
            records,
            coverage,
            surfaces: extra as u64,
            position: entries(&g.position, |s| &s.position),
            axis_x: entries(&g.axis_x, |s| &s.axis_x),
            axis_y: entries(&g.axis_y, |s| &s.axis_y),
            id_flags,
        })
    }

    /// Its slots: as many as it has extra surfaces and edge pixels.
    pub(super) fn slots(&self) -> EdgeSlots {
        EdgeSlots {
            surfaces: self.surfaces,
            pixels: self.records,
        }
    }
}

/// The extra surfaces of every mask half in upload order, as (pixel,
/// half, index in that half): by pixel, a pixel's half-0 surfaces first
/// (each half lists its own in pixel order, as the CPU twin builds them).
fn merged_order(halves: &[&EdgeSurfaces]) -> Result<Vec<(u32, usize, usize)>, GpuError> {
    let mut order: Vec<(u32, usize, usize)> = Vec::new();
    for (half, e) in halves.iter().enumerate() {
        if let Some(k) = e.pixel.windows(2).position(|w| w[0] > w[1]) {
            return Err(GpuError::Unsupported(format!(
                "edge surface {} of half {half} (pixel {}) follows pixel {}'s: not in pixel order",
                k + 1,
                e.pixel[k + 1],
                e.pixel[k]
            )));
        }
        order.extend(e.pixel.iter().enumerate().map(|(k, &p)| (p, half, k)));
    }
    // Stable: within a pixel and half the surfaces keep their order.
    order.sort_by_key(|&(p, half, _)| (p, half));
    Ok(order)
}

/// Whether a frame of `scene` under `settings` can take its edge surfaces
/// from `source`: an uploaded G-buffer brings them exactly when the
/// settings use them, and the GPU's own casts them when they do. Paired64's
/// second half has edge surfaces of its own (`GBuffer::edges_high`): the
/// GPU takes them uploaded, but its `edge_surfaces` pass traces half 0's
/// pattern only, so a GPU-cast Paired64 frame with them is refused by
/// name, never run with half 0's surfaces alone.
pub(super) fn check_source(
    scene: &crate::scene::Scene,
    settings: crate::settings::IzbSettings,
    source: super::GBufferSource,
) -> Result<(), GpuError> {
    let cast = matches!(source, super::GBufferSource::Gpu);
    if cast && settings.edge_halves(scene) == 2 {
        return Err(GpuError::Unsupported(
            "Paired64's edge surfaces from the GPU's own G-buffer: its edge_surfaces pass \
             traces the first half's µQuad pattern only (upload the CPU's G-buffer, as \
             izb render --backend vulkan does, or --no-edge-surfaces)"
                .into(),
        ));
    }
    if let super::GBufferSource::Upload(g) = source {
        let have = usize::from(g.edges.is_some()) + usize::from(g.edges_high.is_some());
        match (settings.edge_halves(scene), have) {
            (want, have) if want == have => {}
            (_, 0) => return Err(GpuError::EdgeSurfaces),
            (want, have) => {
                return Err(GpuError::Unsupported(format!(
                    "the uploaded G-buffer has edge surfaces for {have} mask half(s), \
                     the settings for {want}"
                )))
            }
        }
    }
    Ok(())
}

/// A pixel all of whose samples stand on its centre's surface.
const SMOOTH: [u32; 4] = [u32::MAX, u32::MAX, 0, 0];

/// `B_EDGE_PIXELS` of per-pixel records (`stride` words each, 4 per mask
/// half): a word per pixel (0 for a smooth pixel, all of whose halves
/// have every sample on the centre's surface, else 1 + its record's
/// index), then the edge pixels' records in pixel order; and their number.
fn sparse_records(dense: &[u32], stride: usize) -> (Vec<u32>, u64) {
    let pixels = dense.len() / stride;
    let mut words = vec![0u32; pixels];
    let mut records = Vec::new();
    for (i, r) in dense.chunks_exact(stride).enumerate() {
        if r.iter().step_by(4).any(|&centre| centre != SMOOTH[0]) {
            records.extend_from_slice(r);
            words[i] = (records.len() / stride) as u32;
        }
    }
    let n = (records.len() / stride) as u64;
    words.extend(records);
    (words, n)
}

/// The per-pixel records of `B_EDGE_PIXELS` (`words`, at least a word per
/// pixel and the `records` after them): [`sparse_records`] undone.
fn dense_records(words: &[u32], pixels: usize, records: usize) -> Vec<[u32; 4]> {
    let table = &words[pixels..pixels + 4 * records];
    words[..pixels]
        .iter()
        .map(|&w| match w as usize {
            0 => SMOOTH,
            r if r <= records => table[4 * (r - 1)..4 * r].try_into().unwrap(),
            // Past the slots (the frame is rerun with room): not read.
            _ => SMOOTH,
        })
        .collect()
}

/// The slots a traced frame asked for: extra surfaces and edge pixels'
/// records (both in `edge_capacity` slots).
pub(super) fn slots_needed(counters: &[u32]) -> u64 {
    use shared::counter;
    u64::from(counters[counter::EDGE_SURFACES].max(counters[counter::EDGE_PIXELS]))
}

/// The lit fraction of an edge-surface frame's pixel from its shaded
/// alpha (lit samples of those that count) and the number of `samples`
/// that count (in every mask half): 1 − hidden / samples, as
/// [`crate::cpu::resolve_halves`] computes it; NaN where not shadow-tested.
pub(super) fn lit_fraction_over_counted(alpha: u8, samples: u32) -> f32 {
    if alpha == shared::ALPHA_NOT_TESTED {
        return f32::NAN;
    }
    let hidden = samples.saturating_sub(u32::from(alpha));
    1.0 - hidden as f32 / samples as f32
}

/// A frame's edge surfaces.
pub(super) enum FrameEdges {
    /// A frame without them.
    None,
    /// The CPU twin's, uploaded.
    Uploaded(EdgeUpload),
    /// Cast by the `edge_surfaces` pass into `capacity` slots.
    Traced { capacity: u64 },
}

impl FrameEdges {
    /// The edge surfaces of an IZB frame (`edge_capacity`: the traced
    /// ones' slots) from `source`, whose agreement with the settings
    /// `render` checked.
    pub(super) fn new(
        source: super::GBufferSource,
        passes: FramePasses,
        use_them: bool,
        upload: &SceneUpload,
    ) -> Result<Self, GpuError> {
        Ok(match (passes, source) {
            (FramePasses::Izb { .. }, super::GBufferSource::Upload(g)) => {
                match g.edges.as_deref() {
                    Some(_) => FrameEdges::Uploaded(EdgeUpload::new(g, upload)?),
                    None => FrameEdges::None,
                }
            }
            (FramePasses::Izb { edge_capacity }, super::GBufferSource::Gpu) if use_them => {
                FrameEdges::Traced {
                    capacity: edge_capacity,
                }
            }
            _ => FrameEdges::None,
        })
    }

    /// Slots of extra surfaces and edge pixels, if the frame has them.
    pub(super) fn slots(&self) -> Option<EdgeSlots> {
        match self {
            FrameEdges::None => None,
            FrameEdges::Uploaded(e) => Some(e.slots()),
            FrameEdges::Traced { capacity } => Some(EdgeSlots {
                surfaces: *capacity,
                pixels: *capacity,
            }),
        }
    }

    /// Rows of extra surfaces below a `width`-wide image.
    pub(super) fn rows(&self, width: u32) -> u32 {
        self.slots()
            .map_or(0, |n| n.surfaces.div_ceil(u64::from(width.max(1))) as u32)
    }

    pub(super) fn traced(&self) -> bool {
        matches!(self, FrameEdges::Traced { .. })
    }

    /// The slots a traced frame filled, and its tables (per-pixel records,
    /// per-slot coverage) read back through `read` (binding → bytes).
    #[allow(clippy::type_complexity)]
    pub(super) fn read_back<'a>(
        &self,
        read: &impl Fn(u32) -> Result<&'a [u8], GpuError>,
        counters: &[u32],
        pixels: usize,
    ) -> Result<(usize, Option<(Vec<[u32; 4]>, Vec<u32>)>), GpuError> {
        let FrameEdges::Traced { capacity } = self else {
            return Ok((0, None));
        };
        let found = u64::from(counters[shared::counter::EDGE_SURFACES]).min(*capacity) as usize;
        let records = u64::from(counters[shared::counter::EDGE_PIXELS]).min(*capacity) as usize;
        let words: Vec<u32> = bytemuck::pod_collect_to_vec(
            &read(shared::binding::EDGE_PIXELS)?[..(pixels + 4 * records) * 4],
        );
        let records = dense_records(&words, pixels, records);
        let coverage =
            bytemuck::pod_collect_to_vec(&read(shared::binding::EDGE_COVERAGE)?[..found * 4]);
        Ok((found, Some((records, coverage))))
    }
}

/// What the `edge_surfaces` pass wrote, read back: per pixel its record,
/// and the extra surfaces in the slots they took.
pub(super) struct TracedEdges {
    pub(super) pixels: Vec<[u32; 4]>,
    pub(super) coverage: Vec<u32>,
    pub(super) surfaces: GBuffer,
}

impl TracedEdges {
    /// The [`EdgeSurfaces`] of the read-back tables, surfaces in pixel
    /// order (as the CPU twin lists them); `stats` from the counters.
    pub(super) fn into_edge_surfaces(self, counters: &[u32]) -> EdgeSurfaces {
        use super::shared::counter;
        let mut e = EdgeSurfaces {
            surfaces: GBuffer::select(&self.surfaces, &[]),
            pixel: Vec::with_capacity(self.coverage.len()),
            coverage: Vec::with_capacity(self.coverage.len()),
            centre_coverage: self.pixels.iter().map(|r| r[0]).collect(),
            counted: self.pixels.iter().map(|r| r[1]).collect(),
            facing_away: self.pixels.iter().map(|r| r[2]).collect(),
            stats: crate::gbuffer::edge_surfaces::EdgeStats {
                candidates: counters[counter::EDGE_CANDIDATES] as usize,
                edge_pixels: counters[counter::EDGE_PIXELS] as usize,
                extra_surfaces: self.coverage.len(),
                sample_rays: 32 * u64::from(counters[counter::EDGE_CANDIDATES]),
                sample_rays_unbounded: 32 * u64::from(counters[counter::EDGE_CANDIDATES]),
                facing_away_samples: counters[counter::EDGE_FACING_AWAY_SAMPLES].into(),
                dropped_samples: counters[counter::EDGE_DROPPED_SAMPLES].into(),
                missed_samples: counters[counter::EDGE_MISSED_SAMPLES].into(),
            },
        };
        let mut order = Vec::with_capacity(self.coverage.len());
        for (i, r) in self.pixels.iter().enumerate() {
            let first = (r[3] & ((1 << COUNT_SHIFT) - 1)) as usize;
            for k in first..first + (r[3] >> COUNT_SHIFT) as usize {
                order.push(k);
                e.pixel.push(i as u32);
                e.coverage.push(self.coverage[k]);
            }
        }
        e.surfaces = self.surfaces.select(&order);
        e
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Only edge pixels keep a record, behind their pixel's word, and the
    /// read-back undoes it; a word past the records read back is smooth.
    #[test]
    fn sparse_edge_records_round_trip() {
        let edge = [0x0f0f_0f0f, 0xffff_0fff, 0x0000_0f00, 7 | 2 << COUNT_SHIFT];
        let pixels = vec![SMOOTH, edge, SMOOTH, [1, 3, 2, 9], SMOOTH];
        let (words, records) = sparse_records(pixels.as_flattened(), 4);
        assert_eq!(records, 2);
        assert_eq!(words.len(), 5 + 8);
        assert_eq!(&words[..5], &[0, 1, 0, 2, 0]);
        assert_eq!(dense_records(&words, 5, 2), pixels);
        // A traced frame whose second record fell past its slots.
        assert_eq!(dense_records(&words, 5, 1)[3], SMOOTH);
    }
}
