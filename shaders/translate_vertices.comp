#version 460
// The shadow pass's first step with a moving eye, `translate_vertices` —
// GPU twin of `izb::cpu::translate_vertices`: each distinct scene vertex,
// held relative to the pass's anchor as a double-single (hi, lo), minus
// this frame's eye (anchor-relative, double-single in FrameParams), by
// Knuth's two-sum, rounded once to f32 into B_VERTICES — what every later
// pass reads as the eye-relative scene. The operations are `precise`
// (no reassociation or fused multiply-add) and in the twin's order, so the
// vertices equal the twin's bit for bit.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_LINEAR) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_WORLD_VERTICES) readonly buffer WorldBuf { vec3 world[]; };
layout(scalar, binding = B_VERTICES) writeonly buffer VertexBuf { vec3 vertices[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= frame.world_vertex_count) return;
    vec3 hi = world[2u * i];
    vec3 lo = world[2u * i + 1u];
    precise vec3 s = hi - frame.eye_hi;
    precise vec3 a_part = s + frame.eye_hi;
    precise vec3 b_part = s - a_part;
    precise vec3 error = (hi - a_part) - (frame.eye_hi + b_part);
    precise vec3 low = lo - frame.eye_lo;
    precise vec3 v = s + (error + low);
    vertices[i] = v;
}
