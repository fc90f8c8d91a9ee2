// pixel_frustum.glsl — one pixel's frustum and the frustum-triangle test,
// shared by evaluate's two steps (evaluate.comp). The GPU twin of
// `cpu::evaluate::{pixel_frustum, triangle_mask}` and
// `cpu::light_samples` (paper-notes/frustum-test.md, Wyman et al. 2015,
// §4): a per-pixel depth test at the µQuad centre, then the three
// shadow-volume side planes as affine edge functions over the µQuad — LUT
// masks (MODE_LUT32), all 32 samples evaluated (MODE_EXACT32), or the
// centre only (MODE_ONE) — ANDed per triangle; under an area light the
// same over the light's disk. Include after the bindings, light_view.glsl,
// loop_budget.glsl and entry_normal.glsl.

// The pixel in eye space, as the CPU twin's `PixelFrustum` (the frustum
// test runs in eye space: its depth test then sees the same floats in
// every frame while the light moves; see evaluate::triangle_mask).
vec3 px_p, px_normal, px_ex, px_ey;
// LightSetup::light_from(P): the direction toward a directional light
// (light.rot_z), or the point light's position minus P.
vec3 px_light;
// The depth tolerance's part that does not depend on the triangle: 2^-8 of
// the µQuad, plus the depth's uncertainty where the host's depth made P.
float px_microquad_part;
uint px_receiver;
uint px_cascade;
vec2 px_lo, px_hi; // the µQuad's level-0 grid box
bool px_has_cells;
uint px_cover;    // the centre cell's cover triangle, or NO_COVER
uint px_wanted;   // the samples that count (edge_receivers.glsl)
// Soft shadows (frame.light_samples): the light's disk seen from P
// (LightSetup::light_disk_from), its samples at c + (u-1/2) du + (v-1/2) dv.
bool px_soft;
vec3 px_disk_c, px_disk_u, px_disk_v;

// frustum::may_shadow: the per-pixel depth test at P (t = vertices − P).
// Vector::pow2_normalised: v scaled by the power of two that brings its
// largest component into [1, 2), exact, so the plane normal's squared
// length stays in range at any scene scale.
vec3 pow2_normalised(vec3 v) {
    float m = max(max(abs(v.x), abs(v.y)), abs(v.z));
    uint exponent = floatBitsToUint(m) & 0x7F800000u;
    if (m == 0.0 || exponent == 0x7F800000u) return v;
    precise vec3 scaled = v * uintBitsToFloat(0x7F000000u - min(exponent, 0x7E800000u));
    return scaled;
}

bool may_shadow(vec3 t0, vec3 t1, vec3 t2, vec3 light_rel) {
    precise float height = max_of3(dot(px_normal, t0), dot(px_normal, t1), dot(px_normal, t2));
    // The tolerance is this plus a non-negative term (no fused ops:
    // rounding is monotone), so the lengths wait until the height passes it.
    precise float microquad_part = px_microquad_part;
    if (!(height > microquad_part)) return false;
    precise float reach = max_of3(length(t0), length(t1), length(t2));
    precise float tolerance = microquad_part + float(DEPTH_TOLERANCE_ROUNDING) * reach;
    if (!(height > tolerance)) return false;   // wholly below the tangent plane
    precise vec3 n = pow2_normalised(cross(t1 - t0, t2 - t0));
    precise float facing = light.projection == 0u ? dot(n, light_rel) : dot(n, light_rel - t0);
    if (facing == 0.0) return false;           // seen edge-on from the light
    if (facing < 0.0) n = -n;
    precise float beyond = dot(n, t0);
    return beyond > tolerance * length(n);     // P beyond the plane, away from the light
}

// frustum::side_plane_normal (for a point light (x − l) × (y − x), which
// does not cancel when the light is far).
vec3 side_plane_normal(vec3 x, vec3 y, vec3 light_rel) {
    precise vec3 n = light.projection == 0u ? cross(y - x, light_rel)
                                            : cross(x - light_rel, y - x);
    return n;
}

// frustum::winding: one orientation for all three edges (see there why
// each edge must not orient itself by its own third vertex).
float winding(vec3 t0, vec3 t1, vec3 t2, vec3 light_rel) {
    precise float w = dot(side_plane_normal(t0, t1, light_rel), t2 - t0);
    return w;
}

