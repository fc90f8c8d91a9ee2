#version 460
// The shadow pass's last step, `export_images` — GPU twin of
// `izb::cpu::export_images`: the frame's masks and lit fraction copied
// into the host's storage images, which its lighting pass samples (the
// pass's own results stay in storage buffers). One file, one step per
// output and format:
// - STEP_MASKS: the occlusion masks, R32_UINT (one half) or, with
//   MASKS_PAIRED, R32G32_UINT (bits 32–63 of MODE_PAIRED64 in .y);
// - STEP_LIT with LIT_FORMAT r16 or r8: the lit fraction as UNORM, from
//   resolve's exact lit-sample count: 1 − hidden / samples where
//   shadow-tested (with edge surfaces over the samples that count, the
//   pixel's record's; none counting: 0, as the twin's NaN converts), 0
//   on a surface facing away from the light (its geometry shadows it),
//   1 where no surface is seen.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_PIXELS_X, local_size_y = WORKGROUP_PIXELS_Y) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };

#if defined(STEP_MASKS)
layout(scalar, binding = B_MASKS) readonly buffer MaskBuf { uint masks[]; };
layout(scalar, binding = B_MASKS_HIGH) readonly buffer MaskHighBuf { uint masks_high[]; };
#if defined(MASKS_PAIRED)
layout(set = HOST_SET, binding = HOST_MASKS, rg32ui) uniform writeonly uimage2D masks_out;
#else
layout(set = HOST_SET, binding = HOST_MASKS, r32ui) uniform writeonly uimage2D masks_out;
#endif
#elif defined(STEP_LIT)
layout(scalar, binding = B_G_ID_FLAGS) readonly buffer GidBuf { uint g_id_flags[]; };
layout(scalar, binding = B_SHADED) readonly buffer ShadedBuf { uint shaded[]; };
layout(set = HOST_SET, binding = HOST_LIT, LIT_FORMAT) uniform writeonly image2D lit_out;
#include "edge_receivers.glsl"
#endif

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) return;
    uint i = pixel.y * frame.width + pixel.x;
#if defined(STEP_MASKS)
#if defined(MASKS_PAIRED)
    imageStore(masks_out, ivec2(pixel), uvec4(masks[i], masks_high[i], 0u, 0u));
#else
    imageStore(masks_out, ivec2(pixel), uvec4(masks[i], 0u, 0u, 0u));
#endif
#elif defined(STEP_LIT)
    uint alpha = shaded[i] >> 24;
    uint flags = gbuffer_flags(g_id_flags[i]);
    float lit = (flags & FLAG_HIT) != 0u ? 0.0 : 1.0;
    if (alpha != ALPHA_NOT_TESTED) {
        // resolve's alpha: the lit samples of those that count, 32 per
        // mask half without edge surfaces. 1 − hidden / samples, as the
        // twin forms it (the other form can round the other way).
        uint samples = 32u * frame.mask_halves;
        if (frame.edge_surfaces != 0u) {
            samples = 0u;
            for (uint mask_half = 0u; mask_half < frame.mask_halves; ++mask_half) {
                samples += uint(bitCount(edge_pixel_record(i, mask_half).y));
            }
        }
        lit = samples > 0u ? 1.0 - float(samples - alpha) / float(samples) : 0.0;
    }
    imageStore(lit_out, ivec2(pixel), vec4(lit, 0.0, 0.0, 0.0));
#endif
}
