// common.glsl — the one header every izb compute shader includes.
//
// Mirrored field for field by `src/gpu/shared.rs` (#[repr(C)] + bytemuck,
// with size asserts). Buffers use the scalar block layout
// (GL_EXT_scalar_block_layout), so a `vec3` takes 12 bytes exactly like a
// Rust `[f32; 3]`, and every binding below is one storage buffer of one
// descriptor set shared by all passes (a pass declares only what it reads).
//
// Conventions (README, Conventions; paper-notes/frustum-test.md): positions
// are eye-relative f32 (the f64 → f32 rounding happens on the host after
// subtracting the eye); the frustum-triangle test runs in eye space,
// relative to the pixel's P, never in NDC (light view only places
// triangles and receivers in the grid).

#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_control_flow_attributes : require

#define WORKGROUP_PIXELS_X 8
#define WORKGROUP_PIXELS_Y 8
#define WORKGROUP_PIXELS 64
#define WORKGROUP_LINEAR 256

// ---- bindings (src/gpu/shared.rs: `binding`) ----
#define B_FRAME 0
#define B_TRIANGLES 1
#define B_BVH_NODES 2
#define B_BVH_PRIMS 3
#define B_G_POSITION 4
#define B_G_AXIS_X 5
#define B_G_AXIS_Y 6
#define B_G_ID_FLAGS 7
#define B_LIGHT 8
#define B_COUNTERS 9
#define B_CELL_COVER 10
#define B_CELL_START 11
#define B_CELL_TRIANGLES 12
#define B_OVERFLOW 13
#define B_EDGE_LUT 14
#define B_MASKS 15
#define B_SHADED 16
#define B_TRIANGLE_NORMALS 17
#define B_CELL_RECEIVERS 18
#define B_SHADOW_MAP 19

// ---- G-buffer flags (src/gbuffer: `flags`) ----
#define FLAG_HIT 1u
#define FLAG_SHADOW_TESTED 2u
#define FLAG_AXES_CLAMPED 4u
// GPU only: the receiver's camera-facing normal is −triangle_normals[id].
// The G-buffer stores this bit instead of a normal (12 bytes per pixel):
// the normal is the host's f64 triangle normal either way, so evaluate and
// resolve read exactly what the gbuffer pass saw.
#define FLAG_NORMAL_FLIPPED 8u
#define NO_HIT 0xFFFFFFFFu
// The G-buffer keeps the triangle id and the flags in one word: flags in
// the top 4 bits, the id below (scenes hold fewer than 2^28 − 1
// triangles; the host checks). A miss is flags 0 with every id bit set.
#define ID_BITS 28
#define ID_MASK 0x0FFFFFFFu

uint gbuffer_flags(uint word) {
    return word >> ID_BITS;
}

uint gbuffer_triangle(uint word) {
    return (word & ID_MASK) == ID_MASK ? NO_HIT : (word & ID_MASK);
}

// The receiver's camera-facing normal from its triangle's stored normal.
vec3 receiver_normal(vec3 triangle_normal, uint word) {
    return (gbuffer_flags(word) & FLAG_NORMAL_FLIPPED) != 0u ? -triangle_normal : triangle_normal;
}

// The resolve pass stores the lit fraction exactly in the shaded image's
// alpha: the number of lit samples (0..32), or this value where the pixel
// is not shadow-tested (4 bytes per pixel less than a float image).
#define ALPHA_NOT_TESTED 255u

// ---- skips (src/izb/skips.rs: `Skips::bits`) ----
#define SKIP_FACING_AWAY 1u
#define SKIP_OUTSIDE_BOUNDS 2u
#define SKIP_FULL_MASK 4u
#define SKIP_SATURATED_EDGES 8u
#define SKIP_BEHIND_RECEIVERS 16u
#define SKIP_SHADOW_MAP 32u

// izb::is_receiver: shadow-tested pixels, and with the facing-away skip
// off every hit.
bool is_receiver(uint flags, uint skips) {
    return (flags & FLAG_SHADOW_TESTED) != 0u
        || ((skips & SKIP_FACING_AWAY) == 0u && (flags & FLAG_HIT) != 0u);
}

// ---- sample modes (src/izb/evaluate.rs: `SampleMode`) ----
#define MODE_ONE 0u
#define MODE_LUT32 1u
#define MODE_EXACT32 2u
#define FULL_MASK 0xFFFFFFFFu

// ---- placement of a triangle in one cascade (src/izb/bin.rs: `Placement`) ----
// A cell rectangle is packed as .x = x0 | y0 << 16, .y = x1 | y1 << 16,
// its pyramid level returned beside it.
#define PLACEMENT_CULLED 0xFFFFFFFEu
#define PLACEMENT_OVERFLOW 0xFFFFFFFFu

// ---- list entries (src/izb/bin.rs: `CellEntry`, `OverflowEntry`) ----
// The triangle id in the low ID_BITS; above it a cell entry keeps whether
// the cell is in the first column / first row of the triangle's rectangle
// (footprint::Footprint::touches: whether the triangle lacks the cell to
// the left / below, all a pixel needs to test it once), an overflow entry the cascades
// (bit k = cascade k) whose pixels test it.
#define ENTRY_FIRST_COLUMN (1u << ID_BITS)
#define ENTRY_FIRST_ROW (2u << ID_BITS)

// ---- cascades (src/izb/cascades.rs) ----
#define MAX_CASCADES 4
#define AUTO_MAX_DEPTH_RATIO 16.0
#define MAX_GRID_SIDE 4096
#define DEFAULT_LEVEL_CELLS 1024u
// bin::NO_COVER
#define NO_COVER 0xFFFFFFFFu

