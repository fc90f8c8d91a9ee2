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
//! `B_EDGE_PIXELS`, per edge pixel a record of the samples on its
//! centre's surface, the samples that count, those facing away and its
//! extra surfaces (sparse: courtyard's 224 k edge pixels of 2 M at 1080p),
//! found through a table of 12 bytes per 8×8 tile (which of its pixels
//! have records, and its first one's: 0.19 bytes per pixel, where a word
//! per pixel took 4, 8.3 MB at 1080p); and
//! `B_EDGE_COVERAGE`, per extra surface the samples it covers. Evaluate
//! stops a receiver when its own samples are full (`evaluate_wanted`),
//! and under a point-like light bins and evaluates a partial one over the
//! part of its µQuad its samples span (`receiver_boxes`); resolve combines
//! a pixel's surfaces (`EdgeSurfaces::combine`) and divides by the samples
//! that count.
//!
//! The surfaces come from the `edge_surfaces` pass (`shaders/edge_surfaces.comp`,
//! after the `gbuffer` pass: the 32 sample rays of each edge candidate,
//! into slots taken by an atomic counter, [`read_traced_tables`]) or from
//! the CPU twin's G-buffer ([`super::GBufferSource::Upload`], the twin
//! tests' exact input, [`EdgeUpload`]), both in the shadow pass.

use super::frame_inputs::SceneUpload;
use super::frame_memory::EdgeSlots;
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

/// Words per tile of the edge table, and the tile's side in pixels: the
/// pixel passes' workgroup, whose 64 pixels a tile's two mask words hold.
const TILE_WORDS: usize = izb_contract::size::EDGE_TILE_WORDS as usize;
const TILE: [u32; 2] = shared::WORKGROUP_PIXELS;
const _: () = assert!(TILE[0] * TILE[1] == 64);

/// The 8×8 tiles of a `[w, h]` image, in the edge table's row order.
pub(super) fn edge_tiles([w, h]: [u32; 2]) -> u64 {
    u64::from(w.div_ceil(TILE[0])) * u64::from(h.div_ceil(TILE[1]))
}

/// Pixel `i`'s tile and its bit there (8y + x within the tile), as
/// `edge_receivers.glsl`'s `edge_tile_bit`.
fn tile_bit(i: usize, w: u32) -> (usize, u32) {
    let (x, y) = ((i % w as usize) as u32, (i / w as usize) as u32);
    let tile = (y / TILE[1]) * w.div_ceil(TILE[0]) + x / TILE[0];
    (tile as usize, (y % TILE[1]) * TILE[0] + x % TILE[0])
}

