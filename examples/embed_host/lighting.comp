#version 460
// The worked host's lighting pass: deferred shading of its own
// visibility buffer (Burns and Hunt 2013: the pixel's triangle fetched
// from the host's index and vertex buffers, its plane met by the pixel's
// centre ray), lit by one light whose visibility is izb's lit fraction,
// sampled from the image the shadow pass left. Ambient + Lambert × lit,
// with the constants the host passes (izb's own shading's, so the two
// images can be compared), sRGB-encoded into an RGBA8 storage image.
// Compiled by izb's build script (`host_lighting.spv`, and with
// MULTISAMPLED `host_lighting_multisampled.spv`), so the example
// needs no compiler of its own.
#extension GL_EXT_scalar_block_layout : require

layout(local_size_x = 8, local_size_y = 8) in;

#ifdef MULTISAMPLED
// A multisampled visibility buffer (`--msaa N`): each pixel shaded by its
// sample 0's triangle (an engine would shade its samples and resolve;
// the comparison with izb's own shading then holds away from edges).
layout(binding = 0) uniform usampler2DMS visibility;
#else
layout(binding = 0) uniform usampler2D visibility;
#endif
layout(binding = 1) uniform sampler2D lit_fraction;
layout(binding = 2, rgba8) uniform writeonly image2D shaded;
layout(binding = 3, scalar) readonly buffer Vertices { vec3 vertices[]; };
layout(binding = 4, scalar) readonly buffer Indices { uint indices[]; };

// `LightingView` in `lighting.rs`; every point relative to the mesh's
// origin, as its vertices are.
layout(push_constant, scalar) uniform Lighting {
    vec3 eye;
    uint width;
    // The ray through pixel centre (x, y): corner + (x+½)·dx + (y+½)·dy.
    vec3 corner;
    uint height;
    vec3 dx;
    uint light_is_point;
    vec3 dy;
    float ambient;
    // The point light's position, or the unit direction toward a
    // directional light.
    vec3 light;
    float diffuse;
    vec3 sky;
} l;

const uint NO_TRIANGLE = 0xFFFFFFFFu;

void main() {
    uvec2 p = gl_GlobalInvocationID.xy;
    if (p.x >= l.width || p.y >= l.height) return;
    uint id = texelFetch(visibility, ivec2(p), 0).r;
    vec3 rgb = l.sky;
    if (id != NO_TRIANGLE) {
        vec3 a = vertices[indices[3u * id]];
        vec3 b = vertices[indices[3u * id + 1u]];
        vec3 c = vertices[indices[3u * id + 2u]];
        vec3 n = cross(b - a, c - a);
        vec3 ray = l.corner + (float(p.x) + 0.5) * l.dx + (float(p.y) + 0.5) * l.dy;
        float lambert = 0.0;
        if (dot(n, n) > 0.0) {
            n = normalize(n);
            // The side the eye sees (izb shades back faces too).
            if (dot(n, ray) > 0.0) n = -n;
            vec3 toward = l.light;
            if (l.light_is_point != 0u) {
                vec3 surface = l.eye + ray * (dot(a - l.eye, n) / dot(ray, n));
                toward = normalize(l.light - surface);
            }
            lambert = max(dot(n, toward), 0.0);
        }
        float lit = texelFetch(lit_fraction, ivec2(p), 0).r;
        rgb = vec3(l.ambient + (1.0 - l.ambient) * l.diffuse * lambert * lit);
    }
    imageStore(shaded, ivec2(p), vec4(pow(clamp(rgb, 0.0, 1.0), vec3(1.0 / 2.2)), 1.0));
}
