#version 460
// Baseline pass `shadow_lookup` — GPU twin of
// `baseline::shadow_map::shadow_lookup`: each shadow-tested pixel's lit
// fraction from its cascade's map (the cascade light_setup stored in the
// pixel's `masks` word), one tap (the map carries its slope-scaled bias, [Shadow mapping mechanics]) or k×k
// bilinear PCF with receiver-plane depth bias ([Shadow acne notes]), or PCSS
// (Fernando 2005; pcss.glsl), or a filtered map's moments (moments.glsl). The lit
// fraction's float bits replace the word: a shadow-map frame has no
// occlusion masks.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_PIXELS_X, local_size_y = WORKGROUP_PIXELS_Y) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_G_POSITION) readonly buffer PosBuf { vec3 g_position[]; };
layout(scalar, binding = B_G_ID_FLAGS) readonly buffer GidBuf { uint g_id_flags[]; };
layout(scalar, binding = B_TRIANGLE_NORMALS) readonly buffer TriNrmBuf { vec3 triangle_normals[]; };
#include "scene_triangles.glsl"
layout(scalar, binding = B_LIGHT) readonly buffer LightBuf { LightState light; };
layout(scalar, binding = B_MASKS) buffer MaskBuf { uint masks[]; };
// The depth attachments, copied cascade after cascade (shadow_raster).
layout(scalar, binding = B_SHADOW_MAP) readonly buffer MapBuf { float shadow_map[]; };

#include "light_view.glsl"
#include "shadow_map.glsl"

// The map's depth mapping, set once in main.
vec2 depth_range;

// Stored distance of texel t of cascade k; +inf (lit) outside the map.
float stored(uint k, ivec2 t) {
    int s = int(frame.map_side);
    if (t.x < 0 || t.y < 0 || t.x >= s || t.y >= s) return 1.0 / 0.0;
    float depth = shadow_map[k * frame.map_side * frame.map_side + uint(t.y) * frame.map_side + uint(t.x)];
    return map_distance(depth_range, depth);
}

// Integer texel of a floored coordinate, out of the map when not finite
// or beyond it (the CPU's saturating cast lands outside the map too).
ivec2 texel_of(vec2 floored) {
    vec2 c = clamp(floored, vec2(-1.0), vec2(float(frame.map_side)));
    return isnan(c.x) || isnan(c.y) ? ivec2(-1) : ivec2(c);
}

float texel_world(vec2 texel, vec3 p) {
    float s = max(texel.x, texel.y);
    return light.projection == 0u ? s : s * p.z;
}

// One texel; the map carries the slope-scaled bias (raster::RasterBias).
float one_tap(uint k, vec2 origin, vec2 texel, vec3 p, vec2 ndc) {
    float s = stored(k, texel_of(floor(texel_coords(origin, texel, ndc))));
    precise float bias = texel_world(texel, p) * CONSTANT_BIAS_TEXELS;
    precise float limit = s + bias;
    return light_distance(p) <= limit ? 1.0 : 0.0;
}

float pcf(uint k, vec2 origin, vec2 texel, vec3 p, vec3 n, vec2 ndc, uint size) {
    float own = light_distance(p);
    precise float bias = texel_world(texel, p) * CONSTANT_BIAS_TEXELS;
    vec2 t = texel_coords(origin, texel, ndc);
    int r = int(size / 2u);
    precise float lit = 0.0;
    for (int oy = -r; oy <= r; ++oy) {
        for (int ox = -r; ox <= r; ++ox) {
            precise vec2 s = t + vec2(float(ox), float(oy)) - 0.5;
            vec2 base = floor(s);
            precise vec2 f = s - base;
            ivec2 b = texel_of(base);
            precise float w[4] = float[4]((1.0 - f.x) * (1.0 - f.y), f.x * (1.0 - f.y), (1.0 - f.x) * f.y, f.x * f.y);
            ivec2 d[4] = ivec2[4](ivec2(0, 0), ivec2(1, 0), ivec2(0, 1), ivec2(1, 1));
            [[unroll]] for (int q = 0; q < 4; ++q) {
                ivec2 tx = b + d[q];
                float st = stored(k, tx);
                if (isinf(st)) {
                    lit += w[q];
                    continue;
                }
                float receiver = plane_distance(texel_centre(origin, texel, tx), p, n);
                receiver = finite(receiver) ? min(receiver, own) : own;
                precise float limit = st + bias;
                lit += receiver <= limit ? w[q] : 0.0;
            }
        }
    }
    return lit / float(size * size);
}

