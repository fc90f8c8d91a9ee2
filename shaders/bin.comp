#version 460
// Pass 2, `bin` — GPU twin of `izb::izb::bin::bin`: a counting sort of
// triangles into the light-space grid (seed 000), in three dispatches:
//   STEP_COUNT      (per triangle) light-view vertex cache (written over the
//                   eye-relative triangle it came from: the two bindings
//                   alias one buffer), placement (the first cell only;
//                   scatter recomputes the rectangle from the cache),
//                   atomic count per covered cell, overflow append;
//   STEP_PREFIX_SUM (1 workgroup)  exclusive prefix sum of the counts into
//                   cell_start (and a copy as the scatter cursor), total
//                   checked against the cell list's capacity;
//   STEP_SCATTER    (per triangle) triangle ids into their cells.
// When the total exceeds the capacity nothing is scattered past it and
// C_CAPACITY_EXCEEDED is raised: the host grows the list and runs the frame
// again, it never reads a corrupt grid.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_LINEAR) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_TRIANGLES) buffer TriBuf { Triangle triangles[]; };
layout(scalar, binding = B_LIGHT) readonly buffer LightBuf { LightState light; };
layout(scalar, binding = B_COUNTERS) buffer CountBuf { uint counters[]; };
layout(scalar, binding = B_VERTEX_CACHE) buffer CacheBuf { Triangle vertex_cache[]; };
layout(scalar, binding = B_PLACEMENT) writeonly buffer PlaceBuf { uint placement[]; };
layout(scalar, binding = B_CELL_CURSOR) buffer CursorBuf { uint cell_cursor[]; };
layout(scalar, binding = B_CELL_START) buffer StartBuf { uint cell_start[]; };
layout(scalar, binding = B_CELL_TRIANGLES) writeonly buffer CellTriBuf { uint cell_triangles[]; };
layout(scalar, binding = B_OVERFLOW) writeonly buffer OverflowBuf { uint overflow_list[]; };
layout(scalar, binding = B_G_POSITION) readonly buffer PosBuf { vec3 g_position[]; };
layout(scalar, binding = B_G_AXIS_X) readonly buffer AxBuf { vec3 g_axis_x[]; };
layout(scalar, binding = B_G_AXIS_Y) readonly buffer AyBuf { vec3 g_axis_y[]; };
layout(scalar, binding = B_G_ID_FLAGS) readonly buffer GidBuf { uint g_id_flags[]; };

#include "light_view.glsl"

// Per cell (binding B_CELL_RECEIVERS, filled with ~0 before the frame):
// .x = ordered bits of the lowest light-view z of the µQuad centres of the
// receivers touching the cell (atomicMin), .y = ~reach (atomicMin, so the
// largest reach wins): bin::CellReceivers.
layout(scalar, binding = B_CELL_RECEIVERS) buffer CellRecvBuf { uvec2 cell_receivers[]; };

// bin::BEHIND_MARGIN.
#define BEHIND_MARGIN (1.0 / 1024.0)

// bin::behind_receivers: whether triangle t (light view) lies behind every
// receiver that can test it in cell (x, y), so the cell need not list it.
// Directional lights only (STEP_RECEIVERS gathers nothing for a point light).
bool behind_receivers(Triangle t, uint x, uint y) {
    if ((frame.skips & SKIP_BEHIND_RECEIVERS) == 0u || light.projection != 0u) return false;
    uvec2 r = cell_receivers[y * light.cells_x + x];
    if (r.x == 0xFFFFFFFFu) return true;   // no receiver touches the cell
    float z_min = from_ordered_bits(r.x);
    precise vec3 n = cross(t.b - t.a, t.c - t.a);
    if (n.z < 0.0) n = -n;
    if (!(n.z > 0.0)) return false;
    float reach = float(~r.y) + CELL_PADDING;
    vec2 lo = ndc_of_grid(vec2(float(x) - reach, float(y) - reach));
    vec2 hi = ndc_of_grid(vec2(float(x) + 1.0 + reach, float(y) + 1.0 + reach));
    vec2 q[4] = vec2[4](lo, vec2(hi.x, lo.y), hi, vec2(lo.x, hi.y));
    float plane_max = -1.0 / 0.0;
    [[unroll]] for (int k = 0; k < 4; ++k) {
        precise float h = t.a.z - (n.x * (q[k].x - t.a.x) + n.y * (q[k].y - t.a.y)) / n.z;
        plane_max = max(plane_max, h);
    }
    vec2 box_lo = min(min(lo, t.a.xy), min(t.b.xy, t.c.xy));
    vec2 box_hi = max(max(hi, t.a.xy), max(t.b.xy, t.c.xy));
    float z_lo = min(min(z_min, t.a.z), min(t.b.z, t.c.z));
    float z_hi = max(max(z_min, t.a.z), max(t.b.z, t.c.z));
    float size = length(box_hi - box_lo) + (z_hi - z_lo);
    float margin = BEHIND_MARGIN * size * (length(n) / n.z);
    return plane_max < z_min - margin;
}

