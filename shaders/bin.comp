#version 460
// Pass 2, `bin` — GPU twin of `izb::cpu::bin::bin`: a counting sort of
// triangles into every cascade's light-space grid pyramid ([Compute IZB]; the
// pyramids lie back to back in the cell arrays, levels finest first; each
// triangle at the finest level where its rectangle holds at most
// level_cells cells, listed in the cells its projection touches:
// izb::cpu::footprint), in these dispatches:
//   STEP_LEVELS     (per triangle) per cascade the pyramid levels that hold
//                   a placement (C_LEVELS + k);
//   STEP_RECEIVERS  (per pixel, behind-receivers skip only) per cell of
//                   every used level the farthest receiver and its reach
//                   (bin::cell_receivers);
//   STEP_COUNT      (per triangle) per cascade its placement (from its
//                   light-view vertices), an atomic count per covered cell
//                   (in cell_start) and the cover floor (the conservative
//                   shadow map); one overflow entry tagged with the
//                   cascades it overflows in;
//   (bin_scan.comp) the inclusive prefix sum of the counts in place: each
//                   cell's entry in cell_start becomes its end, the total
//                   checked against the cell list's capacity;
//   STEP_SCATTER    (per triangle) entries into their cells (light view and
//                   rectangle recomputed with the count's `precise`
//                   arithmetic, so the same cells), each taking the slot
//                   below its cell's cursor (atomic decrement: cell_start
//                   ends at each cell's first entry, with no cursor array),
//                   and each cell's cover triangle among the best floors.
// When the total exceeds the capacity, bin_scan raises C_CAPACITY_EXCEEDED
// and STEP_SCATTER scatters nothing. With frame.overrun_exact (a frame
// nobody reruns) each triangle placed in cells goes once
// into the overflow list instead, tagged with those cascades, and evaluate
// skips the grid. Every pixel then tests every triangle of its cascade: the
// frame stays exact, the slow way (a triangle that cannot shadow a sample
// only ORs in an empty mask), and C_CELL_ENTRIES is the need the host grows
// the list to for the next frame; without it the frame's masks are
// incomplete and the host reruns it. No frame reads a corrupt grid.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_LINEAR) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
#include "scene_triangles.glsl"
layout(scalar, binding = B_LIGHT) readonly buffer LightBuf { LightState light; };
layout(scalar, binding = B_COUNTERS) buffer CountBuf { uint counters[]; };
// Per cell, the conservative shadow map: .x = ordered bits of the best
// cover floor (atomicMax; 0 = none), .y = ~id of the lowest-id triangle
// with that floor (atomicMax; 0 = bin::NO_COVER). Filled with 0.
layout(scalar, binding = B_CELL_COVER) buffer CellCoverBuf { uvec2 cell_cover[]; };
layout(scalar, binding = B_CELL_START) buffer StartBuf { uint cell_start[]; };
layout(scalar, binding = B_CELL_TRIANGLES) writeonly buffer CellTriBuf { uint cell_triangles[]; };
layout(scalar, binding = B_OVERFLOW) writeonly buffer OverflowBuf { uint overflow_list[]; };
layout(scalar, binding = B_G_POSITION) readonly buffer PosBuf { vec3 g_position[]; };
layout(scalar, binding = B_G_AXIS_X) readonly buffer AxBuf { vec3 g_axis_x[]; };
layout(scalar, binding = B_G_AXIS_Y) readonly buffer AyBuf { vec3 g_axis_y[]; };
layout(scalar, binding = B_G_ID_FLAGS) readonly buffer GidBuf { uint g_id_flags[]; };
// Before evaluate, a hit pixel's word holds its cascade (light_setup.comp).
layout(scalar, binding = B_MASKS) readonly buffer MaskBuf { uint pixel_cascade[]; };

#include "light_view.glsl"
#include "edge_receivers.glsl"
#define LOOP_BUDGET_SLOTS WORKGROUP_LINEAR
#include "loop_budget.glsl"
#include "counters.glsl"

