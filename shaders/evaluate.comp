#version 460
// Pass 3, `evaluate` — GPU twin of `izb::cpu::evaluate::evaluate`, in two
// steps (build.rs compiles this file once per step):
//
// STEP_TILES: one thread per pixel, 8×8 tiles ([Compute IZB]). A
// shadow-tested pixel's µQuad maps to a rectangle of cells on every level
// of its cascade's grid pyramid; every triangle listed in those cells on
// the non-empty levels, plus the overflow entries of its cascade, is a
// candidate, tested in the first cell of the pixel's rectangle that lists
// it (CellEntry::tested_in, as on the CPU). With the shadow-map skip the
// cover triangle of the centre's cell is tested first, and a pixel it
// alone fills skips the rest. Triangles reach the tile through shared
// memory in batches of 64: the overflow list (the same for every pixel),
// then per level the tile's elected cell (the lowest first cell among its
// pixels); cells a pixel covers beyond the elected one are read from
// global memory. Barriers are reached by every thread: finished or
// inactive pixels still help load batches ([Compute IZB]'s `live` flag).
//
// STEP_HEAVY: a pixel whose cells list more than frame.heavy_entries
// candidates is queued by the tile step instead of walking them alone
// (on a GPU one thread's sequential candidates are the whole dispatch's
// tail: a courtyard pixel at 960×540 tests 40 967 triangles). Here a
// workgroup per queued pixel splits its candidates over its threads, ORs
// their masks (order-independent, so the mask is the tile step's), and
// stops when the shared mask is full. Wyman et al. (TVCG 2016) balance
// long lists the same way.
//
// MASK_HALF_HIGH (with either step): MODE_PAIRED64's second 32 pairs,
// the same steps with the turned patterns (pixel_frustum.glsl's
// PAIR_LIGHT, PAIR_PIXEL), written to B_MASKS_HIGH with their own heavy
// queue count. The host runs them first: a pixel's cascade is read from
// its B_MASKS word, which the first half overwrites.
//
// The test itself: pixel_frustum.glsl. Masks are ORed per pixel, stopping
// when full (Wyman et al. 2015, §6.6): when the samples the receiver
// covers are all set (an edge pixel's surfaces, edge_receivers.glsl, cover
// some of them). The tiles run over every receiver row: the image's, then
// the extra surfaces' (frame.receiver_rows).
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

#ifdef STEP_TILES
layout(local_size_x = WORKGROUP_PIXELS_X, local_size_y = WORKGROUP_PIXELS_Y) in;
#define LOOP_BUDGET_SLOTS WORKGROUP_PIXELS
#else
layout(local_size_x = WORKGROUP_LINEAR) in;
#define LOOP_BUDGET_SLOTS WORKGROUP_LINEAR
#endif

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_G_POSITION) readonly buffer PosBuf { vec3 g_position[]; };
layout(scalar, binding = B_G_AXIS_X) readonly buffer AxBuf { vec3 g_axis_x[]; };
layout(scalar, binding = B_G_AXIS_Y) readonly buffer AyBuf { vec3 g_axis_y[]; };
layout(scalar, binding = B_G_ID_FLAGS) readonly buffer GidBuf { uint g_id_flags[]; };
layout(scalar, binding = B_TRIANGLE_NORMALS) readonly buffer TriNrmBuf { vec3 triangle_normals[]; };
layout(scalar, binding = B_G_NORMAL) readonly buffer GNrmBuf { vec4 g_normal[]; };
layout(scalar, binding = B_LIGHT) readonly buffer LightBuf { LightState light; };
layout(scalar, binding = B_COUNTERS) buffer CountBuf { uint counters[]; };
#include "scene_triangles.glsl"
layout(scalar, binding = B_CELL_COVER) readonly buffer CellCoverBuf { uvec2 cell_cover[]; };
layout(scalar, binding = B_CELL_START) readonly buffer StartBuf { uint cell_start[]; };
layout(scalar, binding = B_CELL_TRIANGLES) readonly buffer CellTriBuf { uint cell_triangles[]; };
layout(scalar, binding = B_OVERFLOW) readonly buffer OverflowBuf { uint overflow_list[]; };
layout(scalar, binding = B_EDGE_LUT) readonly buffer LutBuf { uint edge_lut[]; };
// Read first: a hit pixel's word holds its cascade (light_setup.comp).
layout(scalar, binding = B_MASKS) buffer MaskBuf { uint masks[]; };
// The heavy step's queue: (pixel, cascade).
layout(scalar, binding = B_HEAVY_PIXELS) buffer HeavyBuf { uvec2 heavy_pixels[]; };

