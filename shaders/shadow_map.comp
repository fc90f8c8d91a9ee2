#version 460
// Baseline pass `shadow_map` — GPU twin of
// `baseline::shadow_map::shadow_map`: every triangle drawn into every
// cascade's map, nearest distance to the light kept with atomicMin on
// order-preserving bits. One workgroup per triangle whose 64 invocations
// share its texel box, so a ground plane that covers the whole map does not
// serialise on one invocation. Texel centres inside the projected (and, for
// a point light, near-clipped) triangle take the plane's distance through
// the centre, clamped to the vertices' range.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

#define LOOP_BUDGET_SLOTS 64
layout(local_size_x = 64) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_TRIANGLES) readonly buffer TriBuf { Triangle triangles[]; };
layout(scalar, binding = B_LIGHT) readonly buffer LightBuf { LightState light; };
layout(scalar, binding = B_COUNTERS) buffer CounterBuf { uint counters[]; };
layout(scalar, binding = B_SHADOW_MAP) buffer MapBuf { uint shadow_map[]; };

#include "light_view.glsl"
#include "loop_budget.glsl"
#include "shadow_map.glsl"

void draw(uint k, vec3 f0, vec3 f1, vec3 f2, vec3 plane_point, vec3 plane_normal, float dmin, float dmax) {
    vec2 origin, texel;
    map_frame(k, origin, texel);
    vec2 t0 = texel_coords(origin, texel, ndc_of(f0));
    vec2 t1 = texel_coords(origin, texel, ndc_of(f1));
    vec2 t2 = texel_coords(origin, texel, ndc_of(f2));
    precise float area = perp_dot(t1 - t0, t2 - t0);
    if (!finite(area) || area == 0.0) return;
    vec2 lo = min(min(t0, t1), t2), hi = max(max(t0, t1), t2);
    float side = float(frame.map_side);
    if (hi.x < 0.0 || hi.y < 0.0 || lo.x > side || lo.y > side) return;
    int x0 = int(max(ceil(lo.x - 0.5), 0.0));
    int y0 = int(max(ceil(lo.y - 0.5), 0.0));
    int x1 = int(min(floor(hi.x - 0.5), side - 1.0));
    int y1 = int(min(floor(hi.y - 0.5), side - 1.0));
    if (x1 < x0 || y1 < y0) return;
    uint nx = uint(x1 - x0 + 1), n = nx * uint(y1 - y0 + 1);
    float s = sign(area);
    uint base = k * frame.map_side * frame.map_side;
    for (uint j = gl_LocalInvocationIndex; j < n; j += 64u) {
        if (!spend_trip()) return;
        int x = x0 + int(j % nx), y = y0 + int(j / nx);
        vec2 c = vec2(float(x) + 0.5, float(y) + 0.5);
        precise float e0 = s * perp_dot(t1 - t0, c - t0);
        precise float e1 = s * perp_dot(t2 - t1, c - t1);
        precise float e2 = s * perp_dot(t0 - t2, c - t2);
        if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) continue;
        float d = plane_distance(texel_centre(origin, texel, ivec2(x, y)), plane_point, plane_normal);
        if (!finite(d)) d = dmin;
        d = clamp(d, dmin, dmax);
        atomicMin(shadow_map[base + uint(y) * frame.map_side + uint(x)], ordered_bits(d));
    }
}

void main() {
    loop_budget_reset();
    uint id = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    if (id >= frame.triangle_count) return;
    Triangle tri = triangles[id];
    vec3 v[3] = vec3[3](to_light_view(tri.a), to_light_view(tri.b), to_light_view(tri.c));
    vec3 normal = cross3(v[1] - v[0], v[2] - v[0]);
    float dmin = min(min(light_distance(v[0]), light_distance(v[1])), light_distance(v[2]));
    float dmax = max(max(light_distance(v[0]), light_distance(v[1])), light_distance(v[2]));
    // Point lights: clip to z >= near (clip_to_near), up to 4 vertices.
    vec3 poly[4];
    uint count = 0u;
    if (light.projection == 0u) {
        poly[0] = v[0]; poly[1] = v[1]; poly[2] = v[2];
        count = 3u;
    } else {
        float near = light.receiver_z[0] * 1e-3;
        [[unroll]] for (int i = 0; i < 3; ++i) {
            vec3 a = v[i], b = v[(i + 1) % 3];
            precise float da = a.z - near;
            precise float db = b.z - near;
            if (da >= 0.0) poly[count++] = a;
            if ((da >= 0.0) != (db >= 0.0)) {
                precise vec3 q = a + (b - a) * (da / (da - db));
                poly[count++] = q;
            }
        }
    }
    if (count < 3u) return;
    for (uint k = 0u; k < light.cascade_count; ++k) {
        draw(k, poly[0], poly[1], poly[2], v[0], normal, dmin, dmax);
        if (count == 4u) draw(k, poly[0], poly[2], poly[3], v[0], normal, dmin, dmax);
    }
    loop_budget_report();
}