// Per cell (binding B_CELL_RECEIVERS, filled with ~0 before the frame):
// .x = ordered bits of the lowest light-view z of the µQuad centres of the
// receivers touching the cell (atomicMin), .y = ~reach (atomicMin, so the
// largest reach wins): bin::CellReceivers.
layout(scalar, binding = B_CELL_RECEIVERS) buffer CellRecvBuf { uvec2 cell_receivers[]; };

// Triangle `id` in light view (to_light_view is `precise`): the placement
// input of STEP_COUNT and STEP_SCATTER, as the CPU twin's `light_view`.
Triangle light_view_triangle(uint id) {
    Triangle w = scene_triangle(id);
    return Triangle(to_light_view(w.a), to_light_view(w.b), to_light_view(w.c));
}


#include "bin_placement.glsl"

#ifdef STEP_RECEIVERS
// Registers (z, reach) in every cell of `cells` at `level_start`. On the
// coarse levels a subgroup's pixels (a row of 32) share one rectangle:
// then one lane registers their lowest z and largest reach, one pair of
// atomics per cell instead of 32 on the same words. Otherwise each lane
// registers its own (collecting lanes rectangle by rectangle serialises
// the finest level's many small rectangles). min and max do not depend
// on order: the cells end as the CPU twin's.
void register_receivers(uint k, uint level_start, uint l, uvec4 cells, uint z, uint reach) {
    bool shared_rectangle = subgroupAllEqual(cells);
    if (shared_rectangle) {
        z = subgroupMin(z);
        reach = subgroupMax(reach);
    }
    if (!shared_rectangle || subgroupElect()) {
        for (uint y = cells.y; y <= cells.w && spend_trip(); ++y) {
            for (uint x = cells.x; x <= cells.z && spend_trip(); ++x) {
                uint c = cell_index_at(k, level_start, l, x, y);
                // A relaxed atomic load first: the words only fall, so a
                // value already at or below this pixel's needs no
                // read-modify-write (neighbouring pixels share cells and
                // nearly share z: most registrations end here).
                if (z < atomicLoad(cell_receivers[c].x, gl_ScopeDevice, 0,
                                   gl_SemanticsRelaxed)) {
                    atomicMin(cell_receivers[c].x, z);
                }
                if (~reach < atomicLoad(cell_receivers[c].y, gl_ScopeDevice,
                                        0, gl_SemanticsRelaxed)) {
                    atomicMin(cell_receivers[c].y, ~reach);
                }
            }
        }
    }
}
#endif

#if defined(STEP_COUNT) || defined(STEP_SCATTER)
// Per-invocation counts of the walk (STEP_COUNT).
uint walk_untouched = 0u, walk_dropped = 0u;

// One cell (x, y) of triangle `id`'s rectangle at its level: counted
// (STEP_COUNT: the entry and the cover floor) or scattered (STEP_SCATTER:
// the entry into the slot below the cell's cursor, the cover triangle);
// whether it is listed there.
bool bin_cell(uint id, Triangle t, uint k, Footprint f, uint level_start, uint x, uint y) {
    if (!touches(f, int(x), int(y))) {
#ifdef STEP_COUNT
        walk_untouched += 1u;
#endif
        return false;
    }
    uint c = cell_index_at(k, level_start, f.level, x, y);
    if (behind_receivers(t, k, f.level, c, x, y)) {
#ifdef STEP_COUNT
        walk_dropped += 1u;
#endif
        return false;
    }
    if (!penumbra_reaches_cell(t, k, f, c, x, y)) return false;
    uint fl = cover_floor(t, k, f.level, x, y);
#ifdef STEP_COUNT
    atomicAdd(cell_start[c], 1u);
    if (fl != 0u) atomicMax(cell_cover[c].x, fl);
#else
    uint slot = atomicAdd(cell_start[c], 0xFFFFFFFFu) - 1u;
    // CellEntry::new: whether the cells to the left / below lack it.
    uint entry = id | (touches(f, int(x) - 1, int(y)) ? 0u : ENTRY_FIRST_COLUMN)
        | (touches(f, int(x), int(y) - 1) ? 0u : ENTRY_FIRST_ROW);
    if (slot < frame.cell_capacity) cell_triangles[slot] = entry;
    if (fl != 0u && fl == cell_cover[c].x) atomicMax(cell_cover[c].y, ~id);
#endif
    return true;
}

