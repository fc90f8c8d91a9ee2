#version 460
// Pass 1, `light_setup` — GPU twin of `izb::cpu::light_setup`, in four
// dispatches so nothing is read back inside the frame:
//   STEP_RECEIVERS (per pixel)  bounds and view-depth range of the
//                               shadow-tested hit points;
//   STEP_FRAME     (1 thread)   light-view rotation and origin; cascade
//                               count and splits (cascades.rs);
//   STEP_EXTENT    (per pixel)  each hit pixel's cascade, stored in its
//                               `masks` word until evaluate overwrites it
//                               with the mask (so every later pass reads
//                               the one value, never recomputes it); per
//                               cascade the light-NDC bounds of its µQuads'
//                               corners; the light-view depth range;
//   STEP_GRID      (1 thread)   per cascade padded bounds, grid size, cell
//                               offset and overflow threshold.
// The per-pixel steps run over every receiver row (frame.receiver_rows):
// the image, then the edge pixels' extra surfaces (edge_receivers.glsl),
// which the fit covers as the CPU twin's GBuffer::layers().
// Light view is a rotation plus a translation ([Compute IZB]): only the grid
// lookup uses NDC.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

#if defined(STEP_FRAME) || defined(STEP_GRID)
layout(local_size_x = 1) in;
#else
layout(local_size_x = WORKGROUP_PIXELS_X, local_size_y = WORKGROUP_PIXELS_Y) in;
#endif

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_G_POSITION) readonly buffer PosBuf { vec3 g_position[]; };
layout(scalar, binding = B_G_AXIS_X) readonly buffer AxBuf { vec3 g_axis_x[]; };
layout(scalar, binding = B_G_AXIS_Y) readonly buffer AyBuf { vec3 g_axis_y[]; };
layout(scalar, binding = B_G_ID_FLAGS) readonly buffer GidBuf { uint g_id_flags[]; };
layout(scalar, binding = B_LIGHT) buffer LightBuf { LightState light; };
layout(scalar, binding = B_MASKS) writeonly buffer MaskBuf { uint masks[]; };

#include "light_view.glsl"

// Closest a receiver may come to the point light's image plane, relative to
// the depth range, before the perspective grid is given up
// (light_setup::MIN_PERSPECTIVE_DEPTH_RATIO).

#if defined(STEP_RECEIVERS) || defined(STEP_EXTENT)
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
// Partial reductions: each subgroup reduces its lanes (subgroupMin/Max,
// exact for order-preserving bits), one lane per subgroup folds that into
// shared memory, then one thread per tile touches the global LightState:
// one global atomic per 8×8 tile instead of one per pixel (or corner),
// and no 64-way conflicts on the shared words.
// STEP_RECEIVERS: wg_lo/wg_hi[0..3] position, [3] view depth.
// STEP_EXTENT: wg_lo/wg_hi[0] light-view z, wg_ndc_* per cascade.
shared uint wg_count[MAX_CASCADES];
shared uint wg_lo[4];
shared uint wg_hi[4];
shared uint wg_ndc_lo[MAX_CASCADES][2];
shared uint wg_ndc_hi[MAX_CASCADES][2];
shared uint wg_behind;

void wg_reset() {
    if (gl_LocalInvocationIndex == 0u) {
        wg_behind = 0u;
        for (int k = 0; k < 4; ++k) {
            wg_lo[k] = 0xFFFFFFFFu;
            wg_hi[k] = 0u;
        }
        for (int k = 0; k < MAX_CASCADES; ++k) {
            wg_count[k] = 0u;
            wg_ndc_lo[k] = uint[2](0xFFFFFFFFu, 0xFFFFFFFFu);
            wg_ndc_hi[k] = uint[2](0u, 0u);
        }
    }
    barrier();
}

// The fit covers the shadow-tested pixels whatever the facing-away skip
// says (see cpu::is_receiver).
bool receiver_pixel(out uint i) {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    i = pixel.y * frame.width + pixel.x;
    return pixel.x < frame.width && pixel.y < frame.receiver_rows
        && (gbuffer_flags(g_id_flags[i]) & FLAG_SHADOW_TESTED) != 0u;
}
#endif

