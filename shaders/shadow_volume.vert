#version 460
// Baseline pass `shadow_volumes` — the vertex shader of the volumes'
// stencil pass: vertex v is corner VOLUME_CORNERS[v % 24] of triangle
// v / 24's shadow volume (light cap, dark cap moved volume_extrusion away
// from the light, three side quads), projected by the camera with
// reversed depth near / s (infinite far). No vertex buffer, no fragment
// shader; a triangle edge-on to the light gets no volume (every corner
// at one point). The GPU twin of `baseline::screen_frame::ScreenFrame::
// {corners, framebuffer, depth}`, same order of every operation.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
#include "scene_triangles.glsl"
layout(scalar, binding = B_LIGHT) readonly buffer LightBuf { LightState light; };

#include "light_view.glsl"
#include "shadow_map.glsl"
#include "camera.glsl"

void main() {
    Triangle t = scene_triangle(uint(gl_VertexIndex) / 24u);
    uint corner = VOLUME_CORNERS[uint(gl_VertexIndex) % 24u];
    vec3 a = t.a, b = t.b, c = t.c;
    vec3 n = cross3(b - a, c - a);
    bool point = frame.light_is_point != 0u;
    vec3 to_light = point ? frame.light_vec - a : frame.light_vec;
    float facing = dot3(n, to_light);
    if (isnan(facing) || facing == 0.0) {
        gl_Position = vec4(0.0, 0.0, 0.5, 1.0);
        return;
    }
    if (facing < 0.0) {
        vec3 swap = b;
        b = c;
        c = swap;
    }
    uint k = corner % 3u;
    vec3 v = k == 0u ? a : (k == 1u ? b : c);
    if (corner >= 3u) {
        if (point) {
            precise vec3 d = v - frame.light_vec;
            precise float scale = frame.volume_extrusion / sqrt(dot3(d, d));
            precise vec3 moved = v + d * scale;
            v = moved;
        } else {
            precise vec3 moved = v - frame.light_vec * frame.volume_extrusion;
            v = moved;
        }
    }
    gl_Position = camera_clip(v);
}
