// bin_placement.glsl — where a triangle goes in the light-space grid
// pyramid and which cells keep it, for the bin's steps (bin.comp): its
// placement and footprint (cpu::footprint, cpu::bin::place), whether its
// projection touches a cell (Footprint::touches), the behind-receivers
// cull (cpu::receivers, cpu::receiver_cull), the conservative shadow
// map's cover floor and the area light's penumbra bounds (cpu::penumbra).
// Include after the bindings, light_view.glsl and loop_budget.glsl.

// receiver_cull::upward_normal: the plane normal turned toward the light (+z);
// false when the light sees the triangle edge-on (or it is NaN).
bool upward_normal(Triangle t, out vec3 n) {
    precise vec3 m = cross(t.b - t.a, t.c - t.a);
    n = m.z < 0.0 ? -m : m;
    return n.z > 0.0;
}

// Height of t's plane (normal n) over light-view xy q.
float plane_height(Triangle t, vec3 n, vec2 q) {
    precise float h = t.a.z - (n.x * (q.x - t.a.x) + n.y * (q.y - t.a.y)) / n.z;
    return h;
}

// receiver_cull::plane_beyond_pyramid: the four corners at `depth` of the pyramid
// from the point light (the origin) through NDC [lo, hi] lie on the
// light's side of t's plane by a margin.
bool plane_beyond_pyramid(Triangle t, vec2 lo, vec2 hi, float depth) {
    precise vec3 n = cross(t.b - t.a, t.c - t.a);
    precise float light_side = -dot(n, t.a);
    if (!(light_side != 0.0)) return false;   // the light in the plane (or NaN)
    float side = sign(light_side);
    vec3 q0 = vec3(lo.x * depth, lo.y * depth, depth);
    vec3 q1 = vec3(hi.x * depth, lo.y * depth, depth);
    vec3 q2 = vec3(hi.x * depth, hi.y * depth, depth);
    vec3 q3 = vec3(lo.x * depth, hi.y * depth, depth);
    vec3 box_lo = min(min(min(vec3(0.0), q0), min(q1, q2)), min(min(q3, t.a), min(t.b, t.c)));
    vec3 box_hi = max(max(max(vec3(0.0), q0), max(q1, q2)), max(max(q3, t.a), max(t.b, t.c)));
    float margin = BEHIND_MARGIN * length(box_hi - box_lo) * length(n);
    return side * dot(n, q0 - t.a) > margin && side * dot(n, q1 - t.a) > margin
        && side * dot(n, q2 - t.a) > margin && side * dot(n, q3 - t.a) > margin;
}

// receiver_cull::beyond_every_light_sample: under an area light, the cull
// also needs every light sample on the receivers' side of the plane.
bool beyond_every_light_sample(Triangle t) {
    precise float grow = 1.0 + BEHIND_MARGIN;
    float r = frame.light_radius;
    if (light.projection == 0u) {
        vec3 n;
        if (!upward_normal(t, n)) return false;
        precise float sin_r = r / sqrt(1.0 + r * r);
        return n.z > sin_r * grow * length(n);
    }
    precise vec3 n = cross(t.b - t.a, t.c - t.a);
    return abs(dot(n, t.a)) > r * grow * length(n);
}

// receiver_cull::behind_receivers: whether triangle t (light view) lies behind every
// receiver that can test it in cell `cell` = (x, y) of level `level` of
// cascade k, so the cell need not list it: a directional light's plane
// below the receivers' box, a point light's plane beyond their pyramid.
bool behind_receivers(Triangle t, uint k, uint level, uint cell, uint x, uint y) {
    if ((frame.skips & SKIP_BEHIND_RECEIVERS) == 0u) return false;
    uvec2 r = cell_receivers[cell];
    if (r.x == 0xFFFFFFFFu) return true;   // no receiver touches the cell
    if (frame.light_radius > 0.0 && !beyond_every_light_sample(t)) return false;
    float z_min = from_ordered_bits(r.x);
    float reach = float(~r.y) + CELL_PADDING;
    // Level-l grid coordinates to level 0: times 2^l, exact.
    float up = float(1u << level);
    vec2 lo = ndc_of_grid(k, vec2(float(x) - reach, float(y) - reach) * up);
    vec2 hi = ndc_of_grid(k, vec2(float(x) + 1.0 + reach, float(y) + 1.0 + reach) * up);
    if (light.projection != 0u) return plane_beyond_pyramid(t, lo, hi, -z_min);
    vec3 n;
    if (!upward_normal(t, n)) return false;
    // No loop (see strictly_inside).
    float plane_max = max(max(plane_height(t, n, lo), plane_height(t, n, vec2(hi.x, lo.y))),
                          max(plane_height(t, n, hi), plane_height(t, n, vec2(lo.x, hi.y))));
    vec2 box_lo = min(min(lo, t.a.xy), min(t.b.xy, t.c.xy));
    vec2 box_hi = max(max(hi, t.a.xy), max(t.b.xy, t.c.xy));
    float z_lo = min(min(z_min, t.a.z), min(t.b.z, t.c.z));
    float z_hi = max(max(z_min, t.a.z), max(t.b.z, t.c.z));
    float size = length(box_hi - box_lo) + (z_hi - z_lo);
    float margin = BEHIND_MARGIN * size * (length(n) / n.z);
    return plane_max < z_min - margin;
}

