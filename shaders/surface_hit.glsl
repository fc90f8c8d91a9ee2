// surface_hit.glsl — what the G-buffer passes derive from a primary hit,
// the CPU twin's `gbuffer::{trace_primary, faces_light, microquad_axes}` in
// f32: the gbuffer pass for its centre rays, edge_surfaces for its sample
// rays. Include after common.glsl and the frame and triangle bindings.

// Refines the hit of direction d on triangle `id`, whose camera-facing
// host normal is n, on the triangle's plane: the hit test's t comes out of
// a cancellation (the deckchair's slats: 1.3e-5 relative, several times
// the 2^-8 µQuad depth tolerance, so neighbours shadowed their receiver);
// t = (n·A)/(n·D) with the host's f64 normal is good to a few ulps, as the
// CPU twin's f64 hit is. Keeps t where the plane's is not usable.
float plane_t(uint id, vec3 n, vec3 d, float t) {
    precise float t_plane = dot(n, scene_triangle(id).a) / dot(n, d);
    return t_plane > 0.0 && !isinf(t_plane) ? t_plane : t;
}

// Whether a surface point p with camera-facing normal n faces the light.
bool faces_light(vec3 p, vec3 n) {
    vec3 toward = frame.light_is_point != 0u ? normalize(frame.light_vec - p) : frame.light_vec;
    return dot(n, toward) > 0.0;
}

// µQuad axes of the plane with normal n hit at t along d:
// dP/dx = t (dD/dx − (n·dD/dx)/(n·D) D), likewise for y, then the grazing
// clamp (paper-notes/reference-estimator.md), identical to the CPU twin's.
// Returns whether the clamp applied.
bool microquad_axes(vec3 d, float t, vec3 n, out vec3 ex, out vec3 ey) {
    float n_dot_d = dot(n, d);
    ex = t * (frame.cam_dx - d * (dot(n, frame.cam_dx) / n_dot_d));
    ey = t * (frame.cam_dy - d * (dot(n, frame.cam_dy) / n_dot_d));
    float limit = frame.max_stretch * t * length(frame.cam_dx) * length(d);
    float lx = length(ex);
    float ly = length(ey);
    bool clamped = false;
    if (isnan(lx) || lx > limit) {
        ex = isinf(lx) || isnan(lx) ? vec3(0.0) : ex * (limit / lx);
        clamped = true;
    }
    if (isnan(ly) || ly > limit) {
        ey = isinf(ly) || isnan(ly) ? vec3(0.0) : ey * (limit / ly);
        clamped = true;
    }
    return clamped;
}
