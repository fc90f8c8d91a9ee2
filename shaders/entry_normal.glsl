// entry_normal.glsl — G-buffer entry i's camera-facing unit normal (and
// its depth's uncertainty): its
// own (B_G_NORMAL) where the host's depth and normal made it (id
// DEPTH_SURFACE, `gbuffer_from_depth.comp`), else its triangle's
// (B_TRIANGLE_NORMALS, negated when its word has FLAG_NORMAL_FLIPPED).
// The CPU twin keeps a normal per entry (`GBuffer::normal`). Include after
// common.glsl and both bindings.
vec3 entry_normal(uint i, uint word) {
    uint id = gbuffer_triangle(word);
    return id == DEPTH_SURFACE ? g_normal[i].xyz : receiver_normal(triangle_normals[id], word);
}

// How far entry i's P may lie off its surface along the normal: its
// depth's error where the host's depth made it, else 0 (P is exact to
// rounding). The frustum test's depth tolerance grows by it.
float entry_depth_uncertainty(uint i, uint word) {
    return gbuffer_triangle(word) == DEPTH_SURFACE ? g_normal[i].w : 0.0;
}
