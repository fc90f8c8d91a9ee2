#version 460
// The worked host's read-back of its multisampled visibility buffer (a
// check outside the measured frames): a multisampled image cannot be a
// copy's source for a buffer, so every sample is fetched into one, pixel
// by pixel, sample by sample — the layout the CPU twin reads
// (`izb::gbuffer::gbuffer_from_multisampled_visibility`: `ids[i * N + s]`).
// Compiled by izb's build script (`host_multisampled_ids.spv`).
#extension GL_EXT_samplerless_texture_functions : require

layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = 0) uniform utexture2DMS ids;
layout(binding = 1, std430) writeonly buffer Words { uint words[]; };

layout(push_constant) uniform Size {
    uint width;
    uint height;
    uint samples;
} size;

void main() {
    uvec2 p = gl_GlobalInvocationID.xy;
    if (p.x >= size.width || p.y >= size.height) return;
    uint first = (p.y * size.width + p.x) * size.samples;
    for (uint s = 0u; s < size.samples; ++s) {
        words[first + s] = texelFetch(ids, ivec2(p), int(s)).r;
    }
}
