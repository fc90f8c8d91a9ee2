#version 460
// Pass 1, `light_setup` — GPU twin of `izb::izb::light_setup`, in four
// dispatches so nothing is read back inside the frame:
//   STEP_RECEIVERS (per pixel)  bounds of the shadow-tested hit points;
//   STEP_FRAME     (1 thread)   light-view rotation and origin;
//   STEP_EXTENT    (per pixel)  light-NDC bounds and depth range of every
//                               shadow-tested µQuad's corners;
//   STEP_GRID      (1 thread)   padded bounds and grid size.
// Light view is a rotation plus a translation (seed 000): only the grid
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

// Closest a receiver may come to the point light's image plane, relative to
// the depth range, before the perspective grid is given up
// (light_setup::MIN_PERSPECTIVE_DEPTH_RATIO).
#define MIN_PERSPECTIVE_DEPTH_RATIO 1e-3

// The CPU twin's rotation · (p − origin), same operation order; `precise`
// keeps the compiler from fusing multiply-adds the CPU does not fuse.
vec3 to_light_view(vec3 p) {
    precise vec3 q = p - light.origin;
    precise vec3 r = vec3(dot(light.rot_x, q), dot(light.rot_y, q), dot(light.rot_z, q));
    return r;
}

#if defined(STEP_RECEIVERS) || defined(STEP_EXTENT)
// Workgroup partial reductions: the tile reduces in shared memory, then
// one thread per tile touches the global LightState, so the global atomics
// fall from one per pixel (or corner) to one per 8×8 tile.
shared uint wg_count;
shared uint wg_lo[3];
shared uint wg_hi[3];
shared uint wg_behind;

void wg_reset() {
    if (gl_LocalInvocationIndex == 0u) {
        wg_count = 0u;
        wg_behind = 0u;
        for (int k = 0; k < 3; ++k) {
            wg_lo[k] = 0xFFFFFFFFu;
            wg_hi[k] = 0u;
        }
    }
    barrier();
}

// The fit covers the shadow-tested pixels whatever the facing-away skip
// says (see izb::is_receiver).
bool receiver_pixel(out uint i) {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    i = pixel.y * frame.width + pixel.x;
    return pixel.x < frame.width && pixel.y < frame.height
        && (gbuffer_flags(g_id_flags[i]) & FLAG_SHADOW_TESTED) != 0u;
}
#endif

void main() {
#ifdef STEP_RECEIVERS
    wg_reset();
    uint i;
    if (receiver_pixel(i)) {
        vec3 p = g_position[i];
        atomicAdd(wg_count, 1u);
        for (int k = 0; k < 3; ++k) {
            atomicMin(wg_lo[k], ordered_bits(p[k]));
            atomicMax(wg_hi[k], ordered_bits(p[k]));
        }
    }
    barrier();
    if (gl_LocalInvocationIndex == 0u && wg_count > 0u) {
        atomicAdd(light.receivers, wg_count);
        for (int k = 0; k < 3; ++k) {
            atomicMin(light.pos_lo[k], wg_lo[k]);
            atomicMax(light.pos_hi[k], wg_hi[k]);
        }
    }
#endif

#ifdef STEP_FRAME
    vec3 centre = vec3(0.0);
    if (light.receivers > 0u) {
        vec3 lo = vec3(from_ordered_bits(light.pos_lo[0]), from_ordered_bits(light.pos_lo[1]),
                       from_ordered_bits(light.pos_lo[2]));
        vec3 hi = vec3(from_ordered_bits(light.pos_hi[0]), from_ordered_bits(light.pos_hi[1]),
                       from_ordered_bits(light.pos_hi[2]));
        centre = (lo + hi) * 0.5;
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
    // wg_lo/wg_hi hold (ndc.x, ndc.y, z) here.
    wg_reset();
    uint i;
    if (receiver_pixel(i)) {
        atomicAdd(wg_count, 1u);
        vec3 p = g_position[i];
        vec3 hx = g_axis_x[i] * 0.5;
        vec3 hy = g_axis_y[i] * 0.5;
        vec3 corners[4] = vec3[4](p - hx - hy, p + hx - hy, p + hx + hy, p - hx + hy);
        for (int k = 0; k < 4; ++k) {
            vec3 q = to_light_view(corners[k]);
            atomicMin(wg_lo[2], ordered_bits(q.z));
            atomicMax(wg_hi[2], ordered_bits(q.z));
            vec2 ndc;
            if (light.projection == 0u) {
                ndc = q.xy;
            } else if (q.z > 0.0) {
                ndc = q.xy / q.z;
            } else {
                wg_behind = 1u;
                continue;
            }
            atomicMin(wg_lo[0], ordered_bits(ndc.x));
            atomicMin(wg_lo[1], ordered_bits(ndc.y));
            atomicMax(wg_hi[0], ordered_bits(ndc.x));
            atomicMax(wg_hi[1], ordered_bits(ndc.y));
        }
    }
    barrier();
    if (gl_LocalInvocationIndex == 0u && wg_count > 0u) {
        atomicMin(light.ndc_lo[0], wg_lo[0]);
        atomicMin(light.ndc_lo[1], wg_lo[1]);
        atomicMax(light.ndc_hi[0], wg_hi[0]);
        atomicMax(light.ndc_hi[1], wg_hi[1]);
        atomicMin(light.z_lo, wg_lo[2]);
        atomicMax(light.z_hi, wg_hi[2]);
        if (wg_behind != 0u) light.behind_light = 1u;
    }
#endif

#ifdef STEP_GRID
    light.cells_x = 1u;
    light.cells_y = 1u;
    light.ndc_min = vec2(0.0);
    light.ndc_max = vec2(1.0);
    light.receiver_z = vec2(0.0);
    light.grid_disabled = light.behind_light;
    uint n = light.receivers;
    if (n == 0u) return;
    float zmin = from_ordered_bits(light.z_lo);
    float zmax = from_ordered_bits(light.z_hi);
    if (light.projection == 1u && zmin <= MIN_PERSPECTIVE_DEPTH_RATIO * zmax) {
        light.grid_disabled = 1u;
    }
    light.receiver_z = vec2(zmin, zmax);
    if (light.grid_disabled != 0u) return;
    vec2 nmin = vec2(from_ordered_bits(light.ndc_lo[0]), from_ordered_bits(light.ndc_lo[1]));
    vec2 nmax = vec2(from_ordered_bits(light.ndc_hi[0]), from_ordered_bits(light.ndc_hi[1]));
    vec2 size = nmax - nmin;
    // f32::MIN_POSITIVE = 2^-126.
    float pad = max(max(size.x, size.y), uintBitsToFloat(0x00800000u)) * 1e-4;
    light.ndc_min = nmin - pad;
    light.ndc_max = nmax + pad;
    // light_setup::default_grid_side.
    uint longest = frame.cells_hint != 0u
        ? frame.cells_hint
        : clamp(uint(ceil(sqrt(max(float(n) / 4.0, float(frame.triangle_count) / 16.0)))), 8u, 1024u);
    vec2 extent = light.ndc_max - light.ndc_min;
    if (extent.x >= extent.y) {
        light.cells_x = longest;
        light.cells_y = max(uint(ceil(float(longest) * extent.y / extent.x)), 1u);
    } else {
        light.cells_x = max(uint(ceil(float(longest) * extent.x / extent.y)), 1u);
        light.cells_y = longest;
    }
#endif
}