#ifdef MASK_HALF_HIGH
layout(scalar, binding = B_MASKS_HIGH) buffer MaskHighBuf { uint masks_high[]; };
#define HALF_MASKS masks_high        // where this half's masks go
#define C_HALF_HEAVY_PIXELS C_HEAVY_PIXELS_HIGH
#else
#define HALF_MASKS masks
#define C_HALF_HEAVY_PIXELS C_HEAVY_PIXELS
#endif

#include "light_view.glsl"
#include "edge_receivers.glsl"
#include "loop_budget.glsl"
#include "counters.glsl"

#define NO_CELL 0xFFFFFFFFu
// DEPTH_TOLERANCE_*, SATURATION_MARGIN: contract.glsl (frustum.rs documents them).
#define HALF_DIAGONAL 0.70710677
#define PI 3.14159265

#include "entry_normal.glsl"
#include "pixel_frustum.glsl"

// The candidates listed in the pixel's cells on the used levels of its
// pyramid, counted until they pass `limit` (only that matters).
uint listed_entries(uint limit) {
    uint total = 0u;
    uint level_start = light.cascade[px_cascade].cell_offset;
    for (uint l = 0u; l < light.cascade[px_cascade].levels && total <= limit && spend_trip(); ++l) {
        uvec2 d = level_dims(px_cascade, l);
        uvec4 r;
        if (level_used(l) && cell_range_at(px_cascade, l, px_lo, px_hi, r)) {
            for (uint y = r.y; y <= r.w && total <= limit && spend_trip(); ++y) {
                for (uint x = r.x; x <= r.z && total <= limit && spend_trip(); ++x) {
                    uint c = cell_index_at(px_cascade, level_start, l, x, y);
                    total += cell_start[c + 1u] - cell_start[c];
                }
            }
        }
        level_start += d.x * d.y;
    }
    return total;
}

// The per-invocation work counters, summed per subgroup.
void add_work_counters() {
    count_add64(C_SATURATED_MASKS, saturated_masks);
    count_add64(C_TESTS_SPAWNED, tests_spawned);
    count_add64(C_DEPTH_PASSED, depth_passed);
    count_add64(C_CELLS_VISITED, cells_visited);
    count_add64(C_LEVELS_VISITED, levels_visited);
    count_add64(C_MASKS_NONEMPTY, masks_nonempty);
}

