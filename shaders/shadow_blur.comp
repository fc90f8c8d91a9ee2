#version 460
// Baseline pass `shadow_blur` — GPU twin of `baseline::moments::
// shadow_blur`: a filtered map's depths turned into moments of the moment
// depth u (u, u², u³, u⁴; the first two for VSM; exp(c·(u − 1)) for ESM)
// and blurred by a
// separable 9² Gaussian (weights C(8, i)/256). STEP_X: the moments of each
// texel's row neighbours, summed into the rows; STEP_Y: the rows' column
// neighbours into the result. Texels beyond the map read as empty (u = 1,
// every moment 1). One invocation per texel of every cascade (y runs over
// cascade after cascade); sums in the CPU's order, every one `precise`.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_PIXELS_X, local_size_y = WORKGROUP_PIXELS_Y) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_LIGHT) readonly buffer LightBuf { LightState light; };
layout(scalar, binding = B_SHADOW_MAP) buffer MapBuf { float shadow_map[]; };

#include "light_view.glsl"
#include "shadow_map.glsl"

// C(2r, i) / 2^(2r), in integers first: exact, as on the CPU.
float blur_weight(uint i) {
    uint n = 2u * MAP_FILTER_BLUR_RADIUS, c = 1u;
    for (uint j = 0u; j < i; ++j) c = c * (n - j) / (j + 1u);
    return float(c) / float(1u << n);
}

// moments::moments_of: the moments a texel at moment depth u stores (the
// first moment_count() of the four).
float[4] moments_of(float u) {
    if (frame.map_filter == MAP_FILTER_ESM) {
        precise float e = MAP_FILTER_ESM_EXPONENT * (u - 1.0);
        return float[4](exp(e), 0.0, 0.0, 0.0);
    }
    precise float u2 = u * u;
    precise float u3 = u2 * u;
    precise float u4 = u2 * u2;
    return float[4](u, u2, u3, u4);
}

void main() {
    uint side = frame.map_side;
    uvec2 id = gl_GlobalInvocationID.xy;
    if (id.x >= side || id.y >= side * light.cascade_count) return;
    int x = int(id.x), y = int(id.y % side);
    uint k = id.y / side, n = moment_count(), texels = map_texels();
    uint cascade_start = k * side * side;
    int r = int(MAP_FILTER_BLUR_RADIUS);
    precise float sum[4] = float[4](0.0, 0.0, 0.0, 0.0);
#ifdef STEP_X
    vec2 depth_range = map_depth_range(), moment_range = moment_depth_range();
    for (int j = 0; j <= 2 * r; ++j) {
        int xx = x + j - r;
        float u = 1.0;
        if (xx >= 0 && xx < int(side)) {
            u = moment_of_stored(depth_range, moment_range, shadow_map[cascade_start + uint(y) * side + uint(xx)]);
        }
        float m[4] = moments_of(u);
        float w = blur_weight(uint(j));
        [[unroll]] for (int c = 0; c < 4; ++c) sum[c] += w * m[c];
    }
    uint out_base = texels;
#else
    uint rows = texels;
    for (int j = 0; j <= 2 * r; ++j) {
        int yy = y + j - r;
        bool inside = yy >= 0 && yy < int(side);
        float w = blur_weight(uint(j));
        for (uint c = 0u; c < n; ++c) {
            float m = inside ? shadow_map[rows + (cascade_start + uint(yy) * side + uint(x)) * n + c] : 1.0;
            sum[c] += w * m;
        }
    }
    uint out_base = texels + texels * n;
#endif
    uint at = out_base + (cascade_start + uint(y) * side + uint(x)) * n;
    for (uint c = 0u; c < n; ++c) shadow_map[at + c] = sum[c];
}