// Whether light-view xy q is strictly inside the triangle with vertices
// a, b, c of winding w (glam's perp_dot a.x·b.y − a.y·b.x). No loops: a
// loop here, even one marked [[unroll]], counted toward lavapipe's loop cap
// once per cell and silently cut the count loop of large triangles.
bool strictly_inside(vec2 a, vec2 b, vec2 c, float w, vec2 q) {
    precise float s0 = w * ((b.x - a.x) * (q.y - a.y) - (b.y - a.y) * (q.x - a.x));
    precise float s1 = w * ((c.x - b.x) * (q.y - b.y) - (c.y - b.y) * (q.x - b.x));
    precise float s2 = w * ((a.x - c.x) * (q.y - c.y) - (a.y - c.y) * (q.x - c.x));
    return s0 > 0.0 && s1 > 0.0 && s2 > 0.0;
}

// shadow_map_cover::cover_floor: when t's light-space projection contains cell (x, y)
// of level `level` of cascade k, the lowest height of its plane over the cell (as ordered
// bits, never 0); else 0. Only with the shadow-map skip and a directional
// light.
uint cover_floor(Triangle t, uint k, uint level, uint x, uint y) {
    if ((frame.skips & SKIP_SHADOW_MAP) == 0u || light.projection != 0u) return 0u;
    vec3 n;
    if (!upward_normal(t, n)) return 0u;
    float up = float(1u << level);
    vec2 q0 = ndc_of_grid(k, vec2(float(x), float(y)) * up);
    vec2 q1 = ndc_of_grid(k, vec2(float(x) + 1.0, float(y)) * up);
    vec2 q2 = ndc_of_grid(k, vec2(float(x) + 1.0, float(y) + 1.0) * up);
    vec2 q3 = ndc_of_grid(k, vec2(float(x), float(y) + 1.0) * up);
    vec2 a = t.a.xy, b = t.b.xy, c = t.c.xy;
    precise float w = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if (!(strictly_inside(a, b, c, w, q0) && strictly_inside(a, b, c, w, q1)
          && strictly_inside(a, b, c, w, q2) && strictly_inside(a, b, c, w, q3))) return 0u;
    float floor_z = min(min(plane_height(t, n, q0), plane_height(t, n, q1)),
                        min(plane_height(t, n, q2), plane_height(t, n, q3)));
    return max(ordered_bits(floor_z), 1u);
}


// footprint::Footprint: the level a triangle is binned at, its rectangle
// there, its vertices in that level's grid coordinates and the side of
// each edge it lies on (0: a sliver, every rectangle cell touched).
struct Footprint {
    uint level;
    uvec4 rect;
    vec2 v0;
    vec2 v1;
    vec2 v2;
    float orientation;
    vec2 pad;   // the penumbra pad in this level's cells (0: a point-like light)
};

// footprint::footprint from the vertices' level-0 grid coordinates; false
// when the padded box misses level 0 (culled).
bool footprint(uint k, vec2 g0, vec2 g1, vec2 g2, vec2 pad, out Footprint f) {
    f = Footprint(0u, uvec4(0u), vec2(0.0), vec2(0.0), vec2(0.0), 0.0, vec2(0.0));
    precise vec2 lo = min(min(g0, g1), g2) - pad;
    precise vec2 hi = max(max(g0, g1), g2) + pad;
    uvec4 r;
    if (!cell_range(k, lo, hi, r)) return false;
    uint levels = light.cascade[k].levels;
    uint top = max(levels, 1u) - 1u;
    uint limit = max(light.cascade[k].level_cells, 1u);
    bool found = false;
    for (uint l = 0u; l < levels && spend_trip(); ++l) {
        if (!cell_range_at(k, l, lo, hi, r)) continue;
        // Sides are at most MAX_GRID_SIDE (2^12), so the area fits a uint.
        if (l == top || (r.z - r.x + 1u) * (r.w - r.y + 1u) <= limit) {
            f.level = l;
            f.rect = r;
            found = true;
            break;
        }
    }
    if (!found) return false;
    ivec2 e = ivec2(-int(f.level));
    f.v0 = ldexp(g0, e);
    f.v1 = ldexp(g1, e);
    f.v2 = ldexp(g2, e);
    precise vec2 d1 = f.v1 - f.v0;
    precise vec2 d2 = f.v2 - f.v0;
    precise float winding = d1.x * d2.y - d1.y * d2.x;
    precise float scale = (abs(d1.x) + abs(d1.y)) * (abs(d2.x) + abs(d2.y));
    f.orientation = abs(winding) > SLIVER_RATIO * scale ? sign(winding) : 0.0;
    f.pad = ldexp(pad, e);
    return true;
}