// Every `stride`-th cell of the rectangle from `first`, row by row;
// whether any is listed.
bool bin_cells(uint id, Triangle t, uint k, Footprint f, uint first, uint stride) {
    uint level_start = level_offset(k, f.level);
    uint w = f.rect.z - f.rect.x + 1u;
    uint n = w * (f.rect.w - f.rect.y + 1u);
    bool listed = false;
    for (uint j = first; j < n && spend_trip(); j += stride) {
        if (bin_cell(id, t, k, f, level_start, f.rect.x + j % w, f.rect.y + j / w)) listed = true;
    }
    return listed;
}

Triangle broadcast_triangle(Triangle t, uint lane) {
    return Triangle(subgroupBroadcast(t.a, lane), subgroupBroadcast(t.b, lane),
                    subgroupBroadcast(t.c, lane));
}

Footprint broadcast_footprint(Footprint f, uint lane) {
    return Footprint(subgroupBroadcast(f.level, lane), subgroupBroadcast(f.rect, lane),
                     subgroupBroadcast(f.v0, lane), subgroupBroadcast(f.v1, lane),
                     subgroupBroadcast(f.v2, lane), subgroupBroadcast(f.orientation, lane),
                     subgroupBroadcast(f.pad, lane));
}

// The cells of every lane's rectangle in cascade k (`cells`: this lane
// has one); whether this lane's triangle is listed in any. A rectangle of
// up to a subgroup's worth of cells is walked by its own lane; a larger
// one (a big triangle: up to `level_cells` cells) by the whole subgroup,
// a cell per lane, one rectangle after another — else one lane's long
// walk holds its subgroup, and a scene of few big triangles leaves the
// GPU nearly idle (measured on an H200 at 1920×1080, `default`'s 2 722
// triangles: count 1.6 ms, scatter 2.4 ms). Call in subgroup-uniform
// control flow.
bool walk_rectangles(Triangle t, uint k, Footprint f, bool cells) {
    uint n = cells ? (f.rect.z - f.rect.x + 1u) * (f.rect.w - f.rect.y + 1u) : 0u;
    bool big = n > gl_SubgroupSize;
    uint id = gl_GlobalInvocationID.x;
    bool listed = false;
    if (cells && !big) listed = bin_cells(id, t, k, f, 0u, 1u);
    uvec4 queue = subgroupBallot(big);
    while (queue != uvec4(0u)) {
        uint leader = subgroupBallotFindLSB(queue);
        queue[leader / 32u] &= ~(1u << (leader % 32u));
        uint leader_id = subgroupBroadcast(id, leader);
        bool any = bin_cells(leader_id, broadcast_triangle(t, leader), k,
                             broadcast_footprint(f, leader), gl_SubgroupInvocationID,
                             gl_SubgroupSize);
        any = subgroupAny(any);
        if (gl_SubgroupInvocationID == leader) listed = any;
    }
    return listed;
}
#endif