// frustum::edge_function: (α, β, γ) of the side plane through x→y, flipped
// when the triangle winds negatively.
vec3 edge_function(vec3 x, vec3 y, vec3 light_rel, bool flip) {
    precise vec3 n = side_plane_normal(x, y, light_rel);
    if (flip) n = -n;
    precise vec3 e = vec3(-dot(n, x), dot(n, px_ex), dot(n, px_ey));
    return e;
}

// EdgeLut::lookup, in f32 as the CPU twin computes it; `cheap` says the
// saturated branch answered (no table read).
uint lut_mask(vec3 e, out bool cheap) {
    precise float r = sqrt(e.y * e.y + e.z * e.z);
    cheap = !(abs(e.x) < HALF_DIAGONAL * r);
    if (cheap) {
        return (e.x >= 0.0 && r >= 0.0) ? FULL_MASK : 0u;
    }
    precise float d = e.x / r;
    int rows = int(frame.lut_angles), columns = int(frame.lut_distances);
    precise float angle_f = (atan(e.z, e.y) + PI) * frame.lut_angle_scale;
    int angle = int(floor(angle_f));
    angle = angle >= rows ? angle - rows : max(angle, 0);
    precise float distance_f = (d + HALF_DIAGONAL) * frame.lut_distance_scale;
    int distance = clamp(int(floor(distance_f)), 0, columns - 1);
    return edge_lut[angle * columns + distance];
}

// frustum::exact_edge_mask: the edge function at every sample.
uint exact_mask(vec3 e) {
    uint mask = 0u;
    [[unroll]] for (int i = 0; i < 32; ++i) {
        precise float f = e.x + e.y * (frame.pattern[i].x - 0.5) + e.z * (frame.pattern[i].y - 0.5);
        mask |= uint(f >= 0.0) << i;
    }
    return mask;
}

// frustum::saturated_edge: whether the edge keeps every sample on one side
// (2^-10 relative margin over the pattern's radius), and which.
bool saturated_edge(vec3 e, out uint m) {
    precise float r = sqrt(e.y * e.y + e.z * e.z);
    precise float reach = r * frame.pattern_radius * (1.0 + SATURATION_MARGIN);
    m = e.x > reach ? FULL_MASK : 0u;
    return e.x > reach || -e.x > reach;
}

// frustum::normalised_edge: e scaled by the power of two that brings
// max(|β|, |γ|) into [1, 2), exact, so that β² + γ² stays in range at any
// scene scale.
vec3 normalised_edge(vec3 e) {
    float m = max(abs(e.y), abs(e.z));
    uint exponent = floatBitsToUint(m) & 0x7F800000u;
    if (m == 0.0 || exponent == 0x7F800000u) return e;
    precise vec3 scaled = e * uintBitsToFloat(0x7F000000u - min(exponent, 0x7E800000u));
    return scaled;
}

// MaskRule::edge_mask: the samples edge e keeps inside, and whether the
// cheap path decided them.
uint edge_mask(vec3 e_in, out bool cheap) {
    vec3 e = normalised_edge(e_in);
    if (frame.mode == MODE_ONE) {
        cheap = true;
        return e.x >= 0.0 ? FULL_MASK : 0u;
    }
    if (frame.mode == MODE_LUT32) return lut_mask(e, cheap);
    uint m;
    cheap = saturated_edge(e, m);
    return cheap ? m : exact_mask(e);
}