// One edge a→b of Footprint::touches: whether some corner of the padded
// cell box is inside it, up to rounding. No loops (see strictly_inside).
bool edge_reaches(vec2 a, vec2 b, float o, float lo_x, float lo_y, float hi_x, float hi_y) {
    precise float dx = b.x - a.x, dy = b.y - a.y;
    precise float r0x = lo_x - a.x, r0y = lo_y - a.y;
    precise float r1x = hi_x - a.x, r1y = lo_y - a.y;
    precise float r2x = hi_x - a.x, r2y = hi_y - a.y;
    precise float r3x = lo_x - a.x, r3y = hi_y - a.y;
    precise float e0 = o * (dx * r0y - dy * r0x);
    precise float e1 = o * (dx * r1y - dy * r1x);
    precise float e2 = o * (dx * r2y - dy * r2x);
    precise float e3 = o * (dx * r3y - dy * r3x);
    float inside = max(max(e0, e1), max(e2, e3));
    precise float reach = max(max(abs(r0x) + abs(r0y), abs(r1x) + abs(r1y)),
                              max(abs(r2x) + abs(r2y), abs(r3x) + abs(r3y)));
    precise float bound = TOUCH_ROUNDING * (abs(dx) + abs(dy)) * reach;
    return inside >= -bound;
}

// Footprint::touches: whether the projection touches the padded box of
// cell (x, y) of its level (false outside its rectangle).
bool touches_grown(Footprint f, int x, int y, vec2 grow) {
    ivec4 r = ivec4(f.rect);
    if (x < r.x || x > r.z || y < r.y || y > r.w) return false;
    if (f.orientation == 0.0) return true;
    precise float lo_x = float(x) - grow.x, lo_y = float(y) - grow.y;
    precise float hi_x = float(x) + 1.0 + grow.x, hi_y = float(y) + 1.0 + grow.y;
    return edge_reaches(f.v0, f.v1, f.orientation, lo_x, lo_y, hi_x, hi_y)
        && edge_reaches(f.v1, f.v2, f.orientation, lo_x, lo_y, hi_x, hi_y)
        && edge_reaches(f.v2, f.v0, f.orientation, lo_x, lo_y, hi_x, hi_y);
}

// Footprint::touches: the cell box grown by the pad and the padding.
bool touches(Footprint f, int x, int y) {
    precise vec2 grow = f.pad + CELL_PADDING;
    return touches_grown(f, x, y, grow);
}

// penumbra::penumbra_reaches_cell: a directional area light's per-cell bound,
// from the cell's lowest receiver and its reach (behind-receivers skip).
// penumbra::sphere_pad_in_cell: a sphere light's pad for the receivers
// of cell c = (x, y) of level `level`; false keeps the frame-wide pad.
bool sphere_pad_in_cell(Triangle t, uint k, uint level, uvec2 r, uint x, uint y, out float pad) {
    pad = 0.0;
    precise float grow = 1.0 + PENUMBRA_MARGIN;
    float rad = frame.light_radius;
    float around = float(~r.y) + CELL_PADDING;
    float up = float(1u << level);
    vec2 lo = ndc_of_grid(k, vec2(float(x) - around, float(y) - around) * up);
    vec2 hi = ndc_of_grid(k, vec2(float(x) + 1.0 + around, float(y) + 1.0 + around) * up);
    precise float rho_cell = length(max(abs(lo), abs(hi)));
    precise float depth = -from_ordered_bits(r.x);
    precise float far = depth * sqrt(1.0 + rho_cell * rho_cell) * grow;
    float near = min(min(t.a.z, t.b.z), t.c.z);
    if (!(!isinf(far) && !isnan(far) && near > 2.0 * rad * grow)) return false;
    if (far <= near) return true;   // every receiver nearer than the triangle
    precise float denominator = near * (far + rad) - 2.0 * far * rad * grow;
    if (!(denominator > 0.0)) return false;
    precise float tan_theta = rad * (far - near) / denominator * grow;
    precise float rho = max(max(length(t.a.xy / t.a.z), length(t.b.xy / t.b.z)), length(t.c.xy / t.c.z)) * grow;
    precise float product = rho * tan_theta;
    if (!(product <= MAX_PENUMBRA_TAN_PRODUCT)) return false;
    precise float p = tan_theta * (1.0 + rho * rho) / (1.0 - product) * grow;
    pad = p;
    return true;
}

