//! A frame's device buffers by intent: sizes per binding, grouped per
//! pass for the report and for `izb info --gpu-memory` (no device needed).

use super::frame_report::PassMemory;
use super::resources::{BufferDesc, GpuBuffer};
use super::shared::{binding, counter, FrameParams, GpuDraw, LightState, BINDING_COUNT};
use ash::vk;

/// The sizes that decide a frame's buffers.
#[derive(Clone, Copy, Debug)]
pub struct FrameSizes {
    pub pixels: u64,
    /// 8×8 tiles of the image (the edge surfaces' table).
    pub tiles: u64,
    /// G-buffer entries: the pixels, then with edge surfaces their rows
    /// of extra surfaces ([`receivers`]).
    pub receivers: u64,
    /// Slots for the edge pixels' extra surfaces and records when the
    /// frame has edge surfaces.
    pub edge_surfaces: Option<EdgeSlots>,
    pub triangles: u64,
    /// Distinct vertices of the triangles (`SceneUpload::vertices`).
    pub vertices: u64,
    /// Double-single vertices a moving eye translates (the shadow pass
    /// with a visibility buffer); 0 elsewhere.
    pub world_vertices: u64,
    pub bvh_nodes: u64,
    pub bvh_prims: u64,
    pub max_cells: u64,
    pub cell_capacity: u64,
    pub lut_entries: u64,
    /// Words of the shadow-map buffer: a depth per texel of every
    /// cascade, and a filtered map's moments twice (0 in an IZB frame).
    pub shadow_map_words: u64,
    /// 32-bit mask halves per pixel ([`crate::settings::IzbSettings::mask_halves`]).
    pub mask_halves: u64,
    /// G-buffer entries that carry their own normal (`B_G_NORMAL`): the
    /// pixels with the shadow pass's depth + normal input, 0 elsewhere.
    pub normal_entries: u64,
    /// Draws of the host's a frame may give (`B_DRAWS`): the shadow
    /// pass's `max_draws` with the host's geometry, 0 elsewhere.
    pub draws: u64,
}

/// A frame's room for edge surfaces: extra surfaces (G-buffer rows and
/// `B_EDGE_COVERAGE`) and edge pixels' records (`B_EDGE_PIXELS`, after the
/// tile table).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EdgeSlots {
    pub surfaces: u64,
    pub pixels: u64,
}

/// Bindings of the frame's descriptor set.
const BINDINGS: usize = BINDING_COUNT as usize;

