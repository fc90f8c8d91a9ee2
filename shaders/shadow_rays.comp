#version 460
// `shadow_rays` — GPU twin of `izb::peer::shadow_rays::shadow_rays`: the
// `rt32-rays` peer. Per shadow-tested pixel, the 32 µQuad sample rays
// (`sample_rays`: from each sample toward the light, starting 2^-8 µQuad
// along the way and, for a point light, stopping as far before it) traced
// through the G-buffer pass's BVH with its watertight triangle test, any
// hit ends a ray. What a user with a GPU but no ray-tracing cores would
// run instead of the IZB for the same samples. Writes the 32-bit masks
// (bit k = sample k occluded); the resolve pass then shades them as it
// does the IZB's.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_PIXELS_X, local_size_y = WORKGROUP_PIXELS_Y) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
#include "scene_triangles.glsl"
layout(scalar, binding = B_BVH_NODES) readonly buffer NodeBuf { BvhNode nodes[]; };
layout(scalar, binding = B_BVH_PRIMS) readonly buffer PrimBuf { uint prims[]; };
layout(scalar, binding = B_G_POSITION) readonly buffer PosBuf { vec3 g_position[]; };
layout(scalar, binding = B_G_AXIS_X) readonly buffer AxBuf { vec3 g_axis_x[]; };
layout(scalar, binding = B_G_AXIS_Y) readonly buffer AyBuf { vec3 g_axis_y[]; };
layout(scalar, binding = B_G_ID_FLAGS) readonly buffer GidBuf { uint g_id_flags[]; };
layout(scalar, binding = B_MASKS) writeonly buffer MaskBuf { uint masks[]; };
layout(scalar, binding = B_COUNTERS) buffer CountBuf { uint counters[]; };

// lavapipe ends loops silently past its cap: the traversal counts its trips
// and the host refuses a frame that ran out (GpuError::LoopCap), as for
// the IZB's passes.
#define LOOP_BUDGET_SLOTS WORKGROUP_PIXELS
#include "loop_budget.glsl"

#define STACK_SIZE 64
// frustum::DEPTH_TOLERANCE_MICROQUAD: the rays' start offset in µQuads.

// Whether the ray from `org` along `d` enters the box (relative to org)
// within (0, t_far).
bool box_hit(vec3 lo, vec3 hi, vec3 inv_dir, float t_far) {
    vec3 t0 = lo * inv_dir;
    vec3 t1 = hi * inv_dir;
    vec3 tn = min(t0, t1);
    vec3 tf = max(t0, t1);
    float enter = max(max(tn.x, tn.y), max(tn.z, 0.0));
    float leave = min(min(tf.x, tf.y), min(tf.z, t_far));
    return enter <= leave;
}

#include "watertight_ray.glsl"

// Whether anything meets the ray with t in (t_near, t_far): depth-first,
// stopping at the first hit (an occlusion query needs no nearest one).
bool occluded(vec3 org, vec3 d, float t_near, float t_far) {
    if (frame.triangle_count == 0u) return false;
    vec3 inv_dir = 1.0 / d;
    ShearedRay ray = sheared_ray(d);
    uint stack[STACK_SIZE];
    uint top = 0u;
    uint node = 0u;
    while (spend_trip()) {
        BvhNode n = nodes[node];
        if (n.prim_count > 0u) {
            for (uint k = 0u; k < n.prim_count; ++k) {
                float t = hit_triangle(scene_triangle(prims[n.first + k]), org, ray);
                if (t > t_near && t < t_far) return true;
            }
        } else {
            BvhNode l = nodes[n.first];
            BvhNode r = nodes[n.first + 1u];
            bool hit_l = box_hit(l.lo - org, l.hi - org, inv_dir, t_far);
            bool hit_r = box_hit(r.lo - org, r.hi - org, inv_dir, t_far);
            if (hit_l && hit_r) {
                if (top < STACK_SIZE) stack[top++] = n.first + 1u;
                node = n.first;
                continue;
            } else if (hit_l || hit_r) {
                node = hit_l ? n.first : n.first + 1u;
                continue;
            }
        }
        if (top == 0u) break;
        node = stack[--top];
    }
    return false;
}

void main() {
    loop_budget_reset();
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (pixel.x >= frame.width || pixel.y >= frame.height) return;
    uint i = pixel.y * frame.width + pixel.x;
    if ((gbuffer_flags(g_id_flags[i]) & FLAG_SHADOW_TESTED) == 0u) {
        masks[i] = 0u;
        return;
    }
    vec3 p = g_position[i], ex = g_axis_x[i], ey = g_axis_y[i];
    float offset = float(DEPTH_TOLERANCE_MICROQUAD) * max(length(ex), length(ey));
    uint mask = 0u;
    for (int k = 0; k < 32; ++k) {
        vec3 s = p + (frame.pattern[k].x - 0.5) * ex + (frame.pattern[k].y - 0.5) * ey;
        vec3 d;
        float t_near, t_far;
        if (frame.light_is_point == 0u) {
            d = frame.light_vec;   // unit, toward the light
            t_near = offset;
            t_far = 1.0 / 0.0;
        } else {
            d = frame.light_vec - s;
            float reach = offset / max(length(d), uintBitsToFloat(0x00800000u));
            t_near = reach;
            t_far = 1.0 - reach;
        }
        if (occluded(s, d, t_near, t_far)) mask |= 1u << k;
    }
    masks[i] = mask;
    loop_budget_report();
}
