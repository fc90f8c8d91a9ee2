#version 460
// Pass 0, `gbuffer` — GPU twin of `izb::gbuffer::gbuffer`.
//
// A compute visibility pass, not a raster pipeline: each thread casts the
// pixel-centre ray through a BVH (built on the host by obvhs) exactly as the
// CPU twin does, so both sample the same ray and derive the µQuad axes from
// the same closed form (README, Conventions: derivatives of the ray/tangent-plane
// intersection), with no rasterisation rules or depth-buffer precision in
// between. Output: the struct-of-arrays G-buffer (hit point, µQuad axes,
// triangle id and flags in one word; the normal is the triangle's, with
// FLAG_NORMAL_FLIPPED when it faces the other way).
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_PIXELS_X, local_size_y = WORKGROUP_PIXELS_Y) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_TRIANGLES) readonly buffer TriBuf { Triangle triangles[]; };
layout(scalar, binding = B_BVH_NODES) readonly buffer NodeBuf { BvhNode nodes[]; };
layout(scalar, binding = B_BVH_PRIMS) readonly buffer PrimBuf { uint prims[]; };
layout(scalar, binding = B_G_POSITION) writeonly buffer PosBuf { vec3 g_position[]; };
layout(scalar, binding = B_G_AXIS_X) writeonly buffer AxBuf { vec3 g_axis_x[]; };
layout(scalar, binding = B_G_AXIS_Y) writeonly buffer AyBuf { vec3 g_axis_y[]; };
layout(scalar, binding = B_G_ID_FLAGS) writeonly buffer GidBuf { uint g_id_flags[]; };
layout(scalar, binding = B_TRIANGLE_NORMALS) readonly buffer TriNrmBuf { vec3 triangle_normals[]; };
layout(scalar, binding = B_COUNTERS) buffer CountBuf { uint counters[]; };
#include "counters.glsl"

#define STACK_SIZE 64

// Slab test: entry distance of the ray into the box, or +inf on a miss.
float box_entry(vec3 lo, vec3 hi, vec3 inv_dir, float t_max) {
    vec3 t0 = lo * inv_dir;
    vec3 t1 = hi * inv_dir;
    vec3 tn = min(t0, t1);
    vec3 tf = max(t0, t1);
    float enter = max(max(tn.x, tn.y), max(tn.z, 0.0));
    float leave = min(min(tf.x, tf.y), min(tf.z, t_max));
    return enter <= leave ? enter : 1.0 / 0.0;
}

#include "watertight_ray.glsl"

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) return;
    uint i = pixel.y * frame.width + pixel.x;
    vec2 image_point = vec2(pixel) + 0.5;
    vec3 d = frame.cam_corner + image_point.x * frame.cam_dx + image_point.y * frame.cam_dy;
    vec3 inv_dir = 1.0 / d;
    ShearedRay ray = sheared_ray(d);

    float best_t = frame.far;
    uint best = NO_HIT;
    uint stack[STACK_SIZE];
    uint top = 0u;
    uint node = 0u;
    bool traversing = frame.triangle_count > 0u;
    while (traversing) {
        BvhNode n = nodes[node];
        if (n.prim_count > 0u) {
            for (uint k = 0u; k < n.prim_count; ++k) {
                uint id = prims[n.first + k];
                float t = hit_triangle(triangles[id], vec3(0.0), ray);
                if (t > frame.near && t < best_t) {
                    best_t = t;
                    best = id;
                }
            }
        } else {
            BvhNode l = nodes[n.first];
            BvhNode r = nodes[n.first + 1u];
            float tl = box_entry(l.lo, l.hi, inv_dir, best_t);
            float tr = box_entry(r.lo, r.hi, inv_dir, best_t);
            bool hit_l = !isinf(tl);
            bool hit_r = !isinf(tr);
            if (hit_l && hit_r) {
                uint near_child = tl <= tr ? n.first : n.first + 1u;
                uint far_child = tl <= tr ? n.first + 1u : n.first;
                if (top < STACK_SIZE) stack[top++] = far_child;
                node = near_child;
                continue;
            } else if (hit_l || hit_r) {
                node = hit_l ? n.first : n.first + 1u;
                continue;
            }
        }
        if (top == 0u) break;
        node = stack[--top];
    }

    if (best == NO_HIT) {
        g_id_flags[i] = ID_MASK;   // a miss
        g_position[i] = vec3(0.0);
        g_axis_x[i] = vec3(0.0);
        g_axis_y[i] = vec3(0.0);
        return;
    }
    // The triangle's normal as the host computed it in f64: one from the
    // f32 vertices (error ~ε·|v|/|edge|) flipped 1.06e-4 of the deckchair's
    // samples at 960×540 in the tangent-plane test, which compares heights
    // against 2^-8 of a µQuad.
    vec3 n = triangle_normals[best];
    uint flags = FLAG_HIT;
    if (dot(n, d) > 0.0) {
        n = -n;
        flags |= FLAG_NORMAL_FLIPPED;
    }
    // Refine the hit on the triangle's plane: the hit test's t comes out
    // of a cancellation (the deckchair's slats: 1.3e-5 relative, several
    // times the 2^-8 µQuad depth tolerance, so neighbours shadowed their
    // receiver); t = (n·A)/(n·D) with the host's f64 normal is good to a
    // few ulps, as the CPU twin's f64 hit is.
    precise float t_plane = dot(n, triangles[best].a) / dot(n, d);
    if (t_plane > 0.0 && !isinf(t_plane)) best_t = t_plane;
    vec3 p = d * best_t;
    vec3 toward = frame.light_is_point != 0u ? normalize(frame.light_vec - p) : frame.light_vec;
    if (dot(n, toward) > 0.0) flags |= FLAG_SHADOW_TESTED;

    // µQuad axes: dP/dx = t (dD/dx − (n·dD/dx)/(n·D) D), likewise for y.
    float n_dot_d = dot(n, d);
    vec3 ex = best_t * (frame.cam_dx - d * (dot(n, frame.cam_dx) / n_dot_d));
    vec3 ey = best_t * (frame.cam_dy - d * (dot(n, frame.cam_dy) / n_dot_d));
    // Grazing clamp (paper-notes/reference-estimator.md), identical to the CPU twin's.
    float limit = frame.max_stretch * best_t * length(frame.cam_dx) * length(d);
    float lx = length(ex);
    float ly = length(ey);
    if (isnan(lx) || lx > limit) {
        ex = isinf(lx) || isnan(lx) ? vec3(0.0) : ex * (limit / lx);
        flags |= FLAG_AXES_CLAMPED;
    }
    if (isnan(ly) || ly > limit) {
        ey = isinf(ly) || isnan(ly) ? vec3(0.0) : ey * (limit / ly);
        flags |= FLAG_AXES_CLAMPED;
    }

    g_id_flags[i] = (flags << ID_BITS) | best;
    g_position[i] = p;
    g_axis_x[i] = ex;
    g_axis_y[i] = ey;
    count_add(C_HITS, 1u);
    count_add(C_SHADOW_TESTED, (flags & FLAG_SHADOW_TESTED) != 0u ? 1u : 0u);
    count_add(C_CLAMPED, (flags & FLAG_AXES_CLAMPED) != 0u ? 1u : 0u);
}
