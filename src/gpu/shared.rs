//! The Rust mirror of `shaders/common.glsl`: `#[repr(C)]` + bytemuck structs
//! laid out as the GLSL scalar block layout lays them out (every member
//! 4-byte aligned, `vec3` = `[f32; 3]`), with compile-time size and offset
//! asserts, and the binding, counter and flag constants (kajiya's shared
//! crate does the same). Change one side, change the other.

use crate::izb::cascades::MAX_CASCADES;
use bytemuck::{Pod, Zeroable};
use std::mem::{offset_of, size_of};

/// Descriptor bindings of the one set every pass shares (`B_*`).
pub mod binding {
    pub const FRAME: u32 = 0;
    pub const TRIANGLES: u32 = 1;
    pub const BVH_NODES: u32 = 2;
    pub const BVH_PRIMS: u32 = 3;
    pub const G_POSITION: u32 = 4;
    pub const G_AXIS_X: u32 = 5;
    pub const G_AXIS_Y: u32 = 6;
    /// Triangle id and flags in one word ([`pack_id_flags`]).
    pub const G_ID_FLAGS: u32 = 7;
    pub const LIGHT: u32 = 8;
    pub const COUNTERS: u32 = 9;
    /// Per cell: the conservative shadow map's cover floor (ordered bits)
    /// and !id of its cover triangle ([`crate::izb::bin::Bins::cover`]).
    pub const CELL_COVER: u32 = 10;
    /// Per cell: the count, then (the scan's inclusive end, the scatter's
    /// decrementing cursor) the first entry ([`crate::izb::bin::Bins::cell_start`]).
    pub const CELL_START: u32 = 11;
    pub const CELL_TRIANGLES: u32 = 12;
    pub const OVERFLOW: u32 = 13;
    pub const EDGE_LUT: u32 = 14;
    pub const MASKS: u32 = 15;
    /// Shaded RGB8 with the lit sample count in alpha ([`ALPHA_NOT_TESTED`]).
    pub const SHADED: u32 = 16;
    /// Unit normal per triangle, computed on the host in `f64` exactly as
    /// the CPU twin computes it, then rounded. A receiver's normal is its
    /// triangle's, negated when its G-buffer word has
    /// [`super::FLAG_NORMAL_FLIPPED`].
    pub const TRIANGLE_NORMALS: u32 = 17;
    /// Per cell: lowest receiver z (ordered bits) and !reach
    /// ([`crate::izb::bin::CellReceivers`]).
    pub const CELL_RECEIVERS: u32 = 18;
    /// The shadow-map baseline's maps, cascade after cascade, one
    /// order-preserving distance word per texel ([`ordered_bits`]; empty
    /// texels `u32::MAX`); 4 bytes in an IZB frame.
    pub const SHADOW_MAP: u32 = 19;
    /// Number of bindings.
    pub const COUNT: u32 = 20;
}

/// Word indices into the counters buffer (`C_*`); 64-bit counters take two
/// words, low first.
pub mod counter {
    pub const HITS: usize = 0;
    pub const SHADOW_TESTED: usize = 1;
    pub const CLAMPED: usize = 2;
    pub const BINNED: usize = 3;
    pub const OVERFLOW: usize = 4;
    pub const CULLED: usize = 5;
    pub const CELL_ENTRIES: usize = 6;
    pub const CAPACITY_EXCEEDED: usize = 7;
    pub const PIXELS_TESTED: usize = 8;
    pub const EARLY_OUTS: usize = 9;
    pub const TESTS_SPAWNED: usize = 10;
    pub const DEPTH_PASSED: usize = 12;
    pub const CELLS_VISITED: usize = 14;
    pub const LOOP_BUDGET_EXCEEDED: usize = 16;
    pub const SATURATED_MASKS: usize = 17;
    pub const ENTRIES_BEHIND: usize = 19;
    pub const TRIANGLES_BEHIND: usize = 20;
    pub const SHADOW_MAP_EARLY_OUTS: usize = 21;
    /// Per cascade k, word `LEVELS + k`: bit l set when pyramid level l
    /// holds a placement (atomicOr in the bin count).
    pub const LEVELS: usize = 22;
    pub const LEVELS_VISITED: usize = 26;
    pub const CELLS_UNTOUCHED: usize = 28;
    pub const MASKS_NONEMPTY: usize = 29;
    /// Words in the counters buffer.
    pub const WORDS: usize = 31;
}

