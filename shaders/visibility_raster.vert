#version 460
// Host helper `visibility_raster` — the vertex shader of a minimal
// visibility-buffer pass (Burns and Hunt 2013) for a host that has none:
// positions from the host's vertex buffer (location 0, three floats,
// relative to the origin of `view.eye`), a pinhole camera whose pixel
// centres see exactly the rays of `izb::scene::CameraFrame::direction`,
// the depth of `view.depth_offset / depth_scale` (reverse Z with a finite
// far plane for a visibility buffer, so the near and far planes clip as
// the ray cast's [near, far] view depths do; any `DepthConvention` for a
// depth + normal G-buffer). Its fragment shaders write the triangle id the
// shadow pass reads (`GBufferInput::Visibility`), and with
// `depth_normal_raster.frag` the geometric normal too
// (`GBufferInput::DepthNormal`).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require
#include "contract.glsl"

layout(location = 0) in vec3 position;
layout(push_constant, scalar) uniform ViewBlock { VisibilityView view; };
#ifdef EYE_RELATIVE_OUT
// For `depth_normal_raster.frag` (compiled as `depth_normal_raster_vert`):
// the eye-relative position, whose screen derivatives span the surface.
// Only that build declares it: an output no fragment shader reads is a
// validation warning.
layout(location = 0) out vec3 eye_relative;
#endif

void main() {
    vec3 q = position - view.eye;
#ifdef EYE_RELATIVE_OUT
    eye_relative = q;
#endif
    float depth = dot(q, view.forward);
    gl_Position = vec4(dot(q, view.right), dot(q, view.down),
                       view.depth_offset + view.depth_scale * depth, depth);
}
