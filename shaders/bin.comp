#version 460
// Pass 2, `bin` — GPU twin of `izb::izb::bin::bin`: a counting sort of
// triangles into every cascade's light-space grid (seed 000; the grids lie
// back to back in the cell arrays), in these dispatches:
//   STEP_RECEIVERS  (per pixel, behind-receivers skip only) per cell the
//                   lowest receiver z and reach (bin::cell_receivers);
//   STEP_COUNT      (per triangle) per cascade its placement (from its
//                   light-view vertices), an atomic count per covered cell
//                   and the cover floor (the conservative shadow map); one
//                   overflow entry tagged with the cascades it overflows in;
//   STEP_PREFIX_SUM (1 workgroup)  exclusive prefix sum of the counts into
//                   cell_start (and a copy as the scatter cursor), total
//                   checked against the cell list's capacity;
//   STEP_SCATTER    (per triangle) entries into their cells (light view and
//                   rectangle recomputed with the count's `precise`
//                   arithmetic, so the same cells),
//                   and each cell's cover triangle among the best floors.
// When the total exceeds the capacity nothing is scattered past it and
// C_CAPACITY_EXCEEDED is raised: the host grows the list and runs the frame
// again, it never reads a corrupt grid.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_LINEAR) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_TRIANGLES) readonly buffer TriBuf { Triangle triangles[]; };
layout(scalar, binding = B_LIGHT) readonly buffer LightBuf { LightState light; };
layout(scalar, binding = B_COUNTERS) buffer CountBuf { uint counters[]; };
// Per cell, the conservative shadow map: .x = ordered bits of the best
// cover floor (atomicMax; 0 = none), .y = ~id of the lowest-id triangle
// with that floor (atomicMax; 0 = bin::NO_COVER). Filled with 0.
layout(scalar, binding = B_CELL_COVER) buffer CellCoverBuf { uvec2 cell_cover[]; };
layout(scalar, binding = B_CELL_CURSOR) buffer CursorBuf { uint cell_cursor[]; };
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
#define LOOP_BUDGET_SLOTS WORKGROUP_LINEAR
#include "loop_budget.glsl"

// Per cell (binding B_CELL_RECEIVERS, filled with ~0 before the frame):
// .x = ordered bits of the lowest light-view z of the µQuad centres of the
// receivers touching the cell (atomicMin), .y = ~reach (atomicMin, so the
// largest reach wins): bin::CellReceivers.
layout(scalar, binding = B_CELL_RECEIVERS) buffer CellRecvBuf { uvec2 cell_receivers[]; };

// Triangle `id` in light view (to_light_view is `precise`): the placement
// input of STEP_COUNT and STEP_SCATTER, as the CPU twin's `light_view`.
Triangle light_view_triangle(uint id) {
    Triangle w = triangles[id];
    return Triangle(to_light_view(w.a), to_light_view(w.b), to_light_view(w.c));
}

// bin::BEHIND_MARGIN.
#define BEHIND_MARGIN (1.0 / 1024.0)

// bin::upward_normal: the plane normal turned toward the light (+z);
// false when the light sees the triangle edge-on (or it is NaN).
bool upward_normal(Triangle t, out vec3 n) {
    precise vec3 m = cross(t.b - t.a, t.c - t.a);
    n = m.z < 0.0 ? -m : m;
    return n.z > 0.0;
}

// Height of t's plane (normal n) over light-view xy q.
float plane_height(Triangle t, vec3 n, vec2 q) {
    precise float h = t.a.z - (n.x * (q.x - t.a.x) + n.y * (q.y - t.a.y)) / n.z;
    return h;
}