/// What a frame uploads for its edge surfaces.
pub(super) struct EdgeUpload {
    /// `B_EDGE_PIXELS`: the tile table, then the edge pixels' records,
    /// per mask half (centre coverage, counted, facing away, first extra
    /// surface | count << `EDGE_COUNT_SHIFT`).
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
        let (pixel_words, records) = sparse_records(&records, stride, [g.width, g.height]);
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
/// half) of a `[w, h]` image: per tile its pixels with records (a smooth
/// pixel, all of whose halves have every sample on the centre's surface,
/// has none) and its first record's index, then the records, tile after
/// tile, a tile's in bit order; and their number.
fn sparse_records(dense: &[u32], stride: usize, [w, h]: [u32; 2]) -> (Vec<u32>, u64) {
    let tiles = edge_tiles([w, h]) as usize;
    let mut table = vec![0u32; TILE_WORDS * tiles];
    let mut tile_pixels: Vec<Vec<(u32, usize)>> = vec![Vec::new(); tiles];
    for (i, r) in dense.chunks_exact(stride).enumerate() {
        if r.iter().step_by(4).any(|&centre| centre != SMOOTH[0]) {
            let (tile, bit) = tile_bit(i, w);
            tile_pixels[tile].push((bit, i));
        }
    }
    let mut records = Vec::new();
    for (tile, mut edge) in tile_pixels.into_iter().enumerate() {
        edge.sort_unstable();
        let entry = &mut table[TILE_WORDS * tile..][..TILE_WORDS];
        entry[2] = (records.len() / stride) as u32;
        for (bit, i) in edge {
            entry[(bit / 32) as usize] |= 1 << (bit % 32);
            records.extend_from_slice(&dense[i * stride..][..stride]);
        }
    }
    let n = (records.len() / stride) as u64;
    table.extend(records);
    (table, n)
}

/// Pixel `i`'s record index through the tile table (`words`), as
/// `edge_record_link`: `None` for a pixel without one.
fn record_of(words: &[u32], i: usize, w: u32) -> Option<usize> {
    let (tile, bit) = tile_bit(i, w);
    let entry = &words[TILE_WORDS * tile..][..TILE_WORDS];
    let mask = u64::from(entry[0]) | u64::from(entry[1]) << 32;
    (mask >> bit & 1 == 1)
        .then(|| entry[2] as usize + (mask & ((1u64 << bit) - 1)).count_ones() as usize)
}

/// The per-pixel records of `B_EDGE_PIXELS` (`words`: the tile table of a
/// `[w, h]` image and at least `records` records after it):
/// [`sparse_records`] undone.
fn dense_records(words: &[u32], [w, h]: [u32; 2], records: usize) -> Vec<[u32; 4]> {
    let table_words = TILE_WORDS * edge_tiles([w, h]) as usize;
    let table = &words[table_words..table_words + 4 * records];
    (0..w as usize * h as usize)
        .map(|i| match record_of(words, i, w) {
            None => SMOOTH,
            Some(r) if r < records => table[4 * r..4 * r + 4].try_into().unwrap(),
            // Past the slots (the frame is rerun with room): not read.
            Some(_) => SMOOTH,
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

/// The tables a frame's `edge_surfaces` step traced into `capacity` slots,
/// read back through `read` (binding → bytes): how many slots it filled,
/// per pixel its record and per filled slot its coverage.
#[allow(clippy::type_complexity)]
pub(super) fn read_traced_tables<'a>(
    read: &impl Fn(u32) -> Result<&'a [u8], GpuError>,
    counters: &[u32],
    resolution: [u32; 2],
    capacity: u64,
) -> Result<(usize, (Vec<[u32; 4]>, Vec<u32>)), GpuError> {
    let found = u64::from(counters[shared::counter::EDGE_SURFACES]).min(capacity) as usize;
    let records = u64::from(counters[shared::counter::EDGE_PIXELS]).min(capacity) as usize;
    let table = TILE_WORDS * edge_tiles(resolution) as usize;
    let words: Vec<u32> = bytemuck::pod_collect_to_vec(
        &read(shared::binding::EDGE_PIXELS)?[..(table + 4 * records) * 4],
    );
    let records = dense_records(&words, resolution, records);
    let coverage =
        bytemuck::pod_collect_to_vec(&read(shared::binding::EDGE_COVERAGE)?[..found * 4]);
    Ok((found, (records, coverage)))
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

    /// Only edge pixels keep a record, found through their tile, and the
    /// read-back undoes it; a record past those read back is smooth.
    #[test]
    fn sparse_edge_records_round_trip() {
        let edge = [0x0f0f_0f0f, 0xffff_0fff, 0x0000_0f00, 7 | 2 << COUNT_SHIFT];
        // 10×9 pixels: tiles 2×2, the last column and row partial.
        let (w, h) = (10u32, 9u32);
        let mut pixels = vec![SMOOTH; (w * h) as usize];
        let marked = [
            (3, edge),
            (12, [1, 3, 2, 9]),
            (9, [5, 5, 0, 0]),
            (80, [0, 0, 0, 0]),
        ];
        for (i, r) in marked {
            pixels[i] = r;
        }
        let (words, records) = sparse_records(pixels.as_flattened(), 4, [w, h]);
        assert_eq!(records, 4);
        assert_eq!(words.len(), 3 * 4 + 4 * 4);
        // Tile 0 holds pixels 3 (bit 3) and 12 (row 1, bit 8 + 2) in bit
        // order, then tile 1 pixel 9 (bit 1), tile 2 pixel 80 (row 8: bit 0).
        assert_eq!(
            &words[..12],
            &[1 << 3 | 1 << 10, 0, 0, 1 << 1, 0, 2, 1, 0, 3, 0, 0, 4]
        );
        assert_eq!(&words[12..16], &edge);
        assert_eq!(dense_records(&words, [w, h], 4), pixels);
        // A traced frame whose last records fell past its slots.
        let cut = dense_records(&words, [w, h], 2);
        assert_eq!((cut[12], cut[9], cut[80]), ([1, 3, 2, 9], SMOOTH, SMOOTH));
    }
}
