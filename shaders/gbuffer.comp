#version 460
// Pass 0, `gbuffer` — GPU twin of `izb::gbuffer::gbuffer`.
//
// A compute visibility pass, not a raster pipeline: each thread casts the
// pixel-centre ray through a BVH (built on the host by obvhs) exactly as the
// CPU twin does, so both sample the same ray and derive the µQuad axes from
// the same closed form (README, Conventions: derivatives of the ray/tangent-plane
// intersection), with no rasterisation rules or depth-buffer precision in
// between. Output: the struct-of-arrays G-buffer (hit point, µQuad axes,
// triangle id and flags in one word; the normal is the triangle's, with
// FLAG_NORMAL_FLIPPED when it faces the other way).
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_PIXELS_X, local_size_y = WORKGROUP_PIXELS_Y) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
#include "scene_triangles.glsl"
layout(scalar, binding = B_BVH_NODES) readonly buffer NodeBuf { BvhNode nodes[]; };
layout(scalar, binding = B_BVH_PRIMS) readonly buffer PrimBuf { uint prims[]; };
layout(scalar, binding = B_G_POSITION) writeonly buffer PosBuf { vec3 g_position[]; };
layout(scalar, binding = B_G_AXIS_X) writeonly buffer AxBuf { vec3 g_axis_x[]; };
layout(scalar, binding = B_G_AXIS_Y) writeonly buffer AyBuf { vec3 g_axis_y[]; };
layout(scalar, binding = B_G_ID_FLAGS) writeonly buffer GidBuf { uint g_id_flags[]; };
layout(scalar, binding = B_TRIANGLE_NORMALS) readonly buffer TriNrmBuf { vec3 triangle_normals[]; };
layout(scalar, binding = B_COUNTERS) buffer CountBuf { uint counters[]; };
#include "counters.glsl"

#include "bvh_closest_hit.glsl"
#include "surface_hit.glsl"

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) return;
    uint i = pixel.y * frame.width + pixel.x;
    vec2 image_point = vec2(pixel) + 0.5;
    vec3 d = frame.cam_corner + image_point.x * frame.cam_dx + image_point.y * frame.cam_dy;
    float best_t = frame.far;
    uint best = closest_hit(d, best_t);

    if (best == NO_HIT) {
        g_id_flags[i] = ID_MASK;   // a miss
        g_position[i] = vec3(0.0);
        g_axis_x[i] = vec3(0.0);
        g_axis_y[i] = vec3(0.0);
        return;
    }
    // The triangle's normal as the host computed it in f64: one from the
    // f32 vertices (error ~ε·|v|/|edge|) flipped 1.06e-4 of the deckchair's
    // samples at 960×540 in the tangent-plane test, which compares heights
    // against 2^-8 of a µQuad.
    vec3 n = triangle_normals[best];
    uint flags = FLAG_HIT;
    if (dot(n, d) > 0.0) {
        n = -n;
        flags |= FLAG_NORMAL_FLIPPED;
    }
    best_t = plane_t(best, n, d, best_t);
    vec3 p = d * best_t;
    if (faces_light(p, n)) flags |= FLAG_SHADOW_TESTED;
    vec3 ex, ey;
    if (microquad_axes(d, best_t, n, ex, ey)) flags |= FLAG_AXES_CLAMPED;

    g_id_flags[i] = (flags << ID_BITS) | best;
    g_position[i] = p;
    g_axis_x[i] = ex;
    g_axis_y[i] = ey;
    count_add(C_HITS, 1u);
    count_add(C_SHADOW_TESTED, (flags & FLAG_SHADOW_TESTED) != 0u ? 1u : 0u);
    count_add(C_CLAMPED, (flags & FLAG_AXES_CLAMPED) != 0u ? 1u : 0u);
}