// bin::behind_receivers: whether triangle t (light view) lies behind every
// receiver that can test it in cell (x, y) of cascade k, so the cell need
// not list it. Directional lights only (STEP_RECEIVERS gathers nothing for
// a point light).
bool behind_receivers(Triangle t, uint k, uint x, uint y) {
    if ((frame.skips & SKIP_BEHIND_RECEIVERS) == 0u || light.projection != 0u) return false;
    uvec2 r = cell_receivers[cell_index(k, x, y)];
    if (r.x == 0xFFFFFFFFu) return true;   // no receiver touches the cell
    float z_min = from_ordered_bits(r.x);
    vec3 n;
    if (!upward_normal(t, n)) return false;
    float reach = float(~r.y) + CELL_PADDING;
    vec2 lo = ndc_of_grid(k, vec2(float(x) - reach, float(y) - reach));
    vec2 hi = ndc_of_grid(k, vec2(float(x) + 1.0 + reach, float(y) + 1.0 + reach));
    // No loop (see strictly_inside).
    float plane_max = max(max(plane_height(t, n, lo), plane_height(t, n, vec2(hi.x, lo.y))),
                          max(plane_height(t, n, hi), plane_height(t, n, vec2(lo.x, hi.y))));
    vec2 box_lo = min(min(lo, t.a.xy), min(t.b.xy, t.c.xy));
    vec2 box_hi = max(max(hi, t.a.xy), max(t.b.xy, t.c.xy));
    float z_lo = min(min(z_min, t.a.z), min(t.b.z, t.c.z));
    float z_hi = max(max(z_min, t.a.z), max(t.b.z, t.c.z));
    float size = length(box_hi - box_lo) + (z_hi - z_lo);
    float margin = BEHIND_MARGIN * size * (length(n) / n.z);
    return plane_max < z_min - margin;
}

// Whether light-view xy q is strictly inside the triangle with vertices
// a, b, c of winding w (glam's perp_dot a.x·b.y − a.y·b.x). No loops: a
// loop here, even one marked [[unroll]], counted toward lavapipe's loop cap
// once per cell and silently cut the count loop of large triangles.
bool strictly_inside(vec2 a, vec2 b, vec2 c, float w, vec2 q) {
    precise float s0 = w * ((b.x - a.x) * (q.y - a.y) - (b.y - a.y) * (q.x - a.x));
    precise float s1 = w * ((c.x - b.x) * (q.y - b.y) - (c.y - b.y) * (q.x - b.x));
    precise float s2 = w * ((a.x - c.x) * (q.y - c.y) - (a.y - c.y) * (q.x - c.x));
    return s0 > 0.0 && s1 > 0.0 && s2 > 0.0;
}

// bin::cover_floor: when t's light-space projection contains cell (x, y)
// of cascade k, the lowest height of its plane over the cell (as ordered
// bits, never 0); else 0. Only with the shadow-map skip and a directional
// light.
uint cover_floor(Triangle t, uint k, uint x, uint y) {
    if ((frame.skips & SKIP_SHADOW_MAP) == 0u || light.projection != 0u) return 0u;
    vec3 n;
    if (!upward_normal(t, n)) return 0u;
    vec2 q0 = ndc_of_grid(k, vec2(float(x), float(y)));
    vec2 q1 = ndc_of_grid(k, vec2(float(x) + 1.0, float(y)));
    vec2 q2 = ndc_of_grid(k, vec2(float(x) + 1.0, float(y) + 1.0));
    vec2 q3 = ndc_of_grid(k, vec2(float(x), float(y) + 1.0));
    vec2 a = t.a.xy, b = t.b.xy, c = t.c.xy;
    precise float w = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if (!(strictly_inside(a, b, c, w, q0) && strictly_inside(a, b, c, w, q1)
          && strictly_inside(a, b, c, w, q2) && strictly_inside(a, b, c, w, q3))) return 0u;
    float floor_z = min(min(plane_height(t, n, q0), plane_height(t, n, q1)),
                        min(plane_height(t, n, q2), plane_height(t, n, q3)));
    return max(ordered_bits(floor_z), 1u);
}