bool penumbra_reaches_cell(Triangle t, uint k, Footprint f, uint c, uint x, uint y) {
    if ((frame.skips & SKIP_BEHIND_RECEIVERS) == 0u || frame.light_radius == 0.0) return true;
    uvec2 r = cell_receivers[c];
    precise float pad_ndc;
    if (light.projection == 0u) {
        float z_min = from_ordered_bits(r.x);
        float top = max(max(t.a.z, t.b.z), t.c.z);
        precise float p = frame.light_radius * max(top - z_min, 0.0) * (1.0 + PENUMBRA_MARGIN);
        pad_ndc = p;
    } else if (!sphere_pad_in_cell(t, k, f.level, r, x, y, pad_ndc)) {
        return true;
    }
    CascadeGrid grid = light.cascade[k];
    precise vec2 pad = pad_ndc * vec2(float(grid.cells_x), float(grid.cells_y))
        / (grid.ndc_max - grid.ndc_min);
    precise vec2 grow = ldexp(pad, ivec2(-int(f.level))) + float(~r.y) + CELL_PADDING;
    return touches_grown(f, int(x), int(y), grow);
}

// bin::place in cascade k: PLACEMENT_CULLED, PLACEMENT_OVERFLOW, or
// PLACEMENT_CELLS with the footprint.
#define PLACEMENT_CELLS 0u

// penumbra::penumbra_pad: how far beyond its projection (light NDC) the
// triangle may hide part of an area light; false: it overflows.
bool penumbra_pad(Triangle t, vec2 n0, vec2 n1, vec2 n2, out float pad) {
    float r = frame.light_radius;
    pad = 0.0;
    if (r == 0.0) return true;
    precise float grow = 1.0 + PENUMBRA_MARGIN;
    if (light.projection == 0u) {
        float top = max(max(t.a.z, t.b.z), t.c.z);
        precise float p = r * max(top - light.receiver_z.x, 0.0) * grow;
        pad = p;
        return true;
    }
    float z_min = min(min(t.a.z, t.b.z), t.c.z);
    precise float clearance = z_min - 2.0 * r * grow;
    if (!(clearance > 0.0)) return false;
    precise float tan_theta = r / clearance * grow;
    precise float rho = max(max(length(n0), length(n1)), length(n2)) * grow;
    precise float product = rho * tan_theta;
    if (!(product <= MAX_PENUMBRA_TAN_PRODUCT)) return false;
    precise float p = tan_theta * (1.0 + rho * rho) / (1.0 - product) * grow;
    pad = p;
    return true;
}

uint place(Triangle t, uint k, out Footprint f) {
    f = Footprint(0u, uvec4(0u), vec2(0.0), vec2(0.0), vec2(0.0), 0.0, vec2(0.0));
    if (light.grid_disabled != 0u) return PLACEMENT_OVERFLOW;
    vec2 n0, n1, n2;
    if (light.projection == 0u) {
        n0 = t.a.xy; n1 = t.b.xy; n2 = t.c.xy;
    } else {
        uint in_front = uint(t.a.z > 0.0) + uint(t.b.z > 0.0) + uint(t.c.z > 0.0);
        if (in_front == 0u) {
            // A sphere light's samples reach z = -R behind its image plane.
            bool reaches = max(max(t.a.z, t.b.z), t.c.z) > -frame.light_radius;
            return reaches ? PLACEMENT_OVERFLOW : PLACEMENT_CULLED;   // wholly behind the light
        }
        if (in_front < 3u) return PLACEMENT_OVERFLOW;  // crosses the light's plane
        n0 = t.a.xy / t.a.z; n1 = t.b.xy / t.b.z; n2 = t.c.xy / t.c.z;
    }
    float pad_ndc;
    if (!penumbra_pad(t, n0, n1, n2, pad_ndc)) return PLACEMENT_OVERFLOW;
    CascadeGrid grid = light.cascade[k];
    precise vec2 pad = pad_ndc * vec2(float(grid.cells_x), float(grid.cells_y))
        / (grid.ndc_max - grid.ndc_min);
    if (!footprint(k, grid_coords(k, n0), grid_coords(k, n1), grid_coords(k, n2), pad, f)) return PLACEMENT_CULLED;
    return PLACEMENT_CELLS;
}

// The placement the bin uses: without the outside-bounds skip a triangle
// that misses the grid is tested by every pixel of the cascade (the
// overflow list) instead of dropped.
uint placement_in(Triangle t, uint k, out Footprint f) {
    uint p = place(t, k, f);
    if (p == PLACEMENT_CULLED && (frame.skips & SKIP_OUTSIDE_BOUNDS) == 0u) p = PLACEMENT_OVERFLOW;
    return p;
}