/// Every device buffer of a frame, indexed by its binding
/// (`shared::binding`), each with the pass it counts toward and its size.
pub fn frame_buffer_descs(z: &FrameSizes) -> [BufferDesc; BINDINGS] {
    let (p, r, t, vec3) = (z.pixels, z.receivers, z.triangles, 12u64);
    // The tile table, then 4 words per edge pixel's record and mask half;
    // a coverage word per extra surface and half.
    let h = z.mask_halves;
    let table = u64::from(izb_contract::size::EDGE_TILE_WORDS) * z.tiles;
    let (edge_pixel_words, edge_coverage_words) = z
        .edge_surfaces
        .map_or((0, 0), |e| (table + 4 * h * e.pixels, h * e.surfaces));
    let d = BufferDesc::device;
    by_binding([
        (
            binding::FRAME,
            d("frame", "frame_params", size_of::<FrameParams>() as u64),
        ),
        (binding::TRIANGLES, d("scene", "triangle_corners", t * 12)),
        (binding::VERTICES, d("scene", "vertices", z.vertices * vec3)),
        (
            binding::WORLD_VERTICES,
            d("scene", "world_vertices", z.world_vertices * 2 * vec3),
        ),
        (
            binding::BVH_NODES,
            d("gbuffer", "bvh_nodes", z.bvh_nodes * 32),
        ),
        (
            binding::BVH_PRIMS,
            d("gbuffer", "bvh_prims", z.bvh_prims * 4),
        ),
        (binding::G_POSITION, d("gbuffer", "g_position", r * vec3)),
        (binding::G_AXIS_X, d("gbuffer", "g_axis_x", r * vec3)),
        (binding::G_AXIS_Y, d("gbuffer", "g_axis_y", r * vec3)),
        (binding::G_ID_FLAGS, d("gbuffer", "g_id_flags", r * 4)),
        (
            binding::LIGHT,
            d("light_setup", "light_state", size_of::<LightState>() as u64),
        ),
        (
            binding::COUNTERS,
            d("frame", "counters", counter::WORDS as u64 * 4),
        ),
        (binding::CELL_COVER, d("bin", "cell_cover", z.max_cells * 8)),
        (
            binding::CELL_START,
            d(
                "bin",
                "cell_start",
                (z.max_cells + 1 + scan_blocks(z.max_cells)) * 4,
            ),
        ),
        (
            binding::CELL_TRIANGLES,
            d("bin", "cell_triangles", z.cell_capacity * 4),
        ),
        // Per triangle an entry for the cascades it overflows in and,
        // after a cell-list overrun, one for those it is placed in
        // (`bin.comp`).
        (binding::OVERFLOW, d("bin", "overflow", 2 * t * 4)),
        (
            binding::EDGE_LUT,
            d("evaluate", "edge_lut", z.lut_entries * 4),
        ),
        (binding::MASKS, d("evaluate", "masks", r * 4)),
        (
            binding::MASKS_HIGH,
            d("evaluate", "masks_high", r * 4 * (z.mask_halves - 1)),
        ),
        (
            binding::SHADED,
            d("resolve", "shaded_and_lit_samples", p * 4),
        ),
        (
            binding::TRIANGLE_NORMALS,
            d("scene", "triangle_normals", t * vec3),
        ),
        (
            binding::CELL_RECEIVERS,
            d("bin", "cell_receivers", z.max_cells * 8),
        ),
        (
            binding::SHADOW_MAP,
            d("shadow_map", "shadow_maps", z.shadow_map_words.max(1) * 4),
        ),
        (
            binding::HEAVY_PIXELS,
            d("evaluate", "heavy_pixels", heavy_capacity(r) * 8),
        ),
        (
            binding::EDGE_PIXELS,
            d("gbuffer", "edge_pixels", edge_pixel_words * 4),
        ),
        (
            binding::EDGE_COVERAGE,
            d("gbuffer", "edge_coverage", edge_coverage_words * 4),
        ),
        (
            binding::G_NORMAL,
            d("gbuffer", "g_normal_and_uncertainty", z.normal_entries * 16),
        ),
        (
            binding::DRAWS,
            d("scene", "host_draws", z.draws * size_of::<GpuDraw>() as u64),
        ),
    ])
}

/// Bindings that hold their data in another binding's device buffer, with
/// the name of the buffer they share: their passes never overlap. Only the
/// G-buffer passes (`gbuffer`, `edge_surfaces`) and the shadow-ray peer,
/// which runs no bin, read the BVH; the bin writes its cell list and
/// overflow list after them, over it. This is a render graph's transient
/// aliasing (O'Donnell 2017). A baseline's frame timed over several
/// repetitions copies the BVH in again before each
/// ([`restaged_each_repetition`]); the shadow pass for one view before
/// every frame (`shadow_pass/one_view.rs`).
const SHARED_BUFFERS: [(u32, u32, &str); 2] = [
    (
        binding::BVH_NODES,
        binding::CELL_TRIANGLES,
        "bvh_nodes_then_cell_triangles",
    ),
    (
        binding::BVH_PRIMS,
        binding::OVERFLOW,
        "bvh_prims_then_overflow",
    ),
];

/// Whether binding `b`'s upload must be copied in again before each
/// repetition of a frame's passes: a later pass overwrites it (the light
/// state's reductions, the bin over the BVH).
pub(super) fn restaged_each_repetition(b: u32) -> bool {
    b == binding::LIGHT || SHARED_BUFFERS.iter().any(|&(sharer, _, _)| sharer == b)
}

