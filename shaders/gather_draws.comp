#version 460
// The shadow pass's first step with the host's vertex and index buffers,
// `gather_draws` — GPU twin of `izb::cpu::gather_draws`: one thread per
// triangle of the frame's draws (B_DRAWS, in triangle order) reads its
// indices (u16, u32 or none) and object-space positions from the host's
// buffers (HOST_GEOMETRY slots), moves them by the draw's object-to-eye
// transform (folded with the eye on the host in f64, rounded once), and
// writes the triangle's three eye-relative vertices (B_VERTICES, 3t..3t+2),
// its corners (B_TRIANGLES) and its unit normal (B_TRIANGLE_NORMALS, the
// object-space edge cross product turned by the cofactor rows) — what every
// later pass reads. The vertex arithmetic is `precise` (no fused
// multiply-add) and in the twin's order, so the vertices equal the twin's
// bit for bit. An index at or past its draw's vertex count collapses the
// triangle onto the draw's vertex 0 (it casts no shadow; nothing is read
// out of bounds) and is counted (C_INDEX_OUT_OF_RANGE); a triangle with a
// vertex outside the pass's bounds is counted (C_OUTSIDE_BOUNDS).
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_LINEAR) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_DRAWS) readonly buffer DrawBuf { Draw draws[]; };
layout(scalar, binding = B_TRIANGLES) writeonly buffer TriBuf { TriangleCorners triangle_corners[]; };
layout(scalar, binding = B_VERTICES) writeonly buffer VertexBuf { vec3 vertices[]; };
layout(scalar, binding = B_TRIANGLE_NORMALS) writeonly buffer TriNrmBuf { vec3 triangle_normals[]; };
layout(scalar, binding = B_COUNTERS) buffer CountBuf { uint counters[]; };
layout(set = HOST_SET, binding = HOST_GEOMETRY) readonly buffer GeometryBuf {
    uint words[];
} geometry[HOST_GEOMETRY_SLOTS];

#include "counters.glsl"

// Word `i` of geometry slot `slot`, each slot named by a constant index
// (no descriptor-indexing feature needed of the host's device).
uint geometry_word(uint slot, uint i) {
    switch (slot) {
    case 0u: return geometry[0].words[i];
    case 1u: return geometry[1].words[i];
    case 2u: return geometry[2].words[i];
    default: return geometry[3].words[i];
    }
}
#if HOST_GEOMETRY_SLOTS != 4
#error "geometry_word names HOST_GEOMETRY_SLOTS slots"
#endif

// The draw whose triangles hold triangle t: the last whose first
// triangle is at or before t.
uint draw_of(uint t) {
    uint lo = 0u, hi = frame.draw_count;
    while (hi - lo > 1u) {
        uint mid = (lo + hi) / 2u;
        if (draws[mid].first_triangle <= t) lo = mid; else hi = mid;
    }
    return lo;
}

uint corner_index(Draw d, uint t, uint k) {
    uint i = 3u * t + k;
    if (d.index_slot == NO_INDICES) return i;
    uint at = d.index_offset + i;
    if (d.index_bytes == 2u) return (geometry_word(d.index_slot, at / 2u) >> (16u * (at % 2u))) & 0xFFFFu;
    return geometry_word(d.index_slot, at);
}

vec3 object_vertex(Draw d, uint v) {
    uint first = d.vertex_offset + v * d.vertex_stride;
    return uintBitsToFloat(uvec3(geometry_word(d.vertex_slot, first),
                                 geometry_word(d.vertex_slot, first + 1u),
                                 geometry_word(d.vertex_slot, first + 2u)));
}

float transform_row(vec4 r, vec3 v) {
    precise float x = ((r.x * v.x + r.y * v.y) + r.z * v.z) + r.w;
    return x;
}

vec3 transform_point(Draw d, vec3 v) {
    return vec3(transform_row(d.row_x, v), transform_row(d.row_y, v), transform_row(d.row_z, v));
}

bool inside_bounds(vec3 v) {
    return all(greaterThanEqual(v, frame.bounds_lo)) && all(lessThanEqual(v, frame.bounds_hi));
}

void main() {
    uint t = gl_GlobalInvocationID.x;
    if (t >= frame.triangle_count) return;
    Draw d = draws[draw_of(t)];
    uint local = t - d.first_triangle;
    uvec3 c = uvec3(corner_index(d, local, 0u), corner_index(d, local, 1u),
                    corner_index(d, local, 2u));
    bool out_of_range = any(greaterThanEqual(c, uvec3(d.vertex_count)));
    if (out_of_range) c = uvec3(0u);
    vec3 a = object_vertex(d, c.x);
    vec3 b = object_vertex(d, c.y);
    vec3 e = object_vertex(d, c.z);
    precise vec3 m = cross(b - a, e - a);
    precise vec3 n = vec3(dot(d.cofactor_x, m), dot(d.cofactor_y, m), dot(d.cofactor_z, m));
    precise float len = sqrt(dot(n, n));
    vec3 pa = transform_point(d, a);
    vec3 pb = transform_point(d, b);
    vec3 pc = transform_point(d, e);
    vertices[3u * t] = pa;
    vertices[3u * t + 1u] = pb;
    vertices[3u * t + 2u] = pc;
    triangle_corners[t] = TriangleCorners(3u * t, 3u * t + 1u, 3u * t + 2u);
    triangle_normals[t] = len > 0.0 ? n / len : vec3(0.0);
    count_add(C_INDEX_OUT_OF_RANGE, out_of_range ? 1u : 0u);
    bool inside = inside_bounds(pa) && inside_bounds(pb) && inside_bounds(pc);
    count_add(C_OUTSIDE_BOUNDS, inside ? 0u : 1u);
}
