//! The bin's vertex cache: every cell entry's triangle, its nine vertex
//! floats in planes in cell order beside the entry's key, so that
//! evaluate's walk reads a cell's candidates contiguously and asks the
//! tangent-plane condition of sixteen at a time (issue 30's first two
//! steps; the compute IZB of seed 000 found the same layout paid on the
//! GPU). A triangle's floats are copied, not recomputed, so a lane's
//! vertices are the scalar walk's bit for bit.
//!
//! The planes are cut into segments of `SEGMENT` entries, each holding
//! the [`LANES`] entries after it too: a chunk of sixteen starting
//! anywhere in a segment is then one contiguous read per plane, and the
//! segments are filled in parallel without sharing a slice.
//!
//! One block for all segments, its memory handed from frame to frame
//! (`SPARE`). Fresh memory each frame cost the bin its page faults
//! (courtyard at 960×540: 18 ms for a 59 MB cache, 9 ms reused); a
//! segment per allocation, which the allocator would recycle by itself,
//! made evaluate slower (courtyard 0.25 → 0.32 s, ficus 0.077 → 0.095 s;
//! not understood).

use super::bin::{Bins, CellEntry};
use super::spare::{reused, Spare};
use super::survivor_batch::LANES;
use crate::frustum::max3;
use crate::settings::VertexCache;
use glam::Vec3;
use rayon::prelude::*;

/// The mean length of the list an entry sits in from which the vertex
/// cache pays ([`Bins::cache_vertices`]). Measured at 1920×1080 (two
/// threads, shadow pass with the cache over without): hairball (36 per
/// entry) 0.91, ficus (145) 0.93, courtyard (289) 0.99 with the bin's 30 ms
/// more, tablefan (26) 1.00; engine (19) 1.00–1.05, and where lists are
/// shorter the cache cost up to a fifth (wires (17) 1.18, deckchair (16)
/// 1.20, default (7) 1.18, analytic (1) 1.31): a chunk costs its sixteen
/// lanes and ten cache lines however few entries it holds.
pub const LONG_LISTS: f64 = 24.0;