/// The device buffers a frame allocates for its bindings' descriptions:
/// one per binding, except that the bindings of [`SHARED_BUFFERS`] share
/// one, as large as the larger; and per binding the index of its buffer.
pub(super) fn frame_allocation(
    descs: [BufferDesc; BINDINGS],
) -> (Vec<BufferDesc>, [usize; BINDINGS]) {
    let mut buffers: Vec<BufferDesc> = Vec::with_capacity(BINDINGS);
    let mut at = [usize::MAX; BINDINGS];
    let sharer_of = |owner: u32| SHARED_BUFFERS.iter().find(|s| s.1 == owner);
    for (b, desc) in descs.iter().enumerate() {
        let b = b as u32;
        if SHARED_BUFFERS.iter().any(|s| s.0 == b) {
            continue;
        }
        let mut desc = desc.clone();
        if let Some(&(sharer, _, name)) = sharer_of(b) {
            desc.name = name;
            desc.size = desc.size.max(descs[sharer as usize].size);
            at[sharer as usize] = buffers.len();
        }
        at[b as usize] = buffers.len();
        buffers.push(desc);
    }
    (buffers, at)
}

/// Each description at its binding's index: every binding exactly once (a
/// missing or repeated one panics in the first frame any test builds,
/// not as a wrong buffer in a shader).
fn by_binding(keyed: [(u32, BufferDesc); BINDINGS]) -> [BufferDesc; BINDINGS] {
    let mut slots: [Option<BufferDesc>; BINDINGS] = std::array::from_fn(|_| None);
    for (b, desc) in keyed {
        let name = desc.name;
        let previous = slots[b as usize].replace(desc);
        assert!(previous.is_none(), "binding {b} has two buffers (`{name}`)");
    }
    slots.map(|d| d.expect("every binding has its buffer"))
}

/// G-buffer entries of an image with `extra` edge surfaces: its pixels
/// and whole rows of extra surfaces below it.
pub fn receivers([w, h]: [u32; 2], extra: u64) -> u64 {
    let w = u64::from(w).max(1);
    (u64::from(h) + extra.div_ceil(w)) * w
}

/// Sums buffer sizes per owning pass, keeping each buffer's own size.
pub(super) fn group_by_pass(
    buffers: impl Iterator<Item = (&'static str, &'static str, u64)>,
) -> Vec<PassMemory> {
    let mut out: Vec<PassMemory> = Vec::new();
    for (pass, name, size) in buffers {
        match out.iter_mut().find(|m| m.pass == pass) {
            Some(m) => {
                m.bytes += size;
                m.buffers.push((name, size));
            }
            None => out.push(PassMemory {
                pass,
                bytes: size,
                buffers: vec![(name, size)],
            }),
        }
    }
    out
}

/// Blocks of the bin's prefix sum over at most `max_cells` cells.
pub(super) fn scan_blocks(max_cells: u64) -> u64 {
    max_cells.div_ceil(u64::from(izb_contract::size::SCAN_BLOCK_CELLS))
}

/// Entries of evaluate's heavy-step queue: one pixel in
/// [`HEAVY_QUEUE_FRACTION`] (1 byte per pixel). Pixels past it stay in
/// the tile step: slower, never wrong.
pub(super) fn heavy_capacity(pixels: u64) -> u64 {
    pixels.div_ceil(HEAVY_QUEUE_FRACTION).max(1)
}

/// One queue entry per this many pixels. Measured on an H200 with the
/// default threshold: courtyard queued 44 765 pixels at 960×540 (8.6 % of
/// all pixels) and 89 299 at 1080p, ficus 96 834 at 1080p (4.7 %).
const HEAVY_QUEUE_FRACTION: u64 = 8;

