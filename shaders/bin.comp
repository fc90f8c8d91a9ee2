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

// bin::CELL_PADDING: cell rectangles grow by 1/64 cell on every side, far
// above the f32 rounding of a grid coordinate.
#define CELL_PADDING (1.0 / 64.0)

// The CPU twin's rotation · (p − origin), same operation order; `precise`
// keeps the compiler from fusing multiply-adds the CPU does not fuse.
vec3 to_light_view(vec3 p) {
    precise vec3 q = p - light.origin;
    precise vec3 r = vec3(dot(light.rot_x, q), dot(light.rot_y, q), dot(light.rot_z, q));
    return r;
}

vec2 grid_coords(vec2 ndc) {
    return (ndc - light.ndc_min) / (light.ndc_max - light.ndc_min)
        * vec2(float(light.cells_x), float(light.cells_y));
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
        for (uint y = p.x >> 16; y <= p.y >> 16; ++y)
            for (uint x = p.x & 0xFFFFu; x <= (p.y & 0xFFFFu); ++x)
                atomicAdd(cell_cursor[y * light.cells_x + x], 1u);
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
    uvec2 p = place(vertex_cache[id]);
    if (p.x >= PLACEMENT_CULLED) return;
    for (uint y = p.x >> 16; y <= p.y >> 16; ++y) {
        for (uint x = p.x & 0xFFFFu; x <= (p.y & 0xFFFFu); ++x) {
            uint slot = atomicAdd(cell_cursor[y * light.cells_x + x], 1u);
            if (slot < frame.cell_capacity) cell_triangles[slot] = id;
        }
    }
#endif
}