// bin::place in cascade k: PLACEMENT_CULLED, PLACEMENT_OVERFLOW or a packed
// cell rectangle.
uvec2 place(Triangle t, uint k) {
    if (light.grid_disabled != 0u) return uvec2(PLACEMENT_OVERFLOW);
    vec2 n0, n1, n2;
    if (light.projection == 0u) {
        n0 = t.a.xy; n1 = t.b.xy; n2 = t.c.xy;
    } else {
        uint in_front = uint(t.a.z > 0.0) + uint(t.b.z > 0.0) + uint(t.c.z > 0.0);
        if (in_front == 0u) return uvec2(PLACEMENT_CULLED);   // wholly behind the light
        if (in_front < 3u) return uvec2(PLACEMENT_OVERFLOW);  // crosses the light's plane
        n0 = t.a.xy / t.a.z; n1 = t.b.xy / t.b.z; n2 = t.c.xy / t.c.z;
    }
    vec2 g0 = grid_coords(k, n0), g1 = grid_coords(k, n1), g2 = grid_coords(k, n2);
    uvec4 r;
    if (!cell_range(k, min(min(g0, g1), g2), max(max(g0, g1), g2), r)) return uvec2(PLACEMENT_CULLED);
    // Sides are below 2^16 (the host checks), so the area fits a uint.
    if ((r.z - r.x + 1u) * (r.w - r.y + 1u) > light.cascade[k].overflow_cells) return uvec2(PLACEMENT_OVERFLOW);
    return uvec2(r.x | (r.y << 16), r.z | (r.w << 16));
}

// The placement the bin uses: without the outside-bounds skip a triangle
// that misses the grid is tested by every pixel of the cascade (the
// overflow list) instead of dropped.
uvec2 placement_in(Triangle t, uint k) {
    uvec2 p = place(t, k);
    if (p.x == PLACEMENT_CULLED && (frame.skips & SKIP_OUTSIDE_BOUNDS) == 0u) p = uvec2(PLACEMENT_OVERFLOW);
    return p;
}

#ifdef STEP_PREFIX_SUM
shared uint partial[WORKGROUP_LINEAR];
#endif

