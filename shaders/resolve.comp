#version 460
// Pass 4, `resolve` — GPU twin of `izb::cpu::resolve` and
// `izb::output::shade_pixel`: the shaded image (ambient + Lambert × lit
// fraction, display gamma 2.2) as packed RGB8, with the lit fraction in
// alpha as the count of lit samples, 32 − popcount(mask), exact (the host
// divides by 32), or ALPHA_NOT_TESTED. A MODE_PAIRED64 frame's 64 samples:
// 64 − both halves' popcounts (the host divides by 64). With edge
// surfaces (edge_receivers.glsl) the pixel's surfaces' masks are combined
// first, over the samples that count (the host divides by their number).
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_PIXELS_X, local_size_y = WORKGROUP_PIXELS_Y) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_G_POSITION) readonly buffer PosBuf { vec3 g_position[]; };
layout(scalar, binding = B_G_ID_FLAGS) readonly buffer GidBuf { uint g_id_flags[]; };
layout(scalar, binding = B_TRIANGLE_NORMALS) readonly buffer TriNrmBuf { vec3 triangle_normals[]; };
layout(scalar, binding = B_G_NORMAL) readonly buffer GNrmBuf { vec4 g_normal[]; };
// With edge surfaces the pixel's combined mask is written back to its word.
layout(scalar, binding = B_MASKS) buffer MaskBuf { uint masks[]; };
layout(scalar, binding = B_MASKS_HIGH) buffer MaskHighBuf { uint masks_high[]; };
layout(scalar, binding = B_SHADED) writeonly buffer ShadedBuf { uint shaded[]; };

// output::AMBIENT, output::DIFFUSE and output::SKY_RGB.
#define AMBIENT 0.18
#define DIFFUSE 0.85
const vec3 SKY = vec3(0.55, 0.7, 0.9);

#include "edge_receivers.glsl"
#include "entry_normal.glsl"

// The receivers' masks of half `mask_half`.
uint half_mask(uint mask_half, uint i) {
    return mask_half == 0u ? masks[i] : masks_high[i];
}

// EdgeSurfaces::combine for pixel i's half `mask_half` (record e): the
// centre's mask on its samples, each extra surface's on its own, every
// sample on a surface facing away.
uint combined_mask(uint i, uvec4 e, uint mask_half) {
    uint mask = (half_mask(mask_half, i) & e.x) | e.z;
    uint first = e.w & ((1u << EDGE_COUNT_SHIFT) - 1u);
    uint count = e.w >> EDGE_COUNT_SHIFT;
    uint extra = frame.width * frame.height + first;
    for (uint k = 0u; k < count; ++k) {
        mask |= half_mask(mask_half, extra + k) & surface_coverage(first + k, mask_half);
    }
    return mask;
}

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) return;
    uint i = pixel.y * frame.width + pixel.x;
    uint word = g_id_flags[i];
    uint flags = gbuffer_flags(word);
    bool tested = (flags & FLAG_SHADOW_TESTED) != 0u;
    uint samples = 32u * frame.mask_halves;
    uint hidden = uint(bitCount(masks[i]));
    if (frame.mask_halves == 2u) hidden += uint(bitCount(masks_high[i]));
    if (frame.edge_surfaces != 0u) {
        // Over the samples that count (resolve_halves): the host divides
        // alpha by their number.
        samples = 0u;
        hidden = 0u;
        for (uint mask_half = 0u; mask_half < frame.mask_halves; ++mask_half) {
            uvec4 e = edge_pixel_record(i, mask_half);
            uint mask = combined_mask(i, e, mask_half);
            if (mask_half == 0u) masks[i] = mask;
            else masks_high[i] = mask;
            samples += uint(bitCount(e.y));
            hidden += uint(bitCount(mask));
        }
    }
    uint lit_samples = samples - hidden;
    vec3 rgb = SKY;
    if ((flags & FLAG_HIT) != 0u) {
        vec3 p = g_position[i];
        vec3 toward = frame.light_is_point != 0u ? normalize(frame.light_vec - p) : frame.light_vec;
        vec3 n = entry_normal(i, word);
        float lambert = max(dot(n, toward), 0.0);
        // 1 − hidden / samples, as the CPU twin: with edge surfaces the
        // count is no power of two and (samples − hidden) / samples can
        // round the other way. No sample that counts: dark, as the host
        // shades its NaN lit fraction.
        float v = tested && samples > 0u ? 1.0 - float(hidden) / float(samples) : 0.0;
        rgb = vec3(AMBIENT + (1.0 - AMBIENT) * DIFFUSE * lambert * v);
    }
    uvec3 c = uvec3(round(pow(clamp(rgb, 0.0, 1.0), vec3(1.0 / 2.2)) * 255.0));
    uint alpha = tested ? lit_samples : ALPHA_NOT_TESTED;
    shaded[i] = c.r | (c.g << 8) | (c.b << 16) | (alpha << 24);
}
