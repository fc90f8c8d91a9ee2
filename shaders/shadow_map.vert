#version 460
// Baseline pass `shadow_map` — the vertex shader of the depth-only render
// pass that draws every triangle into cascade gl_InstanceIndex's map on
// the hardware rasteriser (no fragment shader); the GPU twin of
// `baseline::shadow_map::shadow_map` and `baseline::raster`. Vertex v of
// triangle v / 3, no vertex buffers. Clip space puts texel coordinates on
// the viewport (framebuffer pixel = texel) and the map's depth in z:
// - directional light: orthographic, depth (d − near) / range, w = 1;
//   depth clamp keeps casters in front of the range (they clamp to 0);
// - point light: x, y scaled by the light-view z, z = near, w = z, so
//   depth = near / z (reversed, infinite far) and the clipper cuts at
//   z = near exactly as the CPU's clip_to_near does.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
#include "scene_triangles.glsl"
layout(scalar, binding = B_LIGHT) readonly buffer LightBuf { LightState light; };

#include "light_view.glsl"
#include "shadow_map.glsl"

void main() {
    uint k = uint(gl_InstanceIndex);
    Triangle tri = scene_triangle(uint(gl_VertexIndex) / 3u);
    uint corner = uint(gl_VertexIndex) % 3u;
    vec3 q = to_light_view(corner == 0u ? tri.a : (corner == 1u ? tri.b : tri.c));
    vec2 origin, texel;
    map_frame(k, origin, texel);
    vec2 range = map_depth_range();
    float to_clip = 2.0 / float(frame.map_side);
    if (light.projection == 0u) {
        vec2 t = texel_coords(origin, texel, q.xy);
        precise vec2 xy = t * to_clip - 1.0;
        precise float depth = (-q.z - range.x) / range.y;
        gl_Position = vec4(xy, depth, 1.0);
    } else {
        // (t · z): the texel coordinates before the rasteriser divides by w.
        precise vec2 tz = (q.xy - origin * q.z) / texel;
        precise vec2 xy = tz * to_clip - q.z;
        gl_Position = vec4(xy, range.x, q.z);
    }
}