impl Bins {
    /// Writes the vertex cache of the cell lists of `triangles` (the ones
    /// binned), for a walk that batches its survivors (a point-like
    /// light), where `when` says it pays.
    pub fn cache_vertices(&mut self, triangles: &[[Vec3; 3]], when: VertexCache) {
        if when == VertexCache::Never {
            return;
        }
        let (entries, squares) = self
            .cell_start
            .par_windows(2)
            .map(|w| {
                let len = u64::from(w[1] - w[0]);
                (len, len * len)
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        self.stats.list_length_per_entry = squares as f64 / entries.max(1) as f64;
        if !when.pays(self.stats.list_length_per_entry) {
            return;
        }
        self.vertices = CellVertices::new(&self.cell_triangles, triangles);
        self.stats.vertex_cache_bytes = self.vertices.as_ref().map_or(0, |v| v.bytes());
    }
}

/// Entries per segment of the planes.
const SEGMENT: usize = 4096;

/// A segment's length in each plane: its entries and the next [`LANES`].
const WIDTH: usize = SEGMENT + LANES;

/// How many entries ahead the cache's writing asks for a triangle: the
/// entries are in cell order, their ids scattered over the triangle array
/// (courtyard's 31 MB), and the writing waited on each read (courtyard at
/// 960×540: about 11.5 ms a frame without, 10 with, on two threads).
const PREFETCH_AHEAD: usize = 48;

/// A key's triangle id: the bits below the two flags.
const ID_MASK: u32 = (1 << 30) - 1;

/// A key's `first_column` bit ([`CellEntry`]).
const FIRST_COLUMN: u32 = 1 << 31;

/// A key's `first_row` bit.
const FIRST_ROW: u32 = 1 << 30;

/// Each cell entry's key (its id and both flags) and its triangle's nine
/// vertex floats (eye-relative), in the order of the bin's cell lists.
pub struct CellVertices {
    /// `WIDTH` keys per segment.
    keys: Vec<u32>,
    /// `9 · WIDTH` floats per segment: plane `3v + axis` of vertex `v`.
    planes: Vec<f32>,
}

/// The last cache dropped, its memory for the next one: a renderer's
/// frames reuse it as a GPU pass reuses its buffers. At most one is kept
/// (the largest frame's, until a process ends).
static SPARE: Spare<(Vec<u32>, Vec<f32>)> = Spare::new();

impl Drop for CellVertices {
    fn drop(&mut self) {
        let keys = std::mem::take(&mut self.keys);
        SPARE.keep((keys, std::mem::take(&mut self.planes)));
    }
}

impl CellVertices {
    /// The cache of `entries` (the bin's cell lists, cell after cell) of
    /// `triangles`; `None` where an id does not fit beside the flags.
    pub fn new(entries: &[CellEntry], triangles: &[[Vec3; 3]]) -> Option<CellVertices> {
        if triangles.len() > ID_MASK as usize {
            return None;
        }
        let segments = entries.len().div_ceil(SEGMENT).max(1);
        let (keys, planes) = SPARE.take().unwrap_or_default();
        // Every entry is written below, the padding after the last is
        // never a test: what the spare held there does not matter.
        let (mut keys, mut planes) = (
            reused(keys, segments * WIDTH, 0),
            reused(planes, segments * 9 * WIDTH, 0.0),
        );
        keys.par_chunks_mut(WIDTH)
            .zip(planes.par_chunks_mut(9 * WIDTH))
            .enumerate()
            .for_each(|(j, (keys, planes))| {
                let first = j * SEGMENT;
                let last = (first + WIDTH).min(entries.len());
                for (o, e) in entries[first..last].iter().enumerate() {
                    if let Some(next) = entries.get(first + o + PREFETCH_AHEAD) {
                        super::simd::prefetch(triangles.as_ptr().wrapping_add(next.id as usize));
                    }
                    keys[o] = e.id
                        | if e.first_column { FIRST_COLUMN } else { 0 }
                        | if e.first_row { FIRST_ROW } else { 0 };
                    for (v, vertex) in triangles[e.id as usize].iter().enumerate() {
                        for (axis, &value) in vertex.to_array().iter().enumerate() {
                            planes[(3 * v + axis) * WIDTH + o] = value;
                        }
                    }
                }
            });
        Some(CellVertices { keys, planes })
    }

    /// Bytes the cache holds.
    pub fn bytes(&self) -> usize {
        4 * (self.keys.len() + self.planes.len())
    }

    /// The [`LANES`] entries from entry `start` on (those past the cell's
    /// end are the next cells' or padding: the caller masks them).
    #[inline(always)]
    fn chunk(&self, start: usize) -> Chunk<'_> {
        let (segment, o) = (start / SEGMENT, start % SEGMENT);
        let keys = &self.keys[segment * WIDTH..][..WIDTH];
        let planes = &self.planes[segment * 9 * WIDTH..][..9 * WIDTH];
        Chunk {
            keys: lanes(keys, o),
            planes: std::array::from_fn(|k| lanes(&planes[k * WIDTH..][..WIDTH], o)),
        }
    }

    /// Asks for the planes' lines of entry `i` ahead of their read: the
    /// walk reads on along a row's cells, whose entries follow one another.
    #[inline(always)]
    pub fn prefetch(&self, i: usize) {
        let (segment, o) = (i / SEGMENT, i % SEGMENT);
        super::simd::prefetch(self.keys.as_ptr().wrapping_add(segment * WIDTH + o));
        let planes = self.planes.as_ptr().wrapping_add(segment * 9 * WIDTH + o);
        for k in 0..9 {
            super::simd::prefetch(planes.wrapping_add(k * WIDTH));
        }
    }

    /// Entry `i`'s triangle minus `p`, as the scalar walk forms it.
    #[inline]
    pub fn triangle_minus(&self, i: usize, p: Vec3) -> [Vec3; 3] {
        let (segment, o) = (i / SEGMENT, i % SEGMENT);
        let planes = &self.planes[segment * 9 * WIDTH..][..9 * WIDTH];
        let at = |k: usize| planes[k * WIDTH + o];
        let vertex = |v: usize| Vec3::new(at(3 * v), at(3 * v + 1), at(3 * v + 2)) - p;
        [vertex(0), vertex(1), vertex(2)]
    }
}

/// The [`LANES`] values of `plane` from `o` on.
#[inline(always)]
fn lanes<T>(plane: &[T], o: usize) -> &[T; LANES] {
    match plane[o..].first_chunk::<LANES>() {
        Some(lanes) => lanes,
        // A segment holds the LANES entries after its last.
        None => unreachable!("a segment's planes end {LANES} entries past it"),
    }
}

/// Sixteen consecutive entries: keys and vertex planes.
struct Chunk<'a> {
    keys: &'a [u32; LANES],
    planes: [&'a [f32; LANES]; 9],
}

/// What a pixel asks of a chunk of one of its cells.
pub struct ChunkQuery {
    /// The receiver's P, tangent-plane normal and µQuad part of the depth
    /// tolerance ([`crate::frustum::above_tangent_plane`]).
    pub p: Vec3,
    pub normal: Vec3,
    pub microquad_part: f32,
    /// The receiver's own triangle and the conservative shadow map's
    /// candidate, both skipped as the scalar walk skips them.
    pub receiver: u32,
    pub cover: u32,
    /// [`CellEntry::tested_in`]'s flags an entry needs in this cell: the
    /// first-column bit where the cell is not the range's first column,
    /// and the first-row bit likewise.
    pub need: u32,
}

impl ChunkQuery {
    /// The flags an entry of cell (`x`, `y`) needs to be tested by a pixel
    /// whose range starts at (`x0`, `y0`).
    #[inline]
    pub fn flags_needed(x: u32, y: u32, x0: u32, y0: u32) -> u32 {
        (if x != x0 { FIRST_COLUMN } else { 0 }) | (if y != y0 { FIRST_ROW } else { 0 })
    }
}

/// A chunk's lanes after the tangent-plane condition.
#[derive(Default)]
pub struct ChunkTests {
    /// The highest vertex's height above the tangent plane.
    pub height: [f32; LANES],
    /// Bit `l`: lane `l` is a test of the pixel's walk (inside the cell,
    /// tested in this cell, neither the receiver nor the cover).
    pub tested: u32,
    /// Bit `l`: a test that passes the condition.
    pub above: u32,
}

/// The tangent-plane condition over the `len` (≤ [`LANES`]) entries of
/// `cache` from `start` on: each lane as
/// [`crate::frustum::above_tangent_plane`] computes it (`v − P`, glam's
/// dot, the same `max3`, no fused multiply-add). Inlined into the walk,
/// which is compiled once per instruction set ([`super::simd::SimdPath`]).
#[inline(always)]
pub fn tangent_chunk(
    cache: &CellVertices,
    start: usize,
    len: usize,
    q: &ChunkQuery,
    out: &mut ChunkTests,
) {
    let c = cache.chunk(start);
    let (mut tested, mut above) = (0u32, 0u32);
    for l in 0..LANES {
        let key = c.keys[l];
        let id = key & ID_MASK;
        let is_test = (l < len) & (key & q.need == q.need) & (id != q.receiver) & (id != q.cover);
        let mut h = [0.0f32; 3];
        for (v, h) in h.iter_mut().enumerate() {
            let vertex = Vec3::new(
                c.planes[3 * v][l],
                c.planes[3 * v + 1][l],
                c.planes[3 * v + 2][l],
            );
            *h = q.normal.dot(vertex - q.p);
        }
        let height = max3(h[0], h[1], h[2]);
        out.height[l] = height;
        tested |= u32::from(is_test) << l;
        above |= u32::from(is_test & (height > q.microquad_part)) << l;
    }
    out.tested = tested;
    out.above = above;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::test_random::XorShift;

    /// Every chunk, from every entry of a cache three segments long, holds
    /// the entries' keys and vertices bit for bit, and the tangent-plane
    /// bits are the scalar test's lane by lane.
    #[test]
    fn every_chunk_holds_its_entries_and_the_scalar_verdicts() {
        let mut rng = XorShift::new(0x5eed_cafe);
        let mut coordinate = || (rng.unit_f32() - 0.5) * 8.0;
        let triangles: Vec<[Vec3; 3]> = (0..700)
            .map(|_| [0; 3].map(|_| Vec3::new(coordinate(), coordinate(), coordinate())))
            .collect();
        let mut rng = XorShift::new(0x0dd_ba11);
        let entries: Vec<CellEntry> = (0..2 * SEGMENT + 999)
            .map(|_| {
                let bits = rng.next_u64();
                CellEntry {
                    id: (bits % triangles.len() as u64) as u32,
                    first_column: bits & (1 << 40) != 0,
                    first_row: bits & (1 << 41) != 0,
                }
            })
            .collect();
        let cache = CellVertices::new(&entries, &triangles).unwrap();
        let normal = Vec3::new(0.3, -0.8, 0.52);
        let mut out = ChunkTests::default();
        let mut lanes_checked = 0;
        for start in 0..entries.len() {
            let len = (entries.len() - start).min(LANES);
            let c = cache.chunk(start);
            let query = ChunkQuery {
                p: triangles[start % triangles.len()][0] * 0.5,
                normal,
                microquad_part: 0.01,
                receiver: entries[start].id,
                cover: (start % 7) as u32,
                need: ChunkQuery::flags_needed(start as u32 % 3, start as u32 % 2, 1, 0),
            };
            tangent_chunk(&cache, start, len, &query, &mut out);
            for (l, e) in entries[start..start + len].iter().enumerate() {
                let id = c.keys[l] & ID_MASK;
                assert_eq!(id, e.id, "entry {}'s id", start + l);
                let t = triangles[e.id as usize];
                for k in 0..9 {
                    assert_eq!(c.planes[k][l].to_bits(), t[k / 3][k % 3].to_bits());
                }
                let tested = e.tested_in(start as u32 % 3, start as u32 % 2, 1, 0)
                    && e.id != query.receiver
                    && e.id != query.cover;
                assert_eq!(out.tested >> l & 1 == 1, tested, "entry {}", start + l);
                let minus = t.map(|v| v - query.p);
                let above = crate::frustum::above_tangent_plane(&minus, normal, 0.01);
                assert_eq!(out.above >> l & 1 == 1, tested && above.is_some());
                if let Some(height) = above {
                    assert_eq!(out.height[l].to_bits(), height.to_bits());
                }
                let from_cache = cache.triangle_minus(start + l, query.p);
                assert_eq!(
                    from_cache.map(|v| v.to_array().map(f32::to_bits)),
                    minus.map(|v| v.to_array().map(f32::to_bits))
                );
                lanes_checked += 1;
            }
            assert_eq!(out.tested >> len, 0, "lanes past the list are no tests");
        }
        assert_eq!(
            lanes_checked,
            (0..entries.len())
                .map(|s| (entries.len() - s).min(LANES))
                .sum::<usize>()
        );
    }
}
