#version 460
// Pass 0 from the host's visibility buffer, `gbuffer_from_visibility` —
// GPU twin of `izb::gbuffer::gbuffer_from_visibility`.
//
// A renderer that rasterises a visibility buffer (per pixel the id of the
// triangle it sees; Burns and Hunt 2013) already knows each pixel's surface:
// the G-buffer entry follows from the pixel's centre ray and that
// triangle's plane, exactly as the ray-cast `gbuffer.comp` derives it from
// its BVH hit (`gbuffer_store.glsl`), with no depth-buffer quantisation in
// between. Where the raster and the ray cast see the same triangle the
// entries are the same bit for bit; they differ only where coverage rules
// differ (a pixel centre on a shared edge).
//
// An id past the pass's triangles (other than NO_HIT, the host's "no
// surface") or a plane the centre ray does not cross in front of the eye
// is stored as a miss and counted (C_VISIBILITY_REJECTED), never read out
// of bounds.
//
// Built with MULTISAMPLED (`gbuffer_from_multisampled_visibility`, the
// twin `izb::gbuffer::gbuffer_from_multisampled_visibility`) it reads the
// host's ids unresolved, N samples a pixel, none at the centre where P
// belongs: samples that agree on one triangle nominate it; where they
// disagree (or the centre ray misses their one triangle) the samples of
// the pixel and its eight neighbours do, and the centre ray keeps the
// closest candidate by the watertight test (visibility_candidates.glsl).
// A centre that meets none of them is a miss, counted in
// C_CENTRE_UNCOVERED. Its loops are bounded by the sample count
// (visibility_candidates.glsl says how far below lavapipe's cap).
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
layout(scalar, binding = B_TRIANGLE_NORMALS) readonly buffer TriNrmBuf { vec3 triangle_normals[]; };
layout(scalar, binding = B_COUNTERS) buffer CountBuf { uint counters[]; };
#include "counters.glsl"
#ifdef MULTISAMPLED
layout(set = HOST_SET, binding = HOST_VISIBILITY) uniform utexture2DMS visibility;
#include "visibility_candidates.glsl"
#else
layout(set = HOST_SET, binding = HOST_VISIBILITY) uniform utexture2D visibility;
#endif

#include "surface_hit.glsl"
#include "gbuffer_store.glsl"

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) return;
    uint i = pixel.y * frame.width + pixel.x;
    vec2 image_point = vec2(pixel) + 0.5;
    vec3 d = frame.cam_corner + image_point.x * frame.cam_dx + image_point.y * frame.cam_dy;
#ifdef MULTISAMPLED
    uint samples = visibility_samples();
    if (!pixel_ids_valid(ivec2(pixel), samples)) {
        store_miss(i);
        count_add(C_VISIBILITY_REJECTED, 1u);
        return;
    }
    bool any_miss = add_pixel_candidates(ivec2(pixel), samples);
    if (candidate_count == 0u) {
        store_miss(i);
        return;
    }
    float t = frame.far;
    uint id = candidate_count == 1u && !any_miss ? candidate_closest_hit(d, t) : NO_HIT;
    if (id == NO_HIT) {
        candidate_count = 0u;
        add_neighbourhood_candidates(ivec2(pixel), samples);
        t = frame.far;
        id = candidate_closest_hit(d, t);
    }
    if (id == NO_HIT) {
        store_miss(i);
        count_add(C_CENTRE_UNCOVERED, 1u);
        return;
    }
    if (!store_surface(i, id, d, 0.0)) count_add(C_VISIBILITY_REJECTED, 1u);
#else
    uint id = texelFetch(visibility, ivec2(pixel), 0).x;
    if (id == NO_HIT) {
        store_miss(i);
        return;
    }
    if (id >= frame.triangle_count) {
        store_miss(i);
        count_add(C_VISIBILITY_REJECTED, 1u);
        return;
    }
    if (!store_surface(i, id, d, 0.0)) count_add(C_VISIBILITY_REJECTED, 1u);
#endif
}