/// Local sizes of the pixel passes (8×8 tiles) and the linear passes.
pub const WORKGROUP_PIXELS: [u32; 2] = [8, 8];
pub const WORKGROUP_LINEAR: u32 = 256;

/// `MODE_*` of `FrameParams::mode`.
pub mod mode {
    pub const ONE: u32 = 0;
    pub const LUT32: u32 = 1;
    pub const EXACT32: u32 = 2;
}

/// `FrameParams`: per-frame constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FrameParams {
    pub cam_corner: [f32; 3],
    pub near: f32,
    pub cam_dx: [f32; 3],
    pub far: f32,
    pub cam_dy: [f32; 3],
    pub max_stretch: f32,
    pub light_vec: [f32; 3],
    pub light_is_point: u32,
    pub rot_x: [f32; 3],
    pub width: u32,
    pub rot_y: [f32; 3],
    pub height: u32,
    pub rot_z: [f32; 3],
    pub triangle_count: u32,
    pub mode: u32,
    pub cells_hint: u32,
    pub level_cells: u32,
    pub cell_capacity: u32,
    pub lut_angle_scale: f32,
    pub lut_distance_scale: f32,
    pub lut_angles: u32,
    pub lut_distances: u32,
    pub max_cells: u32,
    /// Loop iterations `evaluate` may run per pixel: lavapipe (gallivm)
    /// silently ends a shader's loops after 65535 iterations in total, so
    /// there the shader stops early and raises `LOOP_BUDGET_EXCEEDED`
    /// instead of returning a wrong mask; `u32::MAX` elsewhere.
    pub loop_budget: u32,
    /// [`crate::izb::Skips::bits`].
    pub skips: u32,
    pub pattern_radius: f32,
    /// Unit view direction (view depth = position · it).
    pub cam_forward: [f32; 3],
    /// [`crate::izb::CascadeCount::code`]: 1..=4, 0 for auto.
    pub cascades: u32,
    pub split_lambda: f32,
    /// Shadow-map frames ([`crate::baseline`]): texels per side of each
    /// cascade's map, the filter (0 one tap, k for k×k PCF) and the texels
    /// the map reaches beyond the fitted bounds; 0 in an IZB frame.
    pub map_side: u32,
    pub map_filter: u32,
    pub map_reach: u32,
    pub pattern: [[f32; 2]; 32],
}
const _: () = assert!(size_of::<FrameParams>() == 192 + 256);
const _: () = assert!(offset_of!(FrameParams, mode) == 112);
const _: () = assert!(offset_of!(FrameParams, cam_forward) == 160);
const _: () = assert!(offset_of!(FrameParams, pattern) == 192);

/// `CascadeGrid`: one cascade's grid ([`crate::izb::light_setup::CascadeGrid`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct CascadeGrid {
    pub ndc_min: [f32; 2],
    pub ndc_max: [f32; 2],
    pub cells_x: u32,
    pub cells_y: u32,
    pub cell_offset: u32,
    pub level_cells: u32,
    pub receivers: u32,
    pub ndc_lo: [u32; 2],
    pub ndc_hi: [u32; 2],
    pub levels: u32,
}
const _: () = assert!(size_of::<CascadeGrid>() == 56);