// ---- counters (src/gpu/shared.rs: `counter`) ----
#define C_HITS 0
#define C_SHADOW_TESTED 1
#define C_CLAMPED 2
#define C_BINNED 3
#define C_OVERFLOW 4
#define C_CULLED 5
#define C_CELL_ENTRIES 6
#define C_CAPACITY_EXCEEDED 7
#define C_PIXELS_TESTED 8
#define C_EARLY_OUTS 9
#define C_TESTS_SPAWNED 10   // 64-bit: lo, hi
#define C_DEPTH_PASSED 12    // 64-bit
#define C_CELLS_VISITED 14   // 64-bit
#define C_LOOP_BUDGET_EXCEEDED 16
#define C_SATURATED_MASKS 17 // 64-bit
#define C_ENTRIES_BEHIND 19  // cell entries the behind-receivers skip dropped
#define C_TRIANGLES_BEHIND 20 // binned placements dropped from every cell
#define C_SHADOW_MAP_EARLY_OUTS 21 // pixels the cover triangle alone filled
#define C_LEVELS 22          // per cascade k, word C_LEVELS + k: bit l = level l holds a placement
#define C_LEVELS_VISITED 26  // 64-bit
#define C_CELLS_UNTOUCHED 28 // rectangle cells a binned triangle's projection misses
#define C_MASKS_NONEMPTY 29  // 64-bit
#define COUNTER_WORDS 31

// Per-frame constants, written by the host once per frame.
struct FrameParams {
    vec3 cam_corner;      // unnormalised ray direction through image point (0, 0)
    float near;
    vec3 cam_dx;          // d(direction)/dx per pixel
    float far;
    vec3 cam_dy;          // d(direction)/dy per pixel (y down)
    float max_stretch;    // gbuffer::MAX_MICROQUAD_STRETCH
    vec3 light_vec;       // directional: unit vector toward the light; point: eye-relative position
    uint light_is_point;
    vec3 rot_x;           // directional light: light-view rows (f64 on the host, then f32)
    uint width;
    vec3 rot_y;
    uint height;
    vec3 rot_z;
    uint triangle_count;
    uint mode;
    uint cells_hint;      // 0: from the receiver count
    uint level_cells;  // cells per triangle before it overflows; 0: per cascade (cascades::cascade_level_cells)
    uint cell_capacity;   // entries the cell list can hold
    float lut_angle_scale;
    float lut_distance_scale;
    uint lut_angles;
    uint lut_distances;
    uint max_cells;       // cell_start capacity (all cascades' pyramids)
    uint loop_budget;     // evaluate's loop iterations per pixel (lavapipe's cap), else ~0u
    uint skips;           // SKIP_* bits (src/izb/skips.rs)
    float pattern_radius; // frustum::pattern_radius: largest sample distance from the µQuad centre
    vec3 cam_forward;     // unit view direction: view depth = position · cam_forward
    uint cascades;        // 1..4, or 0 for auto (cascades::CascadeCount::code)
    float split_lambda;   // 1 logarithmic splits, 0 uniform
    uint map_side;        // shadow-map frames: texels per side of each cascade's map
    uint map_filter;      // 0 one tap, k for k×k PCF
    uint map_reach;       // texels the map reaches beyond the fitted bounds
    vec2 pattern[32];
};

// One cascade's grid (light_setup::CascadeGrid).
struct CascadeGrid {
    vec2 ndc_min;
    vec2 ndc_max;
    uint cells_x;         // 0 for a cascade without receivers
    uint cells_y;
    uint cell_offset;     // first cell in the cell arrays (pyramids lie back to back)
    uint level_cells;     // a triangle is binned at the finest level where its rectangle holds ≤ this
    uint receivers;
    // Reduction scratch (ordered bits): light-NDC bounds of its µQuads.
    uint ndc_lo[2];
    uint ndc_hi[2];
    uint levels;          // pyramid levels, finest (cells_x × cells_y) to 1×1
};

// Light view, cascades and grids, computed on the GPU by light_setup (no
// readback).
struct LightState {
    vec3 rot_x;
    uint projection;      // 0 orthographic (directional), 1 perspective (point)
    vec3 rot_y;
    uint grid_disabled;
    vec3 rot_z;
    uint receivers;
    vec3 origin;
    uint cascade_count;
    vec2 receiver_z;
    uint behind_light;
    uint total_cells;     // cells of all cascades
    float split[MAX_CASCADES]; // upper view depth per cascade (cascades::split_depths)
    vec2 view_depth;      // near, far of the shadow-tested pixels
    // Reduction scratch, floats in order-preserving uint encoding.
    uint pos_lo[3];
    uint pos_hi[3];
    uint depth_lo;
    uint depth_hi;
    uint z_lo;
    uint z_hi;
    CascadeGrid cascade[MAX_CASCADES];
};

struct Triangle {
    vec3 a;
    vec3 b;
    vec3 c;
};

struct BvhNode {
    vec3 lo;
    uint prim_count;      // 0: inner node
    vec3 hi;
    uint first;           // inner: left child (right = first + 1); leaf: first primitive slot
};

// A float's bits mapped to a uint with the same order, so atomicMin/Max on
// uints reduce floats (no float atomics needed).
uint ordered_bits(float f) {
    uint u = floatBitsToUint(f);
    return (u & 0x80000000u) != 0u ? ~u : (u | 0x80000000u);
}

float from_ordered_bits(uint u) {
    return uintBitsToFloat((u & 0x80000000u) != 0u ? (u & 0x7FFFFFFFu) : ~u);
}

float max_of3(float a, float b, float c) {
    return max(max(a, b), c);
}