// light_setup::default_grid_side.
uint default_grid_side(uint receivers) {
    // RECEIVERS_PER_CELL, TRIANGLES_PER_CELL.
    return clamp(uint(ceil(sqrt(max(float(receivers) / RECEIVERS_PER_CELL, float(frame.triangle_count) / TRIANGLES_PER_CELL)))), GRID_SIDE_MIN, GRID_SIDE_MAX);
}

void main() {
#ifdef STEP_RECEIVERS
    wg_reset();
    uint i;
    bool receiver = receiver_pixel(i);
    vec3 p = receiver ? g_position[i] : vec3(0.0);
    precise float depth = dot(p, frame.cam_forward);
    // Non-receivers reduce as the identities (~0 for min, 0 for max).
    uint count = subgroupAdd(receiver ? 1u : 0u);
    uint lo[4], hi[4];
    for (int k = 0; k < 4; ++k) {
        uint bits = ordered_bits(k < 3 ? p[k] : depth);
        lo[k] = subgroupMin(receiver ? bits : 0xFFFFFFFFu);
        hi[k] = subgroupMax(receiver ? bits : 0u);
    }
    if (count != 0u && subgroupElect()) {
        atomicAdd(wg_count[0], count);
        for (int k = 0; k < 4; ++k) {
            atomicMin(wg_lo[k], lo[k]);
            atomicMax(wg_hi[k], hi[k]);
        }
    }
    barrier();
    if (gl_LocalInvocationIndex == 0u && wg_count[0] > 0u) {
        atomicAdd(light.receivers, wg_count[0]);
        for (int k = 0; k < 3; ++k) {
            atomicMin(light.pos_lo[k], wg_lo[k]);
            atomicMax(light.pos_hi[k], wg_hi[k]);
        }
        atomicMin(light.depth_lo, wg_lo[3]);
        atomicMax(light.depth_hi, wg_hi[3]);
    }
#endif

#ifdef STEP_FRAME
    vec3 centre = vec3(0.0);
    light.cascade_count = 1u;
    for (int k = 0; k < MAX_CASCADES; ++k) light.split[k] = 1.0 / 0.0;
    if (light.receivers > 0u) {
        vec3 lo = vec3(from_ordered_bits(light.pos_lo[0]), from_ordered_bits(light.pos_lo[1]),
                       from_ordered_bits(light.pos_lo[2]));
        vec3 hi = vec3(from_ordered_bits(light.pos_hi[0]), from_ordered_bits(light.pos_hi[1]),
                       from_ordered_bits(light.pos_hi[2]));
        centre = (lo + hi) * 0.5;
        // cascades::cascade_count and split_depths.
        float near = from_ordered_bits(light.depth_lo), far = from_ordered_bits(light.depth_hi);
        light.view_depth = vec2(near, far);
        uint count = 1u;
        if (frame.cascades != 0u) {
            count = clamp(frame.cascades, 1u, uint(MAX_CASCADES));
        } else {
            float reach = near * AUTO_MAX_DEPTH_RATIO;
            while (count < uint(MAX_CASCADES) && far > reach) {
                count += 1u;
                reach *= AUTO_MAX_DEPTH_RATIO;
            }
        }
        light.cascade_count = count;
        for (uint k = 0u; k + 1u < count; ++k) {
            float s = float(k + 1u) / float(count);
            float log_split = near * pow(far / near, s);
            float uniform_split = near + (far - near) * s;
            light.split[k] = frame.split_lambda * log_split + (1.0 - frame.split_lambda) * uniform_split;
        }
    }
    if (frame.light_is_point == 0u) {
        light.projection = 0u;
        light.rot_x = frame.rot_x;
        light.rot_y = frame.rot_y;
        light.rot_z = frame.rot_z;
        light.origin = centre;
    } else {
        // Point light: look from the light toward the receivers' centre
        // (light_setup::basis_with_z, in f32 here).
        vec3 axis = centre - frame.light_vec;
        float len = length(axis);
        vec3 z = len > 0.0 ? axis / len : vec3(0.0, -1.0, 0.0);
        vec3 helper = abs(z.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
        vec3 x = normalize(cross(helper, z));
        vec3 y = cross(z, x);
        light.projection = 1u;
        light.rot_x = x;
        light.rot_y = y;
        light.rot_z = z;
        light.origin = frame.light_vec;
    }
#endif

#ifdef STEP_EXTENT
    wg_reset();
    uvec2 pixel = gl_GlobalInvocationID.xy;
    uint i = pixel.y * frame.width + pixel.x;
    uint word = pixel.x < frame.width && pixel.y < frame.receiver_rows ? g_id_flags[i] : 0u;
    // Every hit gets its cascade (evaluate tests facing-away hits too when
    // that skip is off); the fit covers the shadow-tested ones.
    uint k = 0u;
    if ((gbuffer_flags(word) & FLAG_HIT) != 0u) {
        k = cascade_of(g_position[i]);
        masks[i] = k;
    }
    // This pixel's corners first (identities when it is not tested), then
    // the subgroup's, per cascade.
    bool tested = (gbuffer_flags(word) & FLAG_SHADOW_TESTED) != 0u;
    uint z_lo = 0xFFFFFFFFu, z_hi = 0u;
    uvec2 ndc_lo = uvec2(0xFFFFFFFFu), ndc_hi = uvec2(0u);
    if (tested) {
        vec3 p = g_position[i];
        vec3 hx = g_axis_x[i] * 0.5;
        vec3 hy = g_axis_y[i] * 0.5;
        vec3 corners[4] = vec3[4](p - hx - hy, p + hx - hy, p + hx + hy, p - hx + hy);
        for (int c = 0; c < 4; ++c) {
            vec3 q = to_light_view(corners[c]);
            z_lo = min(z_lo, ordered_bits(q.z));
            z_hi = max(z_hi, ordered_bits(q.z));
            vec2 ndc;
            if (light.projection == 0u) {
                ndc = q.xy;
            } else if (q.z > 0.0) {
                ndc = q.xy / q.z;
            } else {
                wg_behind = 1u;
                continue;
            }
            uvec2 bits = uvec2(ordered_bits(ndc.x), ordered_bits(ndc.y));
            ndc_lo = min(ndc_lo, bits);
            ndc_hi = max(ndc_hi, bits);
        }
    }
    z_lo = subgroupMin(z_lo);
    z_hi = subgroupMax(z_hi);
    if (subgroupElect()) {
        atomicMin(wg_lo[0], z_lo);
        atomicMax(wg_hi[0], z_hi);
    }
    for (uint c = 0u; c < light.cascade_count; ++c) {
        bool mine = tested && k == c;
        uint count = subgroupAdd(mine ? 1u : 0u);
        uvec2 lo = subgroupMin(mine ? ndc_lo : uvec2(0xFFFFFFFFu));
        uvec2 hi = subgroupMax(mine ? ndc_hi : uvec2(0u));
        if (count != 0u && subgroupElect()) {
            atomicAdd(wg_count[c], count);
            atomicMin(wg_ndc_lo[c][0], lo.x);
            atomicMin(wg_ndc_lo[c][1], lo.y);
            atomicMax(wg_ndc_hi[c][0], hi.x);
            atomicMax(wg_ndc_hi[c][1], hi.y);
        }
    }
    barrier();
    if (gl_LocalInvocationIndex == 0u) {
        bool any = false;
        for (uint c = 0u; c < uint(MAX_CASCADES); ++c) {
            if (wg_count[c] == 0u) continue;
            any = true;
            atomicAdd(light.cascade[c].receivers, wg_count[c]);
            atomicMin(light.cascade[c].ndc_lo[0], wg_ndc_lo[c][0]);
            atomicMin(light.cascade[c].ndc_lo[1], wg_ndc_lo[c][1]);
            atomicMax(light.cascade[c].ndc_hi[0], wg_ndc_hi[c][0]);
            atomicMax(light.cascade[c].ndc_hi[1], wg_ndc_hi[c][1]);
        }
        if (any) {
            atomicMin(light.z_lo, wg_lo[0]);
            atomicMax(light.z_hi, wg_hi[0]);
        }
        if (wg_behind != 0u) light.behind_light = 1u;
    }
#endif

#ifdef STEP_GRID
    // The state of a frame without a grid: one 1×1 cascade, everything in
    // the overflow list (light_setup's early returns).
    light.total_cells = 1u;
    light.receiver_z = vec2(0.0);
    light.grid_disabled = light.behind_light;
    light.cascade[0].ndc_min = vec2(0.0);
    light.cascade[0].ndc_max = vec2(1.0);
    light.cascade[0].cells_x = 1u;
    light.cascade[0].cells_y = 1u;
    light.cascade[0].cell_offset = 0u;
    light.cascade[0].levels = 1u;
    light.cascade[0].level_cells = frame.level_cells != 0u ? frame.level_cells : DEFAULT_LEVEL_CELLS;
    uint n = light.receivers;
    if (n == 0u) {
        light.cascade_count = 1u;
        return;
    }
    float zmin = from_ordered_bits(light.z_lo);
    float zmax = from_ordered_bits(light.z_hi);
    if (light.projection == 1u && zmin <= MIN_PERSPECTIVE_DEPTH_RATIO * zmax) {
        light.grid_disabled = 1u;
    }
    light.receiver_z = vec2(zmin, zmax);
    if (light.grid_disabled != 0u) {
        light.cascade_count = 1u;
        for (int k = 0; k < MAX_CASCADES; ++k) light.split[k] = 1.0 / 0.0;
        return;
    }
    uint side = frame.cells_hint != 0u ? frame.cells_hint : default_grid_side(n);
    uint offset = 0u;
    for (uint k = 0u; k < light.cascade_count; ++k) {
        uint nk = light.cascade[k].receivers;
        light.cascade[k].cell_offset = offset;
        light.cascade[k].cells_x = 0u;
        light.cascade[k].cells_y = 0u;
        light.cascade[k].ndc_min = vec2(0.0);
        light.cascade[k].ndc_max = vec2(0.0);
        light.cascade[k].level_cells = 0u;
        light.cascade[k].levels = 0u;
        if (nk == 0u) continue;   // an empty cascade: no cells, nothing binned
        vec2 nmin = vec2(from_ordered_bits(light.cascade[k].ndc_lo[0]), from_ordered_bits(light.cascade[k].ndc_lo[1]));
        vec2 nmax = vec2(from_ordered_bits(light.cascade[k].ndc_hi[0]), from_ordered_bits(light.cascade[k].ndc_hi[1]));
        vec2 size = nmax - nmin;
        // f32::MIN_POSITIVE = 2^-126.
        float pad = max(max(size.x, size.y), uintBitsToFloat(0x00800000u)) * BOUNDS_PADDING;
        light.cascade[k].ndc_min = nmin - pad;
        light.cascade[k].ndc_max = nmax + pad;
        // cascades::cascade_cells: the budget side² shared by receivers,
        // square cells, sides rounded down.
        float budget = float(side) * float(side);
        float target = light.cascade_count <= 1u ? budget : max(budget * (float(nk) / float(n)), MIN_CASCADE_CELLS);
        vec2 extent = light.cascade[k].ndc_max - light.cascade[k].ndc_min;
        float cell = sqrt(extent.x * extent.y / target);
        uvec2 cells = uvec2(1u);
        if (cell > 0.0) {
            // The shorter side first (cascades::cascade_cells).
            bool x_short = extent.x <= extent.y;
            float short_e = x_short ? extent.x : extent.y, long_e = x_short ? extent.y : extent.x;
            uint n_short = max(uint(min(floor(short_e / cell), float(MAX_GRID_SIDE))), 1u);
            uint n_long = max(uint(min(min(floor(long_e / cell), floor(target / float(n_short))),
                                       float(MAX_GRID_SIDE))), 1u);
            cells = x_short ? uvec2(n_short, n_long) : uvec2(n_long, n_short);
        }
        light.cascade[k].cells_x = cells.x;
        light.cascade[k].cells_y = cells.y;
        light.cascade[k].level_cells = frame.level_cells != 0u ? frame.level_cells : DEFAULT_LEVEL_CELLS;
        // light_setup::pyramid_levels: halve down to 1×1; the pyramid's
        // cells follow level 0 (CascadeGrid::cell_count).
        uint side_max = max(cells.x, cells.y);
        uint levels = 1u + uint(findMSB(side_max - 1u) + 1);   // 1 + ceil(log2(side_max))
        light.cascade[k].levels = levels;
        for (uint l = 0u; l < levels; ++l) {
            offset += level_side(cells.x, l) * level_side(cells.y, l);
        }
    }
    light.total_cells = offset;
    // The host sized the cell arrays for cascades::max_total_cells; should
    // rounding ever exceed it, fall back to the overflow list (exact).
    if (offset > frame.max_cells) light.grid_disabled = 1u;
#endif
}
