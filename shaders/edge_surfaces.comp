#version 460
// Pass 0, step 2, `edge_surfaces` — GPU twin of
// `izb::gbuffer::edge_surfaces` (`sample_surfaces`, as `gbuffer_with`
// calls it), after the `gbuffer` pass has cast every centre ray.
//
// One thread per pixel. A shadow-tested pixel is an edge candidate when
// one of its eight neighbours' centre hits misses or lies off its centre's
// plane (by more than EDGE_PLANE_TOLERANCE of its µQuad). A candidate
// casts its 32 µQuad samples as primary rays through the BVH (the gbuffer
// pass's traversal, against lavapipe's loop cap; with CANDIDATE_HITS
// against the multisampled visibility buffer's candidates), puts each hit on the
// centre's plane or groups it by plane, keeps the centre's surface and the
// EDGE_MAX_SURFACES − 1 largest groups (most samples first, ties by the
// first sample), and gives each kept group facing the light a µQuad of its
// own: its plane's tangent frame at the centroid of its samples,
// re-centred at the pixel centre's offsets (½, ½). Groups facing away
// shadow their samples; samples that miss, or lie on a group past the
// kept ones, do not count. The extra surfaces take slots below the image
// (edge_receivers.glsl) by an atomic counter: which slot a surface gets
// depends on scheduling, its mask does not (evaluate and resolve read a
// pixel's surfaces through its record). The CPU twin traces in f64; here
// the rays and plane tests run in f32, so a sample within rounding of a
// silhouette or of the plane tolerance can land on another surface
// (tests/gpu_edge_surfaces.rs measures how often). Every loop counts
// against lavapipe's loop cap (loop_budget.glsl), each pass twice
// (LOOP_TRIP_COST): counted once, lavapipe's own count (which also takes
// each loop's exit test) passed the cap first and cut hairball's surface
// selection without a word.
//
// Built with CANDIDATE_HITS (`edge_surfaces_from_candidates`: the host's
// multisampled visibility buffer, no BVH) the sample rays take the
// closest hit among the triangles the samples of the pixel and its eight
// neighbours saw (visibility_candidates.glsl; the twin
// `izb::gbuffer::gbuffer_from_multisampled_visibility`).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_samplerless_texture_functions : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_PIXELS_X, local_size_y = WORKGROUP_PIXELS_Y) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
#include "scene_triangles.glsl"
#ifndef CANDIDATE_HITS
layout(scalar, binding = B_BVH_NODES) readonly buffer NodeBuf { BvhNode nodes[]; };
layout(scalar, binding = B_BVH_PRIMS) readonly buffer PrimBuf { uint prims[]; };
#endif
layout(scalar, binding = B_G_POSITION) buffer PosBuf { vec3 g_position[]; };
layout(scalar, binding = B_G_AXIS_X) buffer AxBuf { vec3 g_axis_x[]; };
layout(scalar, binding = B_G_AXIS_Y) buffer AyBuf { vec3 g_axis_y[]; };
layout(scalar, binding = B_G_ID_FLAGS) buffer GidBuf { uint g_id_flags[]; };
layout(scalar, binding = B_TRIANGLE_NORMALS) readonly buffer TriNrmBuf { vec3 triangle_normals[]; };
layout(scalar, binding = B_COUNTERS) buffer CountBuf { uint counters[]; };
// Per 8×8 tile its pixels with records and first record, then the records
// (edge_receivers.glsl).
layout(scalar, binding = B_EDGE_PIXELS) writeonly buffer EdgePixelBuf { uint edge_pixel_words[]; };
layout(scalar, binding = B_EDGE_COVERAGE) writeonly buffer EdgeCoverageBuf { uint edge_coverage[]; };
#define LOOP_BUDGET_SLOTS WORKGROUP_PIXELS
#define LOOP_TRIP_COST 2u
#include "loop_budget.glsl"
#include "counters.glsl"
#ifdef CANDIDATE_HITS
layout(set = HOST_SET, binding = HOST_VISIBILITY) uniform utexture2DMS visibility;
#define CANDIDATE_TRIP() spend_trip()
#include "visibility_candidates.glsl"
#else
#define BVH_TRIP() spend_trip()
#include "bvh_closest_hit.glsl"
#endif
#include "surface_hit.glsl"

