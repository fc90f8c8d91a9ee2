// gbuffer_store.glsl — the G-buffer entry of one pixel from the triangle
// its centre ray sees, shared by the G-buffer producers: `gbuffer.comp`
// (the triangle a BVH traversal hit) and `gbuffer_from_visibility.comp`
// (the triangle the host's visibility buffer names). Both refine the hit
// on the triangle's plane, so the same triangle gives the same entry bit
// for bit. `gbuffer_from_depth.comp` stores its surfaces with
// `store_entry` too. Include after common.glsl, the frame, triangle, normal,
// G-buffer and counter bindings, counters.glsl and surface_hit.glsl.

void store_miss(uint i) {
    g_id_flags[i] = ID_MASK;
    g_position[i] = vec3(0.0);
    g_axis_x[i] = vec3(0.0);
    g_axis_y[i] = vec3(0.0);
}

// Stores pixel i's entry: the surface of camera-facing normal n that its
// centre ray d meets at t > 0, named `id`, with `flags` so far.
void store_entry(uint i, uint id, vec3 d, float t, vec3 n, uint flags) {
    vec3 p = d * t;
    if (faces_light(p, n)) flags |= FLAG_SHADOW_TESTED;
    vec3 ex, ey;
    if (microquad_axes(d, t, n, ex, ey)) flags |= FLAG_AXES_CLAMPED;

    g_id_flags[i] = (flags << ID_BITS) | id;
    g_position[i] = p;
    g_axis_x[i] = ex;
    g_axis_y[i] = ey;
    count_add(C_HITS, 1u);
    count_add(C_SHADOW_TESTED, (flags & FLAG_SHADOW_TESTED) != 0u ? 1u : 0u);
    count_add(C_CLAMPED, (flags & FLAG_AXES_CLAMPED) != 0u ? 1u : 0u);
}

// Pixel i's centre ray d sees triangle `id`; t is the ray's parameter
// where the triangle's plane gives none (`plane_t`), or ≤ 0 when there is
// no other. Returns false (and stores a miss) when the ray does not cross
// the plane in front of the eye.
bool store_surface(uint i, uint id, vec3 d, float t) {
    // The triangle's normal as the host computed it in f64: one from the
    // f32 vertices (error ~ε·|v|/|edge|) flipped 1.06e-4 of the deckchair's
    // samples at 960×540 in the tangent-plane test, which compares heights
    // against 2^-8 of a µQuad.
    vec3 n = triangle_normals[id];
    uint flags = FLAG_HIT;
    if (dot(n, d) > 0.0) {
        n = -n;
        flags |= FLAG_NORMAL_FLIPPED;
    }
    t = plane_t(id, n, d, t);
    if (!(t > 0.0)) {
        store_miss(i);
        return false;
    }
    store_entry(i, id, d, t, n, flags);
    return true;
}
