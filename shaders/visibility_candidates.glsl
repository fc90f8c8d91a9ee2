// visibility_candidates.glsl — a multisampled visibility buffer's samples
// as candidates for eye rays (the CPU twin's `gbuffer::multisampled`):
// the distinct triangle ids the samples of a pixel, or of its 3×3 pixels,
// saw, and the closest of them along a ray by the watertight test. A
// raster's samples cannot trace, but they nominate: the triangle a ray
// meets first is among them unless no sample near it saw that triangle.
// Include after common.glsl and the frame and triangle bindings, with
// `visibility` bound as a `utexture2DMS`; define CANDIDATE_TRIP() as
// spend_trip() to count the loops against lavapipe's cap. Uncounted (the
// G-buffer step), one invocation runs at most about 2 800 loop passes
// (9 pixels × 8 validity, 72 ids × 36 held on average, 72 candidates, at
// 8 samples): 8 lanes apart stay below lavapipe's 65 535.

#ifndef CANDIDATE_TRIP
#define CANDIDATE_TRIP() true
#endif

#include "watertight_ray.glsl"

#define MAX_CANDIDATES (9u * MAX_VISIBILITY_SAMPLES)

uint candidate_ids[MAX_CANDIDATES];
uint candidate_count = 0u;

// The samples a pixel of the host's buffer holds (at most
// MAX_VISIBILITY_SAMPLES; the pass was made for their count).
uint visibility_samples() {
    return min(uint(textureSamples(visibility)), MAX_VISIBILITY_SAMPLES);
}

// Whether every id of pixel q's samples is NO_HIT or a triangle of the
// pass (a pixel with another is rejected and nominates nothing).
bool pixel_ids_valid(ivec2 q, uint samples) {
    bool valid = true;
    for (uint s = 0u; s < samples && CANDIDATE_TRIP(); ++s) {
        uint id = texelFetch(visibility, q, int(s)).x;
        valid = valid && (id == NO_HIT || id < frame.triangle_count);
    }
    return valid;
}

// Adds pixel q's ids not yet held (in the order first seen). Held once
// each: every candidate costs each of an edge pixel's 32 sample rays a
// watertight test, and the 3×3 pixels mostly repeat a few triangles
// (deduplicating only within each pixel, as a review suggested to spare
// the loop budget, made `default`'s 4× G-buffer step at 96×54 slower on
// lavapipe: 18.7 ms against 16.1, medians of 3 interleaved runs). The
// scan counts against the budget. Returns whether a sample of q saw no
// triangle.
bool add_pixel_candidates(ivec2 q, uint samples) {
    bool missed = false;
    for (uint s = 0u; s < samples && CANDIDATE_TRIP(); ++s) {
        uint id = texelFetch(visibility, q, int(s)).x;
        missed = missed || id == NO_HIT;
        bool seen = id == NO_HIT;
        for (uint k = 0u; k < candidate_count && !seen && CANDIDATE_TRIP(); ++k) {
            seen = candidate_ids[k] == id;
        }
        if (!seen && candidate_count < MAX_CANDIDATES) {
            candidate_ids[candidate_count] = id;
            candidate_count += 1u;
        }
    }
    return missed;
}

// The candidates of pixel p and its neighbours inside the image, valid
// pixels only.
void add_neighbourhood_candidates(ivec2 p, uint samples) {
    for (int dy = -1; dy <= 1 && CANDIDATE_TRIP(); ++dy) {
        for (int dx = -1; dx <= 1 && CANDIDATE_TRIP(); ++dx) {
            ivec2 q = p + ivec2(dx, dy);
            if (any(lessThan(q, ivec2(0))) || q.x >= int(frame.width) || q.y >= int(frame.height)) continue;
            if (pixel_ids_valid(q, samples)) add_pixel_candidates(q, samples);
        }
    }
}

// The nearest candidate along direction d from the eye with t in
// (frame.near, best_t) — NO_HIT if none — and its t in best_t; ties to the
// lower id (bvh_closest_hit.glsl's rule).
uint candidate_closest_hit(vec3 d, inout float best_t) {
    ShearedRay ray = sheared_ray(d);
    uint best = NO_HIT;
    for (uint k = 0u; k < candidate_count && CANDIDATE_TRIP(); ++k) {
        uint id = candidate_ids[k];
        float t = hit_triangle(scene_triangle(id), vec3(0.0), ray);
        if (t > frame.near && (t < best_t || (t == best_t && best != NO_HIT && id < best))) {
            best_t = t;
            best = id;
        }
    }
    return best;
}