void main() {
    loop_budget_reset();
#ifdef STEP_RECEIVERS
    // One thread per pixel: bin::cell_receivers, in the pixel's cascade.
    // Directional lights only, as behind_receivers (the CPU twin returns
    // no bounds for a point light).
    uint i = gl_GlobalInvocationID.x;
    if (i >= frame.width * frame.height || light.grid_disabled != 0u || light.projection != 0u) return;
    if (!is_receiver(gbuffer_flags(g_id_flags[i]), frame.skips)) return;
    uint k = pixel_cascade[i];
    vec3 p = g_position[i];
    vec2 lo, hi;
    microquad_grid_box(k, p, g_axis_x[i], g_axis_y[i], lo, hi);
    uvec4 cells;
    if (!cell_range(k, lo, hi, cells)) return;
    uint z = ordered_bits(to_light_view(p).z);
    vec2 extent = hi - lo;
    uint reach = uint(ceil(max(extent.x, extent.y))) + 1u;
    for (uint y = cells.y; y <= cells.w && spend_trip(); ++y) {
        for (uint x = cells.x; x <= cells.z && spend_trip(); ++x) {
            uint c = cell_index(k, x, y);
            atomicMin(cell_receivers[c].x, z);
            atomicMin(cell_receivers[c].y, ~reach);
        }
    }
    loop_budget_report();
#endif

#ifdef STEP_COUNT
    uint id = gl_GlobalInvocationID.x;
    if (id >= frame.triangle_count) return;
    Triangle t = light_view_triangle(id);
    uint overflows = 0u;
    bool placed = false;
    uint binned = 0u, dropped = 0u, dropped_everywhere = 0u;
    for (uint k = 0u; k < light.cascade_count && spend_trip(); ++k) {
        uvec2 p = placement_in(t, k);
        if (p.x == PLACEMENT_CULLED) continue;
        if (p.x == PLACEMENT_OVERFLOW) {
            overflows |= 1u << k;
            continue;
        }
        placed = true;
        binned += 1u;
        bool listed = false;
        for (uint y = p.x >> 16; y <= p.y >> 16 && spend_trip(); ++y) {
            for (uint x = p.x & 0xFFFFu; x <= (p.y & 0xFFFFu) && spend_trip(); ++x) {
                if (behind_receivers(t, k, x, y)) {
                    dropped += 1u;
                    continue;
                }
                uint c = cell_index(k, x, y);
                atomicAdd(cell_cursor[c], 1u);
                listed = true;
                uint f = cover_floor(t, k, x, y);
                if (f != 0u) atomicMax(cell_cover[c].x, f);
            }
        }
        if (!listed) dropped_everywhere += 1u;
    }
    if (overflows != 0u) {
        overflow_list[atomicAdd(counters[C_OVERFLOW], 1u)] = id | (overflows << ID_BITS);
    } else if (!placed) {
        atomicAdd(counters[C_CULLED], 1u);
    }
    if (binned != 0u) atomicAdd(counters[C_BINNED], binned);
    if (dropped != 0u) atomicAdd(counters[C_ENTRIES_BEHIND], dropped);
    if (dropped_everywhere != 0u) atomicAdd(counters[C_TRIANGLES_BEHIND], dropped_everywhere);
    loop_budget_report();
#endif

#ifdef STEP_PREFIX_SUM
    // One workgroup: thread k owns a contiguous chunk of cells, sums it,
    // the workgroup scans the 256 sums, then each chunk is written out.
    uint cells = light.total_cells;
    uint k = gl_LocalInvocationID.x;
    uint chunk = (cells + WORKGROUP_LINEAR - 1u) / WORKGROUP_LINEAR;
    uint begin = min(k * chunk, cells), end = min(begin + chunk, cells);
    uint sum = 0u;
    for (uint c = begin; c < end && spend_trip(); ++c) sum += cell_cursor[c];
    partial[k] = sum;
    barrier();
    // Hillis–Steele inclusive scan of the chunk sums.
    for (uint offset = 1u; offset < WORKGROUP_LINEAR; offset <<= 1) {
        uint add = k >= offset ? partial[k - offset] : 0u;
        barrier();
        partial[k] += add;
        barrier();
    }
    uint running = partial[k] - sum;
    for (uint c = begin; c < end && spend_trip(); ++c) {
        uint count = cell_cursor[c];
        cell_start[c] = running;
        cell_cursor[c] = running;
        running += count;
    }
    if (k == WORKGROUP_LINEAR - 1u) {
        uint total = partial[k];
        cell_start[cells] = total;
        counters[C_CELL_ENTRIES] = total;
        if (total > frame.cell_capacity) counters[C_CAPACITY_EXCEEDED] = 1u;
    }
    loop_budget_report();
#endif

#ifdef STEP_SCATTER
    uint id = gl_GlobalInvocationID.x;
    if (id >= frame.triangle_count) return;
    // The rectangles again: the same `precise` arithmetic on the same
    // floats as STEP_COUNT, so the same cells.
    Triangle t = light_view_triangle(id);
    for (uint k = 0u; k < light.cascade_count && spend_trip(); ++k) {
        uvec2 p = placement_in(t, k);
        if (p.x >= PLACEMENT_CULLED) continue;
        uint x0 = p.x & 0xFFFFu, y0 = p.x >> 16;
        for (uint y = y0; y <= p.y >> 16 && spend_trip(); ++y) {
            for (uint x = x0; x <= (p.y & 0xFFFFu) && spend_trip(); ++x) {
                if (behind_receivers(t, k, x, y)) continue;
                uint c = cell_index(k, x, y);
                uint slot = atomicAdd(cell_cursor[c], 1u);
                uint entry = id | (x == x0 ? ENTRY_FIRST_COLUMN : 0u) | (y == y0 ? ENTRY_FIRST_ROW : 0u);
                if (slot < frame.cell_capacity) cell_triangles[slot] = entry;
                uint f = cover_floor(t, k, x, y);
                if (f != 0u && f == cell_cover[c].x) atomicMax(cell_cover[c].y, ~id);
            }
        }
    }
    loop_budget_report();
#endif
}
