#version 460
// Host helper `visibility_raster` — the fragment shader: the triangle id
// of the draw's primitive (the scene's triangle order from
// `view.first_triangle` on) into an R32_UINT colour attachment, cleared to
// 0xFFFFFFFF (no surface). gl_PrimitiveID in a fragment shader needs the
// device's geometryShader feature.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require
#include "contract.glsl"

layout(push_constant, scalar) uniform ViewBlock { VisibilityView view; };
layout(location = 0) out uint triangle_id;

void main() {
    triangle_id = view.first_triangle + uint(gl_PrimitiveID);
}
