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
#include "gbuffer_store.glsl"

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) return;
    uint i = pixel.y * frame.width + pixel.x;
    vec2 image_point = vec2(pixel) + 0.5;
    vec3 d = frame.cam_corner + image_point.x * frame.cam_dx + image_point.y * frame.cam_dy;
    float best_t = frame.far;
    uint best = closest_hit(d, best_t);

    if (best == NO_HIT) {
        store_miss(i);   // a miss
        return;
    }
    store_surface(i, best, d, best_t);
}
