#version 460
// Host helper `visibility_raster` — the fragment shader of a raster
// G-buffer with depth and a geometric normal (`GBufferInput::DepthNormal`):
// the triangle id into colour attachment 0 (R32_UINT, as
// `visibility_raster.frag`) and the geometric normal into attachment 1
// (R32G32B32A32_SFLOAT, xyz, unnormalised). The normal is the cross
// product of the eye-relative position's screen derivatives: a 2×2 quad's
// differences of points on the triangle's plane (helper lanes extrapolate
// it), so it is perpendicular to that plane up to their rounding — about
// ε·z / (a pixel's footprint) in angle, the error a host's derivative
// normals carry (paper-notes/embedding.md measures what it costs).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require
#include "contract.glsl"

layout(push_constant, scalar) uniform ViewBlock { VisibilityView view; };
layout(location = 0) in vec3 eye_relative;
layout(location = 0) out uint triangle_id;
layout(location = 1) out vec4 normal;

void main() {
    triangle_id = view.first_triangle + uint(gl_PrimitiveID);
    normal = vec4(cross(dFdxFine(eye_relative), dFdyFine(eye_relative)), 0.0);
}
