#version 460
// The shadow pass's first step with a moving eye, `translate_vertices` —
// GPU twin of `izb::cpu::translate_vertices`: each distinct scene vertex,
// held relative to the pass's anchor as a double-single (hi, lo), minus
// this frame's eye (anchor-relative, double-single in FrameParams), by
// Knuth's two-sum, rounded once to f32 into B_VERTICES — what every later
// pass reads as the eye-relative scene. With a ray-cast G-buffer, thread i
// also makes BVH node i eye-relative from the anchor-space node held past
// the eye-relative ones (`translate_node`'s widening keeps every
// translated vertex inside its box). The operations are `precise` (no
// reassociation or fused multiply-add) and in the twin's order, so the
// vertices and nodes equal the twin's bit for bit.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_LINEAR) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_WORLD_VERTICES) readonly buffer WorldBuf { vec3 world[]; };
layout(scalar, binding = B_VERTICES) writeonly buffer VertexBuf { vec3 vertices[]; };
layout(scalar, binding = B_BVH_NODES) buffer NodeBuf { BvhNode nodes[]; };

// hi + lo − eye, rounded to f32 (the twin's `difference`).
vec3 difference(vec3 hi, vec3 lo) {
    precise vec3 s = hi - frame.eye_hi;
    precise vec3 a_part = s + frame.eye_hi;
    precise vec3 b_part = s - a_part;
    precise vec3 error = (hi - a_part) - (frame.eye_hi + b_part);
    precise vec3 low = lo - frame.eye_lo;
    precise vec3 v = s + (error + low);
    return v;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i < frame.world_vertex_count) {
        vertices[i] = difference(world[2u * i], world[2u * i + 1u]);
    }
    if (i < frame.world_node_count) {
        BvhNode n = nodes[frame.world_node_count + i];
        precise vec3 lo = difference(n.lo, vec3(0.0));
        precise vec3 hi = difference(n.hi, vec3(0.0));
        precise vec3 reach = max(max(abs(n.lo), abs(n.hi)), max(abs(lo), abs(hi)));
        precise vec3 margin = reach * NODE_WIDENING + vec3(NODE_WIDENING_FLOOR);
        n.lo = lo - margin;
        n.hi = hi + margin;
        nodes[i] = n;
    }
}