// Plane groups a pixel tracks: one per sample at most, as the CPU twin
// (8 dropped the later samples of hairball's pixels, which see a dozen
// strand facets, and kept the wrong three).
#define MAX_GROUPS 32
#define MAX_EXTRA (EDGE_MAX_SURFACES - 1)

// A plane through `point` with unit normal `normal`, holding hits within
// `tolerance` (edge_surfaces::Plane).
struct Plane {
    vec3 point;
    vec3 normal;
    float tolerance;
};

bool holds(Plane plane, vec3 p) {
    precise float h = dot(plane.normal, p - plane.point);
    return abs(h) <= plane.tolerance;
}

Plane plane_of(vec3 p, vec3 n, vec3 ex, vec3 ey) {
    return Plane(p, n, EDGE_PLANE_TOLERANCE * max(length(ex), length(ey)));
}

// A group of sample hits on one plane, seeded by its first hit (its
// samples are kept apart, in `covers`).
struct Group {
    Plane plane;
    uint triangle;
    uint flipped;   // the seed's normal is minus its triangle's stored one
    float t;        // the seed's ray parameter
};

vec3 ray_direction(vec2 image_point) {
    return frame.cam_corner + image_point.x * frame.cam_dx + image_point.y * frame.cam_dy;
}

// Pixel i's extra surfaces, written to their slots; whether it keeps an
// edge record (not every sample on its centre's surface), and the record.
bool trace_edge_pixel(uvec2 pixel, uint i, out uvec4 record) {
    record = uvec4(0u);
    uint word = g_id_flags[i];
    if ((gbuffer_flags(word) & FLAG_SHADOW_TESTED) == 0u) return false;

    // 1. Edge candidate: a neighbour's centre hit off the centre's plane.
    Plane centre = plane_of(g_position[i],
                            receiver_normal(triangle_normals[gbuffer_triangle(word)], word),
                            g_axis_x[i], g_axis_y[i]);
    bool candidate = false;
    for (int dy = -1; dy <= 1 && spend_trip(); ++dy) {
        for (int dx = -1; dx <= 1 && spend_trip(); ++dx) {
            ivec2 q = ivec2(pixel) + ivec2(dx, dy);
            if ((dx == 0 && dy == 0) || any(lessThan(q, ivec2(0)))
                    || q.x >= int(frame.width) || q.y >= int(frame.height)) continue;
            uint j = uint(q.y) * frame.width + uint(q.x);
            bool hit = (gbuffer_flags(g_id_flags[j]) & FLAG_HIT) != 0u;
            candidate = candidate || !hit || !holds(centre, g_position[j]);
        }
    }
    if (!candidate) return false;
    count_add(C_EDGE_CANDIDATES, 1u);

#ifdef CANDIDATE_HITS
    add_neighbourhood_candidates(ivec2(pixel), visibility_samples());
#endif
    // 2. The sample rays: each hit on the centre's plane or a group's.
    uint centre_coverage = 0u, missed = 0u, dropped = 0u;
    Group groups[MAX_GROUPS];
    // Each group's samples (its count is their number).
    uint covers[MAX_GROUPS];
    uint group_count = 0u;
    for (uint s = 0u; s < 32u && spend_trip(); ++s) {
        uint bit = 1u << s;
        vec2 image_point = vec2(pixel) + frame.pair_pattern[s];
        vec3 d = ray_direction(image_point);
        float t = frame.far;
#ifdef CANDIDATE_HITS
        uint id = candidate_closest_hit(d, t);
#else
        uint id = closest_hit(d, t);
#endif
        if (id == NO_HIT) {
            missed |= bit;
            continue;
        }
        vec3 n = triangle_normals[id];
        bool flipped = dot(n, d) > 0.0;
        if (flipped) n = -n;
        t = plane_t(id, n, d, t);
        vec3 p = d * t;
        if (holds(centre, p)) {
            centre_coverage |= bit;
            continue;
        }
        uint found = group_count;
        for (uint g = 0u; g < group_count && found == group_count && spend_trip(); ++g) {
            if (holds(groups[g].plane, p)) found = g;
        }
        if (found < group_count) {
            covers[found] |= bit;
            continue;
        }
        vec3 ex, ey;
        microquad_axes(d, t, n, ex, ey);
        groups[group_count] = Group(plane_of(p, n, ex, ey), id, flipped ? 1u : 0u, t);
        covers[group_count] = bit;
        group_count += 1u;
    }
    if (centre_coverage == 0u && group_count == 0u) {
        // Every sample ray slipped past a sub-pixel sliver the centre ray
        // hit (or missed everything): the centre's surface stands for the
        // whole pixel.
        count_add(C_EDGE_MISSED_SAMPLES, uint(bitCount(missed)));
        return false;
    }

    // 3. The kept surfaces, most samples first (ties by the first sample).
    uint counted = centre_coverage, facing_away = 0u;
    uint extra = 0u;
    vec3 e_position[MAX_EXTRA], e_ax[MAX_EXTRA], e_ay[MAX_EXTRA];
    uint e_word[MAX_EXTRA], e_coverage[MAX_EXTRA];
    // The EDGE_MAX_SURFACES − 1 largest groups in order, by insertion
    // into a short sorted list (every index valid: an out-of-range one let
    // the compiler assume it away).
    uint kept[MAX_EXTRA];
    uint kept_count = 0u;
    for (uint g = 0u; g < group_count && spend_trip(); ++g) {
        uint at = kept_count;
        uint count = uint(bitCount(covers[g]));
        while (at > 0u && spend_trip()) {
            uint other = covers[kept[at - 1u]];
            uint other_count = uint(bitCount(other));
            bool before = count > other_count
                || (count == other_count && findLSB(covers[g]) < findLSB(other));
            if (!before) break;
            if (at < uint(MAX_EXTRA)) kept[at] = kept[at - 1u];
            at -= 1u;
        }
        if (at < uint(MAX_EXTRA)) {
            kept[at] = g;
            kept_count = min(kept_count + 1u, uint(MAX_EXTRA));
        }
    }
    uint taken = 0u;   // the kept groups
    for (uint k = 0u; k < kept_count && spend_trip(); ++k) {
        taken |= 1u << kept[k];
        Group group = groups[kept[k]];
        uint coverage = covers[kept[k]];
        counted |= coverage;
        // The centroid of its samples: a point its own rays' plane is hit
        // at in front of the eye (edge_surfaces::extra_surface).
        vec2 sum = vec2(0.0);
        [[unroll]] for (uint s = 0u; s < 32u; ++s) {
            if ((coverage & (1u << s)) != 0u) sum += frame.pair_pattern[s];
        }
        vec2 uv = sum / float(bitCount(coverage));
        vec3 n = group.plane.normal;
        vec3 d = ray_direction(vec2(pixel) + uv);
        precise float t = dot(n, group.plane.point) / dot(n, d);
        if (!(t > 0.0) || isinf(t)) {
            // Rounding at a plane seen edge-on: anchor at the seed's ray.
            uv = frame.pair_pattern[findLSB(coverage)];
            d = ray_direction(vec2(pixel) + uv);
            t = group.t;
        }
        vec3 anchor = d * t;
        if (!faces_light(anchor, n)) {
            facing_away |= coverage;
            continue;
        }
        vec3 ex, ey;
        uint flags = FLAG_HIT | FLAG_SHADOW_TESTED;
        if (microquad_axes(d, t, n, ex, ey)) flags |= FLAG_AXES_CLAMPED;
        if (group.flipped != 0u) flags |= FLAG_NORMAL_FLIPPED;
        // The same tangent frame about the pixel centre's offsets.
        precise vec3 position = anchor + (0.5 - uv.x) * ex + (0.5 - uv.y) * ey;
        e_position[extra] = position;
        e_ax[extra] = ex;
        e_ay[extra] = ey;
        e_word[extra] = (flags << ID_BITS) | group.triangle;
        e_coverage[extra] = coverage;
        extra += 1u;
    }

    // The groups past the kept ones do not count.
    for (uint g = 0u; g < group_count && spend_trip(); ++g) {
        if ((taken & (1u << g)) == 0u) dropped |= covers[g];
    }

    // 4. Slots below the image; past the capacity the host reruns.
    uint first = extra > 0u ? atomicAdd(counters[C_EDGE_SURFACES], extra) : 0u;
    if (first + extra > frame.edge_capacity) extra = 0u;
    uint base = frame.width * frame.height + first;
    for (uint k = 0u; k < extra && spend_trip(); ++k) {
        g_position[base + k] = e_position[k];
        g_axis_x[base + k] = e_ax[k];
        g_axis_y[base + k] = e_ay[k];
        g_id_flags[base + k] = e_word[k];
        edge_coverage[first + k] = e_coverage[k];
    }
    count_add(C_EDGE_FACING_AWAY_SAMPLES, uint(bitCount(facing_away)));
    count_add(C_EDGE_DROPPED_SAMPLES, uint(bitCount(dropped)));
    count_add(C_EDGE_MISSED_SAMPLES, uint(bitCount(missed)));
    record = uvec4(centre_coverage, counted, facing_away, first | (extra << EDGE_COUNT_SHIFT));
    return centre_coverage != FULL_MASK;
}