void main() {
    loop_budget_reset();
#ifdef STEP_RECEIVERS
    // One thread per receiver (the pixels, then the edge pixels' extra
    // surfaces): bin::cell_receivers, in the receiver's cascade, on every
    // level of its pyramid.
    uint i = gl_GlobalInvocationID.x;
    if (i >= frame.width * frame.receiver_rows || light.grid_disabled != 0u) return;
    if (!is_receiver(gbuffer_flags(g_id_flags[i]), frame.skips)) return;
    uint k = pixel_cascade[i];
    vec3 p = g_position[i];
    vec2 lo, hi;
    receiver_grid_box(k, i, p, g_axis_x[i], g_axis_y[i], lo, hi);
    // receivers::receiver_key: z toward a directional light, −depth for a point
    // light: the lowest is the farthest.
    vec3 p_light = to_light_view(p);
    uint z = ordered_bits(light.projection == 0u ? p_light.z : -p_light.z);
    // receivers::reach_box: the reach spans the box and P itself, which
    // an edge surface's covered box need not hold.
    vec2 centre = grid_coords(k, ndc_of(p_light));
    vec2 reach_lo = min(lo, centre), reach_hi = max(hi, centre);
    // Every used level of the pyramid (the others are never read): the
    // level-0 box scaled by 2^-l.
    uint used = counters[C_LEVELS + k];
    uint level_start = light.cascade[k].cell_offset;
    for (uint l = 0u; l < light.cascade[k].levels && spend_trip(); ++l) {
        uvec2 d = level_dims(k, l);
        if ((used & (1u << l)) != 0u) {
            uvec4 cells;
            if (!cell_range_at(k, l, lo, hi, cells)) break;
            ivec2 e = ivec2(-int(l));
            vec2 extent = ldexp(reach_hi, e) - ldexp(reach_lo, e);
            uint reach = uint(ceil(max(extent.x, extent.y))) + 1u;
            register_receivers(k, level_start, l, cells, z, reach);
        }
        level_start += d.x * d.y;
    }
    loop_budget_report();
#endif

#ifdef STEP_LEVELS
    // bin::bin's level table: the levels that hold a placement, per
    // cascade (ORed per subgroup: every triangle writes the same words).
    uint id = gl_GlobalInvocationID.x;
    bool valid = id < frame.triangle_count;
    Triangle t;
    if (valid) t = light_view_triangle(id);
    for (uint k = 0u; k < light.cascade_count; ++k) {
        Footprint f;
        bool placed = valid && placement_in(t, k, f) == PLACEMENT_CELLS;
        count_or(C_LEVELS + k, placed ? 1u << f.level : 0u);
    }
#endif

#ifdef STEP_COUNT
    uint id = gl_GlobalInvocationID.x;
    bool valid = id < frame.triangle_count;
    Triangle t;
    if (valid) t = light_view_triangle(id);
    uint overflows = 0u;
    bool placed = false;
    uint binned = 0u, dropped_everywhere = 0u;
    for (uint k = 0u; k < light.cascade_count; ++k) {
        Footprint f;
        uint p = valid ? placement_in(t, k, f) : PLACEMENT_CULLED;
        if (p == PLACEMENT_OVERFLOW) overflows |= 1u << k;
        bool cells = p == PLACEMENT_CELLS;
        if (cells) {
            placed = true;
            binned += 1u;
        }
        if (!walk_rectangles(t, k, f, cells) && cells) dropped_everywhere += 1u;
    }
    if (overflows != 0u) {
        overflow_list[atomicAdd(counters[C_OVERFLOW], 1u)] = id | (overflows << ID_BITS);
    }
    loop_budget_report();
    count_add(C_CELLS_UNTOUCHED, walk_untouched);
    count_add(C_CULLED, valid && overflows == 0u && !placed ? 1u : 0u);
    count_add(C_BINNED, binned);
    count_add(C_ENTRIES_BEHIND, walk_dropped);
    count_add(C_TRIANGLES_BEHIND, dropped_everywhere);
#endif

#ifdef STEP_SCATTER
    uint id = gl_GlobalInvocationID.x;
    bool valid = id < frame.triangle_count;
    // The rectangles again: the same `precise` arithmetic on the same
    // floats as STEP_COUNT, so the same cells.
    Triangle t;
    if (valid) t = light_view_triangle(id);
    // Uniform over the dispatch: bin_scan wrote it before this step.
    bool overrun = counters[C_CAPACITY_EXCEEDED] != 0u;
    bool slow_exact = overrun && frame.overrun_exact != 0u;
    uint placed_in = 0u;
    for (uint k = 0u; k < light.cascade_count; ++k) {
        Footprint f;
        bool cells = valid && placement_in(t, k, f) == PLACEMENT_CELLS;
        if (slow_exact) {
            placed_in |= cells ? 1u << k : 0u;
        } else if (!overrun) {
            walk_rectangles(t, k, f, cells);
        }
    }
    // At most one entry here and one from STEP_COUNT per triangle: the
    // overflow list holds two per triangle.
    if (placed_in != 0u) {
        overflow_list[atomicAdd(counters[C_OVERFLOW], 1u)] = id | (placed_in << ID_BITS);
    }
    loop_budget_report();
#endif
}