#ifdef STEP_TILES
shared Triangle sm_tri[WORKGROUP_PIXELS];
shared uint sm_id[WORKGROUP_PIXELS];
shared uint sm_cell;

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    uint lid = gl_LocalInvocationIndex;
    uint i = pixel.y * frame.width + pixel.x;
    // The image's rows, then the edge pixels' extra surfaces.
    bool inside = pixel.x < frame.width && pixel.y < frame.receiver_rows;
    uint pixel_flags = inside ? gbuffer_flags(g_id_flags[i]) : 0u;
    bool live = inside && is_receiver(pixel_flags, frame.skips);
    stop_when_full = (frame.skips & SKIP_FULL_MASK) != 0u;
    uint mask = 0u;
    loop_budget_reset();
    // A grid overrun (C_CAPACITY_EXCEEDED) leaves cell lists incomplete:
    // skip them (uniformly); the host reruns the frame with room.
    bool grid_usable = counters[C_CAPACITY_EXCEEDED] == 0u;
    bool deferred = false;   // the grid's candidates go to the heavy step
    if (live) {
        pixel_frustum(i, masks[i]);
        if (!grid_usable) px_cover = NO_COVER;
        // An area light's samples below the horizon: the receiver's own.
        if (px_soft && paired_mode()) {
            mask = paired_below_horizon();
        } else if (px_soft) {
            bool cheap;
            mask = edge_mask(below_horizon_function(), cheap);
        }
        // 0. The conservative shadow map: its mask is 0 unless the cover
        // triangle is one of the pixel's candidates (the grid offers every
        // triangle able to shadow a sample), so ORing it in first and not
        // testing it again leaves the mask as it was.
        if (px_cover != NO_COVER && px_cover != px_receiver) {
            tests_spawned += 1u;
            mask |= triangle_mask(scene_triangle(px_cover));
        }
        covered = (mask & px_wanted) == px_wanted;
        if (!done(mask) && px_has_cells && grid_usable && frame.heavy_entries != 0u
                && listed_entries(frame.heavy_entries) > frame.heavy_entries) {
            uint slot = atomicAdd(counters[C_HALF_HEAVY_PIXELS], 1u);
            if (slot < frame.heavy_capacity) {
                heavy_pixels[slot] = uvec2(i, px_cascade);
                deferred = true;
            }
        }
    }

    // 1. The overflow list, through shared memory.
    uint overflow_count = counters[C_OVERFLOW];
    for (uint base = 0u; base < overflow_count; base += WORKGROUP_PIXELS) {
        spend_trip();
        uint count = min(uint(WORKGROUP_PIXELS), overflow_count - base);
        if (lid < count) {
            uint entry = overflow_list[base + lid];
            sm_id[lid] = entry;
            sm_tri[lid] = scene_triangle(entry & ID_MASK);
        }
        barrier();
        if (live && !done(mask)) {
            for (uint k = 0u; k < count && !done(mask) && spend_trip(); ++k) {
                if (!tests_overflow(sm_id[k])) continue;
                tests_spawned += 1u;
                mask |= triangle_mask(sm_tri[k]);
            }
        }
        barrier();
    }

    // 2. Every pyramid level, finest first (a uniform loop: barriers
    // inside). Per level, elect the tile's cell — the lowest first cell of
    // its live pixels there — and read it through shared memory; then each
    // pixel's other cells at that level from global memory.
    uint max_levels = 0u;
    for (uint k = 0u; k < light.cascade_count; ++k) max_levels = max(max_levels, light.cascade[k].levels);
    if (!grid_usable || light.grid_disabled != 0u) max_levels = 0u;
    uint levels_any = 0u;   // levels used by any cascade: the others cost no barrier
    for (uint k = 0u; k < light.cascade_count; ++k) levels_any |= counters[C_LEVELS + k];
    uint level_start = live && px_has_cells ? light.cascade[px_cascade].cell_offset : 0u;
    for (uint l = 0u; l < max_levels; ++l) {
        spend_trip();
        uvec2 dims = live && px_has_cells ? level_dims(px_cascade, l) : uvec2(0u);
        if ((levels_any & (1u << l)) == 0u) {
            level_start += dims.x * dims.y;
            continue;
        }
        uvec4 r = uvec4(0u);
        bool wants_cells = live && !deferred && px_has_cells && !done(mask)
            && l < light.cascade[px_cascade].levels
            && level_used(l) && cell_range_at(px_cascade, l, px_lo, px_hi, r);
        if (wants_cells) levels_visited += 1u;
        if (lid == 0u) sm_cell = NO_CELL;
        barrier();
        if (wants_cells) atomicMin(sm_cell, cell_index_at(px_cascade, level_start, l, r.x, r.y));
        barrier();
        uint cell = sm_cell;
        uint cx = 0u, cy = 0u;
        bool in_elected = false;
        if (cell != NO_CELL) {
            // Whether the elected cell is one of this pixel's at this level.
            if (wants_cells && cell >= level_start && cell < level_start + dims.x * dims.y) {
                uint local = cell - level_start;
                cx = local % dims.x;
                cy = local / dims.x;
                in_elected = cx >= r.x && cx <= r.z && cy >= r.y && cy <= r.w;
            }
            if (in_elected) cells_visited += 1u;
            uint start = cell_start[cell], end = cell_start[cell + 1u];
            for (uint base = start; base < end; base += WORKGROUP_PIXELS) {
                spend_trip();
                uint count = min(uint(WORKGROUP_PIXELS), end - base);
                if (lid < count) {
                    uint entry = cell_triangles[base + lid];
                    sm_id[lid] = entry;
                    sm_tri[lid] = scene_triangle(entry & ID_MASK);
                }
                barrier();
                if (in_elected && !done(mask)) {
                    for (uint k = 0u; k < count && !done(mask) && spend_trip(); ++k) {
                        if (!tests_in_cell(sm_id[k], cx, cy, r)) continue;
                        tests_spawned += 1u;
                        mask |= triangle_mask(sm_tri[k]);
                    }
                }
                barrier();
            }
        }
        // 3. The pixel's other cells at this level, from global memory.
        if (wants_cells) {
            for (uint y = r.y; y <= r.w && !done(mask) && spend_trip(); ++y) {
                for (uint x = r.x; x <= r.z && !done(mask) && spend_trip(); ++x) {
                    if (in_elected && x == cx && y == cy) continue;
                    cells_visited += 1u;
                    uint c = cell_index_at(px_cascade, level_start, l, x, y);
                    uint end = cell_start[c + 1u];
                    for (uint k = cell_start[c]; k < end && !done(mask) && spend_trip(); ++k) {
                        uint entry = cell_triangles[k];
                        if (!tests_in_cell(entry, x, y, r)) continue;
                        tests_spawned += 1u;
                        mask |= triangle_mask(scene_triangle(entry & ID_MASK));
                    }
                }
            }
        }
        level_start += dims.x * dims.y;
    }

    if (!inside) return;
    // Facing-away pixels tested with that skip off keep mask 0, as skipped.
    // A deferred pixel's partial mask: the heavy step reads it and goes on.
    HALF_MASKS[i] = (pixel_flags & FLAG_SHADOW_TESTED) != 0u ? mask : 0u;
    if (!live) return;
    loop_budget_report();