// The tile's pixels with records (bit 8y + x) and its first record.
shared uint sm_tile_edges[2];
shared uint sm_tile_first;

void main() {
    loop_budget_reset();
    uint lid = gl_LocalInvocationIndex;
    if (lid == 0u) {
        sm_tile_edges[0] = 0u;
        sm_tile_edges[1] = 0u;
    }
    barrier();
    uvec2 pixel = gl_GlobalInvocationID.xy;
    bool inside = pixel.x < frame.width && pixel.y < frame.height;
    uint i = pixel.y * frame.width + pixel.x;
    uvec4 record = uvec4(0u);
    bool edge = inside && trace_edge_pixel(pixel, i, record);
    loop_budget_report();
    // lid = 8y + x within the tile (edge_tile_bit).
    if (edge) atomicOr(sm_tile_edges[lid >> 5u], 1u << (lid & 31u));
    barrier();
    uint lo = sm_tile_edges[0], hi = sm_tile_edges[1];
    uint count = uint(bitCount(lo) + bitCount(hi));
    if (lid == 0u) {
        // The tile's records, consecutive, in a slot range of its own;
        // past the capacity the tile keeps none and the host reruns.
        uint first = count > 0u ? atomicAdd(counters[C_EDGE_PIXELS], count) : 0u;
        bool fits = first + count <= frame.edge_capacity;
        uint tiles_x = gl_NumWorkGroups.x;
        uint at = EDGE_TILE_WORDS * (gl_WorkGroupID.y * tiles_x + gl_WorkGroupID.x);
        edge_pixel_words[at] = fits ? lo : 0u;
        edge_pixel_words[at + 1u] = fits ? hi : 0u;
        edge_pixel_words[at + 2u] = first;
        sm_tile_first = fits ? first : frame.edge_capacity;
    }
    barrier();
    uint below = (1u << (lid & 31u)) - 1u;
    uint before = lid < 32u ? uint(bitCount(lo & below)) : uint(bitCount(lo) + bitCount(hi & below));
    uint r = sm_tile_first + before;
    if (edge && r < frame.edge_capacity) {
        // After the table: a word triple per workgroup (edge_table_words).
        uint table = EDGE_TILE_WORDS * gl_NumWorkGroups.x * gl_NumWorkGroups.y;
        uint at = table + 4u * r;
        edge_pixel_words[at] = record.x;
        edge_pixel_words[at + 1u] = record.y;
        edge_pixel_words[at + 2u] = record.z;
        edge_pixel_words[at + 3u] = record.w;
    }
}
