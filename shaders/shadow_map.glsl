// shadow_map.glsl — the shadow-map baseline's arithmetic shared by
// shadow_map.vert, shadow_volume.vert, shadow_blur.comp and
// shadow_lookup.comp: the GPU twin of
// `baseline::shadow_map::{CascadeMap, light_distance, plane_distance,
// texel_world}` and `baseline::raster::MapDepth`, same operation order,
// every product and sum `precise` (no fused multiply-adds the CPU does not
// do). Include after light_view.glsl.

// raster::MapDepth::new: (near, range) of the map's depth. Orthographic:
// the receivers' distances grown by MAP_DEPTH_MARGIN of (their span + the
// first cascade's width) on each side; perspective: (near plane, unused).
vec2 map_depth_range() {
    float zmin = light.receiver_z[0], zmax = light.receiver_z[1];
    if (light.projection != 0u) {
        precise float n = zmin * MAP_NEAR_RATIO;
        return vec2(n, 0.0);
    }
    precise float span = zmax - zmin;
    precise vec2 e = light.cascade[0].ndc_max - light.cascade[0].ndc_min;
    float extent = light.cascade_count > 0u ? max(e.x, e.y) : 0.0;
    precise float margin = MAP_DEPTH_MARGIN * (span + extent);
    if (!(margin > 0.0) || isinf(margin)) margin = 1.0;
    precise float near = -zmax - margin;
    precise float range = span + margin + margin;
    return vec2(near, range);
}

// raster::MapDepth::distance: the light distance a stored depth stands
// for, +inf for the cleared far end.
float map_distance(vec2 range, float depth) {
    if (light.projection == 0u) {
        if (depth >= 1.0) return 1.0 / 0.0;
        precise float d = range.x + depth * range.y;
        return d;
    }
    if (depth <= 0.0) return 1.0 / 0.0;
    return range.x / depth;
}

// CascadeMap of cascade k: light-NDC corner of texel (0, 0), NDC size of a
// texel (cascade_frame: the fitted bounds grown by `reach` texels).
void map_frame(uint k, out vec2 origin, out vec2 texel) {
    vec2 extent = light.cascade[k].ndc_max - light.cascade[k].ndc_min;
    float inner = max(float(frame.map_side) - 2.0 * float(frame.map_reach), 1.0);
    texel = extent / inner;
    precise vec2 o = light.cascade[k].ndc_min - texel * float(frame.map_reach);
    origin = o;
}

vec2 texel_coords(vec2 origin, vec2 texel, vec2 ndc) {
    return (ndc - origin) / texel;
}

vec2 texel_centre(vec2 origin, vec2 texel, ivec2 t) {
    precise vec2 c = origin + (vec2(t) + 0.5) * texel;
    return c;
}

float light_distance(vec3 p) {
    return light.projection == 0u ? -p.z : p.z;
}

// plane_distance: where the light ray through NDC n meets the plane
// (point, normal); NaN/inf when the ray runs along it.
float plane_distance(vec2 n, vec3 point, vec3 normal) {
    vec3 origin = light.projection == 0u ? vec3(n, 0.0) : vec3(0.0);
    vec3 dir = light.projection == 0u ? vec3(0.0, 0.0, -1.0) : vec3(n, 1.0);
    precise float denom = dot3(normal, dir);
    precise float t = dot3(normal, point - origin) / denom;
    return t;
}

bool finite(float x) {
    return !isnan(x) && !isinf(x);
}

// moments::MomentDepth: (lo, range) of the moment depth u. A directional
// light's is the map's own depth range; a point light's is the receivers'
// distances grown by MAP_DEPTH_MARGIN of (their span + the nearest).
vec2 moment_depth_range() {
    if (light.projection == 0u) return map_depth_range();
    float zmin = light.receiver_z[0], zmax = light.receiver_z[1];
    precise float span = zmax - zmin;
    precise float margin = MAP_DEPTH_MARGIN * (span + zmin);
    if (!(margin > 0.0) || isinf(margin)) margin = 1.0;
    precise float lo = zmin - margin;
    precise float range = span + margin + margin;
    return vec2(lo, range);
}

// MomentDepth::of_distance.
float moment_of_distance(vec2 moment_range, float d) {
    precise float u = (d - moment_range.x) / moment_range.y;
    return isnan(u) ? 1.0 : clamp(u, 0.0, 1.0);
}

// MomentDepth::of_stored.
float moment_of_stored(vec2 depth_range, vec2 moment_range, float depth) {
    if (light.projection == 0u) return min(depth, 1.0);
    return moment_of_distance(moment_range, map_distance(depth_range, depth));
}

// Moments a filtered map keeps per texel (Filter::moments).
uint moment_count() {
    if (frame.map_filter == MAP_FILTER_ESM) return 1u;
    return frame.map_filter == MAP_FILTER_MSM ? 4u : 2u;
}

// The SHADOW_MAP buffer of a filtered map: the depths (one word per
// texel of every cascade), then the blur's rows, then its result (moment
// count words per texel each).
uint map_texels() {
    return light.cascade_count * frame.map_side * frame.map_side;
}