#ifndef MASK_HALF_HIGH
    // Once per pixel, not per half; extra surfaces apart.
    count_add(i < frame.width * frame.height ? C_PIXELS_TESTED : C_EXTRA_SURFACES_TESTED, 1u);
#endif
    count_add(C_SHADOW_MAP_EARLY_OUTS, covered ? 1u : 0u);
    count_add(C_EARLY_OUTS, !covered && !deferred && done(mask) ? 1u : 0u);
    uint longest = subgroupMax(tests_spawned);
    if (subgroupElect()) atomicMax(counters[C_LONGEST_TILE_TESTS], longest);
    add_work_counters();
}
#endif

#ifdef STEP_HEAVY
shared uint sm_mask;

// The pixel's frustum (pixel_frustum.glsl's px_* state), set up once per
// queued pixel by the first subgroup and read by the others (before, all
// eight warps of the workgroup set up the same pixel, where a tile-step
// warp sets up 32 pixels at once).
struct PixelState {
    vec3 p, normal, ex, ey, light;
    float microquad_part;
    uint receiver, cascade, has_cells, cover, soft, wanted;
    vec2 lo, hi;
    vec3 disk_c, disk_u, disk_v;
};
shared PixelState sm_pixel;

void share_pixel(uint i, uint cascade) {
    if (gl_SubgroupID == 0u) {
        pixel_frustum(i, cascade);
        if (subgroupElect()) {
            sm_pixel = PixelState(px_p, px_normal, px_ex, px_ey, px_light, px_microquad_part, px_receiver,
                                  px_cascade, px_has_cells ? 1u : 0u, px_cover, px_soft ? 1u : 0u,
                                  px_wanted, px_lo, px_hi, px_disk_c, px_disk_u, px_disk_v);
        }
    }
    barrier();
    PixelState s = sm_pixel;
    px_p = s.p;
    px_normal = s.normal;
    px_ex = s.ex;
    px_ey = s.ey;
    px_light = s.light;
    px_microquad_part = s.microquad_part;
    px_receiver = s.receiver;
    px_cascade = s.cascade;
    px_has_cells = s.has_cells != 0u;
    px_cover = s.cover;
    px_soft = s.soft != 0u;
    px_wanted = s.wanted;
    px_lo = s.lo;
    px_hi = s.hi;
    px_disk_c = s.disk_c;
    px_disk_u = s.disk_u;
    px_disk_v = s.disk_v;
}