/// `LightState`: light view, cascades and grids, written on the GPU by
/// `light_setup`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct LightState {
    pub rot_x: [f32; 3],
    pub projection: u32,
    pub rot_y: [f32; 3],
    pub grid_disabled: u32,
    pub rot_z: [f32; 3],
    pub receivers: u32,
    pub origin: [f32; 3],
    pub cascade_count: u32,
    pub receiver_z: [f32; 2],
    pub behind_light: u32,
    pub total_cells: u32,
    pub split: [f32; MAX_CASCADES],
    pub view_depth: [f32; 2],
    pub pos_lo: [u32; 3],
    pub pos_hi: [u32; 3],
    pub depth_lo: u32,
    pub depth_hi: u32,
    pub z_lo: u32,
    pub z_hi: u32,
    pub cascade: [CascadeGrid; MAX_CASCADES],
}
const _: () = assert!(size_of::<LightState>() == 144 + 4 * 56);
const _: () = assert!(offset_of!(LightState, receiver_z) == 64);
const _: () = assert!(offset_of!(LightState, pos_lo) == 104);
const _: () = assert!(offset_of!(LightState, cascade) == 144);

impl LightState {
    /// The state before the reductions: every minimum at the largest
    /// ordered value, every maximum at the smallest.
    pub fn reset() -> Self {
        let grid = CascadeGrid {
            ndc_lo: [u32::MAX; 2],
            ndc_hi: [0; 2],
            ..Zeroable::zeroed()
        };
        LightState {
            pos_lo: [u32::MAX; 3],
            pos_hi: [0; 3],
            depth_lo: u32::MAX,
            depth_hi: 0,
            z_lo: u32::MAX,
            z_hi: 0,
            cascade: [grid; MAX_CASCADES],
            ..Zeroable::zeroed()
        }
    }
}

/// `Triangle`: three eye-relative vertices.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuTriangle {
    pub v: [[f32; 3]; 3],
}
const _: () = assert!(size_of::<GpuTriangle>() == 36);

/// `BvhNode`: a node of the G-buffer pass's BVH2.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct BvhNode {
    pub lo: [f32; 3],
    /// 0 for an inner node.
    pub prim_count: u32,
    pub hi: [f32; 3],
    /// Inner: left child (right = first + 1); leaf: first primitive slot.
    pub first: u32,
}
const _: () = assert!(size_of::<BvhNode>() == 32);

/// Bits of the G-buffer word that hold the triangle id (`ID_BITS`); the
/// four flag bits sit above them.
pub const ID_BITS: u32 = 28;
/// Id field of a miss; also one more than the largest triangle id.
pub const ID_MASK: u32 = (1 << ID_BITS) - 1;

/// GPU-only G-buffer flag (`FLAG_NORMAL_FLIPPED`): the receiver's
/// camera-facing normal is minus its triangle's stored normal. Stored
/// instead of a per-pixel normal (12 bytes per pixel).
pub const FLAG_NORMAL_FLIPPED: u32 = 8;

/// Alpha of a shaded pixel that is not shadow-tested (`ALPHA_NOT_TESTED`);
/// otherwise alpha is the count of lit samples, 0..=32.
pub const ALPHA_NOT_TESTED: u8 = 255;

/// The lit fraction a shaded pixel's alpha encodes: exact (k/32), NaN
/// where not shadow-tested, as [`crate::izb::resolve`] gives it.
pub fn lit_fraction_of_alpha(alpha: u8) -> f32 {
    if alpha == ALPHA_NOT_TESTED {
        f32::NAN
    } else {
        f32::from(alpha) / 32.0
    }
}

/// The G-buffer word of a triangle id ([`crate::gbuffer::NO_HIT`] for a
/// miss) and its flags (`gbuffer_triangle` / `gbuffer_flags` in GLSL).
pub fn pack_id_flags(triangle: u32, flags: u32) -> u32 {
    let id = if triangle == crate::gbuffer::NO_HIT {
        ID_MASK
    } else {
        triangle & ID_MASK
    };
    (flags << ID_BITS) | id
}

/// Inverse of [`pack_id_flags`]: (triangle id, flags).
pub fn unpack_id_flags(word: u32) -> (u32, u32) {
    let id = word & ID_MASK;
    let id = if id == ID_MASK {
        crate::gbuffer::NO_HIT
    } else {
        id
    };
    (id, word >> ID_BITS)
}

/// The GLSL float ↔ ordered-uint map (`ordered_bits` in the shadow-map
/// shaders), declared with its CPU twin.
pub use crate::baseline::shadow_map::{from_ordered_bits, ordered_bits};