// bin::place: PLACEMENT_CULLED, PLACEMENT_OVERFLOW or a packed cell rectangle.
uvec2 place(Triangle t) {
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
    vec2 g0 = grid_coords(n0), g1 = grid_coords(n1), g2 = grid_coords(n2);
    vec2 lo = min(min(g0, g1), g2) - CELL_PADDING;
    vec2 hi = max(max(g0, g1), g2) + CELL_PADDING;
    float w = float(light.cells_x), h = float(light.cells_y);
    if (hi.x < 0.0 || hi.y < 0.0 || lo.x >= w || lo.y >= h || isnan(lo.x) || isnan(hi.x)) {
        return uvec2(PLACEMENT_CULLED);
    }
    uint x0 = uint(max(lo.x, 0.0)), y0 = uint(max(lo.y, 0.0));
    uint x1 = max(uint(min(hi.x, w - 1.0)), x0), y1 = max(uint(min(hi.y, h - 1.0)), y0);
    if (x1 - x0 >= frame.max_span || y1 - y0 >= frame.max_span) return uvec2(PLACEMENT_OVERFLOW);
    return uvec2(x0 | (y0 << 16), x1 | (y1 << 16));
}

#ifdef STEP_PREFIX_SUM
shared uint partial[WORKGROUP_LINEAR];
#endif

void main() {
#ifdef STEP_RECEIVERS
    // One thread per pixel: bin::cell_receivers.
    // Directional lights only, as behind_receivers (the CPU twin returns
    // no bounds for a point light).
    uint i = gl_GlobalInvocationID.x;
    if (i >= frame.width * frame.height || light.grid_disabled != 0u || light.projection != 0u) return;
    if (!is_receiver(gbuffer_flags(g_id_flags[i]), frame.skips)) return;
    vec3 p = g_position[i];
    vec2 lo, hi;
    microquad_grid_box(p, g_axis_x[i], g_axis_y[i], lo, hi);
    uvec4 cells;
    if (!cell_range(lo, hi, cells)) return;
    uint z = ordered_bits(to_light_view(p).z);
    vec2 extent = hi - lo;
    uint reach = uint(ceil(max(extent.x, extent.y))) + 1u;
    for (uint y = cells.y; y <= cells.w; ++y) {
        for (uint x = cells.x; x <= cells.z; ++x) {
            uint c = y * light.cells_x + x;
            atomicMin(cell_receivers[c].x, z);
            atomicMin(cell_receivers[c].y, ~reach);
        }
    }
#endif

#ifdef STEP_COUNT
    uint id = gl_GlobalInvocationID.x;
    if (id >= frame.triangle_count) return;
    Triangle w = triangles[id];
    Triangle t = Triangle(to_light_view(w.a), to_light_view(w.b), to_light_view(w.c));
    vertex_cache[id] = t;
    uvec2 p = place(t);
    // Without the outside-bounds skip a triangle that misses the grid is
    // tested by every pixel (the overflow list) instead of dropped.
    if (p.x == PLACEMENT_CULLED && (frame.skips & SKIP_OUTSIDE_BOUNDS) == 0u) p = uvec2(PLACEMENT_OVERFLOW);
    placement[id] = p.x;
    if (p.x == PLACEMENT_CULLED) {
        atomicAdd(counters[C_CULLED], 1u);
    } else if (p.x == PLACEMENT_OVERFLOW) {
        overflow_list[atomicAdd(counters[C_OVERFLOW], 1u)] = id;
    } else {
        atomicAdd(counters[C_BINNED], 1u);
        uint dropped = 0u;
        bool listed = false;
        for (uint y = p.x >> 16; y <= p.y >> 16; ++y) {
            for (uint x = p.x & 0xFFFFu; x <= (p.y & 0xFFFFu); ++x) {
                if (behind_receivers(t, x, y)) {
                    dropped += 1u;
                } else {
                    atomicAdd(cell_cursor[y * light.cells_x + x], 1u);
                    listed = true;
                }
            }
        }
        if (dropped != 0u) atomicAdd(counters[C_ENTRIES_BEHIND], dropped);
        if (!listed) atomicAdd(counters[C_TRIANGLES_BEHIND], 1u);
    }
#endif

#ifdef STEP_PREFIX_SUM
    // One workgroup: thread k owns a contiguous chunk of cells, sums it,
    // the workgroup scans the 256 sums, then each chunk is written out.
    uint cells = light.cells_x * light.cells_y;
    uint k = gl_LocalInvocationID.x;
    uint chunk = (cells + WORKGROUP_LINEAR - 1u) / WORKGROUP_LINEAR;
    uint begin = min(k * chunk, cells), end = min(begin + chunk, cells);
    uint sum = 0u;
    for (uint c = begin; c < end; ++c) sum += cell_cursor[c];
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
    for (uint c = begin; c < end; ++c) {
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
#endif

#ifdef STEP_SCATTER
    uint id = gl_GlobalInvocationID.x;
    if (id >= frame.triangle_count) return;
    // The rectangle again, from the values STEP_COUNT stored and placed:
    // the same arithmetic on the same floats, so the same cells.
    Triangle t = vertex_cache[id];
    uvec2 p = place(t);
    if (p.x >= PLACEMENT_CULLED) return;
    for (uint y = p.x >> 16; y <= p.y >> 16; ++y) {
        for (uint x = p.x & 0xFFFFu; x <= (p.y & 0xFFFFu); ++x) {
            if (behind_receivers(t, x, y)) continue;
            uint slot = atomicAdd(cell_cursor[y * light.cells_x + x], 1u);
            if (slot < frame.cell_capacity) cell_triangles[slot] = id;
        }
    }
#endif
}