#include "pcss.glsl"
#include "moments.glsl"
#include "camera.glsl"

// baseline::contact::eye_ray_hit: λ with the eye ray through q meeting
// triangle t at λ·q, or a negative λ for a miss (q is in front of the
// near plane, so a hit has λ > 0).
float eye_ray_hit(Triangle t, vec3 q) {
    vec3 n = cross3(t.b - t.a, t.c - t.a);
    float denom = dot3(n, q);
    if (denom == 0.0) return -1.0;
    precise float lambda = dot3(n, t.a) / denom;
    precise vec3 h = q * lambda;
    bool inside = dot3(cross3(t.b - t.a, h - t.a), n) >= 0.0
        && dot3(cross3(t.c - t.b, h - t.b), n) >= 0.0
        && dot3(cross3(t.a - t.c, h - t.c), n) >= 0.0;
    return inside ? lambda : -1.0;
}

// baseline::contact::contact_shadowed: the march from eye-relative
// receiver p over `len` toward the light through the G-buffer's depths.
bool contact_shadowed(vec3 p, float len) {
    vec3 to_light = frame.light_vec;
    if (frame.light_is_point != 0u) {
        precise vec3 d = frame.light_vec - p;
        precise vec3 n = d * (1.0 / sqrt(dot3(d, d)));
        to_light = n;
    }
    precise vec3 step = to_light * (len / float(CONTACT_STEPS));
    precise float tolerance = CONTACT_TOLERANCE_PIXELS * sqrt(dot3(frame.cam_dx, frame.cam_dx));
    precise float thickness = CONTACT_THICKNESS_STEPS * (len / float(CONTACT_STEPS));
    for (uint k = 1u; k <= CONTACT_STEPS; ++k) {
        precise vec3 q = p + step * float(k);
        float s = view_depth(q);
        if (s < frame.near) return false;
        vec2 f = camera_framebuffer(q);
        if (!(f.x >= 0.0 && f.y >= 0.0 && f.x < float(frame.width) && f.y < float(frame.height))) return false;
        uint j = uint(f.y) * frame.width + uint(f.x);
        if ((gbuffer_flags(g_id_flags[j]) & FLAG_HIT) == 0u) continue;
        float lambda = eye_ray_hit(scene_triangle(gbuffer_triangle(g_id_flags[j])), q);
        if (lambda <= 0.0) continue;
        precise float behind = s - s * lambda;
        if (behind > s * tolerance && behind < thickness) return true;
    }
    return false;
}

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) return;
    uint i = pixel.y * frame.width + pixel.x;
    uint word = g_id_flags[i];
    if ((gbuffer_flags(word) & FLAG_SHADOW_TESTED) == 0u) {
        masks[i] = 0u;
        return;
    }
    uint k = min(masks[i], max(light.cascade_count, 1u) - 1u);
    vec3 position = g_position[i];
    vec3 p = to_light_view(position);
    vec3 n = rotate(receiver_normal(triangle_normals[gbuffer_triangle(word)], word));
    float lit = 1.0;
    depth_range = map_depth_range();
    if (light.projection == 0u || p.z > 0.0) {
        vec2 ndc = ndc_of(p);
        vec2 origin, texel;
        map_frame(k, origin, texel);
        if (frame.map_filter == 0u) {
            lit = one_tap(k, origin, texel, p, ndc);
        } else if (frame.map_filter == MAP_FILTER_VSM || frame.map_filter == MAP_FILTER_MSM
                   || frame.map_filter == MAP_FILTER_ESM) {
            lit = moments_lookup(k, origin, texel, p, ndc);
        } else if (frame.map_filter == PCSS_FILTER) {
            lit = pcss(k, origin, texel, position, p, n, ndc);
        } else {
            lit = pcf(k, origin, texel, p, n, ndc, frame.map_filter);
        }
        if (frame.map_contact != 0u && lit != 0.0) {
            precise float len = CONTACT_LENGTH_TEXELS * texel_world(texel, p);
            if (contact_shadowed(position, len)) lit = 0.0;
        }
    }
    masks[i] = floatBitsToUint(lit);
}