/// First guess of the edge surfaces' slots: one per 8 pixels, at least
/// 1 024 (measured: courtyard 18 % of its pixels at 1080p, default 15 %
/// and grazing 44 % at 240×135; a frame past it is rerun once with room,
/// as for the cell list).
pub(super) fn initial_edge_capacity(pixels: u64) -> u64 {
    (pixels / 8).max(1024)
}

/// First guess of the cell list's entries: 4 per triangle, at least 2^16.
pub(super) fn initial_cell_capacity(triangles: usize) -> u64 {
    (4 * triangles as u64).max(1 << 16)
}

pub(super) fn memory_by_pass(buffers: &[std::sync::Arc<GpuBuffer>]) -> Vec<PassMemory> {
    group_by_pass(buffers.iter().map(|b| (b.desc.pass, b.desc.name, b.size())))
}

/// What the passes accumulate into, back to its starting state: counters
/// 0, empty cell counts, no cover triangle, no receiver. (The light state
/// is copied again from its upload; the shadow maps are cleared by their
/// render pass.)
/// With `traced_edges` the G-buffer words become misses first: the
/// `edge_surfaces` pass fills only the slots it takes, and every pass
/// reads the rest as empty.
pub(super) fn reset_pass_state(
    device: &ash::Device,
    cmd: vk::CommandBuffer,
    buffer: impl Fn(u32) -> vk::Buffer,
    traced_edges: bool,
) {
    let fills = [
        (binding::COUNTERS, 0),
        (binding::CELL_START, 0),
        // Floor bits 0, !id 0.
        (binding::CELL_COVER, 0),
        // z = ~0, reach 0 stored as !0.
        (binding::CELL_RECEIVERS, u32::MAX),
    ];
    let misses = traced_edges.then_some((binding::G_ID_FLAGS, izb_contract::word::ID_MASK));
    for (b, word) in fills.into_iter().chain(misses) {
        // SAFETY: `cmd` is recording; the buffer belongs to the frame and
        // lives until after its fence wait; the fill covers the whole buffer.
        unsafe { device.cmd_fill_buffer(cmd, buffer(b), 0, vk::WHOLE_SIZE, word) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every binding gets a buffer at least its size; only the listed
    /// pairs share one, named after both.
    #[test]
    fn shared_buffers_hold_both_bindings() {
        let descs = frame_buffer_descs(&FrameSizes {
            pixels: 64,
            tiles: 1,
            receivers: 64,
            edge_surfaces: None,
            triangles: 10,
            vertices: 12,
            world_vertices: 0,
            normal_entries: 0,
            draws: 0,
            bvh_nodes: 50_000,
            bvh_prims: 10,
            max_cells: 16,
            cell_capacity: 1 << 16,
            lut_entries: 4,
            shadow_map_words: 0,
            mask_halves: 1,
        });
        let (buffers, at) = frame_allocation(descs.clone());
        assert_eq!(buffers.len(), BINDINGS - SHARED_BUFFERS.len());
        for (b, desc) in descs.iter().enumerate() {
            assert!(
                buffers[at[b]].size >= desc.size,
                "binding {b} ({})",
                desc.name
            );
        }
        let mut shared = 0;
        for b in 0..BINDINGS {
            for c in b + 1..BINDINGS {
                if at[b] == at[c] {
                    let pair = SHARED_BUFFERS
                        .iter()
                        .find(|s| s.0 as usize == b || s.1 as usize == b);
                    let (sharer, owner, name) = *pair.expect("only listed bindings share");
                    assert_eq!(
                        [sharer, owner]
                            .map(|x| x as usize)
                            .iter()
                            .filter(|&&x| x == b || x == c)
                            .count(),
                        2
                    );
                    assert_eq!(buffers[at[b]].name, name);
                    shared += 1;
                }
            }
        }
        assert_eq!(shared, SHARED_BUFFERS.len());
        // The BVH (50 000 nodes of 32 bytes) is the larger of its pair.
        assert_eq!(
            buffers[at[binding::CELL_TRIANGLES as usize]].size,
            50_000 * 32
        );
    }
}