// LightSetup::light_disk_from: the sun's disk, or a sphere light's disk
// facing P (scene::light_disk_f32: Duff et al. 2017's basis, the same
// operations in the same order).
void light_disk_from(vec3 p) {
    if (light.projection == 0u) {
        px_disk_c = light.rot_z;
        px_disk_u = frame.sun_axis_u;
        px_disk_v = frame.sun_axis_v;
        return;
    }
    precise vec3 c = light.origin - p;
    precise float len = length(c);
    precise vec3 n = c * (1.0 / len);
    float s = (floatBitsToUint(n.z) & 0x80000000u) != 0u ? -1.0 : 1.0;   // copysign(1, n.z)
    precise float a = -1.0 / (s + n.z);
    precise float b = n.x * n.y * a;
    precise vec3 u = vec3(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
    precise vec3 v = vec3(b, s + n.y * n.y * a, -n.y);
    precise float diameter = 2.0 * frame.light_radius;
    px_disk_c = c;
    px_disk_u = u * diameter;
    px_disk_v = v * diameter;
}

// frustum::soft::light_edge_function: the plane through P and edge x→y,
// as a line across the light's disk.
vec3 light_edge_function(vec3 x, vec3 y, bool flip) {
    precise vec3 n = cross(x, y);
    if (flip) n = -n;
    precise vec3 e = vec3(dot(n, px_disk_c), dot(n, px_disk_u), dot(n, px_disk_v));
    return e;
}

// frustum::soft::beyond_plane_function: a sphere light's samples beyond
// the triangle's plane, seen from P.
vec3 beyond_plane_function(vec3 t0, vec3 t1, vec3 t2) {
    precise vec3 m = cross(t1 - t0, t2 - t0);
    if (dot(m, t0) < 0.0) m = -m;
    precise vec3 e = vec3(dot(m, px_disk_c - t0), dot(m, px_disk_u), dot(m, px_disk_v));
    return e;
}

// frustum::soft::below_horizon_function: the samples the receiver hides.
vec3 below_horizon_function() {
    precise vec3 e = vec3(-dot(px_normal, px_disk_c), -dot(px_normal, px_disk_u),
                          -dot(px_normal, px_disk_v));
    return e;
}

// frustum::soft::may_shadow_soft: above the tangent plane, and P off the
// triangle's plane (either side), each by the tolerance.
bool may_shadow_soft(vec3 t0, vec3 t1, vec3 t2) {
    precise float height = max_of3(dot(px_normal, t0), dot(px_normal, t1), dot(px_normal, t2));
    precise float microquad_part = px_microquad_part;
    if (!(height > microquad_part)) return false;
    precise float reach = max_of3(length(t0), length(t1), length(t2));
    precise float tolerance = microquad_part + float(DEPTH_TOLERANCE_ROUNDING) * reach;
    if (!(height > tolerance)) return false;
    precise vec3 n = pow2_normalised(cross(t1 - t0, t2 - t0));
    precise float distance = abs(dot(n, t0));
    return distance > tolerance * length(n);
}

uint tests_spawned = 0u, depth_passed = 0u, cells_visited = 0u, saturated_masks = 0u;
uint levels_visited = 0u, masks_nonempty = 0u;
bool stop_when_full;   // the full-mask skip
bool covered = false;  // the cover triangle alone filled the mask

// Whether the receiver is done testing: its wanted samples are all set
// (evaluate_wanted's `full`).
bool done(uint mask) {
    return covered || (stop_when_full && (mask & px_wanted) == px_wanted);
}

// light_samples::occluded_light_samples: the light samples triangle
// (t0, t1, t2) hides from P, the AND of its edges (and for a sphere light
// its plane) over the light's disk. Unrolled: no loop trips to count.
uint soft_triangle_mask(vec3 t0, vec3 t1, vec3 t2) {
    if (!may_shadow_soft(t0, t1, t2)) return 0u;
    depth_passed += 1u;
    precise float o = dot(cross(t0, t1), t2);
    if (!(o != 0.0)) return 0u;   // P in the triangle's plane (or NaN)
    bool flip = o < 0.0;
    bool saturate = (frame.skips & SKIP_SATURATED_EDGES) != 0u;
    bool cheap;
    uint mask = edge_mask(light_edge_function(t0, t1, flip), cheap);
    bool all_cheap = cheap;
    if (mask != 0u || !saturate) {
        mask &= edge_mask(light_edge_function(t1, t2, flip), cheap);
        all_cheap = all_cheap && cheap;
    }
    if (mask != 0u || !saturate) {
        mask &= edge_mask(light_edge_function(t2, t0, flip), cheap);
        all_cheap = all_cheap && cheap;
    }
    if (light.projection != 0u && (mask != 0u || !saturate)) {
        mask &= edge_mask(beyond_plane_function(t0, t1, t2), cheap);
        all_cheap = all_cheap && cheap;
    }
    if (saturate && all_cheap) saturated_masks += 1u;
    if (mask != 0u) masks_nonempty += 1u;
    return mask;
}

// Whether masks pair µQuad samples with light samples (SampleMode::is_paired).
bool paired_mode() {
    return frame.mode == MODE_PAIRED32 || frame.mode == MODE_PAIRED64;
}

// The (light, µQuad) samples of this step's mask half
// (lut::paired_patterns): MODE_PAIRED64's second half turns both.
#ifdef MASK_HALF_HIGH
#define PAIR_LIGHT(i) frame.second_pattern[i]
#define PAIR_PIXEL(i) frame.second_pair_pattern[i]
#else
#define PAIR_LIGHT(i) frame.pattern[i]
#define PAIR_PIXEL(i) frame.pair_pattern[i]
#endif

// light_samples::PairedRays: pair i's offset from P to µQuad sample i,
// the disk point c_i from P, and the ray's direction from S_i.
void paired_ray(int i, out vec3 delta, out vec3 c, out vec3 d) {
    precise vec3 dl = px_ex * (PAIR_PIXEL(i).x - 0.5) + px_ey * (PAIR_PIXEL(i).y - 0.5);
    precise vec3 cl = px_disk_c + px_disk_u * (PAIR_LIGHT(i).x - 0.5)
        + px_disk_v * (PAIR_LIGHT(i).y - 0.5);
    delta = dl;
    c = cl;
    d = light.projection != 0u ? cl - dl : cl;
}

// PairedRays::below_horizon: the pairs whose ray leaves the tangent plane
// downward or along it.
uint paired_below_horizon() {
    uint mask = 0u;
    [[unroll]] for (int i = 0; i < 32; ++i) {
        vec3 delta, c, d;
        paired_ray(i, delta, c, d);
        precise float h = dot(px_normal, d);
        if (h <= 0.0) mask |= 1u << i;
    }
    return mask;
}

// light_samples::paired_occluded_samples: every pair's ray from its µQuad
// sample, the cone from S_i oriented by o - delta_i.m.
uint paired_triangle_mask(vec3 t0, vec3 t1, vec3 t2) {
    if (!may_shadow_soft(t0, t1, t2)) return 0u;
    depth_passed += 1u;
    precise vec3 m = cross(t1 - t0, t2 - t0);
    precise float o = dot(cross(t0, t1), t2);
    precise vec3 n0 = cross(t0, t1);
    precise vec3 n1 = cross(t1, t2);
    precise vec3 n2 = cross(t2, t0);
    precise vec3 e0 = t1 - t0;
    precise vec3 e1 = t2 - t1;
    precise vec3 e2 = t0 - t2;
    bool finite = light.projection != 0u;
    uint mask = 0u;
    [[unroll]] for (int i = 0; i < 32; ++i) {
        vec3 delta, c, d;
        paired_ray(i, delta, c, d);
        precise vec3 w = cross(delta, c);
        precise float oi = o - dot(delta, m);
        // S_i beyond the triangle's plane from P: inside the occluder, as
        // far as the µQuad can tell (paired_occluded_samples).
        if (!(oi * o > 0.0)) continue;
        bool flip = oi < 0.0;
        precise float f0 = dot(n0, d) + dot(e0, w);
        precise float f1 = dot(n1, d) + dot(e1, w);
        precise float f2 = dot(n2, d) + dot(e2, w);
        bool hit = (flip ? -f0 : f0) >= 0.0 && (flip ? -f1 : f1) >= 0.0
            && (flip ? -f2 : f2) >= 0.0;
        if (finite) {
            precise float g = dot(m, c - t0);
            hit = hit && (flip ? -g : g) >= 0.0;
        }
        if (hit) mask |= 1u << i;
    }
    if (mask != 0u) masks_nonempty += 1u;
    return mask;
}

// Occluded samples of one eye-relative triangle for this pixel.
uint triangle_mask(Triangle tri) {
    precise vec3 t0 = tri.a - px_p;
    precise vec3 t1 = tri.b - px_p;
    precise vec3 t2 = tri.c - px_p;
    if (px_soft) {
        return paired_mode() ? paired_triangle_mask(t0, t1, t2)
                                           : soft_triangle_mask(t0, t1, t2);
    }
    vec3 light_rel = px_light;
    if (!may_shadow(t0, t1, t2, light_rel)) return 0u;
    depth_passed += 1u;
    float w = winding(t0, t1, t2, light_rel);
    if (!(w != 0.0)) return 0u;   // edge-on from the light (or NaN)
    bool flip = w < 0.0;
    bool cheap;
    if ((frame.skips & SKIP_SATURATED_EDGES) == 0u) {
        uint m = edge_mask(edge_function(t0, t1, light_rel, flip), cheap)
            & edge_mask(edge_function(t1, t2, light_rel, flip), cheap)
            & edge_mask(edge_function(t2, t0, light_rel, flip), cheap);
        if (m != 0u) masks_nonempty += 1u;
        return m;
    }
    // The cheap path: stop at the first edge that leaves no sample.
    uint mask = edge_mask(edge_function(t0, t1, light_rel, flip), cheap);
    bool all_cheap = cheap;
    if (mask != 0u) {
        mask &= edge_mask(edge_function(t1, t2, light_rel, flip), cheap);
        all_cheap = all_cheap && cheap;
    }
    if (mask != 0u) {
        mask &= edge_mask(edge_function(t2, t0, light_rel, flip), cheap);
        all_cheap = all_cheap && cheap;
    }
    if (all_cheap) saturated_masks += 1u;
    if (mask != 0u) masks_nonempty += 1u;
    return mask;
}

// Whether this pixel tests cell entry `entry` found in cell (x, y) of its
// rectangle `r` at some level (CellEntry::tested_in): not its own receiver
// nor the cover triangle (tested first), and the triangle is absent from
// the cell to the left (or x is r's first column) and from the cell below
// (or y is r's first row).
bool tests_in_cell(uint entry, uint x, uint y, uvec4 r) {
    uint id = entry & ID_MASK;
    if (id == px_receiver || id == px_cover) return false;
    return ((entry & ENTRY_FIRST_COLUMN) != 0u || x == r.x)
        && ((entry & ENTRY_FIRST_ROW) != 0u || y == r.y);
}

// Whether pyramid level l of the pixel's cascade holds a placement.
bool level_used(uint l) {
    return (counters[C_LEVELS + px_cascade] & (1u << l)) != 0u;
}

// Whether this pixel tests overflow entry `entry`: one for its cascade.
bool tests_overflow(uint entry) {
    uint id = entry & ID_MASK;
    return id != px_receiver && id != px_cover && ((entry >> ID_BITS) & (1u << px_cascade)) != 0u;
}

// evaluate::pixel_frustum: the eye-space µQuad, its cascade, its cell
// rectangle, the cover triangle of the centre's cell and the samples that
// count. Receiver i is a pixel or an edge pixel's extra surface.
void pixel_frustum(uint i, uint cascade) {
    vec3 p = g_position[i], ex = g_axis_x[i], ey = g_axis_y[i];
    px_p = p;
    if (light.projection == 0u) {
        px_light = light.rot_z;
    } else {
        precise vec3 l = light.origin - p;
        px_light = l;
    }
    uint word = g_id_flags[i];
    px_receiver = gbuffer_triangle(word);
    px_cascade = cascade;
    // The host's f64 normal, not one rebuilt from the f32 vertices: the
    // tangent-plane test compares heights against 2^-8 of a µQuad, and a
    // normal rebuilt from f32 light-view vertices (error ~ε·|v|/|edge|)
    // flipped 1.1–1.8e-4 of the samples at 960×540 (wires, deckchair).
    // With the host's depth and normal: its normal (`entry_normal.glsl`).
    px_normal = entry_normal(i, word);
    px_ex = ex;
    px_ey = ey;
    precise float size = max(length(px_ex), length(px_ey));
    precise float microquad_part = float(DEPTH_TOLERANCE_MICROQUAD) * size
                                 + entry_depth_uncertainty(i, word);
    px_microquad_part = microquad_part;
    px_soft = frame.light_samples != 0u;
    if (px_soft) light_disk_from(p);
    px_has_cells = false;
    px_cover = NO_COVER;
    px_wanted = receiver_wanted(i);
    if (light.grid_disabled != 0u) return;
    receiver_grid_box(px_cascade, i, p, ex, ey, px_lo, px_hi);
    uvec4 cells;
    px_has_cells = cell_range(px_cascade, px_lo, px_hi, cells);
    vec3 p_light_view = to_light_view(p);
    bool in_front = light.projection == 0u || p_light_view.z > 0.0;
    if (px_has_cells && in_front && (frame.skips & SKIP_SHADOW_MAP) != 0u) {
        // evaluate::cover_of: the cover of the centre's cell on the finest
        // non-empty level that has one.
        vec2 c0 = grid_coords(px_cascade, ndc_of(p_light_view));
        uint level_start = light.cascade[px_cascade].cell_offset;
        for (uint l = 0u; l < light.cascade[px_cascade].levels && spend_trip(); ++l) {
            uvec2 d = level_dims(px_cascade, l);
            uvec4 r;
            if (level_used(l) && cell_range_at(px_cascade, l, px_lo, px_hi, r)) {
                vec2 c = ldexp(c0, ivec2(-int(l)));
                uint x = clamp(uint(max(c.x, 0.0)), r.x, r.z);
                uint y = clamp(uint(max(c.y, 0.0)), r.y, r.w);
                px_cover = ~cell_cover[cell_index_at(px_cascade, level_start, l, x, y)].y;
                if (px_cover != NO_COVER) break;
            }
            level_start += d.x * d.y;
        }
    }
}

