// bvh_closest_hit.glsl — the closest hit of an eye ray through the
// G-buffer's BVH2 (built on the host by obvhs): the traversal the gbuffer
// pass casts its centre rays with and the edge_surfaces pass its sample
// rays, front to back with a short stack. Include after common.glsl, the
// frame, triangle and BVH bindings; define BVH_TRIP() as spend_trip() to
// count the loop against lavapipe's cap (loop_budget.glsl).

#ifndef BVH_TRIP
#define BVH_TRIP() true
#endif

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

// The nearest triangle along direction d from the eye with t in
// (frame.near, best_t) — NO_HIT if none — and its t in best_t.
uint closest_hit(vec3 d, inout float best_t) {
    vec3 inv_dir = 1.0 / d;
    ShearedRay ray = sheared_ray(d);
    uint best = NO_HIT;
    uint stack[STACK_SIZE];
    uint top = 0u;
    uint node = 0u;
    bool traversing = frame.triangle_count > 0u;
    while (traversing && BVH_TRIP()) {
        BvhNode n = nodes[node];
        if (n.prim_count > 0u) {
            for (uint k = 0u; k < n.prim_count && BVH_TRIP(); ++k) {
                uint id = prims[n.first + k];
                float t = hit_triangle(scene_triangle(id), vec3(0.0), ray);
                // Ties go to the lower id, whatever the traversal's order:
                // a resident pass's translated BVH and a BVH built for
                // the same eye see the same hit.
                if (t > frame.near && (t < best_t || (t == best_t && best != NO_HIT && id < best))) {
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
    return best;
}
