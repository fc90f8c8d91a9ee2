#version 460
// Baseline pass `shadow_volumes`, its compute steps — GPU twin of
// `baseline::volumes::shadow_volumes`. STEP_DEPTH: each shadow-tested
// pixel's receiver depth (reversed, near / s, the receiver moved toward
// the camera by VOLUME_NUDGE_PIXELS of its footprint; 0 elsewhere) into
// the first `pixels` words of B_SHADOW_MAP, which the host copies into the
// depth attachment. STEP_LOOKUP: after the volumes' stencil pass and the
// copy of its stencil bytes behind those words, a pixel is lit when its
// count is 0 (modulo 256). The lit fraction's bits go to `masks`, as
// shadow_lookup writes them.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_PIXELS_X, local_size_y = WORKGROUP_PIXELS_Y) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_G_POSITION) readonly buffer PosBuf { vec3 g_position[]; };
layout(scalar, binding = B_G_ID_FLAGS) readonly buffer GidBuf { uint g_id_flags[]; };
#ifdef STEP_DEPTH
layout(scalar, binding = B_SHADOW_MAP) writeonly buffer DepthBuf { float receiver_depth[]; };
#else
layout(scalar, binding = B_SHADOW_MAP) readonly buffer StencilBuf { uint words[]; };
layout(scalar, binding = B_MASKS) writeonly buffer MaskBuf { uint masks[]; };
#endif

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) return;
    uint i = pixel.y * frame.width + pixel.x;
    bool tested = (gbuffer_flags(g_id_flags[i]) & FLAG_SHADOW_TESTED) != 0u;
#ifdef STEP_DEPTH
    float depth = 0.0;
    if (tested) {
        precise float s = dot3(g_position[i], frame.cam_forward);
        precise float nudge = VOLUME_NUDGE_PIXELS * sqrt(dot3(frame.cam_dx, frame.cam_dx));
        precise float moved = s - s * nudge;
        depth = frame.near / moved;
    }
    receiver_depth[i] = depth;
#else
    uint pixels = frame.width * frame.height;
    uint count = (words[pixels + i / 4u] >> (8u * (i % 4u))) & 0xFFu;
    masks[i] = tested ? floatBitsToUint(count == 0u ? 1.0 : 0.0) : 0u;
#endif
}
