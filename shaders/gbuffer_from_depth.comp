#version 460
// Pass 0 from the host's depth and normal images, `gbuffer_from_depth` —
// GPU twin of `izb::gbuffer::gbuffer_from_depth`.
//
// The G-buffer most renderers already have: a hardware depth and a
// geometric normal per pixel. The centre ray d has unit component along
// the view axis, so the surface point is P = z·d at the view depth z the
// host's projection encodes (FrameParams::depth_*, one form for standard
// and reverse Z, finite and infinite far); the µQuad follows from P and
// the normal as the other producers derive it from their triangle's plane
// (`store_entry`). The entry names no triangle (DEPTH_SURFACE) and keeps
// its normal in B_G_NORMAL, which `entry_normal.glsl` reads, with how far
// the depth's error may put P off the surface along it
// (`gbuffer::depth_uncertainty`): the receiver's own triangle, now a
// candidate, lies within that of P's tangent plane, and the frustum
// test's depth tolerance grows by it.
//
// A depth at the far plane's value is no surface. A depth that gives no
// view depth in front of the eye, or a normal that is zero or not finite,
// is stored as a miss and counted (C_VISIBILITY_REJECTED).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_samplerless_texture_functions : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_PIXELS_X, local_size_y = WORKGROUP_PIXELS_Y) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
#include "scene_triangles.glsl"
layout(scalar, binding = B_G_POSITION) writeonly buffer PosBuf { vec3 g_position[]; };
layout(scalar, binding = B_G_AXIS_X) writeonly buffer AxBuf { vec3 g_axis_x[]; };
layout(scalar, binding = B_G_AXIS_Y) writeonly buffer AyBuf { vec3 g_axis_y[]; };
layout(scalar, binding = B_G_ID_FLAGS) writeonly buffer GidBuf { uint g_id_flags[]; };
layout(scalar, binding = B_G_NORMAL) writeonly buffer GNrmBuf { vec4 g_normal[]; };
layout(scalar, binding = B_TRIANGLE_NORMALS) readonly buffer TriNrmBuf { vec3 triangle_normals[]; };
layout(scalar, binding = B_COUNTERS) buffer CountBuf { uint counters[]; };
layout(set = HOST_SET, binding = HOST_DEPTH) uniform texture2D depth_image;
layout(set = HOST_SET, binding = HOST_NORMAL) uniform texture2D normal_image;
#include "counters.glsl"

#include "surface_hit.glsl"
#include "gbuffer_store.glsl"

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) return;
    uint i = pixel.y * frame.width + pixel.x;
    float depth = texelFetch(depth_image, ivec2(pixel), 0).x;
    bool reversed = frame.depth_reversed != 0u;
    if (depth == (reversed ? 0.0 : 1.0)) {
        store_miss(i);
        return;
    }
    // DepthConvention::view_depth: standard Z's 1 − D is exact for D ≥ ½.
    precise float u = reversed ? depth : 1.0 - depth;
    precise float z = frame.depth_near / (frame.depth_near_over_far + u * frame.depth_span);
    vec3 n = texelFetch(normal_image, ivec2(pixel), 0).xyz;
    float length_squared = dot(n, n);
    if (!(u > 0.0 && z > 0.0 && !isinf(z) && length_squared > 0.0 && !isinf(length_squared))) {
        store_miss(i);
        count_add(C_VISIBILITY_REJECTED, 1u);
        return;
    }
    n = normalize(n);
    vec2 image_point = vec2(pixel) + 0.5;
    vec3 d = frame.cam_corner + image_point.x * frame.cam_dx + image_point.y * frame.cam_dy;
    if (dot(n, d) > 0.0) n = -n;
    // The format's spacing at the depth: a float's from its exponent (D
    // is normal or 0 here), a unorm's fixed.
    float float_spacing = uintBitsToFloat(floatBitsToUint(depth) & 0x7F800000u) * exp2(-23.0);
    float spacing = max(float_spacing, frame.depth_step);
    precise float dz = z * z * (frame.depth_span / frame.depth_near) * (DEPTH_INPUT_SPACINGS * spacing);
    precise float uncertainty = dz * abs(dot(n, d));
    g_normal[i] = vec4(n, uncertainty);
    store_entry(i, DEPTH_SURFACE, d, z, n, FLAG_HIT);
}