void main() {
    loop_budget_reset();
    uint lid = gl_LocalInvocationIndex;
    stop_when_full = (frame.skips & SKIP_FULL_MASK) != 0u;
    uint queued = min(counters[C_HALF_HEAVY_PIXELS], frame.heavy_capacity);
    uint early_outs = 0u;
    // Uniform per workgroup: the barriers below are reached by all.
    for (uint q = gl_WorkGroupID.x; q < queued; q += gl_NumWorkGroups.x) {
        uvec2 item = heavy_pixels[q];
        uint i = item.x;
        if (lid == 0u) sm_mask = HALF_MASKS[i];
        share_pixel(i, item.y);
        // The tile step's mask (cover triangle, overflow list), then the
        // grid's candidates: thread lid takes every WORKGROUP_LINEAR-th
        // entry of each cell, sharing its bits for the full-mask stop.
        uint mask = sm_mask;
        uint level_start = light.cascade[px_cascade].cell_offset;
        for (uint l = 0u; l < light.cascade[px_cascade].levels && !done(mask) && spend_trip(); ++l) {
            uvec2 d = level_dims(px_cascade, l);
            uvec4 r;
            if (level_used(l) && cell_range_at(px_cascade, l, px_lo, px_hi, r)) {
                if (lid == 0u) levels_visited += 1u;
                for (uint y = r.y; y <= r.w && !done(mask) && spend_trip(); ++y) {
                    for (uint x = r.x; x <= r.z && !done(mask) && spend_trip(); ++x) {
                        if (lid == 0u) cells_visited += 1u;
                        uint c = cell_index_at(px_cascade, level_start, l, x, y);
                        uint end = cell_start[c + 1u];
                        for (uint k = cell_start[c] + lid; k < end && !done(mask) && spend_trip();
                                k += WORKGROUP_LINEAR) {
                            uint entry = cell_triangles[k];
                            if (!tests_in_cell(entry, x, y, r)) continue;
                            tests_spawned += 1u;
                            uint m = triangle_mask(scene_triangle(entry & ID_MASK));
                            mask |= m;
                            if (stop_when_full) mask |= atomicOr(sm_mask, m);
                        }
                    }
                }
            }
            level_start += d.x * d.y;
        }
        atomicOr(sm_mask, mask);
        barrier();
        if (lid == 0u) {
            bool tested = (gbuffer_flags(g_id_flags[i]) & FLAG_SHADOW_TESTED) != 0u;
            HALF_MASKS[i] = tested ? sm_mask : 0u;
            if (done(sm_mask)) early_outs += 1u;
        }
        // Every thread has read sm_mask before the next pixel resets it.
        barrier();
    }
    loop_budget_report();
    count_add(C_EARLY_OUTS, early_outs);
    add_work_counters();
}
#endif
